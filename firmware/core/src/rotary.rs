//! The rotary location-error stage: the deviation of the tool tip relative to the workpiece, along
//! the linear axes X, Y, Z, caused by the location errors of the two rotary axes of an AC
//! trunnion table.
//!
//! # Glossary
//! - **AC trunnion**: the workpiece sits on a C table (rotation about Z) carried by an A cradle
//!   (rotation about X); the tool moves in X, Y, Z. Nominally both axis lines pass through the
//!   **pivot**, the machine position (X, Y, Z counts) given in [`RotaryLocationSpec::pivot_counts`].
//! - **location errors** (ISO 230-7 names, 8 constants): the A axis line passes through
//!   (0, EY0A, EZ0A) relative to the pivot and is turned by EB0A about Y and EC0A about Z; the C
//!   axis line (in the frame carried by A) passes through (EX0C, EY0C, 0) and is turned by EA0C
//!   about X and EB0C about Y. Offsets in µm, angles in µrad, all small.
//! - **tool tip**: the commanded spindle position minus the tool length along Z:
//!   q = (X, Y, Z − L) − pivot, µm.
//! - **deviation** (the sign convention of the whole crate): reached − target. The rotary errors
//!   move the workpiece point under the tool by e (the workpiece point meant to be at q is at
//!   q + e), so the tool reaches, relative to the workpiece, −e: the stage's deviation is −e and,
//!   like every error, it is subtracted from the command (the tool follows the workpiece by +e).
//!
//! # Model (first order in the location errors)
//! Rotation about a line through o with direction R(ε)·n instead of n through the origin maps p
//! to R_n p + (I − R_n) o + (ε − R_n ε) × (R_n p) to first order in o and ε. Composed for the
//! chain A ∘ C with w = R_Aᵀ q (the tool tip in the frame carried by A):
//!
//! e = R_A [(I − R_C) o_C + (ε_C − R_C ε_C) × w] + (I − R_A) o_A + (ε_A − R_A ε_A) × q,
//!
//! with o_A = (0, EY0A, EZ0A), ε_A = (0, EB0A, EC0A), o_C = (EX0C, EY0C, 0),
//! ε_C = (EA0C, EB0C, 0). The neglected terms are products of two location errors (|ε|·|o|,
//! |ε|²·|q|, |ε|·|δ|): for each error ≤ 50 µrad / 50 µm and |q| ≤ 840 mm they stay below
//! 0.03 µm (checked against the exact homogeneous transforms in `tests/group.rs`: 0.016 µm seen).
//!
//! The angle-dependent parts ((I − R_C) o_C, ε_C − R_C ε_C, (I − R_A) o_A, ε_A − R_A ε_A and
//! sin/cos of both angles) are cached in [`RotaryCache`] and recomputed only when a commanded
//! angle changes; each cycle then costs a few multiply-adds.
//!
//! # sin/cos
//! `libm::sincosf` computes in double precision internally, which a Cortex-M4F emulates in
//! software: about 2 400 instructions per call, 5 000 per cycle whenever both angles move. So
//! `libm::sincos` is called at load only, for [`SINCOS_STEPS`] coarse angles k·step per axis
//! (step = ⌈counts per revolution / 64⌉); per change of the angle n = k·step + m counts the cache
//! takes sin θ = s_k·cos r + c_k·sin r, cos θ = c_k·cos r − s_k·sin r with r = m·2π/cpr < 0.099
//! and the Taylor polynomials
//! sin r ≈ r − r³/6 + r⁵/120, cos r ≈ 1 − r²/2 + r⁴/24 − r⁶/720 (truncation below 2e-11): only
//! integer division and `+ − ×`, so host and target agree bit for bit; within 2e-7 of the exact
//! values (tested).

use crate::error::{Field, ImageError};

/// The 8 location errors of an AC trunnion and the geometry the stage needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotaryLocationSpec {
    /// C axis line offset in X, µm.
    pub ex0c_um: f32,
    /// C axis line offset in Y, µm.
    pub ey0c_um: f32,
    /// C axis line turned about X, µrad.
    pub ea0c_urad: f32,
    /// C axis line turned about Y, µrad.
    pub eb0c_urad: f32,
    /// A axis line offset in Y, µm.
    pub ey0a_um: f32,
    /// A axis line offset in Z, µm.
    pub ez0a_um: f32,
    /// A axis line turned about Y, µrad.
    pub eb0a_urad: f32,
    /// A axis line turned about Z, µrad.
    pub ec0a_urad: f32,
    /// Machine position of the nominal intersection of A and C, counts of X, Y, Z.
    pub pivot_counts: [i64; 3],
    /// Tool length (spindle gauge line to tool tip, along −Z), µm.
    pub tool_length_um: f32,
}

impl RotaryLocationSpec {
    /// The 8 constants in the order of the fields (µm, µm, µrad, µrad, µm, µm, µrad, µrad).
    pub fn constants(&self) -> [f32; 8] {
        [
            self.ex0c_um,
            self.ey0c_um,
            self.ea0c_urad,
            self.eb0c_urad,
            self.ey0a_um,
            self.ez0a_um,
            self.eb0a_urad,
            self.ec0a_urad,
        ]
    }

    /// Range checks: every constant finite, offsets ≤ 10 mm, angles ≤ 10 mrad (the model is
    /// first order), |pivot| ≤ 2^62 counts, tool length in [0, 10 m].
    pub fn validate(&self) -> Result<(), ImageError> {
        for (i, v) in self.constants().into_iter().enumerate() {
            if !v.is_finite() {
                return Err(ImageError::NonFinite {
                    field: Field::RotaryLocation,
                    index: i as u16,
                });
            }
            if libm::fabsf(v) > 1.0e4 {
                return Err(ImageError::OutOfRange {
                    field: Field::RotaryLocation,
                    index: i as u16,
                });
            }
        }
        for (i, p) in self.pivot_counts.iter().enumerate() {
            if !(-(1i64 << 62)..=(1i64 << 62)).contains(p) {
                return Err(ImageError::OutOfRange {
                    field: Field::Pivot,
                    index: i as u16,
                });
            }
        }
        let l = self.tool_length_um;
        if !l.is_finite() {
            return Err(ImageError::NonFinite {
                field: Field::ToolLength,
                index: 0,
            });
        }
        if !(0.0..=1.0e7).contains(&l) {
            return Err(ImageError::OutOfRange {
                field: Field::ToolLength,
                index: 0,
            });
        }
        Ok(())
    }
}

/// Coarse angles per turn of the sin/cos table.
pub const SINCOS_STEPS: usize = 64;

/// sin/cos of a rotary axis at its [`SINCOS_STEPS`] coarse angles k·step·2π/cpr, step =
/// ⌈cpr/64⌉ counts (via `libm::sincos`, at load).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SinCosTable {
    step: u32,
    rad_per_count: f32,
    sin: [f32; SINCOS_STEPS],
    cos: [f32; SINCOS_STEPS],
}

impl SinCosTable {
    pub(crate) const ZERO: SinCosTable = SinCosTable {
        step: 0,
        rad_per_count: 0.0,
        sin: [0.0; SINCOS_STEPS],
        cos: [0.0; SINCOS_STEPS],
    };

    /// For an axis of `cpr` (≥ 1) counts per revolution.
    pub(crate) fn new(cpr: u32) -> SinCosTable {
        let cpr = cpr.max(1);
        let step = cpr.div_ceil(SINCOS_STEPS as u32);
        let rad = core::f64::consts::TAU / cpr as f64;
        let mut t = SinCosTable {
            step,
            rad_per_count: rad as f32,
            ..SinCosTable::ZERO
        };
        for k in 0..SINCOS_STEPS {
            let (s, c) = libm::sincos((k as u64 * step as u64) as f64 * rad);
            t.sin[k] = s as f32;
            t.cos[k] = c as f32;
        }
        t
    }

    /// (sin, cos) of the angle `n`·2π/cpr for `n` < cpr (see the module's notes): the coarse
    /// angle k = n / step from the table, the remainder r = (n − k·step)·2π/cpr by polynomials.
    #[inline]
    pub(crate) fn sincos(&self, n: u32) -> (f32, f32) {
        let k = n.checked_div(self.step).unwrap_or(0);
        let rem = n - k.wrapping_mul(self.step);
        let r = rem as f32 * self.rad_per_count;
        let k = k as usize % SINCOS_STEPS;
        let r2 = r * r;
        let sin_r = r * (1.0 - r2 * (1.0 / 6.0 - r2 * (1.0 / 120.0)));
        let cos_r = 1.0 - r2 * (0.5 - r2 * (1.0 / 24.0 - r2 * (1.0 / 720.0)));
        let (s, c) = (self.sin[k], self.cos[k]);
        (s * cos_r + c * sin_r, c * cos_r - s * sin_r)
    }
}

/// The validated stage: constants in µm and radians, the pivot, the axes' scales.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct RotaryStage {
    /// o_C = (EX0C, EY0C), µm.
    pub(crate) o_c: [f32; 2],
    /// ε_C = (EA0C, EB0C), rad.
    pub(crate) e_c: [f32; 2],
    /// o_A = (EY0A, EZ0A), µm.
    pub(crate) o_a: [f32; 2],
    /// ε_A = (EB0A, EC0A), rad.
    pub(crate) e_a: [f32; 2],
    pub(crate) pivot_counts: [i64; 3],
    pub(crate) tool_length_um: f32,
    /// µm per count of X, Y, Z.
    pub(crate) um_per_count: [f32; 3],
    /// sin/cos tables of A and C.
    pub(crate) sincos: [SinCosTable; 2],
    /// Group slots of X, Y, Z, A, C.
    pub(crate) slot: [u8; 5],
}

impl RotaryStage {
    pub(crate) const ZERO: RotaryStage = RotaryStage {
        o_c: [0.0; 2],
        e_c: [0.0; 2],
        o_a: [0.0; 2],
        e_a: [0.0; 2],
        pivot_counts: [0; 3],
        tool_length_um: 0.0,
        um_per_count: [0.0; 3],
        sincos: [SinCosTable::ZERO; 2],
        slot: [0; 5],
    };

    pub(crate) fn new(
        spec: &RotaryLocationSpec,
        um_per_count: [f32; 3],
        counts_per_rev: [u32; 2],
        slot: [u8; 5],
    ) -> RotaryStage {
        const URAD: f32 = 1.0e-6;
        RotaryStage {
            o_c: [spec.ex0c_um, spec.ey0c_um],
            e_c: [spec.ea0c_urad * URAD, spec.eb0c_urad * URAD],
            o_a: [spec.ey0a_um, spec.ez0a_um],
            e_a: [spec.eb0a_urad * URAD, spec.ec0a_urad * URAD],
            pivot_counts: spec.pivot_counts,
            tool_length_um: spec.tool_length_um,
            um_per_count,
            sincos: counts_per_rev.map(SinCosTable::new),
            slot,
        }
    }

    /// Recompute the angle-dependent terms for the commanded angles (counts within the turn).
    pub(crate) fn refresh(&self, cache: &mut RotaryCache, a_counts: u32, c_counts: u32) {
        let (sa, ca) = self.sincos[0].sincos(a_counts);
        let (sc, cc) = self.sincos[1].sincos(c_counts);
        let [ex, ey] = self.o_c;
        let [ea, eb] = self.e_c;
        // (I − R_C) o_C and g = ε_C − R_C ε_C (z components 0).
        cache.oc = [ex - (cc * ex - sc * ey), ey - (sc * ex + cc * ey)];
        cache.gc = [ea - (cc * ea - sc * eb), eb - (sc * ea + cc * eb)];
        let [oy, oz] = self.o_a;
        let [by, cz] = self.e_a;
        // (I − R_A) o_A and h = ε_A − R_A ε_A (x components 0).
        cache.oa = [oy - (ca * oy - sa * oz), oz - (sa * oy + ca * oz)];
        cache.ha = [by - (ca * by - sa * cz), cz - (sa * by + ca * cz)];
        cache.sin_a = sa;
        cache.cos_a = ca;
        cache.a_counts = a_counts;
        cache.c_counts = c_counts;
        cache.valid = true;
    }

    /// Deviation (reached − target, µm) along X, Y, Z for the tool tip q (µm from the pivot) with
    /// the cached angle terms.
    #[inline(always)]
    pub(crate) fn deviation_um(cache: &RotaryCache, q: [f32; 3]) -> [f32; 3] {
        let (sa, ca) = (cache.sin_a, cache.cos_a);
        // w = R_Aᵀ q.
        let w = [q[0], ca * q[1] + sa * q[2], ca * q[2] - sa * q[1]];
        // δ_C = (I − R_C) o_C + g × w, g = (gx, gy, 0).
        let [gx, gy] = cache.gc;
        let d = [
            cache.oc[0] + gy * w[2],
            cache.oc[1] - gx * w[2],
            gx * w[1] - gy * w[0],
        ];
        // e = R_A δ_C + (I − R_A) o_A + h × q, h = (0, hy, hz).
        let [hy, hz] = cache.ha;
        let e = [
            d[0] + (hy * q[2] - hz * q[1]),
            (ca * d[1] - sa * d[2]) + cache.oa[0] + hz * q[0],
            (sa * d[1] + ca * d[2]) + cache.oa[1] - hy * q[0],
        ];
        [-e[0], -e[1], -e[2]]
    }

    /// The tool tip q (µm from the pivot) for the commanded positions of X, Y, Z (counts).
    #[inline(always)]
    pub(crate) fn tool_tip_um(&self, commands: [i64; 3]) -> [f32; 3] {
        let mut q = [0.0f32; 3];
        for k in 0..3 {
            q[k] = saturate_i32(commands[k].wrapping_sub(self.pivot_counts[k])) as f32
                * self.um_per_count[k];
        }
        q[2] -= self.tool_length_um;
        q
    }
}

/// `d` saturated to i32 (one compare in the common case; the conversion to f32 is then one
/// instruction). Positions and the pivot within ±2^62 never wrap in the subtraction.
#[inline(always)]
pub(crate) fn saturate_i32(d: i64) -> i32 {
    if d as i32 as i64 == d {
        d as i32
    } else if d < 0 {
        i32::MIN
    } else {
        i32::MAX
    }
}

/// Angle-dependent terms of the stage, valid for the commanded angles `a_counts`, `c_counts`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotaryCache {
    pub(crate) valid: bool,
    pub(crate) a_counts: u32,
    pub(crate) c_counts: u32,
    pub(crate) sin_a: f32,
    pub(crate) cos_a: f32,
    pub(crate) oc: [f32; 2],
    pub(crate) gc: [f32; 2],
    pub(crate) oa: [f32; 2],
    pub(crate) ha: [f32; 2],
}

impl RotaryCache {
    /// Nothing cached yet.
    pub const NEW: RotaryCache = RotaryCache {
        valid: false,
        a_counts: 0,
        c_counts: 0,
        sin_a: 0.0,
        cos_a: 0.0,
        oc: [0.0; 2],
        gc: [0.0; 2],
        oa: [0.0; 2],
        ha: [0.0; 2],
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: f64 `sin`/`cos` of n·2π/cpr; tolerance 2e-7 (a few f32 roundings of values
    /// ≤ 1), over every 997th count of turns of 3 600 000, 1000 (not a multiple of 64) and
    /// 2^31 counts, and the last counts of each.
    #[test]
    fn sincos_from_table_and_polynomial() {
        for cpr in [3_600_000u32, 1000, 1 << 31] {
            let t = SinCosTable::new(cpr);
            let mut worst = 0.0f64;
            for n in (0..cpr).step_by(997).chain(cpr - 5..cpr) {
                let (s, c) = t.sincos(n);
                let a = n as f64 * core::f64::consts::TAU / cpr as f64;
                worst = worst
                    .max((s as f64 - a.sin()).abs())
                    .max((c as f64 - a.cos()).abs());
            }
            assert!(worst < 2e-7, "cpr {cpr}: largest error {worst:e}");
        }
    }
}
