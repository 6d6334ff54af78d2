//! Counter extension and approach direction: the scale's wrapping hardware counter becomes an
//! extended i64 position, and a hysteresis decides which table direction applies.
//!
//! # Glossary
//! - **counter width**: `counter_bits` (16..=32) of the hardware counter; it wraps at 2^bits.
//! - **extension**: the extended position adds the sign-extended counter delta each cycle, so any
//!   sequence of steps below half the counter range is followed exactly.
//! - **turn position** (rotary axes of a group): the extended position modulo the counts per
//!   revolution, in `[0, counts_per_rev)`, followed incrementally (one add and one compare per
//!   cycle; the full modulo only on the first cycle or a step of a whole turn or more).
//! - **reversal / hysteresis**: the direction flips only after moving more than
//!   `direction_hysteresis_counts` against it (state: distance moved back since the extreme).

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
const _: () = assert!(Direction::Backward as u16 == crate::Flags::BACKWARD.0);

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

use crate::compensator::{AxisCompensator, State, TableStore};
use crate::limits::cold_path;

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

impl<S: TableStore> AxisCompensator<S> {
    /// Counter extension (wrap-safe, sign-extended delta) and the direction hysteresis; returns
    /// the extended position (also stored in `st`) and the step `delta` that was added to the
    /// previous extended position (position = previous position + delta, exactly).
    #[inline(always)]
    pub(crate) fn track(&self, st: &mut State, raw: u32) -> (i64, i32) {
        if !st.primed {
            cold_path();
            self.prime(st, raw);
        }
        self.track_primed(st, raw)
    }

    /// The first cycle of a fresh or reset state: the counter value (at reset, or this cycle's)
    /// sign-extended is the extended position.
    #[inline(always)]
    fn prime(&self, st: &mut State, raw: u32) {
        let shift = self.sext_shift.get();
        let base = if st.raw_pending { st.last_raw } else { raw };
        st.position = ((base.wrapping_shl(shift) as i32) >> shift) as i64;
        st.last_raw = base;
        st.back_counts = 0;
        st.primed = true;
        st.raw_pending = false;
    }

    /// [`AxisCompensator::track`] without the test of `primed` (the group pipelines, whose
    /// segment cache is void while the state is not primed): on a state that is not primed it
    /// computes something else, which [`AxisCompensator::track_unprimed`] (the cache miss's
    /// path) replaces by what `track` computes.
    #[inline(always)]
    pub(crate) fn track_primed(&self, st: &mut State, raw: u32) -> (i64, i32) {
        let shift = self.sext_shift.get();
        let delta = ((raw.wrapping_sub(st.last_raw)).wrapping_shl(shift) as i32) >> shift;
        let pos = st.position.wrapping_add(delta as i64);
        st.position = pos;

        // back = distance moved against the current direction since its extreme
        // (= extreme − position going forward), ≥ 0, saturating; hysteresis ≤ i32::MAX (validated).
        // (A delta of exactly −2^31, a half turn of a 32-bit counter, is ambiguous anyway; its
        // wrapping negation keeps it "forward".)
        // (m = 0 forward, −1 backward: m − (delta ^ m) is the wrapping negation of delta or
        // delta itself.)
        let m = st.direction.mask();
        let against = m.wrapping_sub(delta ^ m);
        let back = st.back_counts.saturating_add(against);
        let back = if back > self.hysteresis_counts as i32 {
            if S::TURNS {
                // A group axis (segment cache, turn position): out of line.
                st.reverse((pos as u32).wrapping_sub(delta as u32));
            } else {
                st.direction = st.direction.reversed();
                st.seg_limit = 0;
            }
            // Nothing moved back yet in the new direction.
            0
        } else if back < 0 {
            0
        } else {
            back
        };
        // The counter value and the distance moved back side by side (one paired store).
        st.last_raw = raw;
        st.back_counts = back;
        (pos, delta)
    }

    /// After [`AxisCompensator::track_primed`] with `raw` returned `delta` on a state that was
    /// not primed: the state and the result `track` would have given.
    ///
    /// Exact because a state that is not primed is a fresh one or a reset one ([`State::new`],
    /// [`State::reset`]; nothing else clears `primed`): direction forward, nothing moved back,
    /// and the counter value at reset (if any) in `last_raw`, whose low `counter_bits` bits —
    /// all that the priming reads of it — are `raw − delta` (delta is the sign extension of
    /// `raw − last_raw` from those bits).
    #[cold]
    #[inline(never)]
    pub(crate) fn track_unprimed(&self, st: &mut State, raw: u32, delta: i32) -> (i64, i32) {
        st.last_raw = raw.wrapping_sub(delta as u32);
        st.direction = Direction::Forward;
        st.back_counts = 0;
        self.prime(st, raw);
        self.track_primed(st, raw)
    }
}

impl<S: TableStore> AxisCompensator<S> {
    /// The position within the turn of a rotary axis (`counts_per_rev` > 0) at extended
    /// position `pos`, which [`AxisCompensator::track`] just reached by adding `delta`; kept in
    /// `st`.
    ///
    /// While `turn_primed`, the previous cycle ran this after its own `track`, so `pos_in_turn`
    /// belongs to the previous extended position and this cycle's step is exactly `delta` (an
    /// i32: no 64-bit difference to form and test). Everything that moves the extended position
    /// otherwise ([`State::home`], [`State::reset`], [`State::on_new_image`], a fresh state)
    /// clears `turn_primed`, and the next cycle takes the full modulo.
    #[inline(always)]
    pub(crate) fn turn_position(&self, st: &mut State, pos: i64, delta: i32) -> u32 {
        let cpr = self.counts_per_rev;
        st.pos_in_turn = if st.turn_primed {
            step_in_turn(st.pos_in_turn, delta as i64, cpr, pos)
        } else {
            cold_path();
            st.turn_primed = true;
            wrap(pos, cpr)
        };
        st.pos_in_turn
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
