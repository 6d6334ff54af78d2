//! The model's component tables as plain CSV (`fit geometry --export`), for reading and plotting elsewhere.
//! They are not a controller's format: the TwinCAT TF5280 and Heidenhain files are written by the
//! `axcomp-export` crate (`axcomp export --format tf5280|heidenhain`).
//!
//! - **per component** (one 1-D table per component over its own axis): `EXX.csv` … `ECZ.csv`
//!   with columns `component,position_mm,value,unit` (µm or µrad), and `squareness.csv`
//!   (`component,value,unit`).
//! - **per axis** (one table per axis): `axis_X.csv` with columns
//!   `position_mm,EXX,EYX,EZX,EAX,EBX,ECX` (µm and µrad), likewise `axis_Y.csv`, `axis_Z.csv`.
//! - `not_identified.txt`: the components the data could not identify; their tables hold the prior 0 (the
//!   per-component tables of those components are not written at all).
//!
//! Values are the model's errors (tool relative to workpiece, reached − commanded); a controller subtracts
//! them. Positions run over the measured range in `step` mm (the last point is the range end).

use axcomp_kinematics::{Axis, Component};

use crate::model::GeometryModel;

fn positions(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let mut v = Vec::new();
    let mut q = lo;
    while q < hi - 1e-9 {
        v.push(q);
        q += step;
    }
    v.push(hi);
    v
}

/// All export files as (file name, contents); `step_mm` ≤ 0 means 40 steps over each axis.
pub fn export_files(model: &GeometryModel, step_mm: f64) -> Vec<(String, String)> {
    let mut files = Vec::new();
    let mut missing = String::new();
    let pos_of = |a: Axis| {
        let g = model.grids[a.index()];
        let step = if step_mm > 0.0 {
            step_mm
        } else {
            (g.hi - g.lo) / 40.0
        };
        positions(g.lo, g.hi, step)
    };
    for c in &Component::ALL[..18] {
        let m = &model.components[c.index()];
        if !m.identified {
            missing.push_str(&format!("{}: {}\n", c.name(), m.reason));
            if m.coefficients.iter().all(|x| *x == 0.0) {
                continue;
            }
        }
        let mut s = String::from("component,position_mm,value,unit\n");
        for q in pos_of(c.axis().unwrap()) {
            s.push_str(&format!(
                "{},{:.4},{:.5},{}\n",
                c.name(),
                q,
                model.component_value(*c, q),
                c.unit()
            ));
        }
        files.push((format!("{}.csv", c.name()), s));
    }
    let mut s = String::from("component,value,unit\n");
    for c in &Component::ALL[18..] {
        let m = &model.components[c.index()];
        if !m.identified {
            missing.push_str(&format!("{}: {}\n", c.name(), m.reason));
        }
        s.push_str(&format!("{},{:.5},urad\n", c.name(), m.value));
    }
    files.push(("squareness.csv".into(), s));
    for a in Axis::ALL {
        let comps: Vec<Component> = Component::ALL[6 * a.index()..6 * a.index() + 6].to_vec();
        let mut s = String::from("position_mm");
        for c in &comps {
            s.push(',');
            s.push_str(c.name());
        }
        s.push('\n');
        for q in pos_of(a) {
            s.push_str(&format!("{q:.4}"));
            for c in &comps {
                s.push_str(&format!(",{:.5}", model.component_value(*c, q)));
            }
            s.push('\n');
        }
        files.push((format!("axis_{}.csv", a.letter()), s));
    }
    if missing.is_empty() {
        missing.push_str("all 21 components identified\n");
    }
    files.push(("not_identified.txt".into(), missing));
    files
}
