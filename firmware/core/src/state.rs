//! The state of one axis ([`State`]): everything that changes per cycle or per sensor reading,
//! one part per stage — [`CounterState`] ([`crate::counter`]), [`TableState`]
//! ([`crate::table`]), [`LimitState`] ([`crate::limits`]), [`ThermoState`] ([`crate::thermo`]) —
//! each used through `&mut` by its own stage only, while the stages' settings are read through
//! `&self`. The few steps that need two parts (a reversal voids the table's segment cache; the
//! turn position of a rotary axis is kept in the cache while it is valid) are composed here and
//! in the compensator.
//!
//! The parts are `#[repr(C)]` and laid out in this order so that the per-cycle path's fields lie
//! within a few words of each other (one base address per axis of a group; a float load reaches
//! 1020 bytes) and pairs that one paired load reads sit side by side (the counter value and the
//! distance moved back; the segment cache's start and length); the cycle counts depend on it.
//! The counter's part is 4-byte aligned (its i64 position is read with a word-aligned paired
//! load), so the whole state is: 428 bytes, the 2-byte tails of the table's and the thermo
//! parts padded to words, and no padding to 8 bytes after the last part (an axis of a group is
//! 428 bytes from the next). Measured against the one flat struct it replaced (424 bytes, with
//! the fields of the stages interleaved; `.ci/bench`): single axis +0.1 / ±0, group3 −3.8,
//! group5 +0.2, the sensor update +5.

use crate::counter::CounterState;
use crate::counts::Direction;
use crate::limits::LimitState;
use crate::table::TableState;
use crate::thermo::ThermoState;

/// Everything that changes while the axis runs: counter extension, direction, the table's
/// segment cache, the last applied correction, lags, sensor health, cached thermal contribution,
/// predicted forces.
///
/// All zero bytes after [`State::new`].
///
/// Equality compares everything the axis's behaviour depends on; it leaves out the table's
/// segment cache, which the group pipelines keep and the single-axis call does not (it only
/// remembers where the last lookup was; a void or a valid cache gives the same value).
#[derive(Debug, Clone)]
#[repr(C)]
pub struct State {
    pub(crate) counter: CounterState,
    pub(crate) table: TableState,
    pub(crate) limits: LimitState,
    pub(crate) thermo: ThermoState,
}

// The per-cycle fields within the first 80 bytes, the pairs side by side, the size (see the
// module doc).
const _: () = {
    use core::mem::offset_of;
    assert!(offset_of!(State, counter) == 0);
    assert!(offset_of!(CounterState, back_counts) == offset_of!(CounterState, last_raw) + 4);
    assert!(offset_of!(TableState, seg_limit) == offset_of!(TableState, seg_start) + 4);
    assert!(offset_of!(State, thermo) + offset_of!(ThermoState, expansion_um_per_count) < 80);
    assert!(core::mem::align_of::<State>() == 4);
    assert!(core::mem::size_of::<State>() == 428);
};

impl PartialEq for State {
    fn eq(&self, other: &State) -> bool {
        // Destructured, so that a new field cannot be left out by accident.
        let CounterState {
            position,
            last_raw,
            back_counts,
            pos_in_turn: _,
            direction,
            primed,
            raw_pending,
            turn_primed: _,
        } = self.counter;
        let o = &other.counter;
        primed == o.primed
            && raw_pending == o.raw_pending
            && last_raw == o.last_raw
            && position == o.position
            && direction == o.direction
            && back_counts == o.back_counts
            && self.turn_in() == other.turn_in()
            && self.limits == other.limits
            && self.thermo == other.thermo
    }
}

impl Default for State {
    fn default() -> Self {
        State::new()
    }
}

impl State {
    /// Fresh state: the first cycle takes the counter value (sign-extended from `counter_bits`)
    /// as the extended position; direction forward; no correction applied yet.
    pub const fn new() -> State {
        State {
            counter: CounterState::NEW,
            table: TableState::NEW,
            limits: LimitState::NEW,
            thermo: ThermoState::NEW,
        }
    }

    /// Back to [`State::new`], with `scale_raw` as the counter value at reset: the next cycle
    /// starts the extended position at `scale_raw` (sign-extended) and adds the delta to its own
    /// counter value.
    pub fn reset(&mut self, scale_raw: u32) {
        *self = State::new();
        self.counter.raw_pending = true;
        self.counter.last_raw = scale_raw;
    }

    /// Homing: the counter reads `scale_raw` at the extended position `position_counts`.
    pub fn home(&mut self, scale_raw: u32, position_counts: i64) {
        self.counter.home(scale_raw, position_counts);
        self.table.void();
    }

    /// A new image became active: sensor health, lags and the sensor clock restart (the new image
    /// may have other sensors), the thermal contribution stays frozen at its last value until
    /// every sensor of the new image has reported; position, direction and the last applied
    /// correction carry over, so the slew limit bridges the change.
    pub fn on_new_image(&mut self) {
        self.thermo.on_new_image();
        self.counter.turn_primed = false;
        self.table.void();
    }

    /// Position within the turn of a rotary axis of a group (None before it is known): while the
    /// segment cache is valid, the segment's start within the turn + the extended position's
    /// distance from the segment's start (both within one segment of the turn: no wrap), else
    /// the counter stage's `pos_in_turn`.
    pub(crate) fn turn_in(&self) -> Option<u32> {
        if !self.counter.turn_primed {
            return None;
        }
        Some(
            self.table
                .cached_turn(self.counter.position as u32)
                .unwrap_or(self.counter.pos_in_turn),
        )
    }

    /// Before the segment cache is voided or refilled: the turn position of the last cycle's
    /// extended position, whose low 32 bits are `last_low` (see [`settle_turn`]).
    #[inline(always)]
    pub(crate) fn settle_turn(&mut self, last_low: u32) {
        settle_turn(&mut self.counter, &self.table, last_low);
    }

    /// Extended scale position of the last cycle.
    pub fn position_counts(&self) -> i64 {
        self.counter.position
    }
    /// Counter value of the last cycle (or the one at reset, before the first cycle).
    pub(crate) fn counter_raw(&self) -> u32 {
        self.counter.last_raw
    }
    /// Current approach direction.
    pub fn direction(&self) -> Direction {
        self.counter.direction
    }
    /// Applied correction of the last cycle, µm.
    pub fn last_correction_um(&self) -> f32 {
        self.limits.last_correction_um
    }
    /// Cached Σ b_i·ΔT_i, µm (frozen while a sensor is unhealthy).
    pub fn sensor_term_um(&self) -> f32 {
        self.thermo.sensor_um
    }
    /// Cached expansion coefficient c·ΔT_s·um_per_count/1000, µm per count.
    pub fn expansion_um_per_count(&self) -> f32 {
        self.thermo.expansion_um_per_count
    }
    /// True while the thermal contribution follows the readings (not frozen).
    pub fn thermal_live(&self) -> bool {
        self.thermo.thermal_live
    }
    /// True while a sensor is stale or its last reading was rejected.
    pub fn sensor_fault(&self) -> bool {
        self.thermo.sensor_fault
    }
    /// Lagged ΔT of sensor `i` (None before its first accepted reading).
    pub fn filtered_delta_t(&self, i: usize) -> Option<f32> {
        self.thermo
            .sensors
            .get(i)
            .and_then(|s| s.seen().then_some(s.filtered_dt))
    }
    /// True if sensor `i` is stale (or recovering).
    pub fn sensor_stale(&self, i: usize) -> bool {
        self.thermo.sensors.get(i).is_some_and(|s| s.stale())
    }
    /// Number of rejected readings of sensor `i` (saturating at 2^24 − 1 = 16 777 215).
    pub fn rejected_readings(&self, i: usize) -> u32 {
        self.thermo.sensors.get(i).map_or(0, |s| s.rejected())
    }
    /// Cached Σ χ_j·F_j of the predicted forces, µm.
    pub fn predicted_term_um(&self) -> f32 {
        self.thermo.predicted_um
    }
    /// Predicted force `j`, N.
    pub fn predicted_force_n(&self, j: usize) -> f32 {
        self.thermo
            .predicted_forces_n
            .get(j)
            .copied()
            .unwrap_or(0.0)
    }
}

/// Before the segment cache is voided or refilled: the counter stage's `pos_in_turn` set to the
/// turn position of the last cycle's extended position, whose low 32 bits are `last_low` (it was
/// within the cached segment while the cache is valid). Nothing to do for a void cache or a
/// linear axis.
#[inline(always)]
pub(crate) fn settle_turn(counter: &mut CounterState, table: &TableState, last_low: u32) {
    if let Some(in_turn) = table.cached_turn(last_low) {
        counter.settle_turn(in_turn);
    }
}

/// What a reversal does beyond the counter stage (its `on_reversal`): the segment cache, which
/// holds the other half's coefficients, voided — for an axis that may be rotary (`TURNS`) after
/// the turn position of the last cycle's extended position was settled from it.
#[inline(always)]
pub(crate) fn on_reversal<const TURNS: bool>(
    table: &mut TableState,
) -> impl FnOnce(&mut CounterState, u32) + '_ {
    move |counter, last_low| {
        if TURNS {
            settle_turn(counter, table, last_low);
        }
        table.void();
    }
}
