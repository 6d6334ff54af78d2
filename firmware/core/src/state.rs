//! The state of one axis ([`State`]): everything that changes per cycle or per sensor reading,
//! used through `&mut` by the stages ([`crate::counter`], [`crate::table`], [`crate::thermo`],
//! [`crate::limits`]) while their settings are read through `&self`.
//!
//! One struct for all stages rather than one per stage: its `#[repr(C)]` order interleaves the
//! stages' fields so that the per-cycle path's fields lie within a few words of each other and
//! pairs that one paired load reads sit side by side (the counter value and the distance moved
//! back; the segment cache's start and length); the cycle counts depend on it. Each stage
//! touches only its own fields (named in the field docs).

use crate::counts::Direction;
use crate::io::Flags;
use crate::sensor::SensorState;
use crate::{MAX_FORCES, MAX_SENSORS};

/// Everything that changes while the axis runs: counter extension, direction, lags, sensor
/// health, cached thermal contribution, predicted forces, last applied correction.
///
/// All zero bytes after [`State::new`].
///
/// Equality compares everything the axis's behaviour depends on; it leaves out the table's
/// segment cache (`seg_*`), which the group pipelines keep and the single-axis call does not
/// (it only remembers where the last lookup was; a void or a valid cache gives the same value).
#[derive(Debug, Clone)]
// In this order (not the compiler's): the fields of the per-cycle path first, within a few words
// of each other (one base address per axis of a group; a float load reaches 1020 bytes).
#[repr(C)]
pub struct State {
    pub(crate) position: i64,
    pub(crate) last_raw: u32,
    pub(crate) back_counts: i32,
    pub(crate) last_correction_um: f32,
    /// Segment cache of the table (see [`crate::table::TableStage::refill`]): the low 32 bits
    /// of the extended position where the last cycle's table segment starts, that segment's
    /// length while the cache is valid (0: void, the next lookup is a full one; always 0 while
    /// `primed` is false), a copy of its coefficients in the half of the present direction (a
    /// reversal voids the cache) and, for a rotary axis, the segment's start within the turn.
    pub(crate) seg_start: u32,
    pub(crate) seg_limit: u32,
    /// Rotary axis of a group: the position within the turn (see [`crate::counter`]) — while
    /// the segment cache is valid, of the position where it was filled only: the present one is
    /// [`State::turn_in`].
    pub(crate) pos_in_turn: u32,
    pub(crate) seg_turn_start: u32,
    pub(crate) seg_coef: [f32; 4],
    /// The approach direction (its byte is the hysteresis's mask: see [`Direction`]).
    pub(crate) direction: Direction,
    pub(crate) primed: bool,
    pub(crate) raw_pending: bool,
    pub(crate) turn_primed: bool,
    pub(crate) thermal_live: bool,
    pub(crate) sensor_fault: bool,
    pub(crate) clock_started: bool,
    /// A sensor is stale: the thermal term's ramp-out clock runs from `stale_since_ms`.
    pub(crate) stale_ramp: bool,
    /// Thermo flags (SENSOR_FAULT, THERMAL_FROZEN, FORCE_INVALID of the process) XOR the
    /// compensator's `thermo_flags_xor`.
    pub(crate) thermo_bits: u16,
    /// The segment cache's flags: [`Flags::BACKWARD`] if the direction was backward when it was
    /// filled (a reversal voids it), else none.
    pub(crate) seg_flags: u16,
    pub(crate) sensor_um: f32,
    pub(crate) expansion_um_per_count: f32,
    /// Σ χ_j·F_j of the predicted forces, µm.
    pub(crate) predicted_um: f32,
    /// b0 + sensor_um + predicted_um, µm (what the cycle adds).
    pub(crate) cached_um: f32,
    pub(crate) predicted_forces_n: [f32; MAX_FORCES],
    pub(crate) stale_since_ms: u32,
    pub(crate) frozen_sensor_um: f32,
    pub(crate) frozen_expansion_um_per_count: f32,
    pub(crate) sensors: [SensorState; MAX_SENSORS],
}

impl PartialEq for State {
    fn eq(&self, other: &State) -> bool {
        // Destructured, so that a new field cannot be left out by accident.
        let State {
            primed,
            raw_pending,
            last_raw,
            position,
            direction,
            back_counts,
            last_correction_um,
            sensor_um,
            expansion_um_per_count,
            thermal_live,
            sensor_fault,
            clock_started,
            thermo_bits,
            predicted_um,
            cached_um,
            predicted_forces_n,
            sensors,
            turn_primed: _,
            pos_in_turn: _,
            stale_ramp,
            stale_since_ms,
            frozen_sensor_um,
            frozen_expansion_um_per_count,
            seg_start: _,
            seg_turn_start: _,
            seg_flags: _,
            seg_limit: _,
            seg_coef: _,
        } = self;
        *primed == other.primed
            && *raw_pending == other.raw_pending
            && *last_raw == other.last_raw
            && *position == other.position
            && *direction == other.direction
            && *back_counts == other.back_counts
            && *last_correction_um == other.last_correction_um
            && *sensor_um == other.sensor_um
            && *expansion_um_per_count == other.expansion_um_per_count
            && *thermal_live == other.thermal_live
            && *sensor_fault == other.sensor_fault
            && *clock_started == other.clock_started
            && *thermo_bits == other.thermo_bits
            && *predicted_um == other.predicted_um
            && *cached_um == other.cached_um
            && *predicted_forces_n == other.predicted_forces_n
            && *sensors == other.sensors
            && self.turn_in() == other.turn_in()
            && *stale_ramp == other.stale_ramp
            && *stale_since_ms == other.stale_since_ms
            && *frozen_sensor_um == other.frozen_sensor_um
            && *frozen_expansion_um_per_count == other.frozen_expansion_um_per_count
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
            primed: false,
            raw_pending: false,
            last_raw: 0,
            position: 0,
            direction: Direction::Forward,
            back_counts: 0,
            last_correction_um: 0.0,
            sensor_um: 0.0,
            expansion_um_per_count: 0.0,
            thermal_live: false,
            sensor_fault: false,
            clock_started: false,
            thermo_bits: 0,
            predicted_um: 0.0,
            cached_um: 0.0,
            predicted_forces_n: [0.0; MAX_FORCES],
            sensors: [SensorState::NEW; MAX_SENSORS],
            turn_primed: false,
            pos_in_turn: 0,
            seg_start: 0,
            seg_turn_start: 0,
            seg_flags: 0,
            seg_limit: 0,
            seg_coef: [0.0; 4],
            stale_ramp: false,
            stale_since_ms: 0,
            frozen_sensor_um: 0.0,
            frozen_expansion_um_per_count: 0.0,
        }
    }

    /// Back to [`State::new`], with `scale_raw` as the counter value at reset: the next cycle
    /// starts the extended position at `scale_raw` (sign-extended) and adds the delta to its own
    /// counter value.
    pub fn reset(&mut self, scale_raw: u32) {
        *self = State::new();
        self.raw_pending = true;
        self.last_raw = scale_raw;
    }

    /// Homing: the counter reads `scale_raw` at the extended position `position_counts`.
    pub fn home(&mut self, scale_raw: u32, position_counts: i64) {
        self.primed = true;
        self.raw_pending = false;
        self.last_raw = scale_raw;
        self.position = position_counts;
        self.back_counts = 0;
        self.turn_primed = false;
        self.seg_limit = 0;
    }

    /// A new image became active: sensor health, lags and the sensor clock restart (the new image
    /// may have other sensors), the thermal contribution stays frozen at its last value until
    /// every sensor of the new image has reported; position, direction and the last applied
    /// correction carry over, so the slew limit bridges the change.
    pub fn on_new_image(&mut self) {
        self.sensors = [SensorState::NEW; MAX_SENSORS];
        self.clock_started = false;
        self.thermal_live = false;
        self.sensor_fault = false;
        self.thermo_bits = 0;
        self.predicted_um = 0.0;
        self.predicted_forces_n = [0.0; MAX_FORCES];
        self.turn_primed = false;
        self.seg_limit = 0;
        self.stale_ramp = false;
    }

    /// Position within the turn of a rotary axis of a group (None before it is known): while the
    /// segment cache is valid, the segment's start within the turn + the extended position's
    /// distance from the segment's start (both within one segment of the turn: no wrap), else
    /// `pos_in_turn`.
    pub(crate) fn turn_in(&self) -> Option<u32> {
        if !self.turn_primed {
            return None;
        }
        Some(if self.seg_limit != 0 {
            self.cached_turn(self.position as u32)
        } else {
            self.pos_in_turn
        })
    }

    /// While the segment cache is valid: the position within the turn of the extended position
    /// whose low 32 bits are `low` (within the cached segment: its start within the turn + the
    /// distance from its start, no wrap).
    #[inline(always)]
    fn cached_turn(&self, low: u32) -> u32 {
        self.seg_turn_start
            .wrapping_add(low.wrapping_sub(self.seg_start))
    }

    /// Before the segment cache is voided or refilled: `pos_in_turn` of the last cycle's
    /// extended position, whose low 32 bits are `last_low` (it was within the cached segment
    /// while the cache is valid). Nothing to do for a void cache or a linear axis.
    #[inline(always)]
    pub(crate) fn settle_turn(&mut self, last_low: u32) {
        if self.seg_limit != 0 && self.turn_primed {
            self.pos_in_turn = self.cached_turn(last_low);
        }
    }

    /// The direction reverses ([`crate::counter::CounterStage::track`], which also sets the
    /// distance moved back to 0): the segment cache, which holds the other half's coefficients,
    /// voided (the turn position of the last cycle's extended position, whose low 32 bits are
    /// `last_low`, settled first).
    #[cold]
    #[inline(never)]
    pub(crate) fn reverse(&mut self, last_low: u32) {
        self.direction = self.direction.reversed();
        self.settle_turn(last_low);
        self.seg_limit = 0;
    }

    pub(crate) fn set_thermo_flag(&mut self, flag: Flags, on: bool) {
        if on {
            self.thermo_bits |= flag.0;
        } else {
            self.thermo_bits &= !flag.0;
        }
    }

    /// Extended scale position of the last cycle.
    pub fn position_counts(&self) -> i64 {
        self.position
    }
    /// Current approach direction.
    pub fn direction(&self) -> Direction {
        self.direction
    }
    /// Applied correction of the last cycle, µm.
    pub fn last_correction_um(&self) -> f32 {
        self.last_correction_um
    }
    /// Cached Σ b_i·ΔT_i, µm (frozen while a sensor is unhealthy).
    pub fn sensor_term_um(&self) -> f32 {
        self.sensor_um
    }
    /// Cached expansion coefficient c·ΔT_s·um_per_count/1000, µm per count.
    pub fn expansion_um_per_count(&self) -> f32 {
        self.expansion_um_per_count
    }
    /// True while the thermal contribution follows the readings (not frozen).
    pub fn thermal_live(&self) -> bool {
        self.thermal_live
    }
    /// True while a sensor is stale or its last reading was rejected.
    pub fn sensor_fault(&self) -> bool {
        self.sensor_fault
    }
    /// Lagged ΔT of sensor `i` (None before its first accepted reading).
    pub fn filtered_delta_t(&self, i: usize) -> Option<f32> {
        self.sensors
            .get(i)
            .and_then(|s| s.seen().then_some(s.filtered_dt))
    }
    /// True if sensor `i` is stale (or recovering).
    pub fn sensor_stale(&self, i: usize) -> bool {
        self.sensors.get(i).is_some_and(|s| s.stale())
    }
    /// Number of rejected readings of sensor `i` (saturating at 2^24 − 1 = 16 777 215).
    pub fn rejected_readings(&self, i: usize) -> u32 {
        self.sensors.get(i).map_or(0, |s| s.rejected())
    }
    /// Cached Σ χ_j·F_j of the predicted forces, µm.
    pub fn predicted_term_um(&self) -> f32 {
        self.predicted_um
    }
    /// Predicted force `j`, N.
    pub fn predicted_force_n(&self, j: usize) -> f32 {
        self.predicted_forces_n.get(j).copied().unwrap_or(0.0)
    }
}
