//! R-test observations (poses, readings, held-out mask, time and temperatures) and the candidate
//! family types with the helpers that build their columns.

use crate::error::DiagnoseError;
use axcomp_effects::RotaryEffect;
use axcomp_kinematics::rotary::FiveAxis;
use axcomp_rtest::RtestData;
use nalgebra::Vector3;
use serde_json::Value;

/// R-test rows with the held-out mask and the columns the candidates use.
#[derive(Debug, Clone)]
pub struct RtestObservations {
    /// Poses, readings, paths and set-ups (validated by `axcomp_rtest`).
    pub data: RtestData,
    /// Per pose: held out from fitting, used only to judge.
    pub held_out: Vec<bool>,
    /// Per pose: `run` label (`""` without the column).
    pub run: Vec<String>,
    /// Per pose: seconds since the start of the campaign (`time_s`), if the file has it.
    pub time_s: Option<Vec<f64>>,
    /// Temperature sensors (`*_degC`): name and values per pose.
    pub temperatures: Vec<(String, Vec<f64>)>,
}

impl RtestObservations {
    /// From a CSV read by `axcomp-data`: the contract's R-test columns for `machine`, held-out poses from
    /// `holdout` (`COL=V1,V2`, `COL>=X`, ...). Errors name the file, line and column.
    pub fn from_dataset(
        ds: &axcomp_data::Dataset,
        machine: FiveAxis,
        holdout: &str,
    ) -> crate::error::Result<RtestObservations> {
        let spec = axcomp_data::HoldoutSpec::parse(holdout)?;
        let held_out = spec.mask(ds)?;
        let data = RtestData::from_dataset(ds, machine, true)?;
        let run = ds.run().unwrap_or_else(|| vec![String::new(); ds.n_rows()]);
        let time_s = if ds.has("time_s") {
            let t = ds.numeric("time_s")?.to_vec();
            if let Some(r) = t.iter().position(|v| !v.is_finite()) {
                return Err(DiagnoseError::BadValue {
                    at: ds.locate("time_s", r),
                    what: format!("`time_s` is {} (need a finite number)", t[r]),
                });
            }
            Some(t)
        } else {
            None
        };
        let mut temperatures = Vec::new();
        for s in ds.sensors() {
            let col = format!("{s}_degC");
            let v = ds.numeric(&col)?.to_vec();
            if let Some(r) = v.iter().position(|x| !x.is_finite()) {
                return Err(DiagnoseError::BadValue {
                    at: ds.locate(&col, r),
                    what: format!("`{col}` is {} (need a finite number)", v[r]),
                });
            }
            temperatures.push((s, v));
        }
        let o = RtestObservations {
            data,
            held_out,
            run,
            time_s,
            temperatures,
        };
        o.validate().map_err(|e| DiagnoseError::BadValue {
            at: ds.source().to_string(),
            what: e.to_string(),
        })?;
        Ok(o)
    }

    /// Number of poses.
    pub fn n_poses(&self) -> usize {
        self.data.poses.len()
    }

    /// Checks lengths and that both the training and the held-out poses are there.
    pub fn validate(&self) -> Result<(), DiagnoseError> {
        let n = self.n_poses();
        if self.data.d_um.len() != n || self.held_out.len() != n || self.run.len() != n {
            return Err(DiagnoseError::Invalid(
                "R-test observations: columns of different lengths".into(),
            ));
        }
        if self.time_s.as_ref().is_some_and(|t| t.len() != n)
            || self.temperatures.iter().any(|(_, v)| v.len() != n)
        {
            return Err(DiagnoseError::Invalid(
                "R-test observations: time or temperature column of a different length".into(),
            ));
        }
        crate::obs::check_holdout(&self.held_out, "--holdout", "pose")
    }
}

/// One candidate variant: its columns over all rows and its parameters (what the variant is).
pub type RtestVariant = crate::judge::BuiltVariant;

/// A candidate effect kind and its variants.
pub type RtestFamily = crate::judge::BuiltFamily<RotaryEffect>;

/// Stacks per-pose vectors into a column.
pub(super) fn stack(per_pose: &[Vector3<f64>]) -> Vec<f64> {
    per_pose.iter().flat_map(|v| [v[0], v[1], v[2]]).collect()
}

fn nonzero(c: &[f64]) -> bool {
    c.iter().any(|v| v.abs() > 1e-12)
}

pub(super) fn variant(columns: Vec<Vec<f64>>, params: Value) -> RtestVariant {
    let columns: Vec<Vec<f64>> = columns.into_iter().filter(|c| nonzero(c)).collect();
    let n_params = columns.len();
    RtestVariant {
        columns,
        params: params.as_object().cloned().unwrap_or_default(),
        n_params,
    }
}
