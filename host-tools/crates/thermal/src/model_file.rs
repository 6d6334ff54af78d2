//! The thermal model file (`axcomp fit thermal --out MODEL.json`) and its conversion to the core's
//! [`axcomp_core::ThermoForceSpec`] (used by `axcomp image build --thermal`).
//!
//! Glossary:
//! - **sensor order**: the order of `sensors` in the file is the firmware's reading order: reading `i` passed
//!   to `Compensator::update_temperatures` must be sensor `i` here (by its `column`).
//! - **plausibility**: `min_degc`/`max_degc`/`max_rate_degc_per_s`/`stale_timeout_ms` per sensor, derived from
//!   the training data with margins (range −20 K … +30 K, 5× the largest observed rate, at least 1 K/s;
//!   10 sensor periods, at least 10 s).
//! - **force terms**: `law: None` → the firmware uses the measured force at the same index; `Some` → the force
//!   predicted from the process parameters.

use serde::{Deserialize, Serialize};

use crate::thermal::{ThermalFit, ThermalInput};

/// Format tag written into every model file.
pub const FORMAT: &str = "axcomp-thermal-model/1";

/// One sensor of a model file.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ModelSensor {
    /// Sensor name (column without `_degC`).
    pub name: String,
    pub reference_degc: f64,
    pub tau_s: f64,
    pub coef_um_per_k: f64,
    pub min_degc: f64,
    pub max_degc: f64,
    pub max_rate_degc_per_s: f64,
    pub stale_timeout_ms: u32,
    /// Range guard: the rise (K, against the reference reading) beyond which the model drops this sensor's
    /// term (a linear model is not extrapolated far beyond the rises it was fitted on). Absent: no guard.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rise_min_k: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rise_max_k: Option<f64>,
}

/// A force law `F = k·ap^x·fz^y·n^z`.
#[derive(Debug, Clone, Copy, Serialize, Deserialize, PartialEq)]
pub struct ModelForceLaw {
    pub k: f64,
    pub x_ap: f64,
    pub y_fz: f64,
    pub z_n: f64,
}

/// One force term of a model file.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ModelForce {
    pub column: String,
    pub chi_um_per_n: f64,
    pub law: Option<ModelForceLaw>,
}

/// The model file.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ThermalModelFile {
    pub format: String,
    /// Error channel the model predicts.
    pub target: String,
    /// Rate at which the firmware reads the sensors (sets the lag coefficients).
    pub sensor_period_ms: u32,
    pub b0_um: f64,
    pub sensors: Vec<ModelSensor>,
    /// Force terms; absent in a file: none.
    #[serde(default)]
    pub forces: Vec<ModelForce>,
    /// Held-out figures at fit time (for the record; absent in a file: 0).
    #[serde(default)]
    pub raw_rms_um: f64,
    pub holdout_rms_um: Option<f64>,
    /// The target's value at the start, subtracted before the fit (`fit thermal --zero-at-start N`: the mean
    /// of the first N rows), µm. The model (and the firmware) predicts the change since the start; `axcomp
    /// predict` adds this back so that `pred_<target>` predicts the target itself. Absent: 0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_offset_um: Option<f64>,
    /// The runs column of a multi-run campaign (`fit thermal --runs COL`): each run's references (sensors
    /// and target) are its first row, as the firmware's are its readings at switch-on. Absent: one recording
    /// with the fixed `reference_degc`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub runs_column: Option<String>,
}

/// Owned storage for a [`axcomp_core::ThermoForceSpec`].
#[derive(Debug, Clone, PartialEq)]
pub struct OwnedThermoForceSpec {
    pub sensor_period_ms: u32,
    pub sensors: Vec<axcomp_core::SensorSpec>,
    pub b0_um: f32,
    pub b_um_per_k: Vec<f32>,
    pub expansion: Option<axcomp_core::ExpansionSpec>,
    pub forces: Vec<axcomp_core::ForceSpec>,
    /// SwitchOn for a multi-run model (`runs_column`), else Fixed.
    pub reference: axcomp_core::ThermoReference,
    /// The range guard: one `(rise_min_k, rise_max_k)` per sensor, or empty (no guard).
    pub rise_bounds_k: Vec<(f32, f32)>,
}

impl OwnedThermoForceSpec {
    /// The borrowed spec the core's `write_image` takes.
    pub fn spec(&self) -> axcomp_core::ThermoForceSpec<'_> {
        axcomp_core::ThermoForceSpec {
            sensor_period_ms: self.sensor_period_ms,
            sensors: &self.sensors,
            b0_um: self.b0_um,
            b_um_per_k: &self.b_um_per_k,
            expansion: self.expansion,
            forces: &self.forces,
            reference: self.reference,
            rise_bounds_k: &self.rise_bounds_k,
        }
    }
}

/// Why a model file is not usable.
#[derive(Debug, thiserror::Error)]
pub enum ModelFileError {
    #[error("{path}: {cause}")]
    Io { path: String, cause: std::io::Error },
    #[error("{path}: not a thermal model file: {cause}")]
    Json {
        path: String,
        cause: serde_json::Error,
    },
    #[error("{path}: {what}")]
    Invalid { path: String, what: String },
}

impl ThermalModelFile {
    /// A warm-up drift as a model with one input, `warmup` (0 while the axis is cold or de-energised, 1
    /// while it is energised), lagged by `tau_s`: `b0 + drift_um·w` with `b0 = −drift_um·state_ref`, so the
    /// model reads 0 at the reference state the positioning table holds. `period_ms` is the rate the drive
    /// feeds the input (> 0). Errors say why the model is not usable.
    #[allow(clippy::too_many_arguments)]
    pub fn warmup_drift(
        target: &str,
        period_ms: u32,
        tau_s: f64,
        drift_um: f64,
        state_ref: f64,
        raw_rms_um: f64,
        judged_rms_um: f64,
    ) -> Result<ThermalModelFile, String> {
        if period_ms == 0 {
            return Err("--drift-period-ms must be > 0".into());
        }
        let m = ThermalModelFile {
            format: FORMAT.into(),
            target: target.to_string(),
            sensor_period_ms: period_ms,
            b0_um: -drift_um * state_ref,
            sensors: vec![ModelSensor {
                name: "warmup".into(),
                reference_degc: 0.0,
                tau_s,
                coef_um_per_k: drift_um,
                // The input is 0 or 1; any step between them is plausible.
                min_degc: -0.5,
                max_degc: 1.5,
                max_rate_degc_per_s: 1.0e6,
                stale_timeout_ms: (10 * period_ms).max(10_000),
                rise_min_k: None,
                rise_max_k: None,
            }],
            forces: vec![],
            raw_rms_um,
            holdout_rms_um: Some(judged_rms_um),
            target_offset_um: None,
            runs_column: None,
        };
        m.validate()
            .map_err(|e| format!("the warm-up drift model is not usable: {e}"))?;
        Ok(m)
    }

    /// Builds the file from a fit and the data it was fitted on (plausibility limits from the data).
    pub fn from_fit(
        fit: &ThermalFit,
        input: &ThermalInput,
        target: &str,
        sensor_period_ms: u32,
    ) -> Self {
        let period_s = f64::from(sensor_period_ms) / 1000.0;
        let sensors = fit
            .model
            .terms
            .iter()
            .zip(&fit.rise_bounds_k)
            .map(|(t, &(rise_lo, rise_hi))| {
                let s = input
                    .sensors
                    .iter()
                    .find(|s| s.name == t.sensor)
                    .expect("fitted sensor is in the input");
                let min = s.values.iter().cloned().fold(f64::INFINITY, f64::min);
                let max = s.values.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
                let mut rate: f64 = 0.0;
                for k in 1..s.values.len() {
                    let dt = input.time_s[k] - input.time_s[k - 1];
                    if dt > 0.0 {
                        rate = rate.max((s.values[k] - s.values[k - 1]).abs() / dt);
                    }
                }
                ModelSensor {
                    name: t.sensor.clone(),
                    reference_degc: t.reference_degc,
                    tau_s: t.tau_s,
                    coef_um_per_k: t.coef_um_per_k,
                    min_degc: min - 20.0,
                    max_degc: max + 30.0,
                    max_rate_degc_per_s: (5.0 * rate).max(1.0),
                    stale_timeout_ms: ((10.0 * period_s).max(10.0) * 1000.0) as u32,
                    rise_min_k: Some(rise_lo),
                    rise_max_k: Some(rise_hi),
                }
            })
            .collect();
        ThermalModelFile {
            format: FORMAT.into(),
            target: target.into(),
            sensor_period_ms,
            b0_um: fit.model.b0_um,
            sensors,
            forces: fit
                .model
                .forces
                .iter()
                .map(|f| ModelForce {
                    column: f.column.clone(),
                    chi_um_per_n: f.chi_um_per_n,
                    law: None,
                })
                .collect(),
            raw_rms_um: fit.raw_rms_um,
            holdout_rms_um: fit.holdout_rms_um,
            target_offset_um: None,
            runs_column: None,
        }
    }

    /// Checks limits the core enforces too (counts, finiteness, ranges), naming what is wrong.
    pub fn validate(&self) -> Result<(), String> {
        if self.format != FORMAT {
            return Err(format!("format is `{}`, expected `{FORMAT}`", self.format));
        }
        if self.sensor_period_ms == 0 {
            return Err("sensor_period_ms must be > 0".into());
        }
        if self.sensors.len() > axcomp_core::MAX_SENSORS {
            return Err(format!(
                "{} sensors, at most {}",
                self.sensors.len(),
                axcomp_core::MAX_SENSORS
            ));
        }
        if self.forces.len() > axcomp_core::MAX_FORCES {
            return Err(format!(
                "{} forces, at most {}",
                self.forces.len(),
                axcomp_core::MAX_FORCES
            ));
        }
        if !self.b0_um.is_finite() {
            return Err("b0_um is not finite".into());
        }
        for (i, s) in self.sensors.iter().enumerate() {
            let ok = [
                s.reference_degc,
                s.tau_s,
                s.coef_um_per_k,
                s.min_degc,
                s.max_degc,
                s.max_rate_degc_per_s,
            ]
            .iter()
            .all(|v| v.is_finite());
            if !ok {
                return Err(format!("sensors[{i}] (`{}`): non-finite value", s.name));
            }
            if s.tau_s < 0.0
                || s.min_degc >= s.max_degc
                || s.max_rate_degc_per_s <= 0.0
                || s.stale_timeout_ms == 0
            {
                return Err(format!(
                    "sensors[{i}] (`{}`): need tau_s >= 0, min_degc < max_degc, max_rate_degc_per_s > 0, \
                     stale_timeout_ms > 0",
                    s.name
                ));
            }
        }
        for (i, f) in self.forces.iter().enumerate() {
            if !f.chi_um_per_n.is_finite() {
                return Err(format!(
                    "forces[{i}] (`{}`): chi_um_per_n is not finite",
                    f.column
                ));
            }
        }
        Ok(())
    }

    /// Reads and validates a model file.
    pub fn load(path: &std::path::Path) -> Result<Self, ModelFileError> {
        let p = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|cause| ModelFileError::Io {
            path: p.clone(),
            cause,
        })?;
        let text = axcomp_files::model_text(&bytes).map_err(|what| ModelFileError::Invalid {
            path: p.clone(),
            what,
        })?;
        // Another kind of model file: say so before serde's first missing field does.
        if let Some(what) = axcomp_files::wrong_format(text, FORMAT, "thermal model") {
            return Err(ModelFileError::Invalid { path: p, what });
        }
        let m: ThermalModelFile =
            serde_json::from_str(text).map_err(|cause| ModelFileError::Json {
                path: p.clone(),
                cause,
            })?;
        m.validate()
            .map_err(|what| ModelFileError::Invalid { path: p, what })?;
        Ok(m)
    }

    /// Writes the file atomically ([`axcomp_files::write_atomic`]).
    pub fn save(&self, path: &std::path::Path) -> Result<(), ModelFileError> {
        let p = path.display().to_string();
        let text = serde_json::to_string_pretty(self).expect("model file serializes");
        axcomp_files::write_atomic(path, text.as_bytes())
            .map_err(|cause| ModelFileError::Io { path: p, cause })
    }

    /// Converts to the core's owned spec (f32, sensor order kept). Call [`ThermalModelFile::validate`] first
    /// (`load` does). A multi-run model (`runs_column`) takes each sensor's reference at switch-on (the
    /// firmware's first reading after load/reset, as each run's first row in the fit); the range guard is
    /// written when every sensor has both rise bounds (`axcomp predict` then drops the same terms).
    pub fn to_core(&self) -> OwnedThermoForceSpec {
        let rise_bounds_k = self
            .sensors
            .iter()
            .map(|s| Some((s.rise_min_k? as f32, s.rise_max_k? as f32)))
            .collect::<Option<Vec<_>>>()
            .unwrap_or_default();
        OwnedThermoForceSpec {
            reference: if self.runs_column.is_some() {
                axcomp_core::ThermoReference::SwitchOn
            } else {
                axcomp_core::ThermoReference::Fixed
            },
            rise_bounds_k,
            sensor_period_ms: self.sensor_period_ms,
            sensors: self
                .sensors
                .iter()
                .map(|s| axcomp_core::SensorSpec {
                    reference_degc: s.reference_degc as f32,
                    min_degc: s.min_degc as f32,
                    max_degc: s.max_degc as f32,
                    max_rate_degc_per_s: s.max_rate_degc_per_s as f32,
                    lag_tau_s: s.tau_s as f32,
                    stale_timeout_ms: s.stale_timeout_ms,
                })
                .collect(),
            b0_um: self.b0_um as f32,
            b_um_per_k: self
                .sensors
                .iter()
                .map(|s| s.coef_um_per_k as f32)
                .collect(),
            expansion: None,
            forces: self
                .forces
                .iter()
                .map(|f| axcomp_core::ForceSpec {
                    chi_um_per_n: f.chi_um_per_n as f32,
                    law: f.law.map(|l| axcomp_core::ForceLaw {
                        k: l.k as f32,
                        x_ap: l.x_ap as f32,
                        y_fz: l.y_fz as f32,
                        z_n: l.z_n as f32,
                    }),
                })
                .collect(),
        }
    }
}
