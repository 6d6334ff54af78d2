//! The fitted geometry model file (`axcomp fit geometry --out MODEL`) and its evaluation.

use axcomp_data::Dataset;
use axcomp_kinematics::{Component, ComponentValues, Topology, dot, linear_error};
use serde::{Deserialize, Serialize};

use crate::GeometryError;
use crate::data::LineData;
use crate::spline::AxisGrid;

/// Format tag of the model file.
pub const MODEL_FORMAT: &str = "axcomp-geometry-model";

/// The model file version this reader knows (and the fit writes).
pub const MODEL_VERSION: u32 = 1;

/// Largest magnitude a model value may have (µm, µrad, mm): beyond it a value is a corrupted file, not
/// a machine's error.
pub const ABSURD: f64 = 1e12;

/// Most knot intervals an axis grid may have in a model file (the fit uses tens).
pub const MAX_INTERVALS: usize = 100_000;

fn plausible(v: f64) -> bool {
    v.is_finite() && v.abs() < ABSURD
}

/// A grid is usable: finite ends in order, at least one and at most [`MAX_INTERVALS`] intervals.
fn check_grid(g: &AxisGrid) -> Result<(), String> {
    if !(plausible(g.lo) && plausible(g.hi) && g.lo < g.hi) {
        return Err(format!(
            "range {} … {} mm is not an increasing finite range",
            g.lo, g.hi
        ));
    }
    if g.intervals == 0 || g.intervals > MAX_INTERVALS {
        return Err(format!(
            "{} knot intervals (need 1 … {MAX_INTERVALS})",
            g.intervals
        ));
    }
    Ok(())
}

/// The components of a model file in ISO order, each found by its name; the error names the entry
/// (`components[3] (EYX)`) and why.
fn components_by_name(
    entries: Vec<ComponentModel>,
    grids: &[AxisGrid; 3],
) -> Result<Vec<ComponentModel>, (String, String)> {
    let mut slots: Vec<Option<ComponentModel>> = vec![None; Component::ALL.len()];
    for (i, e) in entries.into_iter().enumerate() {
        let entry = format!("components[{i}] ({})", e.name);
        let Some(c) = Component::ALL.iter().copied().find(|c| c.name() == e.name) else {
            return Err((
                entry,
                "unknown component name (expected an ISO 230-1 name EXX … EA0Z)".into(),
            ));
        };
        check_component(c, &e, grids).map_err(|why| (entry.clone(), why))?;
        if slots[c.index()].is_some() {
            return Err((entry, format!("{} appears twice", c.name())));
        }
        slots[c.index()] = Some(e);
    }
    let missing: Vec<&str> = Component::ALL
        .iter()
        .filter(|c| slots[c.index()].is_none())
        .map(|c| c.name())
        .collect();
    if !missing.is_empty() {
        return Err((
            "components".into(),
            format!("missing {}", missing.join(", ")),
        ));
    }
    Ok(slots.into_iter().flatten().collect())
}

/// One component entry fits its kind: its unit, as many coefficients as its axis's grid has basis
/// functions (none for squareness), every value finite and of plausible size.
fn check_component(c: Component, e: &ComponentModel, grids: &[AxisGrid; 3]) -> Result<(), String> {
    if e.unit != c.unit() {
        return Err(format!("unit `{}`, expected `{}`", e.unit, c.unit()));
    }
    let want = c.axis().map_or(0, |a| grids[a.index()].n_basis());
    if e.coefficients.len() != want {
        return Err(format!(
            "{} coefficients, expected {want}{}",
            e.coefficients.len(),
            if want == 0 {
                " (a squareness has a value, no coefficients)"
            } else {
                " (its axis grid's basis functions)"
            }
        ));
    }
    let values = e.coefficients.iter().chain([&e.value]);
    let unc = e.uncertainty.iter().flatten();
    if let Some(v) = values.chain(unc).find(|v| !plausible(**v)) {
        return Err(format!(
            "value {v:e} is not a finite number of plausible size (|v| < {ABSURD:e})"
        ));
    }
    Ok(())
}

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

    /// Reads a model file (JSON): the format tag and version, the grids, and the components read by
    /// name (each of the 21 exactly once, in any order; stored in ISO order), each with as many
    /// coefficients as its axis's grid has basis functions and only finite values of plausible size.
    pub fn from_json(text: &str, source: &str) -> Result<GeometryModel, GeometryError> {
        let bad = |reason: String| GeometryError::BadModel {
            source_name: source.to_string(),
            reason,
        };
        let mut m: GeometryModel = serde_json::from_str(text).map_err(|e| bad(e.to_string()))?;
        if m.format != MODEL_FORMAT {
            return Err(bad(format!(
                "format is `{}`, expected `{MODEL_FORMAT}`",
                m.format
            )));
        }
        if m.version != MODEL_VERSION {
            return Err(bad(format!(
                "version {} is not one this reader knows ({MODEL_VERSION})",
                m.version
            )));
        }
        for (k, g) in m.grids.iter().enumerate() {
            check_grid(g)
                .map_err(|why| bad(format!("grids[{k}] ({} axis): {why}", ["X", "Y", "Z"][k])))?;
        }
        let scalars = [
            ("smoothing_lambda", m.smoothing_lambda),
            ("sigma_um", m.sigma_um),
        ];
        let volume = m.volume_min_mm.iter().chain(&m.volume_max_mm);
        if let Some((what, v)) = scalars
            .into_iter()
            .chain(volume.map(|v| ("volume_min_mm/volume_max_mm", *v)))
            .find(|(_, v)| !plausible(*v))
        {
            return Err(bad(format!(
                "{what}: {v} is not a finite number of plausible size"
            )));
        }
        m.components = components_by_name(std::mem::take(&mut m.components), &m.grids).map_err(
            |(entry, reason)| GeometryError::BadModelEntry {
                source_name: source.to_string(),
                entry,
                reason,
            },
        )?;
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
