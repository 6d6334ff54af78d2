//! Limits of the applied correction (magnitude clamp, slew) and the rounding to counts.
//!
//! # Glossary
//! - **clamp**: |total correction| ≤ `max_correction_um`.
//! - **slew**: the change of the applied correction per cycle ≤ `max_slew_um_per_cycle`.
//! - **counts**: the applied correction in scale counts, rounded half away from zero.

use crate::compensator::Flags;

/// Marks the branch that calls it as rarely taken, so the per-cycle path is laid out as the
/// fall-through (a stand-in for `core::hint::cold_path`, which needs Rust 1.95; MSRV is 1.85).
#[cold]
#[inline(never)]
pub(crate) fn cold_path() {}

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
#[inline]
pub(crate) fn round_half_away_bounded(x: f32) -> i32 {
    let t = (x + x) as i32;
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
    use super::{round_half_away_bounded, round_to_counts};

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
