//! Diagnosis on R-test (or probed sphere-centre) data of a five-axis machine: the location-error model
//! fitted on the training poses, the held-out gap, and which unmodelled effect of the contract's R-test
//! vocabulary ([`RotaryEffect`]) explains it.
//!
//! Glossary:
//! - **row**: one displacement component of one pose; the three components `dx`, `dy`, `dz` (µm) of every
//!   pose are stacked (row `3·pose + component`) and the `component` (0, 1, 2) is a `where` variable.
//! - **base model** (`location_errors`): the 11 location errors and the set-up offsets fitted by
//!   `axcomp_rtest::fit` (Levenberg–Marquardt on the exact HTM model) on the training poses, then
//!   *linearised at that fit*: the target is the measured displacement minus the fitted model, the base
//!   columns are the sensitivity (Jacobian) columns of the parameters the training poses determine
//!   (`axcomp_rtest::sensitivity_matrix`). Refitting base + candidate columns by least squares is the
//!   Gauss–Newton step of the whole model with the candidate added.
//! - **candidate families** (first-order signatures of each effect, built from the data's columns only):
//!   - `rotary_positioning`: an angular positioning error of C (harmonics 0…K of the C angle) and of the
//!     tilt axis (a polynomial in the tilt angle), each mapped through the derivative of the exact
//!     displacement with respect to that axis's angle (central differences of
//!     `FiveAxis::displacement_at`).
//!   - `rotary_wobble`: the C axis tilting about the two axes perpendicular to it and moving radially
//!     (run-out), each varying as `cos kc`, `sin kc` (k = 1…3): small rotations / translations of what C
//!     carries (trunnion: the table, in the frame the tilt axis carries; head: the tool); or the tilt axis
//!     (A or B) tilting about its two perpendicular axes and moving radially as powers 1…2 of its angle
//!     (what `fit rtest --effects rotary_wobble` also fits).
//!   - `linear_geometry`: low-order (Legendre degree 1…3) errors of the tool point along X, Y, Z as
//!     functions of the linear axes' positions (positioning and straightness).
//!
//!   The columns of these three are the signatures of `axcomp_rtest::effects` (the terms `fit rtest
//!   --effects` fits), at the training fit.
//!   - `setup_drift`: the sphere moving with time (linear or quadratic in `time_s`), along the table frame
//!     for trunnions (the sphere's own set-up columns times time), the machine frame for a head.
//!   - `thermal_drift`: the tool point moving along machine X, Y, Z in proportion to the temperature rises
//!     of the `*_degC` columns (and, as a variant, the sphere in the table frame).
//!   - `time_drift`: the tool point moving along machine X, Y, Z with time, with no temperature behind it.
//! - **same signature**: two candidates whose columns span the same space together with the base model on
//!   these poses (e.g. `setup_drift` and `time_drift` on a head, where the sphere and the tool share the
//!   machine frame): the data cannot tell them apart; the result says so (`ties`, `note`).
//!
//! The verdict is the one rule of [`crate::judge`]; this module only builds the columns.

use std::collections::BTreeMap;

use axcomp_effects::RotaryEffect;
use axcomp_kinematics::rotary::N_LOCATION;
use axcomp_rtest::RtestData;
use nalgebra::DMatrix;
use serde::Serialize;
use serde_json::{Map, json};

mod families;
mod observations;

use crate::error::DiagnoseError;
pub use observations::{RtestFamily, RtestObservations, RtestVariant};

/// The stacked campaign: target, base columns, rows and `where` variables.
#[derive(Debug, Clone)]
pub struct RtestCampaign {
    /// Measured − fitted location-error model, µm, stacked (`3·pose + component`).
    pub y: Vec<f64>,
    /// Sensitivity columns of the estimated parameters, stacked.
    pub base_columns: Vec<Vec<f64>>,
    /// Names of the base columns (ISO 230-7 names, set-up offsets, then the told effects' columns).
    pub base_names: Vec<String>,
    pub train: Vec<usize>,
    pub holdout: Vec<usize>,
    /// Training rows grouped by (path, run): blocks for blocked CV and the block bootstrap.
    pub blocks: Vec<Vec<usize>>,
    /// `component`, `c_deg`, `a_deg`|`b_deg`, `time_s` per stacked row.
    pub where_variables: Vec<(String, Vec<f64>)>,
    /// The location-error fit on the training poses.
    pub fit: axcomp_rtest::Fit,
    /// Candidate kinds not considered, with the reason (missing columns).
    pub not_applicable: Vec<(RotaryEffect, String)>,
    /// Candidate families (every kind not in the model that the columns allow).
    pub families: Vec<RtestFamily>,
}

/// What the told model holds (`--model`): `location_errors` and optionally effect kinds of the R-test
/// vocabulary added to it (their richest variant).
pub fn parse_model(list: &str) -> Result<Vec<RotaryEffect>, DiagnoseError> {
    let mut has_base = false;
    let mut kinds = Vec::new();
    for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        if name == axcomp_effects::campaign_kinds::base_model::LOCATION_ERRORS {
            has_base = true;
            continue;
        }
        let k: RotaryEffect = name.parse().map_err(|e| {
            DiagnoseError::Model(format!(
                "{e}; the base model of R-test data is `location_errors`"
            ))
        })?;
        if !kinds.contains(&k) {
            kinds.push(k);
        }
    }
    if !has_base {
        return Err(DiagnoseError::Model(format!(
            "R-test data: the model must hold `location_errors` (the identified location errors), e.g. `--model location_errors`; got `{list}`"
        )));
    }
    Ok(kinds)
}
/// Builds the stacked campaign and the candidate families. `model` = effect kinds told in addition to
/// `location_errors`.
pub fn campaign(
    obs: &RtestObservations,
    model: &[RotaryEffect],
) -> Result<RtestCampaign, DiagnoseError> {
    obs.validate()?;
    let data = &obs.data;
    let machine = data.machine;
    let n = obs.n_poses();
    let train_poses: Vec<usize> = (0..n).filter(|&i| !obs.held_out[i]).collect();
    let fit = axcomp_rtest::fit(data, &train_poses).map_err(|e| {
        DiagnoseError::Invalid(format!("location-error fit on the training poses: {e}"))
    })?;
    // Target: measured − fitted exact model.
    let mut y = Vec::with_capacity(3 * n);
    for i in 0..n {
        let m =
            axcomp_rtest::model_displacement(&machine, &data.poses[i], data.setup[i], &fit.theta);
        #[allow(clippy::needless_range_loop)] // parallel arrays indexed together
        for c in 0..3 {
            y.push(data.d_um[i][c] - m[c]);
        }
    }
    // Base: the sensitivity columns of the estimated parameters.
    let ns = data.setup_names.len();
    let j = axcomp_rtest::sensitivity_matrix(&machine, &data.poses, &data.setup, ns);
    let names = data.param_names();
    let mut base_columns = Vec::new();
    let mut base_names = Vec::new();
    #[allow(clippy::needless_range_loop)] // parallel arrays indexed together
    for k in 0..j.ncols() {
        if fit.ident.estimated[k] {
            base_columns.push(j.column(k).iter().cloned().collect::<Vec<f64>>());
            base_names.push(names[k].clone());
        }
    }
    let stacked = |rows: &[usize]| -> Vec<usize> {
        rows.iter()
            .flat_map(|&i| [3 * i, 3 * i + 1, 3 * i + 2])
            .collect()
    };
    let train = stacked(&train_poses);
    let holdout = stacked(&(0..n).filter(|&i| obs.held_out[i]).collect::<Vec<_>>());
    // Blocks: (path, run) groups of training poses, in order of first appearance.
    let mut keys: Vec<(String, String)> = Vec::new();
    let mut blocks: Vec<Vec<usize>> = Vec::new();
    for &i in &train_poses {
        let key = (data.path[i].clone(), obs.run[i].clone());
        let b = match keys.iter().position(|k| *k == key) {
            Some(b) => b,
            None => {
                keys.push(key);
                blocks.push(Vec::new());
                keys.len() - 1
            }
        };
        blocks[b].extend([3 * i, 3 * i + 1, 3 * i + 2]);
    }
    let per_row = |f: &dyn Fn(usize) -> f64| -> Vec<f64> { (0..3 * n).map(|r| f(r / 3)).collect() };
    let mut where_variables = vec![
        (
            "component".to_string(),
            (0..3 * n).map(|r| (r % 3) as f64).collect::<Vec<f64>>(),
        ),
        ("c_deg".to_string(), per_row(&|i| data.poses[i].c_deg)),
        (
            format!("{}_deg", machine.kind.tilt_letter()),
            per_row(&|i| data.poses[i].tilt_deg),
        ),
    ];
    if let Some(t) = &obs.time_s {
        where_variables.push(("time_s".to_string(), per_row(&|i| t[i])));
    }

    let families::Families {
        families,
        mut not_applicable,
    } = families::Builder {
        obs,
        fit: &fit,
        j: &j,
    }
    .build();
    // The told effects join the base (their richest variant); they are no candidates.
    let mut candidates = Vec::new();
    for f in families {
        if model.contains(&f.kind) {
            let v = f
                .variants
                .iter()
                .max_by_key(|v| v.columns.len())
                .expect("a family has variants");
            for (c, col) in v.columns.iter().enumerate() {
                base_columns.push(col.clone());
                base_names.push(format!("{}[{c}]", f.kind));
            }
        } else {
            candidates.push(f);
        }
    }
    for k in model {
        if let Some(pos) = not_applicable.iter().position(|(kk, _)| kk == k) {
            return Err(DiagnoseError::Invalid(format!(
                "model effect `{k}` cannot be built from this data: {}",
                not_applicable[pos].1
            )));
        }
    }
    not_applicable.retain(|(k, _)| !model.contains(k));
    Ok(RtestCampaign {
        y,
        base_columns,
        base_names,
        train,
        holdout,
        blocks,
        where_variables,
        fit,
        not_applicable,
        families: candidates,
    })
}

/// Whether the columns `extra` add nothing to the span of `base` (relative residual < 1e-6 each).
fn in_span(base: &[&[f64]], extra: &[&[f64]]) -> bool {
    if extra.is_empty() {
        return true;
    }
    if base.is_empty() {
        return false;
    }
    let rows = base[0].len();
    let a = DMatrix::from_fn(rows, base.len(), |r, c| base[c][r]);
    let svd = a.svd(true, true);
    extra.iter().all(|col| {
        let b = nalgebra::DVector::from_column_slice(col);
        let norm = b.norm();
        if norm == 0.0 {
            return true;
        }
        match svd.solve(&b, 1e-10 * svd.singular_values.max()) {
            Ok(x) => {
                let r = &b - DMatrix::from_fn(rows, base.len(), |r, c| base[c][r]) * x;
                r.norm() <= 1e-6 * norm
            }
            Err(_) => false,
        }
    })
}

/// Pairs of candidate kinds with the same signature on these poses (see the glossary): their richest
/// variants span the same space together with the base columns.
pub fn same_signatures(c: &RtestCampaign) -> Vec<(RotaryEffect, RotaryEffect)> {
    let mut out = Vec::new();
    let richest = |f: &RtestFamily| -> Vec<Vec<f64>> {
        f.variants
            .iter()
            .max_by_key(|v| v.columns.len())
            .map(|v| v.columns.clone())
            .unwrap_or_default()
    };
    let cols: Vec<Vec<Vec<f64>>> = c.families.iter().map(richest).collect();
    for a in 0..c.families.len() {
        for b in a + 1..c.families.len() {
            fn with<'a>(base: &'a [Vec<f64>], x: &'a [Vec<f64>]) -> Vec<&'a [f64]> {
                base.iter().chain(x).map(|v| v.as_slice()).collect()
            }
            let ea: Vec<&[f64]> = cols[a].iter().map(|v| v.as_slice()).collect();
            let eb: Vec<&[f64]> = cols[b].iter().map(|v| v.as_slice()).collect();
            if in_span(&with(&c.base_columns, &cols[a]), &eb)
                && in_span(&with(&c.base_columns, &cols[b]), &ea)
            {
                out.push((c.families[a].kind, c.families[b].kind));
            }
        }
    }
    out
}

/// The location-error fit in the result: identified parameters with their values.
#[derive(Debug, Clone, Serialize)]
pub struct BaseFit {
    pub machine: String,
    /// ISO 230-7 name → value (µm or µrad), `null` when not estimated.
    pub location_errors: BTreeMap<String, Option<f64>>,
    /// Parameters the training poses determine (estimated).
    pub estimated: Vec<String>,
    pub condition_number: f64,
    pub fit_rms_um: f64,
}

impl BaseFit {
    pub fn of(c: &RtestCampaign, data: &RtestData) -> BaseFit {
        let names = data.param_names();
        BaseFit {
            machine: data.machine.kind.name().to_string(),
            location_errors: (0..N_LOCATION)
                .map(|k| {
                    (
                        names[k].clone(),
                        c.fit.ident.estimated[k].then_some(c.fit.theta[k]),
                    )
                })
                .collect(),
            estimated: names
                .iter()
                .enumerate()
                .filter(|(k, _)| c.fit.ident.estimated[*k])
                .map(|(_, n)| n.clone())
                .collect(),
            condition_number: c.fit.ident.condition_number,
            fit_rms_um: c.fit.fit_rms_um,
        }
    }
}

/// The R-test diagnosis (`--json` writes it): the contract's `gap`, `where`, `effects`, `verdict` (the
/// shared [`crate::judge`] result, flattened) plus the location-error fit and the candidate pairs the
/// data cannot tell apart.
#[derive(Debug, Clone, Serialize)]
pub struct RtestDiagnosis {
    /// Always `"rtest"`.
    pub data_kind: &'static str,
    /// The location-error fit the base model is linearised at.
    pub base_fit: BaseFit,
    /// Candidate pairs with the same signature on these poses (see the module glossary).
    pub same_signature: Vec<[String; 2]>,
    #[serde(flatten)]
    pub diagnosis: crate::judge::Diagnosis,
}

/// Tie-break rank of a kind among candidates with as many parameters (lower = preferred): a physical
/// cause with its own input before a generic one.
fn simplicity(k: RotaryEffect) -> u8 {
    match k {
        RotaryEffect::ThermalDrift => 1,
        RotaryEffect::SetupDrift => 2,
        RotaryEffect::RotaryPositioning => 2,
        RotaryEffect::RotaryWobble => 3,
        RotaryEffect::LinearGeometry => 3,
        RotaryEffect::TimeDrift => 4,
    }
}

/// Runs the diagnosis on R-test observations with the told model (`location_errors` + `model`); returns
/// the result and the stacked campaign (for reports and oracle refits).
pub fn diagnose(
    obs: &RtestObservations,
    model: &[RotaryEffect],
    opts: &crate::judge::DiagnoseOptions,
) -> Result<(RtestDiagnosis, RtestCampaign), DiagnoseError> {
    use crate::judge::{self, CandidateFamily, ModelTerm};
    let c = campaign(obs, model)?;
    let n_rows = c.y.len();
    // Base: an intercept-free location-error model (its set-up offsets are the constants).
    let mut terms = vec![ModelTerm {
        kind: axcomp_effects::campaign_kinds::base_model::LOCATION_ERRORS.to_string(),
        params: json!({"linearised_at": "the training fit", "parameters": c.base_names.iter().filter(|n| !n.contains('[')).collect::<Vec<_>>()})
            .as_object()
            .cloned()
            .unwrap_or_default(),
        columns: c.base_names.iter().filter(|n| !n.contains('[')).count(),
    }];
    for k in model {
        let prefix = format!("{k}[");
        terms.push(ModelTerm {
            kind: k.name().to_string(),
            params: Map::new(),
            columns: c
                .base_names
                .iter()
                .filter(|n| n.starts_with(&prefix))
                .count(),
        });
    }
    let time_order: Vec<usize> = match &obs.time_s {
        Some(t) => {
            let mut rows = c.train.clone();
            rows.sort_by(|&a, &b| t[a / 3].total_cmp(&t[b / 3]).then(a.cmp(&b)));
            rows
        }
        None => c.train.clone(),
    };
    let jc = judge::Campaign {
        target: "dx_um, dy_um, dz_um (stacked)".to_string(),
        y: &c.y,
        base_columns: c.base_columns.clone(),
        model: terms,
        train: c.train.clone(),
        holdout: c.holdout.clone(),
        blocks: c.blocks.clone(),
        where_variables: c.where_variables.clone(),
        position_order: None,
        time_order,
        not_applicable: crate::judge::not_applicable_lines(&c.not_applicable),
    };
    let families: Vec<CandidateFamily> = c
        .families
        .iter()
        .map(|f| {
            let mut fam = f.candidate(f.kind.name(), simplicity(f.kind));
            fam.last_resort = f.kind == RotaryEffect::TimeDrift;
            fam
        })
        .collect();
    debug_assert!(c.families.iter().all(|f| {
        f.variants
            .iter()
            .all(|v| v.columns.iter().all(|col| col.len() == n_rows))
    }));
    let mut d = judge::judge(&jc, &families, opts)?;
    // Candidates the data cannot tell apart: reported as ties of each other, and said in the note.
    let same = same_signatures(&c);
    for (a, b) in &same {
        for (x, y) in [(a, b), (b, a)] {
            if d.verdict == x.name() && !d.ties.iter().any(|t| t == y.name()) {
                d.ties.push(y.name().to_string());
                d.note.push_str(&format!(
                    " `{x}` and `{y}` have the same signature on these poses: the data cannot tell them apart (a tie, not a choice)."
                ));
            }
        }
    }
    let base_fit = BaseFit::of(&c, &obs.data);
    Ok((
        RtestDiagnosis {
            data_kind: "rtest",
            base_fit,
            same_signature: same
                .iter()
                .map(|(a, b)| [a.name().to_string(), b.name().to_string()])
                .collect(),
            diagnosis: d,
        },
        c,
    ))
}

/// The report: `diagnosis.md` and `heldout_components.svg` (the held-out residual of each displacement
/// component, pose by pose, before and after the verdict's refit). Returns (file name, bytes).
pub fn report_files(d: &RtestDiagnosis, c: &RtestCampaign) -> Vec<(String, Vec<u8>)> {
    use std::fmt::Write;
    let dg = &d.diagnosis;
    let after = dg
        .effects
        .iter()
        .find(|e| e.kind == dg.verdict)
        .map(|e| &e.residual_after);
    let mut md = String::new();
    let _ = writeln!(md, "# Diagnosis of R-test data ({})\n", d.base_fit.machine);
    let _ = writeln!(
        md,
        "Base model: `location_errors` fitted on {} training rows ({} poses × dx, dy, dz) by Levenberg–Marquardt on the exact HTM model (fit RMS {:.3} µm, condition number {:.1}), linearised at that fit; estimated: {}.\n",
        dg.n_train,
        dg.n_train / 3,
        d.base_fit.fit_rms_um,
        d.base_fit.condition_number,
        d.base_fit.estimated.join(", ")
    );
    let _ = writeln!(
        md,
        "Gap: training RMS {:.3} µm, held-out RMS {:.3} µm, held-out max {:.3} µm ({} held-out rows).\n",
        dg.gap.train_rms_um, dg.gap.holdout_rms_um, dg.gap.holdout_max_um, dg.n_holdout
    );
    let _ = writeln!(md, "**Verdict: `{}`** — {}\n", dg.verdict, dg.note);
    if !dg.ties.is_empty() {
        let _ = writeln!(
            md,
            "Ties (indistinguishable on the held-out rows): {}.\n",
            dg.ties.join(", ")
        );
    }
    for [a, b] in &d.same_signature {
        let _ = writeln!(
            md,
            "- `{a}` and `{b}` have the same signature on these poses: the data cannot tell them apart."
        );
    }
    if !d.same_signature.is_empty() {
        md.push('\n');
    }
    md.push_str(
        "## Where the held-out gap lies\n\n| variable | from | to | share |\n|---|---|---|---|\n",
    );
    for r in &dg.where_ {
        let _ = writeln!(
            md,
            "| {} | {:.4} | {:.4} | {:.1} % |",
            r.variable,
            r.from,
            r.to,
            100.0 * r.share
        );
    }
    md.push_str("\n(`component`: 0 = dx, 1 = dy, 2 = dz.)\n\n## Candidates (refit of the whole model with each)\n\n| kind | score | held-out RMS after (µm) | shrink | train p (Bonferroni) | material | explains | params |\n|---|---|---|---|---|---|---|---|\n");
    for e in &dg.effects {
        let params: Vec<String> = e
            .params
            .iter()
            .filter(|(k, _)| k.as_str() != "coefficients")
            .map(|(k, v)| format!("{k}={v}"))
            .collect();
        let _ = writeln!(
            md,
            "| {} | {:.1} | {:.3} | {:.1} % | {:.2e} | {} | {} | {} |",
            e.kind,
            e.score,
            e.holdout_rms_after_um,
            e.shrink_pct,
            e.train_p_value,
            e.material,
            e.explains,
            params.join(", ")
        );
    }
    if !dg.not_applicable.is_empty() {
        let _ = writeln!(md, "\nNot considered: {}.", dg.not_applicable.join("; "));
    }
    let _ = writeln!(md, "\nVerdict rule: {}\n", dg.verdict_rule);
    md.push_str("![held-out residual per component](heldout_components.svg)\n");
    // Figure: held-out poses in measurement order, one panel per component.
    let hold_poses: Vec<usize> = c
        .holdout
        .iter()
        .filter(|&&r| r % 3 == 0)
        .map(|&r| r / 3)
        .collect();
    let x: Vec<f64> = (0..hold_poses.len()).map(|k| k as f64).collect();
    let mut figs = Vec::new();
    for (comp, name) in ["dx", "dy", "dz"].iter().enumerate() {
        let mut f = axcomp_plot::Figure::new(
            &format!(
                "Held-out {name}: measured − location-error model, RMS {:.3} µm over all components{}",
                dg.gap.holdout_rms_um,
                dg.verdict_candidate().map_or(String::new(), |k| format!(
                    ", {:.3} µm after adding {}",
                    k.holdout_rms_after_um, dg.verdict
                ))
            ),
            "held-out pose (measurement order)",
            &axcomp_plot::label(&format!("residual {name}"), "µm"),
        );
        let before: Vec<f64> = hold_poses.iter().map(|&i| c.y[3 * i + comp]).collect();
        f.points("before (location errors)", &x, &before);
        if let Some(a) = after {
            let av: Vec<f64> = hold_poses.iter().map(|&i| a[3 * i + comp]).collect();
            f.points(&format!("after adding {}", dg.verdict), &x, &av);
        }
        f.hline(0.0, "");
        figs.push(f);
    }
    let refs: Vec<&axcomp_plot::Figure> = figs.iter().collect();
    vec![
        ("diagnosis.md".to_string(), md.into_bytes()),
        (
            "heldout_components.svg".to_string(),
            axcomp_plot::panels_svg(&refs, 1).into_bytes(),
        ),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;
    use axcomp_kinematics::rotary::FiveAxis;
    use axcomp_kinematics::rotary::{MachineKind, N_SETUP, c_circle, k4_path};
    use axcomp_rtest::effects::{angle_derivative, c_carried_rotation, geometry};
    use nalgebra::Vector3;

    fn observations(kind: MachineKind) -> RtestObservations {
        let m = FiveAxis::new(kind, 250.0);
        let s = if kind == MachineKind::BcHead {
            [0.0, 0.0, 0.0]
        } else {
            [120.0, 80.0, 100.0]
        };
        let mut poses = k4_path(&m, s, -60.0, 72);
        poses.extend(c_circle(&m, s, 0.0, 36));
        poses.extend(c_circle(&m, s, -60.0, 36));
        poses.extend(k4_path(&m, s, -60.0, 72));
        let n = poses.len();
        // Deterministic pseudo-noise (readings only matter for the fit, not for the signatures).
        let d_um = (0..n)
            .map(|i| [0, 1, 2].map(|c| ((i * 3 + c) as f64 * 0.7).sin() * 0.3))
            .collect();
        let data = RtestData {
            machine: m,
            source: "test".into(),
            poses,
            d_um,
            path: vec![String::new(); n],
            setup: vec![0; n],
            setup_names: vec!["1".into()],
            lines: (0..n).collect(),
            free_head_zero: false,
        };
        RtestObservations {
            data,
            held_out: (0..n).map(|i| i >= n - 72).collect(),
            run: (0..n)
                .map(|i| if i >= n - 72 { "2" } else { "1" }.to_string())
                .collect(),
            time_s: Some((0..n).map(|i| 6.0 * i as f64).collect()),
            temperatures: Vec::new(),
        }
    }

    /// Two independent computations of an angular positioning error's signature: central differences of
    /// the exact HTM displacement (`angle_derivative`) and the first-order rigid-body rotation of what the
    /// axis carries (C: `(Rt·ez) × p` on a trunnion, `−ez × (p − q)` on a head; tilt axis `e_t × p` on a
    /// trunnion). Tolerance 1e-6 µm/µrad (the location errors at zero; the differences' truncation error
    /// is O(h²) with h = 10 µrad).
    #[test]
    fn angle_derivative_is_the_rigid_rotation() {
        for kind in [
            MachineKind::AcTrunnion,
            MachineKind::BcTrunnion,
            MachineKind::BcHead,
        ] {
            let o = observations(kind);
            let m = o.data.machine;
            for pose in o.data.poses.iter().step_by(7) {
                let g = geometry(&m, pose);
                let dc = angle_derivative(&m, pose, &[0.0; N_LOCATION], [0.0; N_SETUP], 1);
                let want = c_carried_rotation(kind, &g, Vector3::z());
                for i in 0..3 {
                    assert!(
                        (dc[i] - want[i]).abs() < 1e-6,
                        "{kind:?} C: {dc:?} vs {want:?}"
                    );
                }
                if kind != MachineKind::BcHead {
                    let axis = if kind == MachineKind::AcTrunnion {
                        Vector3::x()
                    } else {
                        Vector3::y()
                    };
                    let dt = angle_derivative(&m, pose, &[0.0; N_LOCATION], [0.0; N_SETUP], 0);
                    let want = axis.cross(&g.p) * 1e-3;
                    for i in 0..3 {
                        assert!(
                            (dt[i] - want[i]).abs() < 1e-6,
                            "{kind:?} tilt: {dt:?} vs {want:?}"
                        );
                    }
                }
            }
        }
    }

    /// On a head the sphere and the tool drift share the machine frame: `setup_drift` and `time_drift` have
    /// the same signature (reported); on a trunnion the table turns the sphere's drift, so they differ.
    #[test]
    fn same_signature_of_setup_and_time_drift_on_a_head_only() {
        let head = campaign(&observations(MachineKind::BcHead), &[]).unwrap();
        assert!(
            same_signatures(&head).contains(&(RotaryEffect::SetupDrift, RotaryEffect::TimeDrift)),
            "{:?}",
            same_signatures(&head)
        );
        let trunnion = campaign(&observations(MachineKind::AcTrunnion), &[]).unwrap();
        assert!(
            same_signatures(&trunnion).is_empty(),
            "{:?}",
            same_signatures(&trunnion)
        );
        // No temperature column: thermal_drift is not applicable, and said so.
        assert!(
            trunnion
                .not_applicable
                .iter()
                .any(|(k, why)| *k == RotaryEffect::ThermalDrift && why.contains("_degC"))
        );
    }

    /// `--model`: `location_errors` is required; told effects leave the candidates and join the base.
    #[test]
    fn model_parsing_and_told_effects() {
        assert!(
            parse_model("setup_drift")
                .unwrap_err()
                .to_string()
                .contains("location_errors")
        );
        assert!(
            parse_model("location_errors,wobble")
                .unwrap_err()
                .to_string()
                .contains("`wobble`")
        );
        let k = parse_model("location_errors, setup_drift").unwrap();
        assert_eq!(k, [RotaryEffect::SetupDrift]);
        let o = observations(MachineKind::BcTrunnion);
        let plain = campaign(&o, &[]).unwrap();
        let told = campaign(&o, &k).unwrap();
        assert!(
            told.families
                .iter()
                .all(|f| f.kind != RotaryEffect::SetupDrift)
        );
        assert_eq!(told.base_columns.len(), plain.base_columns.len() + 6);
        assert!(
            campaign(&o, &[RotaryEffect::ThermalDrift])
                .unwrap_err()
                .to_string()
                .contains("_degC")
        );
    }
}
