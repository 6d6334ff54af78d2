//! The validated runtime object ([`Compensator`]), its per-axis [`State`] and the per-cycle call.
//!
//! Coefficients live in `&self` (loaded once from an image), everything that changes per cycle or
//! per sensor reading lives in `&mut State`. The per-cycle path ([`Compensator::cycle`]) uses no
//! i64 multiplication/division and no i64↔f32 conversion, indexes arrays through masks or
//! validated indices and never panics.
//!
//! The stages it composes live by what they are: [`crate::counter`] (counter extension,
//! direction), [`crate::table`] (positioning table), [`crate::thermo`] (thermo-force term),
//! [`crate::limits`] (clamp, slew, rounding to counts).

use crate::ImageError;
use crate::counter::Direction;
use crate::limits::{cold_path, limit, round_half_away_bounded, round_to_counts};
use crate::spec::{ForceLaw, LimitSpec};
use crate::thermo::{MeasuredSet, SensorRt, SensorState, ZERO_LAW};
use crate::{MAX_FORCE_TERM_UM, MAX_FORCES, MAX_SEGMENTS, MAX_SENSORS};

/// Input of one control cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleInput {
    /// Raw hardware counter of the scale (wraps at `counter_bits`).
    pub scale_raw: u32,
    /// Commanded position, counts.
    pub command_counts: i64,
    /// Measured forces, N (only used by measured force terms; NaN = no reading).
    pub forces_n: [f32; MAX_FORCES],
}

/// Bit set recording what happened in a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct Flags(pub u16);

impl Flags {
    /// Nothing special happened.
    pub const NONE: Flags = Flags(0);
    /// The position was outside the table's stroke (hold or taper applied).
    pub const TABLE_OUTSIDE: Flags = Flags(1 << 0);
    /// The total correction was clamped to `max_correction_um`.
    pub const CLAMPED: Flags = Flags(1 << 1);
    /// The change of the applied correction was limited to `max_slew_um_per_cycle`.
    pub const SLEWED: Flags = Flags(1 << 2);
    /// A sensor is stale or its last reading was rejected.
    pub const SENSOR_FAULT: Flags = Flags(1 << 3);
    /// The thermal contribution is frozen (a sensor is stale, recovering, or has not reported yet).
    pub const THERMAL_FROZEN: Flags = Flags(1 << 4);
    /// A force value was NaN, infinite or beyond [`crate::MAX_FORCE_N`] and was ignored.
    pub const FORCE_INVALID: Flags = Flags(1 << 5);
    /// The total correction was not finite; the last applied correction was held.
    pub const NON_FINITE: Flags = Flags(1 << 6);
    /// The backward table was selected (current direction is backward).
    pub const BACKWARD: Flags = Flags(1 << 7);
    /// No image is loaded: identity correction.
    pub const IDENTITY: Flags = Flags(1 << 8);

    /// Raw bits.
    pub const fn bits(self) -> u16 {
        self.0
    }
    /// From raw bits.
    pub const fn from_bits(bits: u16) -> Flags {
        Flags(bits)
    }
    /// True if every bit of `other` is set.
    pub const fn contains(self, other: Flags) -> bool {
        self.0 & other.0 == other.0
    }
    /// True if no bit is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// Set the bits of `other`.
    pub fn insert(&mut self, other: Flags) {
        self.0 |= other.0;
    }
}

// `Compensator::cycle` builds the BACKWARD bit with a shift.
const _: () = assert!(Flags::BACKWARD.0 == 1 << 7);

impl core::ops::BitOr for Flags {
    type Output = Flags;
    fn bitor(self, rhs: Flags) -> Flags {
        Flags(self.0 | rhs.0)
    }
}

impl core::ops::BitOrAssign for Flags {
    fn bitor_assign(&mut self, rhs: Flags) {
        self.0 |= rhs.0;
    }
}

/// Output of one control cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleOutput {
    /// Extended scale position, counts.
    pub position_counts: i64,
    /// `command − correction_counts` (saturating).
    pub corrected_command_counts: i64,
    /// `round(correction_um / um_per_count)`, half away from zero, saturating.
    pub correction_counts: i32,
    /// Applied (clamped, slewed) correction before rounding to counts, µm.
    pub correction_um: f32,
    /// What happened.
    pub flags: Flags,
}

/// The validated runtime compensation object: owned, fixed capacity, no borrow of the image.
///
/// [`Compensator::IDENTITY`] is all zero bytes, so a `static` holding it (or an [`crate::Engine`])
/// lands in `.bss` (checked on thumbv7em: a `static` Engine adds 67 400 bytes of `.bss`, no `.data`).
#[derive(Debug, Clone)]
#[repr(C)]
pub struct Compensator {
    pub(crate) loaded: bool,
    pub(crate) axis_id: u16,
    pub(crate) counter_bits: u8,
    /// 32 − counter_bits (0 for the identity: a 32-bit counter).
    pub(crate) sext_shift: u32,
    pub(crate) um_per_count: f32,
    // ---- positioning table ----
    pub(crate) has_table: bool,
    pub(crate) bidirectional: bool,
    pub(crate) taper: bool,
    pub(crate) n_segments: u32,
    pub(crate) start_counts: i64,
    pub(crate) segment_counts: u32,
    pub(crate) span_counts: i64,
    pub(crate) inv_segment: f32,
    pub(crate) taper_counts: u32,
    pub(crate) inv_taper: f32,
    /// `[direction][0 = low end, 1 = high end]` table value at the stroke ends.
    pub(crate) edge: [[f32; 2]; 2],
    // ---- thermo-force term ----
    pub(crate) has_thermo: bool,
    pub(crate) sensor_period_ms: u32,
    pub(crate) n_sensors: u8,
    pub(crate) sensors: [SensorRt; MAX_SENSORS],
    pub(crate) b0_um: f32,
    pub(crate) has_expansion: bool,
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
    // ---- limits ----
    pub(crate) max_correction_um: f32,
    pub(crate) max_slew_um_per_cycle: f32,
    pub(crate) hysteresis_counts: u32,
    /// True if every applied correction, in counts, is below 2^29 in magnitude
    /// ([`MAX_LIMIT_UM`] / `um_per_count` < 2^29), so the cycle may round with
    /// [`round_half_away_bounded`].
    pub(crate) counts_bounded: bool,
    /// Forward segments at `0..n`, backward at `MAX_SEGMENTS..MAX_SEGMENTS + n` (a copy of the
    /// forward ones for a unidirectional table). Last, so that
    /// every other field is within a load's immediate offset of `self`.
    pub(crate) coeffs: [[f32; 4]; 2 * MAX_SEGMENTS],
}

impl Default for Compensator {
    fn default() -> Self {
        Compensator::IDENTITY
    }
}

impl Compensator {
    /// Zero correction, valid. All zero bytes.
    pub const IDENTITY: Compensator = Compensator {
        loaded: false,
        axis_id: 0,
        counter_bits: 0,
        sext_shift: 0,
        um_per_count: 0.0,
        has_table: false,
        bidirectional: false,
        taper: false,
        n_segments: 0,
        start_counts: 0,
        segment_counts: 0,
        span_counts: 0,
        inv_segment: 0.0,
        taper_counts: 0,
        inv_taper: 0.0,
        edge: [[0.0; 2]; 2],
        has_thermo: false,
        sensor_period_ms: 0,
        n_sensors: 0,
        sensors: [SensorRt::ZERO; MAX_SENSORS],
        b0_um: 0.0,
        has_expansion: false,
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
        max_slew_um_per_cycle: 0.0,
        hysteresis_counts: 0,
        counts_bounded: false,
        coeffs: [[0.0; 4]; 2 * MAX_SEGMENTS],
    };

    /// Parse and validate `image`, then copy it into `self`. On `Err`, `self` is untouched.
    ///
    /// Works in place: no copy of the table on the stack.
    pub fn load(&mut self, image: &[u8]) -> Result<(), ImageError> {
        let layout = crate::image::validate(image)?;
        crate::image::copy_into(&layout, image, self);
        Ok(())
    }

    /// Back to the identity (in place, no large temporary).
    pub fn clear(&mut self) {
        self.loaded = false;
        self.has_table = false;
        self.has_thermo = false;
        self.n_segments = 0;
        self.n_sensors = 0;
        self.n_forces = 0;
        self.chi_um_per_n = [0.0; MAX_FORCES];
        self.force_predicted = [false; MAX_FORCES];
        self.measured_mask = 0;
        self.chi_measured = [0.0; MAX_FORCES];
        self.measured = MeasuredSet::None;
        self.thermo_flags_xor = 0;
        self.axis_id = 0;
        self.counter_bits = 0;
        self.sext_shift = 0;
        self.um_per_count = 0.0;
        self.counts_bounded = false;
    }

    /// True once an image has been loaded (false for the identity).
    pub fn is_loaded(&self) -> bool {
        self.loaded
    }
    /// Axis the loaded image belongs to (0 for the identity).
    pub fn axis_id(&self) -> u16 {
        self.axis_id
    }
    /// Scale resolution (0 for the identity).
    pub fn um_per_count(&self) -> f32 {
        self.um_per_count
    }
    /// Counter width (0 for the identity, which extends a 32-bit counter).
    pub fn counter_bits(&self) -> u8 {
        self.counter_bits
    }
    /// The limits (all 0 for the identity).
    pub fn limits(&self) -> LimitSpec {
        LimitSpec {
            max_correction_um: self.max_correction_um,
            max_slew_um_per_cycle: self.max_slew_um_per_cycle,
            direction_hysteresis_counts: self.hysteresis_counts,
        }
    }
    /// The per-cycle call: counter extension, direction, table + thermo-force, clamp, slew, counts.
    ///
    /// No library calls, no i64 multiplication/division, no i64↔f32 conversion, no panic path.
    /// Cost on a Cortex-M4F (QEMU count by `.ci/bench`, firmware bin `axcomp-qemu-bench`): about
    /// 127 instructions for the [`crate::bench`] workload (table + 8-sensor thermo-force + 3
    /// forces), about 95 with the table only. The common case is laid out as the fall-through
    /// (the rare branches — first cycle, clamp/slew acting, command near ±2^63 — are marked
    /// cold) and is sensitive to register pressure: measure any change with `.ci/bench`.
    ///
    /// The thermo-force term adds the contribution cached by [`Compensator::update_temperatures`]
    /// and [`Compensator::set_process`] (b0 + Σ b_i·ΔT_i + predicted forces), the expansion term
    /// (one multiply-add with the cached c·ΔT_s) and the measured forces of this input.
    pub fn cycle(&self, st: &mut State, input: &CycleInput) -> CycleOutput {
        // ---- counter extension (wrap-safe, sign-extended delta) ----
        let shift = self.sext_shift;
        let raw = input.scale_raw;
        if !st.primed {
            cold_path();
            let base = if st.raw_pending { st.last_raw } else { raw };
            st.position = ((base.wrapping_shl(shift) as i32) >> shift) as i64;
            st.last_raw = base;
            st.back_counts = 0;
            st.primed = true;
            st.raw_pending = false;
        }
        let delta = ((raw.wrapping_sub(st.last_raw)).wrapping_shl(shift) as i32) >> shift;
        st.last_raw = raw;
        let pos = st.position.wrapping_add(delta as i64);
        st.position = pos;

        // ---- direction with hysteresis ----
        // back = distance moved against the current direction since its extreme
        // (= extreme − position going forward), ≥ 0, saturating; hysteresis ≤ i32::MAX (validated).
        // (A delta of exactly −2^31, a half turn of a 32-bit counter, is ambiguous anyway; its
        // wrapping negation keeps it "forward".)
        let against = if st.backward {
            delta
        } else {
            delta.wrapping_neg()
        };
        let back = st.back_counts.saturating_add(against);
        if back > self.hysteresis_counts as i32 {
            st.backward = !st.backward;
            st.back_counts = 0;
        } else {
            st.back_counts = if back < 0 { 0 } else { back };
        }

        let mut flags = Flags((st.backward as u16) << 7); // Flags::BACKWARD
        if !self.loaded {
            flags |= Flags::IDENTITY;
            return CycleOutput {
                position_counts: pos,
                corrected_command_counts: input.command_counts,
                correction_counts: 0,
                correction_um: 0.0,
                flags,
            };
        }

        // ---- table ----
        let mut total = 0.0f32;
        if self.has_table {
            let direction = if st.backward {
                Direction::Backward
            } else {
                Direction::Forward
            };
            let (table, outside) = self.table_um(direction, pos);
            if outside {
                flags |= Flags::TABLE_OUTSIDE;
            }
            total = table;
        }

        // ---- thermo-force ----
        if self.has_thermo {
            // x − x_ref as i32 (saturated) so that the conversion to f32 is one instruction.
            // Positions and x_ref within ±2^62 (x_ref is validated, positions are physical) never
            // wrap; beyond, the term stays finite and the clamp holds.
            let d = pos.wrapping_sub(self.x_ref_counts);
            let d32 = if d as i32 as i64 == d {
                d as i32
            } else if d < 0 {
                i32::MIN
            } else {
                i32::MAX
            };
            // b0 + Σ b_i·ΔT_i + Σ χ_j·F_j (predicted) is cached at the sensor/process rate.
            total += st.cached_um + st.expansion_um_per_count * d32 as f32;
            // Measured forces: one multiply-add each, one plausibility check of their sum
            // (catches NaN, ±inf and absurd readings; the whole measured term is then dropped).
            // One straight-line sum per set of measured terms (in index order), so inputs of
            // unmeasured terms (NaN = no reading) are never read and no per-term select is paid.
            if self.measured != MeasuredSet::None {
                let c = &self.chi_measured;
                let f = &input.forces_n;
                let force_um = match self.measured {
                    MeasuredSet::None | MeasuredSet::F0 => c[0] * f[0],
                    MeasuredSet::F1 => c[1] * f[1],
                    MeasuredSet::F01 => c[0] * f[0] + c[1] * f[1],
                    MeasuredSet::F2 => c[2] * f[2],
                    MeasuredSet::F02 => c[0] * f[0] + c[2] * f[2],
                    MeasuredSet::F12 => c[1] * f[1] + c[2] * f[2],
                    MeasuredSet::F012 => c[0] * f[0] + c[1] * f[1] + c[2] * f[2],
                };
                if libm::fabsf(force_um) <= MAX_FORCE_TERM_UM {
                    total += force_um;
                } else {
                    flags |= Flags::FORCE_INVALID;
                }
            }
            flags |= Flags(st.thermo_bits ^ self.thermo_flags_xor);
        }

        // ---- clamp (also catches a non-finite total), slew ----
        let last = st.last_correction_um;
        let max = self.max_correction_um;
        let slew = self.max_slew_um_per_cycle;
        // Common case first: within the clamp and the slew limit, two compares and no move
        // (NaN fails the first). Otherwise the full rules of `limit`.
        let applied = if libm::fabsf(total) <= max && libm::fabsf(total - last) <= slew {
            total
        } else {
            cold_path();
            let (applied, limit_flags) = limit(total, last, max, slew);
            flags |= limit_flags;
            applied
        };
        st.last_correction_um = applied;

        // ---- to counts: round half away from zero, saturating ----
        // |applied| ≤ MAX_LIMIT_UM always: every image's clamp is validated ≤ MAX_LIMIT_UM, the
        // slew only moves between the last applied value and the clamped one, and a NaN holds.
        let quotient = applied / self.um_per_count;
        let counts = if self.counts_bounded {
            round_half_away_bounded(quotient)
        } else {
            cold_path();
            round_to_counts(quotient)
        };
        // command − counts, saturating. |counts| < 2^31, so a command in [−2^62, 2^62) (bits 63
        // and 62 equal: one test of the high word) cannot overflow; the saturating form only
        // beyond, out of the way.
        let command = input.command_counts;
        let high = (command >> 32) as i32;
        let corrected = if (high ^ (high << 1)) >= 0 {
            command.wrapping_sub(counts as i64)
        } else {
            cold_path();
            command.saturating_sub(counts as i64)
        };
        CycleOutput {
            position_counts: pos,
            corrected_command_counts: corrected,
            correction_counts: counts,
            correction_um: applied,
            flags,
        }
    }
}

/// Everything that changes while the axis runs: counter extension, direction, lags, sensor
/// health, cached thermal contribution, predicted forces, last applied correction.
///
/// All zero bytes after [`State::new`].
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    pub(crate) primed: bool,
    pub(crate) raw_pending: bool,
    pub(crate) last_raw: u32,
    pub(crate) position: i64,
    pub(crate) backward: bool,
    pub(crate) back_counts: i32,
    pub(crate) last_correction_um: f32,
    pub(crate) sensor_um: f32,
    pub(crate) expansion_um_per_count: f32,
    pub(crate) thermal_live: bool,
    pub(crate) sensor_fault: bool,
    pub(crate) clock_started: bool,
    /// Thermo flags (SENSOR_FAULT, THERMAL_FROZEN, FORCE_INVALID of the process) XOR the
    /// compensator's `thermo_flags_xor`.
    pub(crate) thermo_bits: u16,
    /// Σ χ_j·F_j of the predicted forces, µm.
    pub(crate) predicted_um: f32,
    /// b0 + sensor_um + predicted_um, µm (what the cycle adds).
    pub(crate) cached_um: f32,
    pub(crate) predicted_forces_n: [f32; MAX_FORCES],
    pub(crate) sensors: [SensorState; MAX_SENSORS],
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
            backward: false,
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
        if self.backward {
            Direction::Backward
        } else {
            Direction::Forward
        }
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
            .and_then(|s| s.seen.then_some(s.filtered_dt))
    }
    /// True if sensor `i` is stale (or recovering).
    pub fn sensor_stale(&self, i: usize) -> bool {
        self.sensors.get(i).is_some_and(|s| s.stale)
    }
    /// Number of rejected readings of sensor `i`.
    pub fn rejected_readings(&self, i: usize) -> u32 {
        self.sensors.get(i).map_or(0, |s| s.rejected)
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
