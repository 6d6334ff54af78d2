//! The thermo-force error law `e = b0 + Σ b (lag(T, τ) − T_ref) + Σ χ F`: the model the thermal fit
//! produces and the twin's spindle generator takes as its truth, shared here so that the twin does not
//! depend on the fitting crate.

use axcomp_numeric::lag::lag;
use serde::{Deserialize, Serialize};

/// A named column.
#[derive(Debug, Clone)]
pub struct Series {
    pub name: String,
    pub values: Vec<f64>,
}

/// One sensor term of a fitted model.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SensorTerm {
    pub sensor: String,
    pub reference_degc: f64,
    pub tau_s: f64,
    pub coef_um_per_k: f64,
}

/// One force term of a fitted model.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ForceTerm {
    pub column: String,
    pub chi_um_per_n: f64,
}

/// A fitted thermo-force model: `e = b0 + Σ b (lag(T, τ) − T_ref) + Σ χ F`.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ThermalModel {
    pub b0_um: f64,
    pub terms: Vec<SensorTerm>,
    pub forces: Vec<ForceTerm>,
}

impl ThermalModel {
    /// Predicted error per row. Sensors and forces are looked up by name.
    pub fn predict(
        &self,
        time_s: &[f64],
        sensors: &[Series],
        forces: &[Series],
    ) -> Result<Vec<f64>, String> {
        let mut out = vec![self.b0_um; time_s.len()];
        for t in &self.terms {
            let s = sensors
                .iter()
                .find(|s| s.name == t.sensor)
                .ok_or_else(|| format!("sensor `{}` missing", t.sensor))?;
            let l = lag(time_s, &s.values, t.tau_s);
            for (o, v) in out.iter_mut().zip(l) {
                *o += t.coef_um_per_k * (v - t.reference_degc);
            }
        }
        for f in &self.forces {
            let s = forces
                .iter()
                .find(|s| s.name == f.column)
                .ok_or_else(|| format!("force column `{}` missing", f.column))?;
            for (o, v) in out.iter_mut().zip(&s.values) {
                *o += f.chi_um_per_n * v;
            }
        }
        Ok(out)
    }

    /// A one-line formula, e.g. `e = 1.2 + 3.4·ΔT(frame, τ=600 s) + 0.02·force_N`.
    pub fn formula(&self) -> String {
        let mut s = format!("e = {:.4}", self.b0_um);
        for t in &self.terms {
            s += &format!(
                " {:+.4}·ΔT({}, τ={:.0} s)",
                t.coef_um_per_k, t.sensor, t.tau_s
            );
        }
        for f in &self.forces {
            s += &format!(" {:+.6}·{}", f.chi_um_per_n, f.column);
        }
        s
    }
}
