//! Each artefact's linearisation (see the glossary of [`super`]): the radial residual about a sphere fit
//! or the touches' mean plane, the outward normals, and the artefact's placement columns — in the base
//! model when it has training touches, projected out of its held-out rows when it has none.

use serde_json::{Map, Value, json};

use super::{ArtefactFit, ProbeData, norm, orthonormal, params, rms_on, sub};
use crate::error::DiagnoseError;

/// The campaign's rows as the artefacts linearise them.
pub(super) struct Linearised {
    /// Artefact index per row.
    pub(super) art: Vec<usize>,
    /// Radial residual, µm.
    pub(super) y: Vec<f64>,
    /// The artefact's outward normal at each touch.
    pub(super) normal: Vec<[f64; 3]>,
    /// Placement columns of the artefacts with training touches.
    pub(super) base_columns: Vec<Vec<f64>>,
    pub(super) base_terms: Vec<(String, Map<String, Value>, usize)>,
    /// Held-out-only artefacts: their rows and the orthonormal placement basis to project out.
    pub(super) projections: Vec<(Vec<usize>, Vec<Vec<f64>>)>,
    pub(super) artefacts: Vec<ArtefactFit>,
}

/// Linearises every artefact's touches.
pub(super) fn linearise(d: &ProbeData) -> Result<Linearised, DiagnoseError> {
    let n = d.touches.len();
    let mut names: Vec<String> = Vec::new();
    let art: Vec<usize> = d
        .artefact
        .iter()
        .map(|a| match names.iter().position(|x| x == a) {
            Some(k) => k,
            None => {
                names.push(a.clone());
                names.len() - 1
            }
        })
        .collect();
    let mut lin = Linearised {
        art,
        y: vec![0.0; n],
        normal: vec![[0.0; 3]; n],
        base_columns: Vec::new(),
        base_terms: Vec::new(),
        projections: Vec::new(),
        artefacts: Vec::new(),
    };
    for (a, name) in names.iter().enumerate() {
        let rows: Vec<usize> = (0..n).filter(|&i| lin.art[i] == a).collect();
        one_artefact(d, name, &rows, &mut lin)?;
    }
    Ok(lin)
}

fn one_artefact(
    d: &ProbeData,
    name: &str,
    rows: &[usize],
    lin: &mut Linearised,
) -> Result<(), DiagnoseError> {
    let tr: Vec<usize> = rows.iter().copied().filter(|&i| !d.held_out[i]).collect();
    let ho: Vec<usize> = rows.iter().copied().filter(|&i| d.held_out[i]).collect();
    let pts =
        |r: &[usize]| -> Vec<[f64; 3]> { r.iter().map(|&i| d.touches[i].position_mm).collect() };
    let labels = |r: &[usize]| -> Vec<String> { r.iter().map(|&i| d.labels[i].clone()).collect() };
    // A sphere when the touches span three dimensions (≥ 4 not on one plane); fitted on the training
    // touches when they suffice (else on all of the artefact's touches: the placement is projected out).
    let spans = |r: &[usize]| {
        r.len() >= 4 && axcomp_probe::geometry::check_not_coplanar(&pts(r), &labels(r)).is_ok()
    };
    let fit_rows = if spans(&tr) {
        Some(tr.clone())
    } else if spans(rows) {
        Some(rows.to_vec())
    } else {
        None
    };
    let mut fit = ArtefactFit {
        name: name.to_string(),
        shape: "planar",
        reference_mm: [0.0; 3],
        radius_mm: 0.0,
        train_touches: tr.len(),
        holdout_touches: ho.len(),
        placement: if tr.is_empty() { "projected" } else { "base" },
    };
    let cols = match fit_rows {
        Some(fr) => sphere(d, name, rows, &pts(&fr), &mut fit, lin)?,
        None => planar(d, rows, &mut fit, lin),
    };
    if tr.is_empty() {
        let b = orthonormal(cols, &ho);
        lin.projections.push((ho, b));
    } else {
        let b = orthonormal(cols, rows);
        lin.base_terms.push((
            "artefact_placement".to_string(),
            params(&[("artefact", json!(name)), ("shape", json!(fit.shape))]),
            b.len(),
        ));
        lin.base_columns.extend(b);
    }
    lin.artefacts.push(fit);
    Ok(())
}

/// The artefact's placement columns on its rows: a size change along the normal (1), then a translation
/// (the normal's three components).
fn size_and_normal(n: usize, rows: &[usize], normal: &[[f64; 3]]) -> Vec<Vec<f64>> {
    let mut size = vec![0.0; n];
    for &i in rows {
        size[i] = 1.0;
    }
    let mut out = vec![size];
    out.extend((0..3).map(|k| {
        let mut c = vec![0.0; n];
        for &i in rows {
            c[i] = normal[i][k];
        }
        c
    }));
    out
}

/// A sphere fitted to `fit_points`: residual `|p − C| − R`, radial normals; returns the placement columns.
fn sphere(
    d: &ProbeData,
    name: &str,
    rows: &[usize],
    fit_points: &[[f64; 3]],
    fit: &mut ArtefactFit,
    lin: &mut Linearised,
) -> Result<Vec<Vec<f64>>, DiagnoseError> {
    let s = axcomp_probe::geometric_sphere(fit_points, None)
        .map_err(|e| DiagnoseError::Invalid(format!("artefact `{name}`: sphere fit: {e}")))?;
    fit.shape = "sphere";
    fit.reference_mm = s.center_mm;
    fit.radius_mm = s.radius_mm;
    for &i in rows {
        let q = sub(d.touches[i].position_mm, s.center_mm);
        let l = norm(q);
        if l.is_nan() || l <= 0.0 {
            return Err(DiagnoseError::Invalid(format!(
                "{}: the touch is at the fitted sphere centre",
                d.labels[i]
            )));
        }
        lin.normal[i] = [q[0] / l, q[1] / l, q[2] / l];
        lin.y[i] = (l - s.radius_mm) * 1000.0;
    }
    Ok(size_and_normal(d.touches.len(), rows, &lin.normal))
}

/// A planar artefact (a plane, a ring gauge): residual `n·(p − p̄)` with `n = −u`; returns the placement
/// columns (size, the translations some touch approaches along, the rotations its shape shows).
fn planar(
    d: &ProbeData,
    rows: &[usize],
    fit: &mut ArtefactFit,
    lin: &mut Linearised,
) -> Vec<Vec<f64>> {
    let n = d.touches.len();
    let m = rows.len().max(1) as f64;
    let mut pbar = [0.0; 3];
    for &i in rows {
        #[allow(clippy::needless_range_loop)] // parallel arrays indexed together
        for k in 0..3 {
            pbar[k] += d.touches[i].position_mm[k] / m;
        }
    }
    fit.reference_mm = pbar;
    let normal = &mut lin.normal;
    for &i in rows {
        let u = d.touches[i].approach;
        normal[i] = [-u[0], -u[1], -u[2]];
        let q = sub(d.touches[i].position_mm, pbar);
        lin.y[i] = (0..3).map(|k| normal[i][k] * q[k]).sum::<f64>() * 1000.0;
    }
    let mut cols = size_and_normal(n, rows, normal);
    // A translation along a direction no touch approaches is left out (its column is noise).
    cols.retain(|c| rms_on(c, rows) >= 1e-3);
    // Small rotation ω of the artefact: n·(ω × q) = ω·(q × n), q in mm. A component that the artefact's
    // shape does not show (a ring's tilt: its touches have one height) comes out at the measured
    // residual's µm level: columns below 1e-3 of the artefact's extent are left out, so that no placement
    // column is built from what was measured.
    let qs: Vec<[f64; 3]> = rows
        .iter()
        .map(|&i| sub(d.touches[i].position_mm, pbar))
        .collect();
    let extent = (qs
        .iter()
        .map(|q| q[0] * q[0] + q[1] * q[1] + q[2] * q[2])
        .sum::<f64>()
        / qs.len().max(1) as f64)
        .sqrt();
    for k in 0..3 {
        let mut c = vec![0.0; n];
        for (q, &i) in qs.iter().zip(rows) {
            let nn = normal[i];
            let x = [
                q[1] * nn[2] - q[2] * nn[1],
                q[2] * nn[0] - q[0] * nn[2],
                q[0] * nn[1] - q[1] * nn[0],
            ];
            c[i] = x[k];
        }
        if rms_on(&c, rows) >= 1e-3 * extent {
            cols.push(c);
        }
    }
    cols
}
