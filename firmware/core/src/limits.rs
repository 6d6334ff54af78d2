//! Limits of the applied correction (magnitude clamp, slew) and the rounding to counts.
//!
//! # Glossary
//! - **clamp**: |total correction| ≤ `max_correction_um`.
//! - **slew**: the change of the applied correction per cycle ≤ `max_slew_um_per_cycle`.
//! - **counts**: the applied correction in scale counts, rounded half away from zero.
//!
//! The stage is a value: its settings [`LimitStage`] (read through `&self`, set by the loader)
//! and its state [`LimitState`] (the last applied correction, through `&mut`), one part of the
//! axis's [`crate::State`].

use crate::hint::cold_path;
use crate::io::{CycleOutput, Flags};

/// The limits stage's state: the correction applied by the last cycle, µm (what the slew limit
/// is measured from).
#[derive(Debug, Clone, PartialEq)]
#[repr(C)]
pub(crate) struct LimitState {
    pub(crate) last_correction_um: f32,
}

impl LimitState {
    /// No correction applied yet (all zero bytes).
    pub(crate) const NEW: LimitState = LimitState {
        last_correction_um: 0.0,
    };
}

/// The settings of the limits stage (validated at load): the per-cycle fields first, the two
/// magnitude keys side by side (one paired load reads both).
#[derive(Debug, Clone, Copy)]
#[repr(C)]
pub(crate) struct LimitStage {
    /// [`magnitude_key`] of `max_correction_um` if every applied correction, in counts, is below
    /// 2^29 in magnitude (`MAX_LIMIT_UM` / `um_per_count` < 2^29), else 0: the cycle's fast path
    /// (within the clamp, rounded with `round_half_away_bounded`) is never taken for an
    /// unbounded image (no magnitude's key is below 0).
    pub(crate) fast_max_key: u32,
    /// `max_slew_um_per_cycle` as the cycle's fast path tests it: see [`magnitude_key`].
    pub(crate) slew_key: u32,
    /// `um_per_count / 2` (exact), so that the cycle's quotient is already doubled for the
    /// bounded rounding.
    pub(crate) half_um_per_count: f32,
    // ---- read off the per-cycle path ----
    /// Scale resolution, µm per count (0 for the identity).
    pub(crate) um_per_count: f32,
    pub(crate) max_correction_um: f32,
}

impl LimitStage {
    /// The identity's limits (all zero bytes).
    pub(crate) const IDENTITY: LimitStage = LimitStage {
        fast_max_key: 0,
        slew_key: 0,
        half_um_per_count: 0.0,
        um_per_count: 0.0,
        max_correction_um: 0.0,
    };

    /// Clamp, slew, rounding to counts and the corrected command: the last stage of an axis.
    ///
    /// Common case first: within the clamp and the slew limit (two compares, NaN fails the
    /// first), rounded in five instructions from `applied · 2/um_per_count` (see
    /// `round_half_away_bounded`); otherwise the full rules of `limit` and `round_to_counts`.
    /// µm → counts divides by `um_per_count / 2` (exact halving at load), which is bit for bit
    /// 2·(applied / um_per_count): the doubling of the bounded rounding costs nothing and the
    /// counts equal `libm::roundf(applied / um_per_count)`. (A multiply by a reciprocal computed
    /// at load would save the division's 13 extra cycles on a Cortex-M4F, but not an
    /// instruction, and it rounds differently near half counts: 9000 µm at 0.001 µm/count would
    /// give 8 999 999 counts instead of 9 000 000.)
    #[inline(always)]
    pub(crate) fn finish(
        &self,
        st: &mut LimitState,
        pos: i64,
        total: f32,
        command: i64,
        mut flags: Flags,
    ) -> CycleOutput {
        let last = st.last_correction_um;
        // |total| ≤ max and |total − last| ≤ slew as compares of magnitude keys (see
        // `magnitude_key`: the same outcome for every value, NaN failing): one integer compare of
        // a shifted operand each, no `vabs`, `vcmp`, `vmrs`.
        let (applied, counts) = if magnitude_key_of(total) < self.fast_max_key
            && magnitude_key_of(total - last) < self.slew_key
        {
            // |total| ≤ max ≤ MAX_LIMIT_UM and the image is bounded: |counts| < 2^29.
            (
                total,
                round_half_away_bounded2(total / self.half_um_per_count),
            )
        } else {
            cold_path();
            let slew = self.max_slew_um_per_cycle();
            let (applied, limit_flags) = limit(total, last, self.max_correction_um, slew);
            flags |= limit_flags;
            // |applied| ≤ MAX_LIMIT_UM always: every image's clamp is validated ≤
            // MAX_LIMIT_UM, the slew only moves between the last applied value and the
            // clamped one, and a NaN holds.
            (applied, round_to_counts(applied / self.um_per_count))
        };
        st.last_correction_um = applied;
        // command − counts, saturating. |counts| < 2^31, so a command in [−2^62, 2^62) (bits 63
        // and 62 equal, i.e. the high word in [−2^30, 2^30): one add and its sign, the add
        // wrapping to a negative value exactly outside) cannot overflow; the saturating form
        // only beyond, out of the way.
        let high = (command >> 32) as i32;
        let corrected = if high.wrapping_add(1 << 30) < 0 {
            cold_path();
            command.saturating_sub(counts as i64)
        } else {
            command.wrapping_sub(counts as i64)
        };
        CycleOutput {
            position_counts: pos,
            corrected_command_counts: corrected,
            correction_counts: counts,
            correction_um: applied,
            flags,
        }
    }

    /// The slew limit, µm per cycle (0 for the identity).
    #[inline(always)]
    pub(crate) fn max_slew_um_per_cycle(&self) -> f32 {
        f32::from_bits(self.slew_key >> 1)
    }
}

/// The key of a limit `m` (finite, ≥ 0: validated) for the fast path's magnitude tests:
/// `magnitude_key_of(x) < magnitude_key(m)` exactly when |x| ≤ m, for every f32 x (NaN fails).
///
/// Why: the bits of a non-negative non-NaN f32, as a u32, order as its value; shifting out the
/// sign bit gives the bits of |x| times 2 (even), so |x| ≤ m ⟺ 2·bits(|x|) ≤ 2·bits(m) ⟺
/// 2·bits(|x|) < 2·bits(m) + 1 (bits(m) < 2^31: the shift keeps every bit). A NaN's magnitude
/// bits are above +∞'s, above any finite m's. The limit's bits are `key >> 1`. Equality of the
/// test with `fabsf(x) <= m` is tested over every magnitude and both signs.
pub(crate) const fn magnitude_key(m: f32) -> u32 {
    (m.to_bits() << 1) | 1
}

/// 2·bits(|x|) (the sign bit shifted out), the left side of the test of [`magnitude_key`].
#[inline(always)]
pub(crate) const fn magnitude_key_of(x: f32) -> u32 {
    x.to_bits() << 1
}

/// Clamp `total` to ±`max` (a NaN holds `last`: NON_FINITE), then limit the change from `last` to
/// `slew`. The per-cycle path takes this only when a limit acts (or the total is NaN).
#[inline(always)]
pub(crate) fn limit(total: f32, last: f32, max: f32, slew: f32) -> (f32, Flags) {
    let mut flags = Flags::NONE;
    let mut desired = total;
    // False for NaN too.
    let within = libm::fabsf(desired) <= max;
    if !within {
        if desired > max {
            desired = max;
            flags |= Flags::CLAMPED;
        } else if desired < -max {
            desired = -max;
            flags |= Flags::CLAMPED;
        } else {
            // NaN: unreachable with a validated image and bounded inputs; hold.
            desired = last;
            flags |= Flags::NON_FINITE;
        }
    }
    let step = desired - last;
    let mut applied = desired;
    if libm::fabsf(step) > slew {
        flags |= Flags::SLEWED;
        if step > 0.0 {
            let a = last + slew;
            applied = if a > desired { desired } else { a };
        } else {
            let a = last - slew;
            applied = if a < desired { desired } else { a };
        }
    }
    (applied, flags)
}

/// Largest `max_correction_um` / `max_slew_um_per_cycle` an image may have (validated), µm.
pub(crate) const MAX_LIMIT_UM: f32 = 1.0e5;

/// [`round_to_counts`] for |x| < 2^30 (NaN → 0), in five integer/convert instructions: with
/// t = trunc(2x) (exact), round half away from zero is (t + 1) >> 1 for t ≥ 0 and t >> 1 for
/// t < 0 (arithmetic shifts, i.e. floor). Equality with [`round_to_counts`] over |x| < 2^30 is
/// tested.
#[cfg(test)]
pub(crate) fn round_half_away_bounded(x: f32) -> i32 {
    round_half_away_bounded2(x + x)
}

/// [`round_half_away_bounded`] of x given `twice_x` = 2x (e.g. a quotient by a halved divisor,
/// which is exactly twice the quotient), so that the doubling folds into a load-time constant.
#[inline]
pub(crate) fn round_half_away_bounded2(twice_x: f32) -> i32 {
    let t = twice_x as i32;
    t.wrapping_add(1).wrapping_add(t >> 31) >> 1
}

/// `libm::roundf(x) as i32` (round half away from zero, saturating, NaN → 0) without the
/// library call: two conversions and a compare on a Cortex-M4F. Equality with `libm::roundf`
/// is property-tested over all magnitudes.
#[inline]
pub fn round_to_counts(x: f32) -> i32 {
    // For |x| < 2^23 the truncation and the fraction are exact; for larger |x| the value is
    // already an integer (fraction 0). The cast saturates beyond the i32 range.
    let i = x as i32;
    let frac = x - i as f32;
    if frac >= 0.5 {
        i.saturating_add(1)
    } else if frac <= -0.5 {
        i.saturating_sub(1)
    } else {
        i
    }
}

#[cfg(test)]
mod tests {
    use super::{magnitude_key, magnitude_key_of, round_half_away_bounded, round_to_counts};

    /// Reference: `libm::fabsf(x) <= m`, the float test the fast path had; tolerance: exact
    /// equality of the outcome, for limits m of every kind the images allow (finite, ≥ 0: zero,
    /// subnormal, around 1, up to `MAX_LIMIT_UM` and beyond) and x over a stride through every
    /// bit pattern (both signs, subnormals, ±∞, NaNs) plus each limit and its neighbours.
    #[test]
    fn magnitude_key_test_equals_the_float_compare() {
        let limits = [
            0.0f32,
            f32::from_bits(1),
            1.0e-30,
            0.001,
            0.5,
            1.0,
            3.0,
            1.0e4,
            super::MAX_LIMIT_UM,
            f32::MAX,
        ];
        let mut checked = 0u32;
        for &m in &limits {
            let key = magnitude_key(m);
            let mut xs = [m, -m, 0.0, -0.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN].to_vec();
            for d in [1u32, 2] {
                xs.push(f32::from_bits(m.to_bits().wrapping_add(d)));
                xs.push(f32::from_bits(m.to_bits().wrapping_sub(d)));
                xs.push(-f32::from_bits(m.to_bits().wrapping_add(d)));
            }
            let mut bits = 0u32;
            while bits <= u32::MAX - 65_521 {
                xs.push(f32::from_bits(bits));
                bits += 65_521;
            }
            for &x in &xs {
                assert_eq!(
                    magnitude_key_of(x) < key,
                    libm::fabsf(x) <= m,
                    "x = {x:e} ({:#x}), m = {m:e}",
                    x.to_bits()
                );
                checked += 1;
            }
        }
        assert!(checked > 600_000);
    }

    /// Reference: `round_to_counts` (itself property-tested equal to `libm::roundf` as i32);
    /// tolerance: exact equality, over |x| < 2^30 as `round_half_away_bounded` requires.
    #[test]
    fn bounded_rounding_equals_round_to_counts() {
        let limit = (1u32 << 30) as f32;
        let mut checked = 0u32;
        // A stride through every magnitude below 2^30 (bit patterns 0 .. 0x4E80_0000), both signs.
        let mut bits = 0u32;
        while bits < 0x4E80_0000 {
            for x in [f32::from_bits(bits), -f32::from_bits(bits)] {
                assert!(libm::fabsf(x) < limit);
                assert_eq!(round_half_away_bounded(x), round_to_counts(x), "x = {x:e}");
                checked += 1;
            }
            bits += 211;
        }
        // Every half-integer up to 2^22 (exact in f32) and its two neighbours, both signs.
        for k in 0..(1i32 << 22) {
            let h = k as f32 + 0.5;
            for x in [
                h,
                f32::from_bits(h.to_bits() - 1),
                f32::from_bits(h.to_bits() + 1),
            ] {
                assert_eq!(round_half_away_bounded(x), round_to_counts(x), "x = {x:e}");
                assert_eq!(
                    round_half_away_bounded(-x),
                    round_to_counts(-x),
                    "x = {:e}",
                    -x
                );
                checked += 2;
            }
        }
        assert_eq!(round_half_away_bounded(f32::NAN), 0);
        assert!(checked > 30_000_000);
    }
}
