//! The validated runtime object ([`Compensator`]), its per-axis [`State`] and the per-cycle call.
//!
//! Coefficients live in `&self` (loaded once from an image), everything that changes per cycle or
//! per sensor reading lives in `&mut State`. The per-cycle path ([`Compensator::cycle`]) uses no
//! i64 multiplication/division and no i64↔f32 conversion, indexes arrays through masks or
//! validated indices and never panics.

use crate::spec::{ExpansionSpec, ForceLaw, ForceSpec, LimitSpec, OutsideStroke, SensorSpec};
use crate::{
    MAX_FORCE_N, MAX_FORCE_TERM_UM, MAX_FORCES, MAX_SEGMENTS, MAX_SENSORS, RECOVERY_READINGS,
};

/// Approach direction of the axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Direction {
    /// Increasing scale position (also the initial direction).
    #[default]
    Forward,
    /// Decreasing scale position.
    Backward,
}

/// Where the force F_j of a force term comes from.
///
/// Chosen by the image: a [`ForceSpec`] with a `law` is `Predicted` (from the process parameters
/// given to [`Compensator::set_process`]; 0 N until the first call), one without is `Measured`
/// (from [`CycleInput::forces_n`] at the same index).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ForceSource {
    /// From the force sensor values in each [`CycleInput`].
    Measured,
    /// From the force law and the current process parameters.
    Predicted,
}

/// Process parameters for predicted forces.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ProcessParams {
    /// Depth of cut, mm.
    pub ap_mm: f32,
    /// Feed per tooth, mm.
    pub fz_mm: f32,
    /// Spindle speed, rpm.
    pub n_rpm: f32,
}

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

/// Which force terms are measured (bit j of the discriminant = term j), for the cycle's dispatch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub(crate) enum MeasuredSet {
    None = 0,
    F0 = 0b001,
    F1 = 0b010,
    F01 = 0b011,
    F2 = 0b100,
    F02 = 0b101,
    F12 = 0b110,
    F012 = 0b111,
}

impl MeasuredSet {
    /// From the bit mask (bits above 2 are ignored).
    pub(crate) const fn from_mask(mask: u8) -> MeasuredSet {
        match mask & 0b111 {
            0b001 => MeasuredSet::F0,
            0b010 => MeasuredSet::F1,
            0b011 => MeasuredSet::F01,
            0b100 => MeasuredSet::F2,
            0b101 => MeasuredSet::F02,
            0b110 => MeasuredSet::F12,
            0b111 => MeasuredSet::F012,
            _ => MeasuredSet::None,
        }
    }
}

/// Validated sensor settings with the derived lag coefficient.
#[derive(Debug, Clone, Copy)]
pub(crate) struct SensorRt {
    pub(crate) reference_degc: f32,
    pub(crate) min_degc: f32,
    pub(crate) max_degc: f32,
    pub(crate) max_rate_degc_per_s: f32,
    pub(crate) lag_tau_s: f32,
    pub(crate) stale_timeout_ms: u32,
    pub(crate) b_um_per_k: f32,
    /// α = 1 − exp(−period/τ), 1 without lag.
    pub(crate) alpha: f32,
}

impl SensorRt {
    pub(crate) const ZERO: SensorRt = SensorRt {
        reference_degc: 0.0,
        min_degc: 0.0,
        max_degc: 0.0,
        max_rate_degc_per_s: 0.0,
        lag_tau_s: 0.0,
        stale_timeout_ms: 0,
        b_um_per_k: 0.0,
        alpha: 0.0,
    };
}

pub(crate) const ZERO_LAW: ForceLaw = ForceLaw {
    k: 0.0,
    x_ap: 0.0,
    y_fz: 0.0,
    z_n: 0.0,
};

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
    /// True if a positioning table is loaded.
    pub fn has_table(&self) -> bool {
        self.has_table
    }
    /// Position of knot 0.
    pub fn table_start_counts(&self) -> i64 {
        self.start_counts
    }
    /// Knot spacing.
    pub fn segment_counts(&self) -> u32 {
        self.segment_counts
    }
    /// Behaviour beyond the stroke.
    pub fn outside(&self) -> OutsideStroke {
        if self.taper {
            OutsideStroke::Taper {
                length_counts: self.taper_counts,
            }
        } else {
            OutsideStroke::Hold
        }
    }
    /// Forward segments (empty without a table).
    pub fn forward_segments(&self) -> &[[f32; 4]] {
        let n = (self.n_segments as usize).min(MAX_SEGMENTS);
        self.coeffs.get(..n).unwrap_or(&[])
    }
    /// Backward segments (empty for a unidirectional table).
    pub fn backward_segments(&self) -> &[[f32; 4]] {
        let n = if self.bidirectional {
            (self.n_segments as usize).min(MAX_SEGMENTS)
        } else {
            0
        };
        self.coeffs
            .get(MAX_SEGMENTS..MAX_SEGMENTS + n)
            .unwrap_or(&[])
    }
    /// True if a thermo-force term is loaded.
    pub fn has_thermo(&self) -> bool {
        self.has_thermo
    }
    /// Sensor period of the thermo-force term, ms.
    pub fn sensor_period_ms(&self) -> u32 {
        self.sensor_period_ms
    }
    /// Number of sensors.
    pub fn sensor_count(&self) -> usize {
        self.n_sensors as usize
    }
    /// Settings of sensor `i`.
    pub fn sensor(&self, i: usize) -> Option<SensorSpec> {
        if i >= self.n_sensors as usize {
            return None;
        }
        self.sensors.get(i).map(|s| SensorSpec {
            reference_degc: s.reference_degc,
            min_degc: s.min_degc,
            max_degc: s.max_degc,
            max_rate_degc_per_s: s.max_rate_degc_per_s,
            lag_tau_s: s.lag_tau_s,
            stale_timeout_ms: s.stale_timeout_ms,
        })
    }
    /// b_i of sensor `i`, µm/K.
    pub fn b_um_per_k(&self, i: usize) -> Option<f32> {
        if i >= self.n_sensors as usize {
            return None;
        }
        self.sensors.get(i).map(|s| s.b_um_per_k)
    }
    /// Lag coefficient α of sensor `i` (1 = no lag).
    pub fn lag_alpha(&self, i: usize) -> Option<f32> {
        if i >= self.n_sensors as usize {
            return None;
        }
        self.sensors.get(i).map(|s| s.alpha)
    }
    /// Constant term b0, µm.
    pub fn b0_um(&self) -> f32 {
        self.b0_um
    }
    /// The expansion term, if any.
    pub fn expansion(&self) -> Option<ExpansionSpec> {
        self.has_expansion.then_some(ExpansionSpec {
            sensor: self.expansion_sensor,
            x_ref_counts: self.x_ref_counts,
            c_um_per_mm_k: self.c_um_per_mm_k,
        })
    }
    /// Number of force terms.
    pub fn force_count(&self) -> usize {
        self.n_forces as usize
    }
    /// Force term `j`.
    pub fn force(&self, j: usize) -> Option<ForceSpec> {
        if j >= self.n_forces as usize || j >= MAX_FORCES {
            return None;
        }
        Some(ForceSpec {
            chi_um_per_n: self.chi_um_per_n[j],
            law: if self.force_predicted[j] {
                Some(self.laws[j])
            } else {
                None
            },
        })
    }
    /// Where force `j` comes from.
    pub fn force_source(&self, j: usize) -> Option<ForceSource> {
        self.force(j).map(|f| match f.law {
            Some(_) => ForceSource::Predicted,
            None => ForceSource::Measured,
        })
    }

    /// Positioning-table value (µm) at `position_counts` for `direction`, and whether the position
    /// was outside the stroke. 0 without a table.
    #[inline]
    pub fn table_um(&self, direction: Direction, position_counts: i64) -> (f32, bool) {
        if !self.has_table {
            return (0.0, false);
        }
        // A unidirectional table has its forward segments in the backward half too (see `load`).
        let dir = (direction == Direction::Backward) as usize;
        // Compare first, then subtract: exact for every i64 without a saturating subtraction.
        let (end, dist) = if position_counts < self.start_counts {
            (
                self.edge[dir][0],
                self.start_counts.wrapping_sub(position_counts) as u64,
            )
        } else {
            let diff = position_counts.wrapping_sub(self.start_counts) as u64;
            if diff < self.span_counts as u64 {
                // span ≤ u32::MAX is validated, so the offset fits in u32.
                let offset = diff as u32;
                let seg_counts = self.segment_counts;
                // Never 0 for a loaded table; `checked_div` keeps the code panic-free.
                let seg = offset.checked_div(seg_counts).unwrap_or(0);
                let rem = offset - seg.wrapping_mul(seg_counts);
                let t = rem as f32 * self.inv_segment;
                let idx = (seg as usize + dir * MAX_SEGMENTS) & (2 * MAX_SEGMENTS - 1);
                let c = &self.coeffs[idx];
                return (c[0] + t * (c[1] + t * (c[2] + t * c[3])), false);
            }
            (self.edge[dir][1], diff - self.span_counts as u64)
        };
        let v = if !self.taper {
            end
        } else if dist >= self.taper_counts as u64 {
            0.0
        } else {
            end * (1.0 - dist as u32 as f32 * self.inv_taper)
        };
        (v, true)
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

    /// Sensor-rate update: health checks, lags, and the cached thermal contribution.
    ///
    /// `readings[i]` is sensor i in °C; NaN (or a missing entry) = no reading. Call it every
    /// `sensor_period_ms` (the lag coefficients assume that period), also when the image has no
    /// sensors: the cycle adds a cached b0 + Σ b_i·ΔT_i + Σ χ_j·F_j(predicted), refreshed here
    /// and in [`Compensator::set_process`] (a fresh [`State`] contributes 0 until then). Rules:
    /// - a reading is accepted if finite, within `[min_degc, max_degc]` and, after the first
    ///   accepted one, within `max_rate_degc_per_s · (now − time of the last accepted reading)` of
    ///   the last accepted value; otherwise it is rejected (counted) and the last good value held;
    /// - each lag advances once per call with the last accepted value as input; it starts at the
    ///   first accepted reading (no transient from 0);
    /// - a sensor without an accepted reading for more than `stale_timeout_ms` (counted from the
    ///   first call for a sensor that never reported) is stale; it recovers after
    ///   [`RECOVERY_READINGS`] consecutive accepted readings;
    /// - the thermal contribution (Σ b_i·ΔT_i and the expansion coefficient) is recomputed only
    ///   while every sensor has reported and none is stale; otherwise it stays frozen at the last
    ///   good value (THERMAL_FROZEN); SENSOR_FAULT while any sensor is stale or its last reading
    ///   was rejected.
    pub fn update_temperatures(&self, st: &mut State, now_ms: u32, readings: &[f32]) {
        if !self.loaded || !self.has_thermo {
            return;
        }
        let n = (self.n_sensors as usize).min(MAX_SENSORS);
        if !st.clock_started {
            st.clock_started = true;
            for s in st.sensors.iter_mut() {
                s.last_good_ms = now_ms;
            }
        }
        let mut all_healthy = true;
        let mut fault = false;
        for (i, (cfg, s)) in self.sensors.iter().zip(st.sensors.iter_mut()).enumerate() {
            if i >= n {
                break;
            }
            let r = readings.get(i).copied().unwrap_or(f32::NAN);
            let since_good_ms = now_ms.wrapping_sub(s.last_good_ms);
            let plausible = r.is_finite()
                && r >= cfg.min_degc
                && r <= cfg.max_degc
                && (!s.seen
                    || libm::fabsf(r - s.last_good_degc)
                        <= cfg.max_rate_degc_per_s * (since_good_ms as f32 * 0.001));
            if plausible {
                if !s.seen {
                    s.seen = true;
                    s.filtered_dt = r - cfg.reference_degc;
                }
                s.last_good_degc = r;
                s.last_good_ms = now_ms;
                s.streak = s.streak.saturating_add(1);
                s.last_rejected = false;
            } else {
                s.streak = 0;
                s.last_rejected = !r.is_nan();
                if s.last_rejected {
                    s.rejected = s.rejected.saturating_add(1);
                }
            }
            if s.seen {
                let u = s.last_good_degc - cfg.reference_degc;
                s.filtered_dt += cfg.alpha * (u - s.filtered_dt);
            }
            if now_ms.wrapping_sub(s.last_good_ms) > cfg.stale_timeout_ms {
                s.stale = true;
            }
            if s.stale && s.streak >= RECOVERY_READINGS {
                s.stale = false;
            }
            if !s.seen || s.stale {
                all_healthy = false;
            }
            if s.stale || s.last_rejected {
                fault = true;
            }
        }
        st.sensor_fault = fault;
        st.thermal_live = all_healthy;
        let mut bits = st.thermo_bits ^ self.thermo_flags_xor;
        bits &= !(Flags::SENSOR_FAULT.0 | Flags::THERMAL_FROZEN.0);
        if fault {
            bits |= Flags::SENSOR_FAULT.0;
        }
        if !all_healthy {
            bits |= Flags::THERMAL_FROZEN.0;
        }
        st.thermo_bits = bits ^ self.thermo_flags_xor;
        if all_healthy {
            let mut sum = 0.0f32;
            for (cfg, s) in self.sensors.iter().zip(st.sensors.iter()).take(n) {
                sum += cfg.b_um_per_k * s.filtered_dt;
            }
            st.sensor_um = sum;
            st.cached_um = self.b0_um + st.sensor_um + st.predicted_um;
            st.expansion_um_per_count = if self.has_expansion {
                let dt = st
                    .sensors
                    .get(self.expansion_sensor as usize)
                    .map_or(0.0, |s| s.filtered_dt);
                self.expansion_um_per_count_k * dt
            } else {
                0.0
            };
        }
    }

    /// Predicted forces from the process parameters (F = k·ap^x·fz^y·n^z via `libm::powf`),
    /// computed here only. A non-finite or implausible prediction is replaced by 0 N and flagged
    /// (FORCE_INVALID) until the next call.
    pub fn set_process(&self, st: &mut State, p: &ProcessParams) {
        let mut invalid = false;
        let mut sum = 0.0f32;
        for j in 0..MAX_FORCES {
            let mut f = 0.0;
            if self.loaded && j < self.n_forces as usize && self.force_predicted[j] {
                let law = self.laws[j];
                let v = law.k
                    * libm::powf(p.ap_mm, law.x_ap)
                    * libm::powf(p.fz_mm, law.y_fz)
                    * libm::powf(p.n_rpm, law.z_n);
                if libm::fabsf(v) <= MAX_FORCE_N {
                    f = v;
                    sum += self.chi_um_per_n[j] * v;
                } else {
                    invalid = true;
                }
            }
            st.predicted_forces_n[j] = f;
        }
        st.predicted_um = sum;
        st.cached_um = self.b0_um + st.sensor_um + st.predicted_um;
        st.set_thermo_flag(Flags::FORCE_INVALID, invalid);
    }
}

/// Marks the branch that calls it as rarely taken, so the per-cycle path is laid out as the
/// fall-through (a stand-in for `core::hint::cold_path`, which needs Rust 1.95; MSRV is 1.85).
#[cold]
#[inline(never)]
fn cold_path() {}

/// Clamp `total` to ±`max` (a NaN holds `last`: NON_FINITE), then limit the change from `last` to
/// `slew`. The per-cycle path takes this only when a limit acts (or the total is NaN).
#[inline(always)]
fn limit(total: f32, last: f32, max: f32, slew: f32) -> (f32, Flags) {
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

/// Per-sensor health and lag state.
#[derive(Debug, Clone, Copy, PartialEq)]
struct SensorState {
    seen: bool,
    stale: bool,
    last_rejected: bool,
    streak: u8,
    last_good_degc: f32,
    last_good_ms: u32,
    /// Lagged ΔT, kelvin.
    filtered_dt: f32,
    rejected: u32,
}

impl SensorState {
    const NEW: SensorState = SensorState {
        seen: false,
        stale: false,
        last_rejected: false,
        streak: 0,
        last_good_degc: 0.0,
        last_good_ms: 0,
        filtered_dt: 0.0,
        rejected: 0,
    };
}

/// Everything that changes while the axis runs: counter extension, direction, lags, sensor
/// health, cached thermal contribution, predicted forces, last applied correction.
///
/// All zero bytes after [`State::new`].
#[derive(Debug, Clone, PartialEq)]
pub struct State {
    primed: bool,
    raw_pending: bool,
    last_raw: u32,
    position: i64,
    backward: bool,
    back_counts: i32,
    last_correction_um: f32,
    sensor_um: f32,
    expansion_um_per_count: f32,
    thermal_live: bool,
    sensor_fault: bool,
    clock_started: bool,
    /// Thermo flags (SENSOR_FAULT, THERMAL_FROZEN, FORCE_INVALID of the process) XOR the
    /// compensator's `thermo_flags_xor`.
    thermo_bits: u16,
    /// Σ χ_j·F_j of the predicted forces, µm.
    predicted_um: f32,
    /// b0 + sensor_um + predicted_um, µm (what the cycle adds).
    cached_um: f32,
    predicted_forces_n: [f32; MAX_FORCES],
    sensors: [SensorState; MAX_SENSORS],
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

    fn set_thermo_flag(&mut self, flag: Flags, on: bool) {
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

use crate::ImageError;

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
