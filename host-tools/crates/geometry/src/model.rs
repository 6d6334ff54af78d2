//! The fitted geometry model file (`axcomp fit geometry --out MODEL`) and its evaluation.

use axcomp_data::Dataset;
use axcomp_kinematics::{Component, ComponentValues, Topology, dot, linear_error};
use serde::{Deserialize, Serialize};

use crate::GeometryError;
use crate::data::LineData;
use crate::spline::AxisGrid;

/// Format tag of the model file.
pub const MODEL_FORMAT: &str = "axcomp-geometry-model";

/// One component in the model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ComponentModel {
    pub name: String,
    pub identified: bool,
    pub reason: String,
    pub unit: String,
    /// Cubic B-spline coefficients on the axis's grid (functions); empty for squareness.
    pub coefficients: Vec<f64>,
    /// Squareness value (µrad); 0 for functions.
    pub value: f64,
    /// `[position_mm, standard uncertainty]` samples (functions) or one `[0, u]` (squareness).
    pub uncertainty: Vec<[f64; 2]>,
}

/// A fitted geometry model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GeometryModel {
    pub format: String,
    pub version: u32,
    pub topology: Topology,
    /// Knot grids of X, Y, Z.
    pub grids: [AxisGrid; 3],
    /// The 21 components in ISO order (`EXX` … `EA0Z`).
    pub components: Vec<ComponentModel>,
    /// How it was fitted (method, smoothing λ and why).
    pub method: String,
    pub smoothing_lambda: f64,
    /// Residual standard deviation of the fit (µm).
    pub sigma_um: f64,
    /// Axis-position box of the measurements (mm), the volume the model covers.
    pub volume_min_mm: [f64; 3],
    pub volume_max_mm: [f64; 3],
}

impl GeometryModel {
    /// Value of component `c` at its axis position `pos` (µm or µrad); squareness ignores `pos`.
    pub fn component_value(&self, c: Component, pos: f64) -> f64 {
        let m = &self.components[c.index()];
        match c.axis() {
            Some(a) => self.grids[a.index()].eval(&m.coefficients, pos),
            None => m.value,
        }
    }

    /// All 21 values at axis positions `q`.
    pub fn values_at(&self, q: [f64; 3]) -> ComponentValues {
        let mut v = [0.0; 21];
        for (i, c) in Component::ALL.iter().enumerate() {
            v[i] = match c.axis() {
                Some(a) => self.component_value(*c, q[a.index()]),
                None => self.components[i].value,
            };
        }
        v
    }

    /// Predicted tool-point error (µm) at axis positions `q` with tool offset `t`; `None` outside the grid.
    pub fn error_at(&self, q: [f64; 3], t: [f64; 3]) -> Option<[f64; 3]> {
        if (0..3).any(|k| !self.grids[k].contains(q[k])) {
            return None;
        }
        Some(linear_error(&self.topology, q, t, &self.values_at(q)))
    }

    /// Reads a model file (JSON), checking its format tag.
    pub fn from_json(text: &str, source: &str) -> Result<GeometryModel, GeometryError> {
        let m: GeometryModel = serde_json::from_str(text).map_err(|e| GeometryError::BadModel {
            source_name: source.to_string(),
            reason: e.to_string(),
        })?;
        if m.format != MODEL_FORMAT || m.components.len() != 21 {
            return Err(GeometryError::BadModel {
                source_name: source.to_string(),
                reason: format!("not an {MODEL_FORMAT} file with 21 components"),
            });
        }
        Ok(m)
    }

    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("serialisable");
        s.push('\n');
        s
    }
}

/// One predicted row: `pred_ex_um`, `pred_ey_um`, `pred_ez_um`, and `pred_deviation_um` when the row's
/// beam is known (beam columns, or the line's direction from a `line` column).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowPrediction {
    pub e_um: [f64; 3],
    pub deviation_um: Option<f64>,
}

/// Predictions of a geometry model for every row of `ds` (inputs: `x_mm`, `y_mm`, `z_mm`, optional
/// `tool_*_mm`, `beam_*` or `line`). A row outside the model's grid is an error naming the row.
/// This is the library entry `axcomp predict` calls for geometry models.
pub fn predict_rows(
    model: &GeometryModel,
    ds: &Dataset,
) -> Result<Vec<RowPrediction>, GeometryError> {
    let has_beam = ["beam_x", "beam_y", "beam_z"].iter().all(|c| ds.has(c));
    let beam_known = has_beam || ds.has("line");
    let data = LineData::from_dataset(ds, false)?;
    let mut out = Vec::with_capacity(data.readings.len());
    for r in &data.readings {
        let e = model.error_at(r.q, r.tool).ok_or_else(|| {
            // Name the column of the axis that is outside (it was always `x_mm`).
            let k = (0..3)
                .find(|&k| !model.grids[k].contains(r.q[k]))
                .unwrap_or(0);
            let g = &model.grids[k];
            GeometryError::OutsideModel {
                at: ds.locate(["x_mm", "y_mm", "z_mm"][k], r.row),
                q: r.q,
                range: format!("{} {} … {} mm", ["X", "Y", "Z"][k], g.lo, g.hi),
            }
        })?;
        out.push(RowPrediction {
            e_um: e,
            deviation_um: beam_known.then(|| dot(e, r.beam)),
        });
    }
    Ok(out)
}
