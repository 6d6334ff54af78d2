//! The counter's arithmetic that the runtime types hold and several stages share: the approach
//! [`Direction`], the sign extension's shift ([`CounterShift`]) and the position within a turn.
//! A leaf below [`crate::runtime`]; the stage that uses them per cycle is [`crate::counter`].
//!
//! # Glossary
//! - **turn position** (rotary axes of a group): the extended position modulo the counts per
//!   revolution, in `[0, counts_per_rev)`, followed incrementally (one add and one compare per
//!   cycle; the full modulo only on the first cycle or a step of a whole turn or more).

use crate::hint::cold_path;
use crate::io::Flags;

/// Approach direction of the axis.
///
/// Its byte is [`crate::Flags::BACKWARD`] (bit 7) if backward, else 0, so that what the cycle
/// needs of a [`crate::State`]'s direction is one operation on its byte with no conversion per
/// cycle: the flag itself (an `orr`), the table's backward half (bit 7 shifted to the half's
/// offset) and, from its sign-extending load, the hysteresis's mask (0 forward, −1 backward: the
/// byte's sign shifted in, an operand shift of the operations that use it).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum Direction {
    /// Increasing scale position (also the initial direction).
    #[default]
    Forward = 0,
    /// Decreasing scale position.
    Backward = 0x80,
}

// The byte of `Direction::Backward` is the BACKWARD flag.
const _: () = assert!(Direction::Backward as u16 == Flags::BACKWARD.0);

impl Direction {
    /// The other direction.
    #[inline(always)]
    pub const fn reversed(self) -> Direction {
        match self {
            Direction::Forward => Direction::Backward,
            Direction::Backward => Direction::Forward,
        }
    }
    /// 0 forward, −1 backward (the byte's bit 7, sign-extended).
    #[inline(always)]
    pub(crate) const fn mask(self) -> i32 {
        (self as u8 as i8 as i32) >> 7
    }
    /// The table's direction half: 0 forward, 1 backward.
    #[inline(always)]
    pub(crate) const fn half(self) -> usize {
        (self as u8 >> 7) as usize
    }
    /// `bits` with [`crate::Flags::BACKWARD`] if backward.
    #[inline(always)]
    pub(crate) const fn with_flag(self, bits: u16) -> u16 {
        bits | self as u8 as u16
    }
    /// [`crate::Flags::BACKWARD`] if backward, else 0.
    #[inline(always)]
    pub(crate) const fn flag(self) -> u16 {
        self as u8 as u16
    }
}

/// The shift of the counter's sign extension, 32 − `counter_bits` (0..=31): an enum, so that a load
/// of it carries its range and the shifts by it need no `& 31` (one instruction per axis and cycle).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u32)]
pub(crate) enum CounterShift {
    /// A 32-bit counter (and the identity).
    #[default]
    S0 = 0,
    S1 = 1,
    S2 = 2,
    S3 = 3,
    S4 = 4,
    S5 = 5,
    S6 = 6,
    S7 = 7,
    S8 = 8,
    S9 = 9,
    S10 = 10,
    S11 = 11,
    S12 = 12,
    S13 = 13,
    S14 = 14,
    S15 = 15,
    S16 = 16,
    S17 = 17,
    S18 = 18,
    S19 = 19,
    S20 = 20,
    S21 = 21,
    S22 = 22,
    S23 = 23,
    S24 = 24,
    S25 = 25,
    S26 = 26,
    S27 = 27,
    S28 = 28,
    S29 = 29,
    S30 = 30,
    S31 = 31,
}

impl CounterShift {
    /// `shift` modulo 32 (a counter width of 16..=32 bits gives 0..=16).
    pub(crate) const fn new(shift: u32) -> CounterShift {
        use CounterShift::*;
        const ALL: [CounterShift; 32] = [
            S0, S1, S2, S3, S4, S5, S6, S7, S8, S9, S10, S11, S12, S13, S14, S15, S16, S17, S18,
            S19, S20, S21, S22, S23, S24, S25, S26, S27, S28, S29, S30, S31,
        ];
        ALL[(shift & 31) as usize]
    }
    /// The shift.
    #[inline(always)]
    pub(crate) const fn get(self) -> u32 {
        self as u32
    }
}

/// `in_turn + delta` modulo `cpr` (> 0), for `in_turn < cpr` and `absolute` ≡ in_turn + delta:
/// one add and one compare when the step stays within the turn, the full (slow) modulo for a
/// step of a turn or more.
///
/// The common case runs on 32 bits. With delta an i32 d and in_turn < cpr ≤ 2^31, the sum
/// s = in_turn + d lies in (−2^31, 2^32), and its wrapping u32 value v is below cpr exactly when
/// s is in [0, cpr) (a negative s wraps to v ≥ 2^31 ≥ cpr): then v is the result, whatever d's
/// size. Otherwise, for |d| < cpr, s lies in (−cpr, 2·cpr) and one correction by ±cpr, in
/// wrapping u32 arithmetic, gives the exact value. Anything else (a delta that does not fit an
/// i32, a step of a turn or more, `in_turn` ≥ cpr) takes [`step_in_turn_wide`], the same rule on
/// 64 bits.
#[inline(always)]
pub(crate) fn step_in_turn(in_turn: u32, delta: i64, cpr: u32, absolute: i64) -> u32 {
    let d = delta as i32;
    if d as i64 == delta && in_turn < cpr {
        let v = in_turn.wrapping_add(d as u32);
        if v < cpr {
            return v;
        }
        if d.unsigned_abs() < cpr {
            return if d < 0 { v.wrapping_add(cpr) } else { v - cpr };
        }
    }
    cold_path();
    step_in_turn_wide(in_turn, delta, cpr, absolute)
}

/// [`step_in_turn`] in 64-bit arithmetic (any `in_turn`); also the rotary stage's slow path of
/// its commanded angles.
#[inline(never)]
pub(crate) fn step_in_turn_wide(in_turn: u32, delta: i64, cpr: u32, absolute: i64) -> u32 {
    let c = cpr as i64;
    if delta > -c && delta < c {
        let v = in_turn as i64 + delta;
        if v < 0 {
            (v + c) as u32
        } else if v >= c {
            (v - c) as u32
        } else {
            v as u32
        }
    } else {
        wrap(absolute, cpr)
    }
}

/// `x` modulo `cpr` in `[0, cpr)` (0 for `cpr` = 0).
pub(crate) fn wrap(x: i64, cpr: u32) -> u32 {
    x.rem_euclid((cpr as i64).max(1)) as u32
}

#[cfg(test)]
mod tests {
    use super::{step_in_turn, step_in_turn_wide};

    /// Reference: `step_in_turn_wide`, the 64-bit rule (the code before the 32-bit fast path);
    /// tolerance: exact equality, for turn lengths 2 … 2^31, positions within and beyond the turn
    /// and steps of every size (below a turn, exactly a turn, beyond 2^31, ±2^63).
    #[test]
    fn fast_step_equals_the_64_bit_rule() {
        let mut next = crate::test_rng::xorshift(0x9E37_79B9_7F4A_7C15u64);
        let mut checked = 0u32;
        for cpr in [2u32, 3, 1000, 3_600_000, (1 << 31) - 1, 1 << 31] {
            let c = cpr as i64;
            let specials = [
                0,
                1,
                -1,
                c - 1,
                -(c - 1),
                c,
                -c,
                c + 1,
                i32::MIN as i64,
                i32::MAX as i64,
                1 << 31,
                i64::MIN,
                i64::MAX,
            ];
            for k in 0..20_000 {
                let r = next();
                let in_turn = if k % 10 == 0 {
                    r as u32
                } else {
                    (r % cpr as u64) as u32
                };
                let delta = match k % 4 {
                    0 => specials[(r >> 40) as usize % specials.len()],
                    1 => ((r >> 20) as i64) % c,
                    2 => (r >> 8) as i32 as i64,
                    _ => r as i64,
                };
                let absolute = (in_turn as i64).wrapping_add(delta);
                assert_eq!(
                    step_in_turn(in_turn, delta, cpr, absolute),
                    step_in_turn_wide(in_turn, delta, cpr, absolute),
                    "cpr {cpr}, in_turn {in_turn}, delta {delta}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 120_000);
    }
}
