//! The thermo-force term: sensors (plausibility, staleness, lag), the cached thermal
//! contribution, predicted and measured forces.
//!
//! # Glossary
//! - **thermo-force term**: E = b0 + Σ b_i·ΔT_i + c·(x − x_ref)·ΔT_s + Σ χ_j·F_j (µm).
//! - **sensor rate**: [`ThermoForceStage::update_temperatures`] and
//!   [`ThermoForceStage::set_process`] run at the sensor/process rate and cache
//!   b0 + Σ b_i·ΔT_i + Σ χ_j·F_j(predicted) and c·ΔT_s in the [`ThermoState`]; the cycle only
//!   adds them (see [`ThermoForceStage::thermo_um`]).
//! - **stale**: no accepted reading for `stale_timeout_ms`; the thermal contribution freezes.
//!
//! The stage is a value: its settings [`ThermoForceStage`] (read through `&self`, set by the
//! loader; `Sn` is where the sensors' settings are kept: with the stage for a single axis, `()`
//! for an axis of a group, which keeps them in an array of its own and passes them in) and its
//! state [`ThermoState`] (lags, sensor health, the cached contribution, the predicted forces, the
//! thermo flags; through `&mut`), one part of the axis's [`crate::State`].

use crate::io::Flags;
use crate::sensor::SensorState;
use crate::sensor::{
    ForceSource, MeasuredSet, ProcessParams, REJECTED_MASK, SEEN, STALE, STREAK_MASK, STREAK_MAX,
    STREAK_ONE, SensorRt, ZERO_LAW, sensor_b_alpha, sensor_spec,
};
use crate::spec::{ExpansionSpec, ForceLaw, ForceSpec, SensorSpec};
use crate::{MAX_FORCE_N, MAX_FORCE_TERM_UM, MAX_FORCES, MAX_SENSORS, RECOVERY_READINGS};

/// The thermo-force stage's state: sensor health and lags, the cached thermal contribution, the
/// predicted forces, the thermo flags.
///
/// `#[repr(C)]` in this order: the flags and the cached values the cycle reads first, the
/// sensor-rate fields after them.
#[derive(Debug, Clone, PartialEq)]
#[repr(C)]
pub(crate) struct ThermoState {
    /// Thermo flags (SENSOR_FAULT, THERMAL_FROZEN, FORCE_INVALID of the process) XOR the
    /// stage's `thermo_flags_xor`.
    pub(crate) thermo_bits: u16,
    pub(crate) thermal_live: bool,
    pub(crate) sensor_fault: bool,
    pub(crate) clock_started: bool,
    /// A sensor is stale: the thermal term's ramp-out clock runs from `stale_since_ms`.
    pub(crate) stale_ramp: bool,
    /// b0 + sensor_um + predicted_um, µm (what the cycle adds).
    pub(crate) cached_um: f32,
    pub(crate) expansion_um_per_count: f32,
    pub(crate) sensor_um: f32,
    /// Σ χ_j·F_j of the predicted forces, µm.
    pub(crate) predicted_um: f32,
    pub(crate) predicted_forces_n: [f32; MAX_FORCES],
    pub(crate) stale_since_ms: u32,
    pub(crate) frozen_sensor_um: f32,
    pub(crate) frozen_expansion_um_per_count: f32,
    pub(crate) sensors: [SensorState; MAX_SENSORS],
}

impl ThermoState {
    /// Fresh state: no reading yet, nothing predicted (all zero bytes).
    pub(crate) const NEW: ThermoState = ThermoState {
        thermo_bits: 0,
        thermal_live: false,
        sensor_fault: false,
        clock_started: false,
        stale_ramp: false,
        sensor_um: 0.0,
        expansion_um_per_count: 0.0,
        predicted_um: 0.0,
        cached_um: 0.0,
        predicted_forces_n: [0.0; MAX_FORCES],
        stale_since_ms: 0,
        frozen_sensor_um: 0.0,
        frozen_expansion_um_per_count: 0.0,
        sensors: [SensorState::NEW; MAX_SENSORS],
    };

    /// A new image became active: sensor health, lags and the sensor clock restart (the new image
    /// may have other sensors), the predicted forces are dropped, and the thermal contribution
    /// stays frozen at its last value until every sensor of the new image has reported.
    pub(crate) fn on_new_image(&mut self) {
        self.sensors = [SensorState::NEW; MAX_SENSORS];
        self.clock_started = false;
        self.thermal_live = false;
        self.sensor_fault = false;
        self.thermo_bits = 0;
        self.predicted_um = 0.0;
        self.predicted_forces_n = [0.0; MAX_FORCES];
        self.stale_ramp = false;
    }

    fn set_flag(&mut self, flag: Flags, on: bool) {
        if on {
            self.thermo_bits |= flag.0;
        } else {
            self.thermo_bits &= !flag.0;
        }
    }
}

/// The settings of the thermo-force term (validated at load).
#[derive(Debug, Clone)]
#[repr(C)]
pub(crate) struct ThermoForceStage<Sn> {
    pub(crate) has_thermo: bool,
    pub(crate) sensor_period_ms: u32,
    pub(crate) n_sensors: u8,
    /// The sensors' settings where the storage keeps them with the axis (the single axis: all
    /// [`MAX_SENSORS`]); a group keeps its axes' in an array of their own (`()` here), so that
    /// the per-cycle fields of all five axes are within short load offsets of the group.
    pub(crate) sensors: Sn,
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
    /// THERMAL_FROZEN if the image has sensors: [`ThermoState::thermo_bits`] holds the thermo
    /// flags XOR this, so that a fresh (all-zero) state reads as frozen until its sensors report.
    pub(crate) thermo_flags_xor: u16,
    pub(crate) laws: [ForceLaw; MAX_FORCES],
}

impl<Sn> ThermoForceStage<Sn> {
    /// No thermo-force term (all zero bytes if `sensors` is), the sensors' settings `sensors`.
    pub(crate) const fn none(sensors: Sn) -> ThermoForceStage<Sn> {
        ThermoForceStage {
            has_thermo: false,
            sensor_period_ms: 0,
            n_sensors: 0,
            sensors,
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
        }
    }

    /// Back to no thermo-force term ([`ThermoForceStage::none`]), the sensors' settings left as
    /// they are (the loader copies them separately, to wherever the storage keeps them). Out of
    /// line: one copy for the loader and `clear` (code size; run at load only).
    #[inline(never)]
    pub(crate) fn reset(&mut self) {
        self.has_thermo = false;
        self.sensor_period_ms = 0;
        self.n_sensors = 0;
        self.b0_um = 0.0;
        self.has_expansion = false;
        self.reference_at_switch_on = false;
        self.rise_guard = false;
        self.expansion_sensor = 0;
        self.x_ref_counts = 0;
        self.c_um_per_mm_k = 0.0;
        self.expansion_um_per_count_k = 0.0;
        self.n_forces = 0;
        self.chi_um_per_n = [0.0; MAX_FORCES];
        self.force_predicted = [false; MAX_FORCES];
        self.measured_mask = 0;
        self.chi_measured = [0.0; MAX_FORCES];
        self.measured = MeasuredSet::None;
        self.thermo_flags_xor = 0;
        self.laws = [ZERO_LAW; MAX_FORCES];
    }

    /// `total` (the table value) plus the thermo-force term at `pos` for one cycle (µm): the
    /// cached b0 + Σ b_i·ΔT_i + Σ χ_j·F_j (predicted) with the expansion term (one multiply-add
    /// with the cached c·ΔT_s), then the measured forces of this input — added to `total` in
    /// that order (the order fixes the f32 rounding); ORs the thermo flags into `flags`.
    #[inline(always)]
    pub(crate) fn thermo_um(
        &self,
        st: &ThermoState,
        pos: i64,
        forces_n: &[f32; MAX_FORCES],
        flags: &mut Flags,
        mut total: f32,
    ) -> f32 {
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
            let f = forces_n;
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
                *flags |= Flags::FORCE_INVALID;
            }
        }
        *flags |= Flags(st.thermo_bits ^ self.thermo_flags_xor);
        total
    }

    /// True if a thermo-force term is loaded.
    pub(crate) fn has_thermo(&self) -> bool {
        self.has_thermo
    }
    /// Sensor period of the thermo-force term, ms.
    pub(crate) fn sensor_period_ms(&self) -> u32 {
        self.sensor_period_ms
    }
    /// Number of sensors.
    pub(crate) fn sensor_count(&self) -> usize {
        self.n_sensors as usize
    }
    /// Constant term b0, µm.
    pub(crate) fn b0_um(&self) -> f32 {
        self.b0_um
    }
    /// The expansion term, if any.
    pub(crate) fn expansion(&self) -> Option<ExpansionSpec> {
        self.has_expansion.then_some(ExpansionSpec {
            sensor: self.expansion_sensor,
            x_ref_counts: self.x_ref_counts,
            c_um_per_mm_k: self.c_um_per_mm_k,
        })
    }
    /// What each ΔT is taken against.
    pub(crate) fn thermo_reference(&self) -> crate::spec::ThermoReference {
        if self.reference_at_switch_on {
            crate::spec::ThermoReference::SwitchOn
        } else {
            crate::spec::ThermoReference::Fixed
        }
    }
    /// True if the image has the range guard (per-sensor rise bounds).
    pub(crate) fn has_rise_guard(&self) -> bool {
        self.rise_guard
    }
    /// Number of force terms.
    pub(crate) fn force_count(&self) -> usize {
        self.n_forces as usize
    }
    /// Force term `j`.
    pub(crate) fn force(&self, j: usize) -> Option<ForceSpec> {
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
    pub(crate) fn force_source(&self, j: usize) -> Option<ForceSource> {
        self.force(j).map(|f| match f.law {
            Some(_) => ForceSource::Predicted,
            None => ForceSource::Measured,
        })
    }

    /// The sensor-rate update (its rules: the single axis's `update_temperatures`) with the
    /// sensors' settings `cfgs` (the axis's own, or its group's array:
    /// [`crate::group::Group::update_temperatures`]); nothing without a thermo-force term.
    pub(crate) fn update_temperatures(
        &self,
        cfgs: &[SensorRt; MAX_SENSORS],
        st: &mut ThermoState,
        now_ms: u32,
        readings: &[f32],
    ) {
        if !self.has_thermo {
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
        let mut any_stale = false;
        let mut fault = false;
        let mut sum = 0.0f32;
        let mut guarded = false;
        for (i, (cfg, s)) in cfgs.iter().zip(st.sensors.iter_mut()).enumerate() {
            if i >= n {
                break;
            }
            let r = readings.get(i).copied().unwrap_or(f32::NAN);
            let since_good_ms = now_ms.wrapping_sub(s.last_good_ms);
            let mut w = s.health;
            let plausible = r.is_finite()
                && r >= cfg.min_degc
                && r <= cfg.max_degc
                && (w & SEEN == 0
                    || libm::fabsf(r - s.last_good_degc)
                        <= cfg.max_rate_degc_per_s * (since_good_ms as f32 * 0.001));
            let rejected_now;
            if plausible {
                if w & SEEN == 0 {
                    w |= SEEN;
                    s.reference_degc = if self.reference_at_switch_on {
                        r
                    } else {
                        cfg.reference_degc
                    };
                    s.filtered_dt = r - s.reference_degc;
                }
                s.last_good_degc = r;
                s.last_good_ms = now_ms;
                if w < STREAK_MAX {
                    w += STREAK_ONE;
                }
                rejected_now = false;
            } else {
                w &= !STREAK_MASK;
                rejected_now = !r.is_nan();
                if rejected_now && w & REJECTED_MASK != REJECTED_MASK {
                    w += 1;
                }
            }
            if w & SEEN != 0 {
                let u = s.last_good_degc - s.reference_degc;
                s.filtered_dt += cfg.alpha * (u - s.filtered_dt);
                // Σ b_i·ΔT_i in index order, without the term of a sensor whose unlagged rise u
                // is beyond its bounds (the range guard; ±∞ without it: every term counts).
                if u >= cfg.rise_min_k && u <= cfg.rise_max_k {
                    sum += cfg.b_um_per_k * s.filtered_dt;
                } else {
                    guarded = true;
                }
            }
            if now_ms.wrapping_sub(s.last_good_ms) > cfg.stale_timeout_ms {
                w |= STALE;
            }
            if w & STALE != 0 && w >= RECOVERY_READINGS as u32 * STREAK_ONE {
                w &= !STALE;
            }
            s.health = w;
            let stale = w & STALE != 0;
            if w & SEEN == 0 || stale {
                all_healthy = false;
            }
            any_stale |= stale;
            if stale || rejected_now {
                fault = true;
            }
        }
        st.sensor_fault = fault;
        st.thermal_live = all_healthy;
        let mut bits = st.thermo_bits ^ self.thermo_flags_xor;
        bits &= !(Flags::SENSOR_FAULT.0 | Flags::THERMAL_FROZEN.0 | Flags::THERMAL_RAMP_OUT.0);
        if fault {
            bits |= Flags::SENSOR_FAULT.0;
        }
        if !all_healthy {
            bits |= Flags::THERMAL_FROZEN.0;
        }
        self.stale_ramp_out(st, now_ms, any_stale, &mut bits);
        st.thermo_bits = bits ^ self.thermo_flags_xor;
        if all_healthy {
            self.refresh_thermal(st, sum, guarded);
        }
    }

    /// Stale ramp-out: a frozen term is held for STALE_HOLD_MS after a sensor went stale, then
    /// Σ b_i·ΔT_i and c·ΔT_s ramp linearly to 0 over STALE_RAMP_MS, leaving the safe value
    /// b0 + predicted forces (which need no sensor); THERMAL_RAMP_OUT into `bits` while it does.
    #[inline(always)]
    fn stale_ramp_out(&self, st: &mut ThermoState, now_ms: u32, any_stale: bool, bits: &mut u16) {
        if !any_stale {
            st.stale_ramp = false;
            return;
        }
        if !st.stale_ramp {
            st.stale_ramp = true;
            st.stale_since_ms = now_ms;
            st.frozen_sensor_um = st.sensor_um;
            st.frozen_expansion_um_per_count = st.expansion_um_per_count;
        }
        let since = now_ms.wrapping_sub(st.stale_since_ms);
        if since > crate::STALE_HOLD_MS {
            let into = since - crate::STALE_HOLD_MS;
            let k = if into >= crate::STALE_RAMP_MS {
                0.0
            } else {
                1.0 - into as f32 / crate::STALE_RAMP_MS as f32
            };
            st.sensor_um = st.frozen_sensor_um * k;
            st.expansion_um_per_count = st.frozen_expansion_um_per_count * k;
            st.cached_um = self.b0_um + st.sensor_um + st.predicted_um;
            *bits |= Flags::THERMAL_RAMP_OUT.0;
        }
    }

    /// Every sensor healthy: the new Σ b_i·ΔT_i `sum` (`guarded`: a term was left out by the range
    /// guard, THERMAL_GUARDED), the cached term and c·ΔT_s.
    #[inline(always)]
    fn refresh_thermal(&self, st: &mut ThermoState, sum: f32, guarded: bool) {
        st.thermo_bits &= !Flags::THERMAL_GUARDED.0;
        if guarded {
            st.thermo_bits |= Flags::THERMAL_GUARDED.0;
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

    /// Predicted forces from the process parameters (F = k·ap^x·fz^y·n^z via `libm::powf`),
    /// computed here only. A non-finite or implausible prediction is replaced by 0 N and flagged
    /// (FORCE_INVALID) until the next call. Without an image (`loaded` false) no force is
    /// predicted.
    pub(crate) fn set_process(&self, loaded: bool, st: &mut ThermoState, p: &ProcessParams) {
        let mut invalid = false;
        let mut sum = 0.0f32;
        for j in 0..MAX_FORCES {
            let mut f = 0.0;
            if loaded && j < self.n_forces as usize && self.force_predicted[j] {
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
        st.set_flag(Flags::FORCE_INVALID, invalid);
    }
}

impl ThermoForceStage<[SensorRt; MAX_SENSORS]> {
    /// Settings of sensor `i`.
    pub(crate) fn sensor(&self, i: usize) -> Option<SensorSpec> {
        sensor_spec(&self.sensors, self.n_sensors, i)
    }
    /// b_i of sensor `i`, µm/K.
    pub(crate) fn b_um_per_k(&self, i: usize) -> Option<f32> {
        sensor_b_alpha(&self.sensors, self.n_sensors, i).map(|(b, _)| b)
    }
    /// Rise bounds `(rise_min_k, rise_max_k)` of sensor `i`'s range guard (None without the
    /// guard or sensor).
    pub(crate) fn rise_bounds_k(&self, i: usize) -> Option<(f32, f32)> {
        if !self.rise_guard || i >= self.n_sensors as usize {
            return None;
        }
        self.sensors.get(i).map(|s| (s.rise_min_k, s.rise_max_k))
    }
    /// Lag coefficient α of sensor `i` (1 = no lag).
    pub(crate) fn lag_alpha(&self, i: usize) -> Option<f32> {
        sensor_b_alpha(&self.sensors, self.n_sensors, i).map(|(_, a)| a)
    }
}
