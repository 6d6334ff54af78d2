//! The rotary location-error stage: the deviation of the tool tip relative to the workpiece, along
//! the linear axes X, Y, Z, caused by the location errors of the two rotary axes of a five-axis
//! machine and by the squareness of its linear axes.
//!
//! # Glossary
//! - **machine kinds** ([`RotaryMachine`], the host's `axcomp_kinematics::rotary::MachineKind`):
//!   - **AC trunnion**: the workpiece sits on a C table (rotation about Z) carried by an A cradle
//!     (rotation about X); the tool moves in X, Y, Z;
//!   - **BC trunnion**: likewise with a B cradle (rotation about Y);
//!   - **BC head**: the spindle head carries B (about Y) riding on C (about Z); the workpiece does
//!     not turn.
//!
//!   The **tilt axis** is A (AC trunnion) or B (the two others). Nominally both axis lines pass
//!   through the **pivot**, the machine position (X, Y, Z counts) given in
//!   [`RotaryLocationSpec::pivot_counts`] (for the head: the X, Y, Z counts at which the head's
//!   pivot sits at the origin the squareness is measured from).
//! - **location errors** (ISO 230-7 names, 8 constants; offsets in µm, angles in µrad, all small):
//!   the C axis line (in the frame carried by the tilt axis for a trunnion, relative to the pivot
//!   for the head) passes through (EX0C, EY0C, 0) and is turned by EA0C about X and EB0C about Y.
//!   The A axis line passes through (0, EY0A, EZ0A) and is turned by EB0A about Y and EC0A about
//!   Z; a B axis line passes through (EX0B, 0, EZ0B), turned by EA0B about X and EC0B about Z. The
//!   four tilt-axis fields of [`RotaryLocationSpec`] are named after A; for a B axis they hold
//!   EX0B, EZ0B, EA0B, EC0B in the same places (offset ⟂ 1, offset along Z, turn about axis ⟂ 1,
//!   turn about Z).
//! - **squareness** (µrad): EA0Z, EB0Z (Z turned about X and Y), EC0Y (Y turned about Z): the
//!   linear axes move along ey + EC0Y·(−1, 0, 0) and ez + (EB0Z, −EA0Z, 0).
//! - **tool tip** q (µm): trunnion: the commanded spindle position minus the tool length along Z,
//!   q = (X, Y, Z − L) − pivot; head: the commanded pivot position q = (X, Y, Z) − pivot, and the
//!   tool tip sits L below the pivot at B = C = 0 (L = [`RotaryLocationSpec::tool_length_um`],
//!   pivot to tool tip).
//! - **deviation** (the sign convention of the whole crate): reached − target, the tool tip
//!   relative to the workpiece. Like every error it is subtracted from the command. The host's
//!   R-test displacement d = sphere − tool point is its negative.
//!
//! # Model (first order in the location errors)
//! Rotation by R about a line through o with direction turned by ε maps v to
//! R v + (I − R) o + (ε − R ε) × (R v) to first order in o and ε. Composed for a trunnion (tilt
//! rotation R_T, C rotation R_C, workpiece point p with R_T R_C p = q):
//! e = R_T [(I − R_C) o_C] + (I − R_T) o_T + ω × q, ω = R_T (ε_C − R_C ε_C) + (ε_T − R_T ε_T),
//! the displacement of the workpiece point meant to be at q; for the head (tool vector
//! v = (0, 0, −L) from the pivot): δ = (I − R_C) o_C + (ε_C − R_C ε_C) × (R_C R_B v)
//! \+ R_C [(I − R_B) o_T + (ε_T − R_B ε_T) × (R_B v)], the displacement of the tool tip. With the
//! squareness displacement s(q) = (−EC0Y·q_y + EB0Z·q_z, −EA0Z·q_z, 0) of the tool tip:
//!
//! deviation = s(q) − e (trunnion), s(q) + δ (head) — in both cases an affine map k + M q whose
//! k and M depend on the angles only.
//!
//! The neglected terms are products of two errors (|ε|·|o|, |ε|²·|q|, |ε|·|δ|): for each error
//! ≤ 50 µrad / 50 µm and |q| ≤ 840 mm they stay below 0.03 µm (checked against exact homogeneous
//! transforms in `tests/group.rs` and `host-tools/tests/rotary_stage_cli.rs` (all three kinds)).
//!
//! k and M (9 numbers: M's diagonal is 0), with the axes' µm per count folded in (and a
//! trunnion's tool length folded into the pivot's Z in whole counts of Z:
//! `RotaryStage::tool_counts_z`), are cached in [`RotaryCache`] and recomputed only when a commanded angle changes; each cycle
//! without a change then costs the commanded counts from the pivot and 6 multiply-adds. A cycle
//! with a change computes them and the deviation from them in registers
//! (`RotaryStage::refresh_deviation`) and keeps only the four sin/cos values; the first cycle
//! without a change folds those into k and M (`RotaryStage::fold_angles`: the same operations
//! on the same values, the same bits) — while both angles move, no nine stores and reloads per
//! cycle. The same cache follows each commanded angle from cycle to cycle within its **cell**,
//! the counts of the turn that share its nearest coarse angle of the sin/cos below
//! (`AngleCell`), as the command at the cell's first count and the position within the cell:
//! one 64-bit difference and one compare per axis, the angle test is the position's change,
//! and the sin/cos's coarse angle and remainder need no division. Only when it is primed
//! (first cycle, reset, new image) or a step leaves the cell (to the next coarse angle, across
//! 0, a whole turn) does it find the position within the turn (one wrap across 0, or the full
//! modulo) and its cell (one division). What depends only on the image is done at load: the
//! squareness terms scaled by the axes' µm per count, the tool length in whole counts of Z added to
//! the pivot, the radians per count folded into the sin/cos polynomials.
//!
//! The stage is a value: its settings `RotaryStage` (read through `&self`, built at load) and
//! its state, the angle cache [`RotaryCache`] (through `&mut`: `RotaryStage::track`, the
//! refresh and fold), held in the group's state.
//!
//! # sin/cos
//! `libm::sincosf` computes in double precision internally, which a Cortex-M4F emulates in
//! software: about 2 400 instructions per call, 5 000 per cycle whenever both angles move. So
//! `libm::sincos` is called at load only, for the [`SINCOS_STEPS`] coarse angles k·step per axis
//! (step = ⌈counts per revolution / 63⌉, made odd, k = 0..64: 63 steps cover the turn with half a
//! step to spare, so k ≤ 63 and the index is masked, not clamped). For the angle n the stage takes
//! the nearest coarse angle, k = ⌊(n + ⌊step/2⌋)/step⌋, the signed remainder
//! x = n − k·step counts, |x| ≤ ⌊step/2⌋ (both tracked by the angle cache within the cell of k,
//! the table's entry copied there: the division only when a cell is taken; bit for bit those of
//! the division, tested), r = x·ρ with ρ = 2π/cpr, and
//! sin θ = s_k·cos r + c_k·sin r, cos θ = c_k·cos r − s_k·sin r with
//! sin r ≈ r − r³/6 = x·(ρ − (ρ³/6)·x²), 1 − cos r ≈ r²/2 − r⁴/24 = x²·(ρ²/2 − (ρ⁴/24)·x²) (the
//! four coefficients rounded once from f64 at load): only integer division and `+ − ×`, so host
//! and target agree bit for bit.
//!
//! Error analysis (what the cheaper polynomials cost):
//! - |r| ≤ ⌊step/2⌋·ρ ≤ π/63 + 2π/cpr: below 0.0509 for any turn of 6 400 counts or more, below
//!   0.0982 for every turn (the worst is a turn of 64 counts, step 3);
//! - truncation: |sin r − (r − r³/6)| ≤ r⁵/120 ≤ 2.8e-9 (7.7e-8 at 0.0982),
//!   |cos r − (1 − r²/2 + r⁴/24)| ≤ r⁶/720 ≤ 2.5e-11;
//! - rounding: table entries within 2⁻²⁵ ≈ 3e-8 of the exact values; x is an exact integer
//!   (|x| < 2²⁴) and the coefficients are within 2⁻²⁴ relative, so sin r and 1 − cos r are within
//!   a few 2⁻²⁴ relative (≤ 2e-8 absolute); a few f32 roundings of values ≤ 1 in the sum: sin θ
//!   and cos θ are within δ = 2e-7 of the exact values (tested against f64 over turns of 65 …
//!   2³¹ counts; worst measured 9.9e-8). C's table holds (sin, 1 − cos) of the coarse angles
//!   (its angle terms need only sin θ and 1 − cos θ, which then takes three operations and no
//!   1 − cos θ from cos θ): sin θ = (s + sin r) − s·(1 − cos r) − d·sin r and
//!   1 − cos θ = d + (1 − cos r) − d·(1 − cos r) + s·sin r, d = 1 − cos of the coarse angle;
//!   its roundings are at the magnitude of 1 − cos θ ≤ 2 (half an ulp 1.2e-7 above 1), so for C
//!   δ = 2.5e-7 (tested; worst measured 1.4e-7 for sin θ, 2.1e-7 for 1 − cos θ, where the former
//!   1 − cos θ from cos θ measured 1.4e-7);
//! - effect on the deviation: every entry of k and M·q is a sum of (offset or angle × |q|) × (a
//!   sin/cos or a product of two), so an error δ in each sin/cos moves the deviation by at most
//!   about 2δ·(|o_C| + |o_T| + (|ε_C| + |ε_T|)·|q|): for offsets ≤ 50 µm and angles ≤ 100 µrad
//!   at |q| ≤ 1 m, 2·2.5e-7·(100 µm + 200e-6·1e6 µm) = 1.5e-4 µm — below 0.001 µm by nearly a
//!   decade and far below the first-order model's neglected terms (0.03 µm). The scales folded at
//!   load (M' = M·diag(µm per count)) add a few f32 roundings relative to the terms (≤ 1e-6
//!   relative: below 1e-4 µm for deviations below 100 µm); the trunnion's tool length, held in
//!   whole counts of Z in the pivot, is off by at most half a count, which moves the deviation by
//!   that times the angle errors (1e-4 rad × 0.25 µm = 2.5e-5 µm). Tested against the same model
//!   evaluated with f64 sin/cos and the exact tool length (tolerance 0.001 µm; worst measured
//!   4.4e-5 µm, with a tool 0.94 count off whole counts; 3.8e-5 µm before the tool length moved
//!   into the pivot, for whole counts only) in this module, and against exact
//!   homogeneous transforms in `tests/group.rs` and `host-tools/tests/rotary_stage_cli.rs` (all
//!   three kinds).

pub use crate::rotary_spec::{
    MAX_WOBBLE, RotaryLocationSpec, RotaryMachine, RotaryWobble, WOBBLE_HARMONICS,
    WOBBLE_TILT_DEGREE,
};

use crate::counts::{step_in_turn_wide, wrap};
use crate::rotary_wobble::{WobbleAngles, WobbleTerms, frame_factors};

/// Coarse angles per turn of the sin/cos table (a power of two: the index is masked, not
/// clamped).
pub const SINCOS_STEPS: usize = 64;

/// sin/cos of a rotary axis at its [`SINCOS_STEPS`] coarse angles k·step·2π/cpr, k = 0..64,
/// step = ⌈cpr/63⌉ counts made odd (via `libm::sincos`, at load; 63 steps cover the turn with
/// half a step to spare, so the nearest coarse angle of any count of the turn is in the table and
/// its index is below 64), and the remainder polynomials' coefficients with the radians per count
/// folded in.
#[derive(Debug, Clone, Copy, PartialEq)]
// The step and the polynomial first, then the table (all within a load's 8-bit scaled offset).
#[repr(C)]
pub(crate) struct SinCosTable {
    /// ⌈cpr/63⌉ made odd (+1 if even), ≥ 1 once built; 0 only in [`SinCosTable::ZERO`], which
    /// keeps a new group all zero bytes, so that a `static` engine lands in `.bss`.
    step: u32,
    /// ⌊step / 2⌋: the offset that makes the integer division round to the nearest coarse angle.
    half_step: u32,
    /// For the remainder x (counts) and ρ = 2π/cpr: sin r = x·(ρ − (ρ³/6)·x²),
    /// 1 − cos r = x²·(ρ²/2 − (ρ⁴/24)·x²): [ρ, ρ³/6, ρ²/2, ρ⁴/24] (each rounded once from f64).
    poly: [f32; 4],
    /// (sin, cos) of each coarse angle; (sin, 1 − cos) in a table built by
    /// [`SinCosTable::new_versine`] (C: its angle terms need only sin and 1 − cos).
    sin_cos: [[f32; 2]; SINCOS_STEPS],
}

impl SinCosTable {
    pub(crate) const ZERO: SinCosTable = SinCosTable {
        step: 0,
        half_step: 0,
        poly: [0.0; 4],
        sin_cos: [[0.0; 2]; SINCOS_STEPS],
    };

    /// For an axis of `cpr` (≥ 1) counts per revolution (at load): (sin, cos) of the coarse
    /// angles, for [`SinCosTable::sincos_at`].
    pub(crate) fn new(cpr: u32) -> SinCosTable {
        SinCosTable::build(cpr, false)
    }

    /// The same with (sin, 1 − cos) of the coarse angles (1 − cos rounded once from f64), for
    /// [`SinCosTable::sin_versine_at`].
    pub(crate) fn new_versine(cpr: u32) -> SinCosTable {
        SinCosTable::build(cpr, true)
    }

    fn build(cpr: u32, versine: bool) -> SinCosTable {
        let cpr = cpr.max(1);
        // Odd (see `sincos`): ⌈cpr/63⌉, or one more.
        let step = cpr.div_ceil(SINCOS_STEPS as u32 - 1) | 1;
        let rad = core::f64::consts::TAU / cpr as f64;
        let mut t = SinCosTable {
            step,
            half_step: step / 2,
            poly: [
                rad as f32,
                (rad * rad * rad / 6.0) as f32,
                (rad * rad / 2.0) as f32,
                (rad * rad * rad * rad / 24.0) as f32,
            ],
            ..SinCosTable::ZERO
        };
        for (k, sc) in t.sin_cos.iter_mut().enumerate() {
            // Through a function pointer the optimiser cannot see through: `libm::sincos` stays
            // one out-of-line function at libm's size-optimised level (inlined here it measured
            // 4.9 KB more code; an `#[inline(never)]` wrapper still takes libm's code inlined at
            // this crate's level: +864 B).
            let sincos: fn(f64) -> (f64, f64) = core::hint::black_box(libm::sincos);
            let (s, c) = sincos((k as u64 * step as u64) as f64 * rad);
            *sc = [s as f32, if versine { 1.0 - c } else { c } as f32];
        }
        t
    }

    /// (sin, cos) of the angle `n`·2π/cpr for `n` < cpr (see the module's notes): the nearest
    /// coarse angle k = ⌊(n + ⌊step/2⌋) / step⌋ ≤ 63 from the table, the signed remainder
    /// x = n − k·step counts, |x| ≤ ⌊step/2⌋, by polynomials.
    /// A table from [`SinCosTable::new`].
    #[cfg(test)]
    pub(crate) fn sincos(&self, n: u32) -> (f32, f32) {
        let (k, x) = self.coarse(n);
        self.sincos_at(self.entry(k), x)
    }

    /// `sincos` from the table's entry of the coarse angle k and the remainder `x` of
    /// [`SinCosTable::coarse`].
    #[inline(always)]
    pub(crate) fn sincos_at(&self, [s, c]: [f32; 2], x: i32) -> (f32, f32) {
        let (sin_r, one_minus_cos_r) = self.remainder(x);
        (
            s - s * one_minus_cos_r + c * sin_r,
            c - c * one_minus_cos_r - s * sin_r,
        )
    }

    /// (sin, 1 − cos) of the angle `n`·2π/cpr for `n` < cpr, as `sincos`, from a
    /// table of [`SinCosTable::new_versine`]: with d = 1 − cos of the coarse angle,
    /// sin θ = s·cos r + (1 − d)·sin r = (s + sin r) − s·(1 − cos r) − d·sin r and
    /// 1 − cos θ = d + (1 − d)·(1 − cos r) + s·sin r (three operations each; 1 − cos θ without
    /// the cancellation of 1 − cos θ from cos θ).
    #[cfg(test)]
    pub(crate) fn sin_versine(&self, n: u32) -> (f32, f32) {
        let (k, x) = self.coarse(n);
        self.sin_versine_at(self.entry(k), x)
    }

    /// `sin_versine` from the table's entry of the coarse angle k and the remainder `x` of
    /// [`SinCosTable::coarse`].
    #[inline(always)]
    pub(crate) fn sin_versine_at(&self, [s, d]: [f32; 2], x: i32) -> (f32, f32) {
        let (sin_r, one_minus_cos_r) = self.remainder(x);
        (
            s + sin_r - s * one_minus_cos_r - d * sin_r,
            d + one_minus_cos_r - d * one_minus_cos_r + s * sin_r,
        )
    }

    /// The nearest coarse angle k = ⌊(n + ⌊step/2⌋) / step⌋ ≤ 63 of the count `n` < cpr and the
    /// signed remainder x = n − k·step, |x| ≤ ⌊step/2⌋ (the only division of the sin/cos; the
    /// stage's angle cache tracks k and x from cycle to cycle instead, see
    /// [`RotaryStage::track`]).
    #[inline(always)]
    pub(crate) fn coarse(&self, n: u32) -> (u32, i32) {
        // n < cpr ≤ 2^31 and half_step < 2^25: no overflow; k ≤ (cpr − 1 + ⌊step/2⌋) / step
        // < 64 since 63·step ≥ cpr.
        let m = n.wrapping_add(self.half_step);
        // The step is odd (set at load), so `| 1` changes nothing but tells the compiler the
        // divisor is not 0 (the zero table, step 0, divides by 1).
        let step = self.step | 1;
        let k = m / step;
        let rem = m - k.wrapping_mul(step);
        // Exact: |x| ≤ ⌊step/2⌋ < 2^24.
        (k, rem.wrapping_sub(self.half_step) as i32)
    }

    /// sin r and 1 − cos r of the remainder `x` counts (as [`SinCosTable::coarse`] gives it).
    #[inline(always)]
    fn remainder(&self, x: i32) -> (f32, f32) {
        let x = x as f32;
        let [rho, s3, c2, c4] = self.poly;
        let x2 = x * x;
        (x * (rho - s3 * x2), x2 * (c2 - c4 * x2))
    }

    /// The table's entry of the coarse angle `k` (as [`SinCosTable::coarse`] gives it).
    #[inline(always)]
    fn entry(&self, k: u32) -> [f32; 2] {
        // The mask changes nothing for a coarse angle of a count within the turn (k < 64); it
        // keeps the index check-free.
        self.sin_cos[k as usize % SINCOS_STEPS]
    }
}

#[inline(always)]
fn add3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

#[inline(always)]
fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// The validated stage: constants in µm and radians, the pivot, the axes' scales.
///
/// The tilt axis's **plane** is (p, Z), p = Y for A and X for B; in it the tilt rotation is
/// (v_p, v_z) ↦ (c·v_p − s'·v_z, s'·v_p + c·v_z) with s' = sin θ for A and −sin θ for B (a
/// positive turn about Y takes Z towards X). The remaining coordinate ("other": X for A, Y for B)
/// is unchanged.
#[derive(Debug, Clone, Copy, PartialEq)]
// In this order (not the compiler's): the pivot and the constants first, within the reach of a
// load's 8-bit scaled offset from the stage's address (paired loads of the pivot, the angle
// terms' constants without a base register), then the tables.
#[repr(C)]
pub(crate) struct RotaryStage {
    /// The pivot (counts of X, Y, Z), for a trunnion with the tool length added to Z in whole
    /// counts of Z ([`RotaryStage::tool_counts_z`]), minus 2^31: a command minus it is in
    /// [0, 2^32) exactly when the command minus the (shifted) pivot fits an i32 (one high word to
    /// test per axis). 0 in the zero stage, which never computes a deviation.
    pub(crate) pivot_low_counts: [i64; 3],
    /// (EX0C, EY0C), µm; negated for a trunnion.
    pub(crate) o_c: [f32; 2],
    /// (EA0C, EB0C), rad.
    pub(crate) e_c: [f32; 2],
    /// Tilt axis offsets in its plane (p, Z): A (EY0A, EZ0A), B (EX0B, EZ0B), µm; negated for a
    /// trunnion.
    pub(crate) o_t: [f32; 2],
    /// Tilt axis turns in its plane: A (EB0A, EC0A), B (EA0B, EC0B), rad.
    pub(crate) e_t: [f32; 2],
    /// Squareness terms of the deviation: (−EC0Y, EB0Z, −EA0Z), rad: the deviation of the tool
    /// tip gains (sq[0]·q_y + sq[1]·q_z, sq[2]·q_z, 0).
    pub(crate) sq: [f32; 3],
    /// The squareness terms scaled as M' (trunnion): (sq[0]·µm per count of Y, sq[1]·µm per
    /// count of Z, sq[2]·µm per count of Z).
    pub(crate) sq_scaled: [f32; 3],
    /// Head: pivot to tool tip, µm (0 for a trunnion).
    pub(crate) head_length_um: f32,
    /// µm per count of X, Y, Z.
    pub(crate) um_per_count: [f32; 3],
    /// Counts per revolution of the tilt axis and C.
    pub(crate) counts_per_rev: [u32; 2],
    /// sin/cos table of the tilt axis, sin/(1 − cos) table of C.
    pub(crate) sincos: [SinCosTable; 2],
    /// [`RotaryMachine::code`] of the machine kind; 0 in [`RotaryStage::ZERO`] (all zero
    /// bytes, so that a new group, and a `static` engine holding it, lands in `.bss`; its
    /// constants are all 0, and it is refreshed as an AC trunnion: a zero deviation).
    pub(crate) machine: u8,
    /// Group slots of X, Y, Z, the tilt axis (A or B), C.
    pub(crate) slot: [u8; 5],
    /// The rotary axes' wobble (last: read only when an angle changes, and only if it is on).
    pub(crate) wobble: WobbleTerms,
}

impl RotaryStage {
    pub(crate) const ZERO: RotaryStage = RotaryStage {
        machine: 0,
        o_c: [0.0; 2],
        e_c: [0.0; 2],
        o_t: [0.0; 2],
        e_t: [0.0; 2],
        sq: [0.0; 3],
        pivot_low_counts: [0; 3],
        sq_scaled: [0.0; 3],
        head_length_um: 0.0,
        um_per_count: [0.0; 3],
        sincos: [SinCosTable::ZERO; 2],
        counts_per_rev: [0; 2],
        slot: [0; 5],
        wobble: WobbleTerms::ZERO,
    };

    /// `counts_per_rev` and `slot` in the order (tilt axis, C) and (X, Y, Z, tilt axis, C).
    pub(crate) fn new(
        spec: &RotaryLocationSpec,
        um_per_count: [f32; 3],
        counts_per_rev: [u32; 2],
        slot: [u8; 5],
    ) -> RotaryStage {
        const URAD: f32 = 1.0e-6;
        let head = spec.machine == RotaryMachine::BcHead;
        let [ea0z, eb0z, ec0y] = spec.squareness_urad;
        // Trunnions keep the offsets negated (see `refresh_trunnion`).
        let o = if head { 1.0 } else { -1.0 };
        let sq = [-ec0y * URAD, eb0z * URAD, -ea0z * URAD];
        let [_, uy, uz] = um_per_count;
        let tool_counts = if head {
            0
        } else {
            RotaryStage::tool_counts_z(spec.tool_length_um, uz)
        };
        let mut pivot = spec.pivot_counts;
        // Within ±2^62 (validated), the tool length's counts added and kept within ±2^62: no
        // wrap in the cycle's subtraction.
        pivot[2] = pivot[2]
            .saturating_add(tool_counts)
            .clamp(-(1 << 62), 1 << 62);
        RotaryStage {
            machine: spec.machine.code(),
            o_c: [o * spec.ex0c_um, o * spec.ey0c_um],
            e_c: [spec.ea0c_urad * URAD, spec.eb0c_urad * URAD],
            o_t: [o * spec.ey0a_um, o * spec.ez0a_um],
            e_t: [spec.eb0a_urad * URAD, spec.ec0a_urad * URAD],
            sq,
            pivot_low_counts: pivot.map(|p| p - (1 << 31)),
            sq_scaled: [sq[0] * uy, sq[1] * uz, sq[2] * uz],
            head_length_um: if head { spec.tool_length_um } else { 0.0 },
            um_per_count,
            sincos: [
                SinCosTable::new(counts_per_rev[0]),
                SinCosTable::new_versine(counts_per_rev[1]),
            ],
            counts_per_rev,
            slot,
            wobble: WobbleTerms::new(&spec.wobble),
        }
    }

    /// True if the stage has a wobble to add (the X, Y, Z, A, C cycle's inline refresh has none:
    /// such a stage takes the general cycle).
    pub(crate) fn has_wobble(&self) -> bool {
        self.wobble.on
    }

    /// A trunnion's tool length L (µm, validated in [0, 1e7]) in whole counts of Z (µm per count
    /// `uz` ≥ 1e-6 once loaded; 0 for the zero stage's 0): round(L/uz), rounded once from f64.
    /// The pivot's Z is shifted by it, so the counts from the pivot are those of the tool tip,
    /// q = diag(µm per count)·n: the angle terms need no k − M·(0, 0, L). The tool length is then
    /// L to within half a count of Z; the deviation moves by that times M's entries (angles of
    /// the location errors: 1e−4 rad of error and 0.5 µm per count give 2.5e−5 µm).
    pub(crate) fn tool_counts_z(tool_length_um: f32, uz: f32) -> i64 {
        if uz > 0.0 {
            libm::round(tool_length_um as f64 / uz as f64) as i64
        } else {
            0
        }
    }

    /// Recompute the angle-dependent terms k' and M' for the commanded angles of the tilt axis and
    /// C in the cells and store them ([`RotaryStage::refresh_deviation`]; for the tests).
    #[cfg(test)]
    pub(crate) fn refresh(&self, cache: &mut RotaryCache) {
        self.refresh_deviation(cache, 0.0, 0.0, 0.0);
    }

    /// The general cycle's refresh after an angle change (every kind, any slot order; and
    /// [`crate::group::Group::error_at`]): the angle-dependent terms k' and M' (the deviation is
    /// k' + M'·n) for the commanded angles of the tilt axis and C in the cells, stored, and the
    /// deviation for the commanded counts `n` from the pivot, as [`RotaryStage::deviation_um`]
    /// computes it. Out of line: the cycles without an angle change keep the caller's registers
    /// free. The AC trunnion (and the zero stage) through [`RotaryStage::fold_angles`], the
    /// other kinds through `refresh_other`. The X, Y, Z, A, C cycle, an AC trunnion's, has its
    /// own refresh inline ([`RotaryStage::refresh_deviation_ac`]: the same bits).
    #[inline(never)]
    pub(crate) extern "C" fn refresh_deviation(
        &self,
        cache: &mut RotaryCache,
        n0: f32,
        n1: f32,
        n2: f32,
    ) -> Deviation {
        if self.machine > RotaryMachine::AcTrunnion.code() {
            let [st, ct, sc, omc] = self.angles(cache);
            self.refresh_other(cache, st, ct, sc, omc);
        } else {
            self.fold_angles(cache);
        }
        if self.wobble.on {
            self.add_wobble(cache);
        }
        let [x, y, z] = RotaryStage::deviation_um(cache, [n0, n1, n2]);
        Deviation { x, y, z }
    }

    /// The X, Y, Z, A, C cycle's refresh after an angle change (an AC trunnion's: no test of
    /// the machine kind, no call), inlined into its stage: the deviation for the commanded
    /// counts `n` from the pivot, computed from k' and M' in registers and nothing of them
    /// stored (nine stores and nine loads per moving cycle), the cache marked `unfolded`; the
    /// first cycle without an angle change computes k' and M' from the cells
    /// ([`RotaryStage::fold_angles`]: the same operations on the same values, the same bits as
    /// [`RotaryStage::refresh_deviation`]). (Inlined since the five pipelines are a function of
    /// their own: 17 instructions fewer per moving cycle than the call.)
    #[inline(always)]
    pub(crate) fn refresh_deviation_ac(&self, cache: &mut RotaryCache, n: [f32; 3]) -> [f32; 3] {
        let [st, ct, sc, omc] = self.angles(cache);
        let (k, m) = self.trunnion_terms::<false>(st, ct, sc, omc);
        cache.unfolded = true;
        deviation(&k, &m, n)
    }

    /// The angle terms k' and M' of an AC trunnion (and the zero stage) for the angles of the
    /// cells, stored: for the first cycle without an angle change after a moving one of the
    /// X, Y, Z, A, C cycle, and for [`RotaryStage::refresh_deviation`].
    // Not `#[cold]`: the call then sits beside the test, which is one compare-and-branch on the
    // cycles without it (held share −1).
    #[inline(never)]
    pub(crate) fn fold_angles(&self, cache: &mut RotaryCache) {
        let [st, ct, sc, omc] = self.angles(cache);
        (cache.k, cache.m) = self.trunnion_terms::<false>(st, ct, sc, omc);
        cache.unfolded = false;
    }

    /// sin θ and cos θ of the tilt axis's angle, sin and 1 − cos of C's (their cells in `cache`).
    #[inline(always)]
    fn angles(&self, cache: &RotaryCache) -> [f32; 4] {
        let [t, c] = &cache.cell;
        let [et, ec] = cache.entry;
        let (st, ct) = self.sincos[0].sincos_at(et, t.coarse().1);
        let (sc, omc) = self.sincos[1].sin_versine_at(ec, c.coarse().1);
        [st, ct, sc, omc]
    }

    /// Add the wobble's terms ([`crate::rotary_wobble`]) to the k' and M' stored in `cache` for
    /// the angles of its cells: a trunnion's deviation gains −T − W × q, the head's
    /// W × (R_C R_B (0, 0, −L)) + T (M' folded as in [`RotaryStage::fold`]).
    #[cold]
    #[inline(never)]
    fn add_wobble(&self, cache: &mut RotaryCache) {
        let [st, ct, sc, omc] = self.angles(cache);
        let cc = 1.0 - omc;
        // The tilt axis's signed angle: its position within the turn, above half a turn less a
        // turn.
        let cpr = self.counts_per_rev[0];
        let n = cache.cell[0].turn(&self.sincos[0]);
        // n − cpr ∈ (−2^31, 0] (cpr ≤ 2^31): exact in an i32.
        let signed = n.wrapping_sub(if n > cpr / 2 { cpr } else { 0 }) as i32;
        let t = signed as f32 * self.sincos[0].poly[0];
        let head = self.machine == RotaryMachine::BcHead.code();
        let about_x = self.machine == RotaryMachine::AcTrunnion.code();
        let p = frame_factors(head, about_x, st, ct, sc, cc);
        let (w, tr) = self.wobble.terms(&WobbleAngles { sc, cc, t }, &p);
        let k = &mut cache.k;
        if head {
            let l = self.head_length_um;
            let v = [cc * -st * l, sc * -st * l, -ct * l];
            let d = add3(cross(w, v), tr);
            *k = add3(*k, d);
        } else {
            *k = [k[0] - tr[0], k[1] - tr[1], k[2] - tr[2]];
            let [ux, uy, uz] = self.um_per_count;
            let m = &mut cache.m;
            m[0] += w[2] * uy;
            m[1] -= w[1] * uz;
            m[2] -= w[2] * ux;
            m[3] += w[0] * uz;
            m[4] += w[1] * ux;
            m[5] -= w[0] * uy;
        }
    }

    /// [`RotaryStage::refresh_deviation`] of the BC trunnion and the BC head (k' and M' stored).
    #[inline(never)]
    /// `omc` is 1 − cos of C's angle.
    fn refresh_other(&self, cache: &mut RotaryCache, st: f32, ct: f32, sc: f32, omc: f32) {
        cache.unfolded = false;
        if self.machine == RotaryMachine::BcTrunnion.code() {
            (cache.k, cache.m) = self.trunnion_terms::<true>(st, ct, sc, omc);
        } else {
            self.refresh_head(cache, st, ct, sc, 1.0 - omc);
        }
    }

    /// Fold the scales into M (unscaled M, without its zero diagonal) and store k and M' (the
    /// head: no tool length in q): the deviation is k + M'·n for the commanded counts n from the
    /// pivot (q = diag(µm per count)·n). The trunnion path does the same inline.
    fn fold(&self, cache: &mut RotaryCache, k: [f32; 3], m: [f32; 6]) {
        let [ux, uy, uz] = self.um_per_count;
        cache.k = k;
        cache.m = [
            m[0] * uy,
            m[1] * uz,
            m[2] * ux,
            m[3] * uz,
            m[4] * ux,
            m[5] * uy,
        ];
    }

    /// Trunnion (tilt axis B if `B`, else A): e = R_T u + (I − R_T) o_T + ω × q with
    /// u = (I − R_C) o_C, ω = R_T g + h, g = ε_C − R_C ε_C, h = ε_T − R_T ε_T; the deviation is
    /// s(q) − e. The offsets are stored negated, so k = −(R_T u + (I − R_T) o_T) is a plain sum;
    /// in the tilt plane R_T (u_p, 0) + o_T − R_T o_T = (c·(u_p − o_p) + o_p + s'·o_z,
    /// s'·(u_p − o_p) + o_z − c·o_z), and likewise for ω. The scales are folded in as in
    /// [`RotaryStage::fold`] (M' = M·diag(µm per count)); the tool length is in the pivot
    /// ([`RotaryStage::tool_counts_z`]), so k' = k.
    #[inline(always)]
    fn trunnion_terms<const B: bool>(
        &self,
        st: f32,
        ct: f32,
        sc: f32,
        omc: f32,
    ) -> ([f32; 3], [f32; 6]) {
        // In the tilt plane (p, Z) the tilt turns by +θ for A and −θ for B.
        let s = if B { -st } else { st };
        // −u and g (z components 0): (I − R_C) v = ((1 − cos)·v_x + sin·v_y, (1 − cos)·v_y −
        // sin·v_x), 1 − cos of C from its table (`omc`).
        let [ox, oy] = self.o_c;
        let u = [omc * ox + sc * oy, omc * oy - sc * ox];
        let [ex, ey] = self.e_c;
        let g = [omc * ex + sc * ey, omc * ey - sc * ex];
        // −(I − R_T) o_T and h in the tilt plane.
        let [p1, p3] = self.o_t;
        let [e1, e3] = self.e_t;
        let (u_p, u_o, g_p, g_o) = if B {
            (u[0], u[1], g[0], g[1])
        } else {
            (u[1], u[0], g[1], g[0])
        };
        let a = u_p - p1;
        let k_p = ct * a + (p1 + s * p3);
        let k_z = s * a + (p3 - ct * p3);
        let b = g_p - e1;
        let w_p = ct * b + (e1 + s * e3);
        let w_z = s * b + (e3 - ct * e3);
        let (k, w) = if B {
            ([k_p, u_o, k_z], [w_p, g_o, w_z])
        } else {
            ([u_o, k_p, k_z], [g_o, w_p, w_z])
        };
        // s(q) − ω × q, off-diagonal entries (the diagonal is 0): M = [sq_y + w_z, sq_z − w_y,
        // −w_z, sq_yz + w_x, w_y, −w_x], scaled by (uy, uz, ux, uz, ux, uy) (the squareness
        // terms scaled at load). The tool length is in the pivot (the counts n are from the
        // tool tip's pivot): k' = k.
        let [sq_y, sq_z, sq_yz] = self.sq_scaled;
        let [ux, uy, uz] = self.um_per_count;
        let m1 = sq_z - w[1] * uz;
        let m3 = sq_yz + w[0] * uz;
        (
            k,
            [
                sq_y + w[2] * uy,
                m1,
                -(w[2] * ux),
                m3,
                w[1] * ux,
                -(w[0] * uy),
            ],
        )
    }

    /// BC head: the deviation is the tool tip's displacement δ + s(q) (see
    /// [`RotaryStage::head_deviation`]).
    #[cold]
    #[inline(never)]
    fn refresh_head(&self, cache: &mut RotaryCache, st: f32, ct: f32, sc: f32, cc: f32) {
        let [ox, oy] = self.o_c;
        let u = [ox - (cc * ox - sc * oy), oy - (sc * ox + cc * oy), 0.0];
        let [ex, ey] = self.e_c;
        let g = [ex - (cc * ex - sc * ey), ey - (sc * ex + cc * ey), 0.0];
        let [sq_y, sq_z, sq_yz] = self.sq;
        let k = self.head_deviation(st, ct, sc, cc, u, g);
        self.fold(cache, k, [sq_y, sq_z, 0.0, sq_yz, 0.0, 0.0]);
    }

    /// BC head: the tool tip's displacement δ = u + g × (R_C R_B v) + R_C [(I − R_B) o_B +
    /// (ε_B − R_B ε_B) × (R_B v)], v = (0, 0, −L).
    #[cold]
    fn head_deviation(
        &self,
        st: f32,
        ct: f32,
        sc: f32,
        cc: f32,
        u: [f32; 3],
        g: [f32; 3],
    ) -> [f32; 3] {
        let l = self.head_length_um;
        let turn = |v: [f32; 3]| [cc * v[0] - sc * v[1], sc * v[0] + cc * v[1], v[2]];
        let tilt = |v: [f32; 3]| [ct * v[0] + st * v[2], v[1], ct * v[2] - st * v[0]];
        let vb = [-st * l, 0.0, -ct * l];
        let o_b = [self.o_t[0], 0.0, self.o_t[1]];
        let e_b = [self.e_t[0], 0.0, self.e_t[1]];
        let r_o = tilt(o_b);
        let r_e = tilt(e_b);
        let ob = [o_b[0] - r_o[0], 0.0, o_b[2] - r_o[2]];
        let h = [e_b[0] - r_e[0], 0.0, e_b[2] - r_e[2]];
        let inner = add3(ob, cross(h, vb));
        add3(add3(u, cross(g, turn(vb))), turn(inner))
    }

    /// Deviation (reached − target, µm) along X, Y, Z for the commanded counts `n` from the pivot
    /// ([`RotaryStage::counts_from_pivot`]) with the cached angle terms: k' + M'·n (M' without its
    /// zero diagonal).
    #[inline(always)]
    pub(crate) fn deviation_um(cache: &RotaryCache, n: [f32; 3]) -> [f32; 3] {
        deviation(&cache.k, &cache.m, n)
    }

    /// The commanded positions of X, Y, Z (counts) minus the pivot, saturated to i32, as f32.
    #[inline(always)]
    pub(crate) fn counts_from_pivot(&self, commands: [i64; 3]) -> [f32; 3] {
        // Positions and the pivot within ±2^62 never wrap in the subtraction. v = d + 2^31 for the
        // difference d to the pivot.
        let v = [0, 1, 2].map(|k| commands[k].wrapping_sub(self.pivot_low_counts[k]));
        // One test for the three in the common case (each d fits in an i32: v's high word is 0);
        // d is then v's low word minus 2^31, i.e. with its top bit flipped, and the conversions
        // are one instruction each.
        let outside = v.iter().fold(0, |acc, &v| acc | (v >> 32) as i32);
        if outside == 0 {
            v.map(|v| (v as u32 ^ 1 << 31) as i32 as f32)
        } else {
            // (Element by element, not through `map`: no array on the stack whose address a
            // call takes, which would keep the cycle's later calls from being tail calls.)
            let d = |v: i64| saturate_i32(v.wrapping_sub(1 << 31)) as f32;
            [d(v[0]), d(v[1]), d(v[2])]
        }
    }
}

/// A deviation along X, Y, Z (µm) as the C calling convention returns it: in s0–s2.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub(crate) struct Deviation {
    pub(crate) x: f32,
    pub(crate) y: f32,
    pub(crate) z: f32,
}

/// k' + M'·n (M' without its zero diagonal).
#[inline(always)]
fn deviation(k: &[f32; 3], m: &[f32; 6], n: [f32; 3]) -> [f32; 3] {
    [
        (k[0] + m[0] * n[1]) + m[1] * n[2],
        (k[1] + m[2] * n[0]) + m[3] * n[2],
        (k[2] + m[4] * n[0]) + m[5] * n[1],
    ]
}

/// `d` saturated to i32 (out of line: the per-cycle path tests only whether it fits).
#[cold]
#[inline(never)]
pub(crate) fn saturate_i32(d: i64) -> i32 {
    d.clamp(i32::MIN as i64, i32::MAX as i64) as i32
}

/// One rotary axis's commanded angle within its turn, as the stage's angle cache follows it: the
/// **cell** of the angle's nearest coarse angle k (the counts n of the turn with
/// k = ⌊(n + ⌊step/2⌋) / step⌋, i.e. k·step + [−⌊step/2⌋, ⌊step/2⌋] within [0, cpr)), the
/// position within that cell, and k with the signed remainder x = n − k·step at the cell's start
/// ([`SinCosTable::coarse`] of the position, without its division).
#[derive(Debug, Clone, Copy, PartialEq)]
// The cell's length and the position first (one paired load on the fast path), then the position
// with the packed coarse angle (one paired load in the refresh).
#[repr(C)]
pub(crate) struct AngleCell {
    /// Counts of the cell within the turn (≥ 1 once primed); 0 until the first cycle (and after a
    /// reset or a new image), so that the fast path's range test fails.
    len: u32,
    /// Position within the cell: n − (the cell's first count).
    in_cell: u32,
    /// (x0 << 6) | k as a u32: k ≤ 63, x0 = (the cell's first count) − k·step ∈ [−⌊step/2⌋, 0]
    /// (|x0| < 2^25: x0·64 fits an i32), so that x = `in_cell` + x0 (an add with the shifted
    /// operand) and k = `coarse_x0` & 63.
    coarse_x0: u32,
}

impl AngleCell {
    const NEW: AngleCell = AngleCell {
        len: 0,
        in_cell: 0,
        coarse_x0: 0,
    };

    /// The cell of the position `n` < `cpr` of a turn whose sin/cos table is `table` (at load;
    /// step ≥ 1).
    fn at(n: u32, cpr: u32, table: &SinCosTable) -> AngleCell {
        let (k, x) = table.coarse(n);
        // k·step ≤ n + ⌊step/2⌋ < 2^32: no wrap.
        let center = n.wrapping_sub(x as u32);
        let start = center.saturating_sub(table.half_step);
        let end = center.saturating_add(table.half_step + 1).min(cpr);
        let x0 = start.wrapping_sub(center) as i32;
        AngleCell {
            len: end.saturating_sub(start),
            in_cell: n - start,
            coarse_x0: ((x0 << 6) as u32) | (k % SINCOS_STEPS as u32),
        }
    }

    /// The coarse angle k and the remainder x of the position (those of [`SinCosTable::coarse`]).
    #[inline(always)]
    fn coarse(&self) -> (u32, i32) {
        let x = self
            .in_cell
            .wrapping_add(((self.coarse_x0 as i32) >> 6) as u32);
        (self.coarse_x0 % SINCOS_STEPS as u32, x as i32)
    }

    /// The position within the turn (k·step + x).
    fn turn(&self, table: &SinCosTable) -> u32 {
        let (k, x) = self.coarse();
        k.wrapping_mul(table.step).wrapping_add(x as u32)
    }
}

/// The commanded angles of the tilt axis (A or B) and C within their turns, tracked from cycle to
/// cycle (each as its `AngleCell`), and the angle-dependent terms of the stage for them: the
/// deviation is k' + M'·n for the commanded counts n from the pivot (k + M q with the scales
/// folded in; a trunnion's tool length is in the pivot).
#[derive(Debug, Clone, Copy, PartialEq)]
// The commands and cells first (paired loads and stores), then the angle terms, then what only
// the slow path reads.
#[repr(C)]
pub struct RotaryCache {
    /// The commands (extended counts) at the cells' first counts: the last command minus its
    /// position within the cell.
    pub(crate) cell_cmd: [i64; 2],
    /// The commanded positions within their turns (< `cpr` once primed), the angles k and M are
    /// for.
    pub(crate) cell: [AngleCell; 2],
    pub(crate) k: [f32; 3],
    /// M' = M·diag(µm per count): its off-diagonal entries M'01, M'02, M'10, M'12, M'20, M'21 (the
    /// diagonal is 0).
    pub(crate) m: [f32; 6],
    /// True when `k` and `m` are not yet computed for the angles of the cells: the last angle
    /// change was a moving cycle's ([`RotaryStage::refresh_deviation_ac`]), which computed the
    /// deviation in registers and stored nothing of them; the first cycle without a change
    /// computes them from the cells ([`RotaryStage::fold_angles`]: the same operations on the
    /// same values, the same bits).
    pub(crate) unfolded: bool,
    /// Counts per revolution of the tilt axis and C the cells were taken with; 0 until the first
    /// cycle (and after a reset or a new image).
    pub(crate) cpr: [u32; 2],
    /// The sin/cos tables' entries of the cells' coarse angles (copied when a cell is taken: the
    /// refresh reads them here, with no index arithmetic).
    pub(crate) entry: [[f32; 2]; 2],
}

impl RotaryCache {
    /// Nothing cached yet (all zero bytes).
    pub const NEW: RotaryCache = RotaryCache {
        cell_cmd: [0; 2],
        cell: [AngleCell::NEW; 2],
        k: [0.0; 3],
        m: [0.0; 6],
        unfolded: false,
        cpr: [0; 2],
        entry: [[0.0; 2]; 2],
    };
}

/// The angle cache through the stage's settings: the stage read through `&self`, its cache
/// ([`RotaryCache`]) through `&mut`.
impl RotaryStage {
    /// A cache at the positions `turn` within the turns (each below its turn) of the tilt axis and
    /// C of this stage (loaded), for [`RotaryStage::refresh_deviation`] (the cycle's own cache is
    /// not touched: [`crate::group::Group::error_at`]).
    pub(crate) fn cache_at(&self, turn: [u32; 2]) -> RotaryCache {
        let mut c = RotaryCache::NEW;
        for (k, &n) in turn.iter().enumerate() {
            c.take_cell(k, n, self.counts_per_rev[k], &self.sincos[k]);
        }
        c
    }

    /// The positions within the turns of the tilt axis and C held by `cache`.
    #[cfg(test)]
    pub(crate) fn turn(&self, cache: &RotaryCache) -> [u32; 2] {
        [0, 1].map(|k| cache.cell[k].turn(&self.sincos[k]))
    }

    /// Follow the commanded positions `cmd` of the tilt axis and C (turns of this stage's counts
    /// per revolution, read only on the slow path) into the cells of `cache`; true if a turn
    /// position changed or the cache was not yet primed (k and M must then be recomputed; a whole
    /// turn is no change).
    ///
    /// Per axis the fast path is one 64-bit difference of the command to the command at the
    /// cell's first count and one unsigned compare of it with the cell's length: in [0, len)
    /// exactly when the true difference is (a negative one is ≥ 2^63 as unsigned; commands
    /// within ±2^62 never wrap). It is then the new position within the cell, which lies within
    /// the turn, so the step neither wraps nor changes the coarse angle k, and x moves with the
    /// position (the sin/cos need no division); the angle changed exactly when the position
    /// within the cell did. Anything else (not primed, a step out of the cell: to the next coarse
    /// angle, across 0 or a full turn or more) takes [`RotaryStage::track_slow`].
    #[inline(always)]
    pub(crate) fn track(&self, cache: &mut RotaryCache, cmd: [i64; 2]) -> bool {
        let mut moved = 0u32;
        // An index loop (as an iterator over `cmd` it measured 15 instructions more per cycle).
        #[allow(clippy::needless_range_loop)]
        for k in 0..2 {
            // Within [0, len) exactly when its high word is 0 and its low word is below the
            // cell's length.
            let v = cmd[k].wrapping_sub(cache.cell_cmd[k]) as u64;
            let cell = &mut cache.cell[k];
            if v < cell.len as u64 {
                moved |= v as u32 ^ cell.in_cell;
                cell.in_cell = v as u32;
            } else {
                moved |= self.track_slow(cache, cmd[k], k) as u32;
            }
        }
        moved != 0
    }

    /// The slow path of [`RotaryStage::track`] for axis `k` (0: tilt, 1: C): the position within
    /// a turn of `cpr` counts after the step from the last command to the command `cmd` — one
    /// wrap across 0 for a step shorter than a turn from a position taken with the same turn,
    /// else the full modulo of `cmd` — and its cell. True if it changed or the cache was not
    /// primed (a whole turn lands on the same angle: no recomputation).
    #[cold]
    #[inline(never)]
    fn track_slow(&self, cache: &mut RotaryCache, cmd: i64, k: usize) -> bool {
        let k = k % 2;
        let (cpr, table) = (self.counts_per_rev[k], &self.sincos[k]);
        let (turn, primed_cpr) = (cache.cell[k].turn(table), cache.cpr[k]);
        let last = cache.cell_cmd[k].wrapping_add(cache.cell[k].in_cell as i64);
        let t = if primed_cpr == cpr && turn < cpr {
            step_in_turn_wide(turn, cmd.wrapping_sub(last), cpr, cmd)
        } else {
            wrap(cmd, cpr)
        };
        cache.take_cell(k, t, cpr, table);
        cache.cell_cmd[k] = cmd.wrapping_sub(cache.cell[k].in_cell as i64);
        t != turn || primed_cpr != cpr
    }
}

impl RotaryCache {
    /// Axis `k`'s cell at the position `n` < `cpr` of its turn (table `table`). One copy for
    /// the slow path and [`RotaryStage::cache_at`] (code size).
    #[inline(never)]
    fn take_cell(&mut self, k: usize, n: u32, cpr: u32, table: &SinCosTable) {
        let k = k % 2;
        let cell = AngleCell::at(n, cpr, table);
        self.cell[k] = cell;
        self.entry[k] = table.entry(cell.coarse().0);
        self.cpr[k] = cpr;
    }
}

#[cfg(test)]
mod tests;
