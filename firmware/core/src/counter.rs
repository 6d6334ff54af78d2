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
//!
//! The stage is a value: its settings [`CounterStage`] (read through `&self`, set by the loader)
//! and its state [`CounterState`] (the extended position, the counter value, the distance moved
//! back, the direction, and for a rotary axis the turn position; through `&mut`), one part of
//! the axis's [`crate::State`]. A reversal calls the caller's `on_reversal` after the direction
//! flipped (the compensator passes [`crate::state::on_reversal`], which voids the table's segment
//! cache); with `TURNS` (a compile-time choice of the caller: the axis may be rotary) out of
//! line.

use crate::counts::{CounterShift, Direction, step_in_turn, wrap};
use crate::hint::cold_path;

/// The counter stage's state: what [`CounterStage`] keeps between cycles.
///
/// `#[repr(C)]` in this order: the extended position first, the counter value and the distance
/// moved back side by side (one paired load and store), within a few words of the other parts of
/// the axis's [`crate::State`]. Aligned to 4 bytes, not the i64's 8 (`packed(4)`: every field
/// stays at its natural offset; the position's paired load and store need only word alignment),
/// so that the state has no padding to 8 bytes (see [`crate::state`]). Fields are read and
/// written by value only (no reference to the position).
#[derive(Debug, Clone, Copy)]
#[repr(C, packed(4))]
pub(crate) struct CounterState {
    pub(crate) position: i64,
    pub(crate) last_raw: u32,
    pub(crate) back_counts: i32,
    /// Rotary axis of a group: the position within the turn — while the table's segment cache
    /// is valid, of the position where it was filled only: the present one is
    /// [`crate::State::turn_in`].
    pub(crate) pos_in_turn: u32,
    /// The approach direction (its byte is the hysteresis's mask: see [`Direction`]).
    pub(crate) direction: Direction,
    pub(crate) primed: bool,
    pub(crate) raw_pending: bool,
    pub(crate) turn_primed: bool,
}

impl CounterState {
    /// Fresh state: not primed, direction forward (all zero bytes).
    pub(crate) const NEW: CounterState = CounterState {
        position: 0,
        last_raw: 0,
        back_counts: 0,
        pos_in_turn: 0,
        direction: Direction::Forward,
        primed: false,
        raw_pending: false,
        turn_primed: false,
    };

    /// Homing: the counter reads `scale_raw` at the extended position `position_counts`; the
    /// turn position is taken anew at the next cycle.
    pub(crate) fn home(&mut self, scale_raw: u32, position_counts: i64) {
        self.primed = true;
        self.raw_pending = false;
        self.last_raw = scale_raw;
        self.position = position_counts;
        self.back_counts = 0;
        self.turn_primed = false;
    }

    /// Flip the direction: a reversal (the caller resets the distance moved back).
    #[inline(always)]
    pub(crate) fn reverse(&mut self) {
        self.direction = self.direction.reversed();
    }

    /// The turn position of the last cycle's extended position, `in_turn`, kept (if the turn
    /// position is known at all): what the table's segment cache held for it.
    #[inline(always)]
    pub(crate) fn settle_turn(&mut self, in_turn: u32) {
        if self.turn_primed {
            self.pos_in_turn = in_turn;
        }
    }
}

/// A reversal on an axis that may be rotary (`TURNS`): the direction flipped and `on_reversal`
/// called out of line, off the cycle's common path.
#[cold]
#[inline(never)]
fn reverse_out_of_line<F: FnOnce(&mut CounterState, u32)>(
    st: &mut CounterState,
    last_low: u32,
    on_reversal: F,
) {
    st.reverse();
    on_reversal(st, last_low);
}

/// The settings of the counter stage (validated at load).
#[derive(Debug, Clone, Copy)]
#[repr(C)]
pub(crate) struct CounterStage {
    /// Width of the hardware counter, bits (0 for the identity, which extends a 32-bit counter).
    pub(crate) counter_bits: u8,
    // The shift and the hysteresis side by side: one paired load reads both.
    /// 32 − counter_bits (0 for the identity: a 32-bit counter).
    pub(crate) sext_shift: CounterShift,
    pub(crate) hysteresis_counts: u32,
}

impl CounterStage {
    /// The identity's counter (a 32-bit counter, no hysteresis; all zero bytes).
    pub(crate) const IDENTITY: CounterStage = CounterStage {
        counter_bits: 0,
        sext_shift: CounterShift::S0,
        hysteresis_counts: 0,
    };

    /// Counter extension (wrap-safe, sign-extended delta) and the direction hysteresis; returns
    /// the extended position (also stored in `st`) and the step `delta` that was added to the
    /// previous extended position (position = previous position + delta, exactly). On a
    /// reversal, `on_reversal(st, last_low)` after the direction flipped, with the low 32 bits of
    /// the last cycle's extended position.
    #[inline(always)]
    pub(crate) fn track<const TURNS: bool>(
        &self,
        st: &mut CounterState,
        raw: u32,
        on_reversal: impl FnOnce(&mut CounterState, u32),
    ) -> (i64, i32) {
        if !st.primed {
            cold_path();
            self.prime(st, raw);
        }
        self.track_primed::<TURNS>(st, raw, on_reversal)
    }

    /// The first cycle of a fresh or reset state: the counter value (at reset, or this cycle's)
    /// sign-extended is the extended position.
    #[inline(always)]
    fn prime(&self, st: &mut CounterState, raw: u32) {
        let shift = self.sext_shift.get();
        let base = if st.raw_pending { st.last_raw } else { raw };
        st.position = ((base.wrapping_shl(shift) as i32) >> shift) as i64;
        st.last_raw = base;
        st.back_counts = 0;
        st.primed = true;
        st.raw_pending = false;
    }

    /// [`CounterStage::track`] without the test of `primed` (the group pipelines, whose
    /// segment cache is void while the state is not primed): on a state that is not primed it
    /// computes something else, which [`CounterStage::track_unprimed`] (the cache miss's
    /// path) replaces by what `track` computes.
    #[inline(always)]
    pub(crate) fn track_primed<const TURNS: bool>(
        &self,
        st: &mut CounterState,
        raw: u32,
        on_reversal: impl FnOnce(&mut CounterState, u32),
    ) -> (i64, i32) {
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
            let last_low = (pos as u32).wrapping_sub(delta as u32);
            if TURNS {
                // A group axis (segment cache, turn position): out of line.
                reverse_out_of_line(st, last_low, on_reversal);
            } else {
                st.reverse();
                on_reversal(st, last_low);
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

    /// After [`CounterStage::track_primed`] with `raw` returned `delta` on a state that was
    /// not primed: the state and the result `track` would have given.
    ///
    /// Exact because a state that is not primed is a fresh one or a reset one
    /// ([`crate::State::new`], [`crate::State::reset`]; nothing else clears `primed`): direction forward, nothing moved back,
    /// and the counter value at reset (if any) in `last_raw`, whose low `counter_bits` bits —
    /// all that the priming reads of it — are `raw − delta` (delta is the sign extension of
    /// `raw − last_raw` from those bits).
    #[cold]
    #[inline(never)]
    pub(crate) fn track_unprimed<const TURNS: bool>(
        &self,
        st: &mut CounterState,
        raw: u32,
        delta: i32,
        on_reversal: impl FnOnce(&mut CounterState, u32),
    ) -> (i64, i32) {
        st.last_raw = raw.wrapping_sub(delta as u32);
        st.direction = Direction::Forward;
        st.back_counts = 0;
        self.prime(st, raw);
        self.track_primed::<TURNS>(st, raw, on_reversal)
    }

    /// The position within the turn of a rotary axis (`cpr` counts per revolution, > 0) at
    /// extended position `pos`, which [`CounterStage::track`] just reached by adding `delta`;
    /// kept in `st`.
    ///
    /// While `turn_primed`, the previous cycle ran this after its own `track`, so `pos_in_turn`
    /// belongs to the previous extended position and this cycle's step is exactly `delta` (an
    /// i32: no 64-bit difference to form and test). Everything that moves the extended position
    /// otherwise ([`crate::State::home`], [`crate::State::reset`], [`crate::State::on_new_image`],
    /// a fresh state) clears `turn_primed`, and the next cycle takes the full modulo.
    #[inline(always)]
    pub(crate) fn turn_position(
        &self,
        st: &mut CounterState,
        cpr: u32,
        pos: i64,
        delta: i32,
    ) -> u32 {
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
