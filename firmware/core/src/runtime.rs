//! The runtime types of one axis: the validated object [`AxisCompensator`] (its coefficients, read
//! through `&self`, loaded once from an image) and its [`State`] (everything that changes per cycle
//! or per sensor reading, through `&mut`), with where the table segments are kept ([`TableStore`]).
//!
//! Only data and its small accessors live here; the stages that read them are
//! [`crate::counter`], [`crate::table`], [`crate::thermo`] and [`crate::limits`], composed by
//! [`crate::compensator`]; the loader ([`crate::image`]) fills them. Both layouts are `#[repr(C)]`
//! in an order chosen for the per-cycle path's loads: keep it.

use crate::counts::{CounterShift, Direction};
use crate::io::Flags;
use crate::sensor::{MeasuredSet, SensorRt, SensorState, ZERO_LAW};
use crate::spec::ForceLaw;
use crate::{MAX_FORCES, MAX_SEGMENTS, MAX_SENSORS};

/// The validated runtime compensation object of one axis: owned, fixed capacity, no borrow of
/// the image.
///
/// [`Compensator::IDENTITY`] is all zero bytes, so a `static` holding it (or an [`crate::Engine`])
/// lands in `.bss` (checked on thumbv7em: a `static` Engine adds 67 400 bytes of `.bss`, no `.data`).
pub type Compensator = AxisCompensator<OwnTable>;

/// One axis's pipeline (counter, direction, table, thermo-force, limits) with its table segments
/// kept by `S`: in the object itself ([`OwnTable`], the single-axis [`Compensator`]) or in the
/// coefficient pool of an axis group ([`crate::group`]).
#[derive(Debug, Clone)]
#[repr(C)]
pub struct AxisCompensator<S: TableStore> {
    pub(crate) loaded: bool,
    pub(crate) axis_id: u16,
    pub(crate) counter_bits: u8,
    // ---- the per-cycle fields of the counter and the limits, in pairs that one paired load
    // reads (the shift and the hysteresis; the two magnitude keys) ----
    /// 32 − counter_bits (0 for the identity: a 32-bit counter).
    pub(crate) sext_shift: CounterShift,
    pub(crate) hysteresis_counts: u32,
    /// [`crate::limits::magnitude_key`] of `max_correction_um` if every applied correction, in counts, is below
    /// 2^29 in magnitude (`MAX_LIMIT_UM` / `um_per_count` < 2^29), else 0: the cycle's fast path
    /// (within the clamp, rounded with `round_half_away_bounded`) is never taken for an
    /// unbounded image (no magnitude's key is below 0).
    pub(crate) fast_max_key: u32,
    /// `max_slew_um_per_cycle` as the cycle's fast path tests it: see [`crate::limits::magnitude_key`].
    pub(crate) slew_key: u32,
    /// `um_per_count / 2` (exact), so that the cycle's quotient is already doubled for the
    /// bounded rounding.
    pub(crate) half_um_per_count: f32,
    // ---- read off the per-cycle path ----
    pub(crate) um_per_count: f32,
    pub(crate) max_correction_um: f32,
    /// Counts per revolution of a rotary group axis (its table is indexed by the position within
    /// the turn); 0 for a linear axis and always for [`OwnTable`] storage.
    pub(crate) counts_per_rev: u32,
    // ---- positioning table ----
    pub(crate) bidirectional: bool,
    pub(crate) taper: bool,
    pub(crate) n_segments: u32,
    pub(crate) start_counts: i64,
    /// Knot spacing; `None` = no table (so the division needs no zero check).
    pub(crate) segment: Option<core::num::NonZeroU32>,
    /// n·segment_counts ≤ u32::MAX (validated).
    pub(crate) span_counts: u32,
    pub(crate) taper_counts: u32,
    pub(crate) inv_taper: f32,
    /// `[direction][0 = low end, 1 = high end]` table value at the stroke ends.
    pub(crate) edge: [[f32; 2]; 2],
    // ---- thermo-force term ----
    pub(crate) has_thermo: bool,
    pub(crate) sensor_period_ms: u32,
    pub(crate) n_sensors: u8,
    /// The sensors' settings where the storage keeps them with the axis ([`OwnTable`]: all
    /// [`MAX_SENSORS`]); a group keeps its axes' in an array of their own (`()` here), so that
    /// the per-cycle fields of all five axes are within short load offsets of the group.
    pub(crate) sensors: S::Sensors,
    pub(crate) b0_um: f32,
    pub(crate) has_expansion: bool,
    /// ΔT against each sensor's first accepted reading (thermo flag REFERENCE_AT_SWITCH_ON).
    pub(crate) reference_at_switch_on: bool,
    /// The range guard is on (thermo flag RISE_GUARD; bounds in the sensors' settings).
    pub(crate) rise_guard: bool,
    pub(crate) expansion_sensor: u8,
    pub(crate) x_ref_counts: i64,
    pub(crate) c_um_per_mm_k: f32,
    /// c · um_per_count / 1000: µm per count per kelvin.
    pub(crate) expansion_um_per_count_k: f32,
    pub(crate) n_forces: u8,
    pub(crate) chi_um_per_n: [f32; MAX_FORCES],
    pub(crate) force_predicted: [bool; MAX_FORCES],
    /// Bit j set: force j is measured (χ_j in `chi_measured[j]`).
    pub(crate) measured_mask: u8,
    pub(crate) chi_measured: [f32; MAX_FORCES],
    /// `measured_mask` as an enum, so the cycle's dispatch needs no range check.
    pub(crate) measured: MeasuredSet,
    /// THERMAL_FROZEN if the image has sensors: `State::thermo_bits` holds the thermo flags
    /// XOR this, so that a fresh (all-zero) State reads as frozen until its sensors report.
    pub(crate) thermo_flags_xor: u16,
    pub(crate) laws: [ForceLaw; MAX_FORCES],
    /// The table segments (or where to find them). Last, so that every other field is within a
    /// load's immediate offset of `self`.
    pub(crate) table: S,
}

/// Where a pipeline finds its group's coefficient pool: the pool itself, or the group it is a
/// field of (then its address is formed where it is used, on the cache miss's cold path, and
/// is not held in a register across the inlined pipelines).
pub(crate) trait PoolSource: Copy {
    /// The pool.
    fn pool(&self) -> &[[f32; 4]];
}

impl PoolSource for &[[f32; 4]] {
    #[inline(always)]
    fn pool(&self) -> &[[f32; 4]] {
        self
    }
}

impl<const N: usize> PoolSource for &[[f32; 4]; N] {
    #[inline(always)]
    fn pool(&self) -> &[[f32; 4]] {
        &self[..]
    }
}

/// Where an axis keeps its table segments: `[c0, c1, c2, c3]` per segment and direction half
/// (0 forward, 1 backward; a unidirectional table has its forward segments in both halves).
pub trait TableStore {
    /// Segment `seg` (< the axis's segment count, checked by the caller) of half `dir`; `pool` is
    /// the group's coefficient pool (unused by [`OwnTable`]).
    fn segment<'a>(&'a self, pool: &'a [[f32; 4]], dir: Direction, seg: u32) -> &'a [f32; 4];
    /// True if axes with this storage may be rotary (turn tracking compiled in).
    const TURNS: bool = false;
    /// The sensors' settings kept in the axis itself (see [`AxisCompensator`]'s field).
    type Sensors: core::fmt::Debug + Clone;
    /// [`TableStore::Sensors`] of the identity (all zero bytes).
    const NO_SENSORS: Self::Sensors;
}

/// The single-axis table storage: forward segments at `0..n`, backward at
/// `MAX_SEGMENTS..MAX_SEGMENTS + n`.
#[derive(Debug, Clone)]
pub struct OwnTable(pub(crate) [[f32; 4]; 2 * MAX_SEGMENTS]);

impl TableStore for OwnTable {
    type Sensors = [SensorRt; MAX_SENSORS];
    const NO_SENSORS: Self::Sensors = [SensorRt::ZERO; MAX_SENSORS];
    #[inline(always)]
    fn segment<'a>(&'a self, _pool: &'a [[f32; 4]], dir: Direction, seg: u32) -> &'a [f32; 4] {
        // (The direction's byte, 0 or 128, times MAX_SEGMENTS / 128: the backward half's offset.)
        const _: () = assert!(MAX_SEGMENTS % 128 == 0);
        let half = dir as u8 as usize * (MAX_SEGMENTS / 128);
        &self.0[(seg as usize + half) & (2 * MAX_SEGMENTS - 1)]
    }
}

impl<S: TableStore> AxisCompensator<S> {
    /// The identity (zero correction, valid) with table storage `table`.
    pub const fn identity_with(table: S) -> AxisCompensator<S> {
        AxisCompensator {
            loaded: false,
            axis_id: 0,
            counter_bits: 0,
            sext_shift: CounterShift::S0,
            um_per_count: 0.0,
            counts_per_rev: 0,
            bidirectional: false,
            taper: false,
            n_segments: 0,
            start_counts: 0,
            segment: None,
            span_counts: 0,
            taper_counts: 0,
            inv_taper: 0.0,
            edge: [[0.0; 2]; 2],
            has_thermo: false,
            sensor_period_ms: 0,
            n_sensors: 0,
            sensors: S::NO_SENSORS,
            b0_um: 0.0,
            has_expansion: false,
            reference_at_switch_on: false,
            rise_guard: false,
            expansion_sensor: 0,
            x_ref_counts: 0,
            c_um_per_mm_k: 0.0,
            expansion_um_per_count_k: 0.0,
            n_forces: 0,
            chi_um_per_n: [0.0; MAX_FORCES],
            force_predicted: [false; MAX_FORCES],
            measured_mask: 0,
            chi_measured: [0.0; MAX_FORCES],
            measured: MeasuredSet::None,
            thermo_flags_xor: 0,
            laws: [ZERO_LAW; MAX_FORCES],
            max_correction_um: 0.0,
            slew_key: 0,
            hysteresis_counts: 0,
            half_um_per_count: 0.0,
            fast_max_key: 0,
            table,
        }
    }
}

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
    /// Segment cache of the table (see [`AxisCompensator::table_um_refill`]): the low 32 bits
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

    /// The direction reverses ([`AxisCompensator::track`], which also sets the distance moved
    /// back to 0): the segment cache, which holds the other half's coefficients, voided (the turn position of
    /// the last cycle's extended position, whose low 32 bits are `last_low`, settled first).
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

/// A group axis's table in the group's pool: the first segment of each direction half.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PoolTable {
    pub(crate) base: [u32; 2],
}

const ZERO_SEGMENT: [f32; 4] = [0.0; 4];

impl TableStore for PoolTable {
    const TURNS: bool = true;
    // In `Group::sensors`.
    type Sensors = ();
    const NO_SENSORS: () = ();
    #[inline(always)]
    fn segment<'a>(&'a self, pool: &'a [[f32; 4]], dir: Direction, seg: u32) -> &'a [f32; 4] {
        // In range for a loaded group (checked at load). The remainder is a no-op for valid
        // indices; with the pool's length known at the call (a power of two), it is a mask and
        // the bounds check folds away. The fallbacks keep the path panic-free.
        let i = self.base[dir.half()] as usize + seg as usize;
        i.checked_rem(pool.len())
            .and_then(|j| pool.get(j))
            .unwrap_or(&ZERO_SEGMENT)
    }
}
