//! Diagnosis on touch-probe data (contract "Effect kinds for geometry, rotary-axis and probe data"):
//! which unmodelled effect explains what the probe model misses on held-out touches.
//!
//! # Glossary
//! - **touch**: a latched stylus-tip centre `p`, its unit approach `u` (toward the surface), the probing
//!   speed `v` and the artefact touched ([`ProbeData`]).
//! - **normal** `n`: the artefact's outward surface normal at the touch; for a sphere the radial unit vector
//!   from its (linearisation) centre, for a planar artefact (a plane, a ring gauge) `−u`.
//! - **radial residual** `y` (µm, the target): for a sphere `|p − C₀| − R₀` about a geometric sphere fit
//!   (axcomp-probe) of the artefact's training touches; for a planar artefact `n·(p − p̄)`. A latched point
//!   that stays short of the surface has `y` larger, pretravel makes `y` smaller.
//! - **artefact placement** (nuisance): where an artefact stands and how big it is: the radial size
//!   (indicator column), a translation (`n_x, n_y, n_z`) and, for planar artefacts, a small rotation
//!   (`(q × n)`, `q = p − p̄`). These are linear in the residual (the linearised artefact fit); an artefact
//!   with training touches has them in the base model; an artefact touched only on held-out rows has them
//!   projected out of its held-out rows (its placement is not known from training, and says nothing about
//!   the probe), the target and every column alike, so the held-out prediction error is the radial
//!   residual about the artefact's own best placement.
//! - **base model** (`--model`): `probe_radius` = the placements (one effective radius: the intercept of
//!   each artefact's size); `probe_pretravel` = plus the pretravel by direction and speed that
//!   `axcomp-probe` calibrates (its best harmonic structure by cross-validation on the training sphere,
//!   columns from [`axcomp_probe::Structure::basis`]). Further probe effect kinds may be named to hold them
//!   too (`probe_radius,lobing`).
//! - **candidate families** (one per [`ProbeEffect`], columns over all rows):
//!   - `lobing`: azimuthal harmonics of the approach × cos²φ (3-lobe: orders 3; 3 + 6; 3 + 6 + the zonal
//!     cos²φ; 3 + 6 + 9 + zonal; a 4-lobe: 4 + 8 + zonal);
//!   - `speed_pretravel`: `v·cos²φ`, `v·sin²φ` (a lateral and an axial speed term; and × 3-lobe);
//!   - `latch_latency`: `v` (the latched point late by `v·latency` along the approach, the same in every
//!     direction);
//!   - `stylus_bending`: `cos φ` (the horizontal component of the approach) or `cos²φ`;
//!   - `machine_geometry`: `n_k·q_j` (degree 1) and `n_k·q_j²`, `n_k·q_j·q_l` (degree 2) with `q` the
//!     position scaled to the touched volume: the machine's low-order position-dependent error projected on
//!     the normal;
//!   - `thermal_drift`: `n_k·ΔT` (a drift of the tip relative to the artefacts) and `ΔT` (a size change) per
//!     `*_degC` sensor.
//!
//! # What touches can and cannot tell apart
//! Latch latency and a speed-linear pretravel both move the latched point along the approach by an amount
//! ∝ speed: `latch_latency` (`v`) lies inside `speed_pretravel`'s span (`v·cos²φ + v·sin²φ = v`). Only a
//! speed term that differs between lateral and axial touches is `speed_pretravel`; an isotropic one is
//! reported as `latch_latency` with `speed_pretravel` as a tie when both explain the gap. A linear machine
//! error on one sphere is a degree-2 pattern of the normal (like a 2-lobe or an elevation dependence) — only
//! artefacts at other places (a plane grid, a second sphere) tell it from the probe.

use crate::error::DiagnoseError;
use axcomp_effects::ProbeEffect;
use axcomp_probe::{DirSpeed, Touch};
use serde_json::{Map, Value, json};

mod artefacts;
mod families;

/// One candidate variant: its columns over all rows and its parameters (what the variant is).
pub type ProbeVariant = crate::judge::BuiltVariant;

/// A candidate effect kind and its variants.
pub type ProbeFamily = crate::judge::BuiltFamily<ProbeEffect>;

/// Touch data as plain columns, with the held-out mask.
#[derive(Debug, Clone)]
pub struct ProbeData {
    pub touches: Vec<Touch>,
    /// Artefact label per touch (one artefact when the file has none).
    pub artefact: Vec<String>,
    /// Run label per touch (blocks of the training rows), if any.
    pub run: Option<Vec<String>>,
    pub time_s: Option<Vec<f64>>,
    /// `*_degC` sensors: (name without the suffix, values).
    pub temperatures: Vec<(String, Vec<f64>)>,
    pub held_out: Vec<bool>,
    /// Names of the rows in messages (`file:line`).
    pub labels: Vec<String>,
}

/// The base model named by `--model`.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeModelSpec {
    /// `probe_pretravel` (else `probe_radius`).
    pub pretravel: bool,
    /// Further effect kinds held by the model.
    pub extra: Vec<ProbeEffect>,
}

impl ProbeModelSpec {
    /// Parses `probe_radius|probe_pretravel[,KIND,...]`.
    pub fn parse(list: &str) -> Result<Self, DiagnoseError> {
        let mut base = None;
        let mut extra = Vec::new();
        for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            match name {
                axcomp_effects::campaign_kinds::base_model::PROBE_RADIUS
                | axcomp_effects::campaign_kinds::base_model::PROBE_PRETRAVEL => {
                    if base.is_some() {
                        return Err(DiagnoseError::Model(format!(
                            "`{list}`: name one base model (`probe_radius` or `probe_pretravel`), not two"
                        )));
                    }
                    base =
                        Some(name == axcomp_effects::campaign_kinds::base_model::PROBE_PRETRAVEL);
                }
                _ => {
                    let k: ProbeEffect = name.parse().map_err(|e| {
                        DiagnoseError::Model(format!(
                            "{e}; the base model is `probe_radius` or `probe_pretravel`"
                        ))
                    })?;
                    if !extra.contains(&k) {
                        extra.push(k);
                    }
                }
            }
        }
        let pretravel = base.ok_or_else(|| {
            DiagnoseError::Model(format!(
                "`{list}`: probe touches need a base model, `probe_radius` (one effective radius) or \
                 `probe_pretravel` (pretravel by direction and speed), optionally followed by effect kinds"
            ))
        })?;
        Ok(ProbeModelSpec { pretravel, extra })
    }
}

/// One campaign ready for the verdict rule: target, base columns, candidate families, rows.
#[derive(Debug, Clone)]
pub struct ProbeCampaign {
    /// Radial residual, µm (held-out rows of held-out-only artefacts with their placement projected out).
    pub y: Vec<f64>,
    pub base_columns: Vec<Vec<f64>>,
    /// What the base model holds (for the JSON): `[{kind, params, columns}]`.
    pub base_terms: Vec<(String, Map<String, Value>, usize)>,
    pub train: Vec<usize>,
    pub holdout: Vec<usize>,
    /// Run index per row (for blocked checks), if the file has runs.
    pub blocks: Option<Vec<usize>>,
    /// Where the gap may lie: `azimuth_deg`, `elevation_deg`, `feed_mm_min`, `time_s`, `artefact` index.
    pub where_variables: Vec<(String, Vec<f64>)>,
    pub families: Vec<ProbeFamily>,
    /// Kinds held by the model (not candidates).
    pub held: Vec<ProbeEffect>,
    /// Kinds not considered, with why.
    pub not_applicable: Vec<(ProbeEffect, String)>,
    /// What the data cannot determine (for the note).
    pub notes: Vec<String>,
    /// Linearisation per artefact: (name, kind, centre or reference point, radius or 0, training touches).
    pub artefacts: Vec<ArtefactFit>,
}

/// How one artefact's touches were linearised.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ArtefactFit {
    pub name: String,
    /// `sphere` or `planar` (a plane or a ring gauge: touches on one plane).
    pub shape: &'static str,
    /// Sphere centre (fitted) or the touches' mean position, mm.
    pub reference_mm: [f64; 3],
    /// Fitted sphere radius of the latched points (sphere radius + effective stylus radius), mm; 0 for planar.
    pub radius_mm: f64,
    pub train_touches: usize,
    pub holdout_touches: usize,
    /// `base` (placement fitted on training rows) or `projected` (held-out only: placement projected out).
    pub placement: &'static str,
}

fn rms_on(c: &[f64], rows: &[usize]) -> f64 {
    let ss: f64 = rows.iter().map(|&i| c[i] * c[i]).sum();
    (ss / rows.len().max(1) as f64).sqrt()
}

/// Orthonormal basis (on `rows`) of `cols` (each zero outside `rows`), columns scaled to unit RMS first,
/// directions below `1e-7` relative dropped (modified Gram–Schmidt, twice).
fn orthonormal(cols: Vec<Vec<f64>>, rows: &[usize]) -> Vec<Vec<f64>> {
    let mut basis: Vec<Vec<f64>> = Vec::new();
    for mut c in cols {
        let s = rms_on(&c, rows);
        if s.is_nan() || s <= 1e-300 {
            continue;
        }
        for &i in rows {
            c[i] /= s;
        }
        for _ in 0..2 {
            for b in &basis {
                let d: f64 = rows.iter().map(|&i| c[i] * b[i]).sum();
                for &i in rows {
                    c[i] -= d * b[i];
                }
            }
        }
        let l: f64 = rows.iter().map(|&i| c[i] * c[i]).sum::<f64>().sqrt();
        if l > 1e-7 * (rows.len() as f64).sqrt() {
            for &i in rows {
                c[i] /= l;
            }
            basis.push(c);
        }
    }
    basis
}

/// Removes from `v` (on `rows`) its projection on the orthonormal `basis`.
fn project_out(v: &mut [f64], basis: &[Vec<f64>], rows: &[usize]) {
    for b in basis {
        let d: f64 = rows.iter().map(|&i| v[i] * b[i]).sum();
        for &i in rows {
            v[i] -= d * b[i];
        }
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

fn params(pairs: &[(&str, Value)]) -> Map<String, Value> {
    pairs
        .iter()
        .map(|(k, v)| ((*k).to_string(), v.clone()))
        .collect()
}

/// Whether the probe data are usable: sizes, finite values, unit approach vectors, a non-empty split.
pub fn validate(d: &ProbeData) -> Result<(), DiagnoseError> {
    let n = d.touches.len();
    if d.artefact.len() != n || d.held_out.len() != n || d.labels.len() != n {
        return Err(DiagnoseError::Invalid(
            "touch columns of different lengths".into(),
        ));
    }
    axcomp_probe::validate_touches(&d.touches, &d.labels)
        .map_err(|e| DiagnoseError::Invalid(e.to_string()))?;
    if let Some(t) = &d.time_s {
        if let Some(i) = (0..n).find(|&i| !t[i].is_finite()) {
            return Err(DiagnoseError::Invalid(format!(
                "{}: time_s is {} (not a finite number)",
                d.labels[i], t[i]
            )));
        }
    }
    for (name, v) in &d.temperatures {
        if let Some(i) = (0..n).find(|&i| !v[i].is_finite()) {
            return Err(DiagnoseError::Invalid(format!(
                "{}: {name}_degC is {} (not a finite number)",
                d.labels[i], v[i]
            )));
        }
    }
    crate::obs::check_holdout(&d.held_out, "--holdout", "touch")
}

/// Builds the campaign: linearised radial residuals, the base model's columns and the candidate families.
pub fn build(d: &ProbeData, model: &ProbeModelSpec) -> Result<ProbeCampaign, DiagnoseError> {
    validate(d)?;
    let n = d.touches.len();
    let train: Vec<usize> = (0..n).filter(|&i| !d.held_out[i]).collect();
    let holdout: Vec<usize> = (0..n).filter(|&i| d.held_out[i]).collect();
    let ds: Vec<DirSpeed> = d.touches.iter().map(Touch::dir_speed).collect();

    let artefacts::Linearised {
        art,
        mut y,
        normal,
        mut base_columns,
        mut base_terms,
        projections,
        artefacts,
    } = artefacts::linearise(d)?;

    // The target before any projection (for the nominal positions below).
    let y_raw = y.clone();
    let inputs = families::Inputs::new(d, &train, &ds, &normal, &y_raw);
    let has_speed = inputs.has_speed;
    let families::Families {
        mut families,
        mut not_applicable,
        notes,
    } = families::build(&inputs);
    // ---- the base model: probe_pretravel and the named kinds ----
    let mut held: Vec<ProbeEffect> = Vec::new();
    if model.pretravel {
        let (cols, term, kinds) = pretravel_term(d, &train, &artefacts, &art, &ds)?;
        held.extend(kinds);
        base_terms.push(term);
        base_columns.extend(cols);
    }
    for k in &model.extra {
        if let Some(pos) = families.iter().position(|f| f.kind == *k) {
            let f = families.remove(pos);
            // The richest variant holds the kind.
            let v = f
                .variants
                .into_iter()
                .max_by_key(|v| v.columns.len())
                .expect("a family has variants");
            base_terms.push((k.name().to_string(), v.params.clone(), v.columns.len()));
            base_columns.extend(v.columns);
        }
        if !held.contains(k) {
            held.push(*k);
        }
    }
    families.retain(|f| !held.contains(&f.kind));
    not_applicable.retain(|(k, _)| !held.contains(k));

    // ---- held-out-only artefacts: placement projected out of target and columns ----
    for (rows, b) in &projections {
        project_out(&mut y, b, rows);
        for c in base_columns.iter_mut() {
            project_out(c, b, rows);
        }
        for f in families.iter_mut() {
            for v in f.variants.iter_mut() {
                for c in v.columns.iter_mut() {
                    project_out(c, b, rows);
                }
            }
        }
    }

    Ok(ProbeCampaign {
        y,
        base_columns,
        base_terms,
        train,
        holdout,
        blocks: run_blocks(d),
        where_variables: where_variables(d, &ds, has_speed),
        families,
        held,
        not_applicable,
        notes,
        artefacts,
    })
}

/// A base term: (kind, params, number of columns).
type BaseTerm = (String, Map<String, Value>, usize);

/// `probe_pretravel`'s columns (the calibrated structure's basis without its constant), its term, and the
/// effect kinds the structure holds.
type PretravelTerm = (Vec<Vec<f64>>, BaseTerm, Vec<ProbeEffect>);

/// Builds the [`PretravelTerm`] from the structure calibrated on the training touches of one sphere.
fn pretravel_term(
    d: &ProbeData,
    train: &[usize],
    artefacts: &[ArtefactFit],
    art: &[usize],
    ds: &[DirSpeed],
) -> Result<PretravelTerm, DiagnoseError> {
    let n = ds.len();
    let mut held = Vec::new();
    let (structure, why) = pretravel_structure(d, train, artefacts, art)?;
    let p = structure.len();
    let mut phi = vec![0.0; p];
    let mut cols = vec![vec![0.0; n]; p];
    for i in 0..n {
        structure.basis(ds[i], &mut phi);
        for k in 0..p {
            cols[k][i] = phi[k];
        }
    }
    // The constant is each artefact's size (already in the placements).
    let cols: Vec<Vec<f64>> = cols
        .into_iter()
        .filter(|c| c.iter().any(|&x| (x - 1.0).abs() > 1e-12))
        .collect();
    if let axcomp_probe::Structure::Harmonic {
        max_order,
        elevation_degree,
        speed_terms,
    } = structure
    {
        if max_order >= 3 {
            held.push(ProbeEffect::Lobing);
        }
        if elevation_degree >= 1 {
            held.push(ProbeEffect::StylusBending);
        }
        if speed_terms >= 1 {
            held.push(ProbeEffect::LatchLatency);
        }
        if speed_terms >= 2 {
            held.push(ProbeEffect::SpeedPretravel);
        }
    }
    let term = (
        axcomp_effects::campaign_kinds::base_model::PROBE_PRETRAVEL.to_string(),
        params(&[
            ("structure", json!(structure.name())),
            ("chosen", json!(why)),
        ]),
        cols.len(),
    );
    Ok((cols, term, held))
}

/// Run index per row (blocks of the training rows), if the file has runs.
fn run_blocks(d: &ProbeData) -> Option<Vec<usize>> {
    d.run.as_ref().map(|r| {
        let mut u: Vec<&String> = Vec::new();
        r.iter()
            .map(|l| match u.iter().position(|x| *x == l) {
                Some(k) => k,
                None => {
                    u.push(l);
                    u.len() - 1
                }
            })
            .collect()
    })
}

/// Where the gap may lie: the approach's azimuth and elevation, the feed (when it varies or is given) and
/// time.
fn where_variables(d: &ProbeData, ds: &[DirSpeed], has_speed: bool) -> Vec<(String, Vec<f64>)> {
    let mut where_variables = vec![
        (
            "azimuth_deg".to_string(),
            ds.iter().map(|x| x.azimuth_deg()).collect(),
        ),
        (
            "elevation_deg".to_string(),
            ds.iter().map(|x| x.elevation_deg()).collect(),
        ),
    ];
    if has_speed || d.touches.iter().any(|t| t.feed_mm_min > 0.0) {
        where_variables.push((
            "feed_mm_min".to_string(),
            d.touches.iter().map(|t| t.feed_mm_min).collect(),
        ));
    }
    if let Some(t) = &d.time_s {
        where_variables.push(("time_s".to_string(), t.clone()));
    }
    where_variables
}

/// The pretravel structure of `probe_pretravel`: `axcomp-probe`'s calibration (best harmonic structure by
/// cross-validation) on the training touches of the sphere with the most training touches.
fn pretravel_structure(
    d: &ProbeData,
    train: &[usize],
    artefacts: &[ArtefactFit],
    art: &[usize],
) -> Result<(axcomp_probe::Structure, String), DiagnoseError> {
    let (a, fit) = artefacts
        .iter()
        .enumerate()
        .filter(|(_, f)| f.shape == "sphere" && f.train_touches > 0)
        .max_by_key(|(_, f)| f.train_touches)
        .ok_or_else(|| {
            DiagnoseError::Invalid(
                "probe_pretravel: no sphere among the training touches to calibrate the pretravel on"
                    .into(),
            )
        })?;
    let rows: Vec<usize> = train.iter().copied().filter(|&i| art[i] == a).collect();
    let touches: Vec<Touch> = rows.iter().map(|&i| d.touches[i]).collect();
    let labels: Vec<String> = rows.iter().map(|&i| d.labels[i].clone()).collect();
    // The sphere's diameter is not known here: the fitted radius of the latched points stands for sphere +
    // stylus (the effective radius then comes out near 0; the structure choice does not depend on it).
    let mut opts = axcomp_probe::CalibrationOptions::new(2.0 * fit.radius_mm);
    opts.model = axcomp_probe::ModelChoice::Harmonic;
    let r = axcomp_probe::calibrate(&touches, &labels, &opts).map_err(|e| {
        DiagnoseError::Invalid(format!(
            "probe_pretravel: calibration on `{}`: {e}",
            fit.name
        ))
    })?;
    Ok((r.calibration.structure.clone(), r.why.clone()))
}

/// The diagnosis of probe touches (`--json` writes this): the verdict rule's result plus what the probe data
/// add — how each artefact was linearised, what the model holds, what touches cannot tell apart.
#[derive(Debug, Clone, serde::Serialize)]
pub struct ProbeDiagnosis {
    /// Always `probe_touches`.
    pub data_kind: &'static str,
    #[serde(flatten)]
    pub diagnosis: crate::judge::Diagnosis,
    /// Effect kinds the model holds (not candidates).
    pub model_holds: Vec<String>,
    pub artefacts: Vec<ArtefactFit>,
    /// What these data cannot determine.
    pub cannot_tell: Vec<String>,
}

/// Simplicity rank of a kind for the tie rule (lower = simpler, preferred among candidates with as many
/// parameters): latch latency before speed pretravel (its special case), the probe's own effects before the
/// machine's.
fn simplicity(k: ProbeEffect) -> u8 {
    match k {
        ProbeEffect::LatchLatency | ProbeEffect::StylusBending => 1,
        ProbeEffect::SpeedPretravel | ProbeEffect::Lobing | ProbeEffect::ThermalDrift => 2,
        ProbeEffect::MachineGeometry => 3,
    }
}

/// Runs the verdict rule ([`crate::judge::judge`], one implementation for every data kind) on a probe
/// campaign.
pub fn diagnose(
    c: &ProbeCampaign,
    opts: &crate::DiagnoseOptions,
) -> Result<ProbeDiagnosis, DiagnoseError> {
    use crate::judge::{Campaign, CandidateFamily, ModelTerm};
    let mut time_order = c.train.clone();
    if let Some((_, t)) = c.where_variables.iter().find(|(n, _)| n == "time_s") {
        time_order.sort_by(|&a, &b| t[a].total_cmp(&t[b]));
    }
    let blocks: Vec<Vec<usize>> = match &c.blocks {
        Some(b) => {
            let k = b.iter().copied().max().map_or(0, |m| m + 1);
            let mut out = vec![Vec::new(); k];
            for &i in &c.train {
                out[b[i]].push(i);
            }
            out.retain(|v| !v.is_empty());
            out
        }
        None => Vec::new(),
    };
    let campaign = Campaign {
        target: "radial_residual_um".into(),
        y: &c.y,
        base_columns: c.base_columns.clone(),
        model: c
            .base_terms
            .iter()
            .map(|(kind, params, columns)| ModelTerm {
                kind: kind.clone(),
                params: params.clone(),
                columns: *columns,
            })
            .collect(),
        train: c.train.clone(),
        holdout: c.holdout.clone(),
        blocks,
        where_variables: c.where_variables.clone(),
        position_order: None,
        time_order,
        not_applicable: crate::judge::not_applicable_lines(&c.not_applicable),
    };
    let families: Vec<CandidateFamily> = c
        .families
        .iter()
        .map(|f| f.candidate(f.kind.name(), simplicity(f.kind)))
        .collect();
    let mut d = crate::judge::judge(&campaign, &families, opts)?;
    // Latch latency and an isotropic speed pretravel are the same columns' span on touches: say so.
    let lat = ProbeEffect::LatchLatency.name();
    let spd = ProbeEffect::SpeedPretravel.name();
    let both = [lat, spd]
        .iter()
        .all(|k| d.effects.iter().any(|e| e.kind == *k && e.explains));
    if both && (d.verdict == lat || d.verdict == spd) {
        d.note.push_str(if d.verdict == spd {
            "; latch_latency explains part of the gap too: on touches alone the two differ only by the speed \
             term's direction dependence, which is beyond noise here (speed_pretravel)"
        } else {
            "; speed_pretravel explains the gap too: on touches alone the two differ only by the speed term's \
             direction dependence, which is not beyond noise here, so the isotropic latch_latency is named"
        });
    }
    Ok(ProbeDiagnosis {
        data_kind: "probe_touches",
        diagnosis: d,
        model_holds: c.held.iter().map(|k| k.name().to_string()).collect(),
        artefacts: c.artefacts.clone(),
        cannot_tell: c.notes.clone(),
    })
}

/// The report: `diagnosis.md` and SVG figures of the held-out radial residual against the approach's
/// azimuth, elevation, the feed and time, before and after the verdict's refit.
pub fn report_files(
    dir: &std::path::Path,
    c: &ProbeCampaign,
    d: &ProbeDiagnosis,
) -> crate::error::Result<Vec<(std::path::PathBuf, Vec<u8>)>> {
    let dg = &d.diagnosis;
    let mut files = Vec::new();
    let after = dg.verdict_candidate().map(|k| &k.residual_after);
    let mut figs = Vec::new();
    for (name, v) in &c.where_variables {
        let xs: Vec<f64> = c.holdout.iter().map(|&i| v[i]).collect();
        if xs.iter().all(|x| (x - xs[0]).abs() < 1e-12) {
            continue;
        }
        let before: Vec<f64> = c.holdout.iter().map(|&i| dg.residual[i]).collect();
        let label = match name.as_str() {
            "azimuth_deg" => axcomp_plot::label("approach azimuth", "°"),
            "elevation_deg" => axcomp_plot::label("approach elevation", "°"),
            "feed_mm_min" => axcomp_plot::label("feed", "mm/min"),
            "time_s" => axcomp_plot::label("time", "s"),
            other => other.replace('_', " "),
        };
        let quantity = label.split(" (").next().unwrap_or(&label).to_string();
        let model = if d.model_holds.is_empty() {
            "one effective radius".to_string()
        } else {
            d.model_holds.join(", ")
        };
        let mut title = format!(
            "Held-out radial residual vs {quantity}: model ({model}) RMS {:.3} µm",
            dg.gap.holdout_rms_um
        );
        if let Some(k) = dg.verdict_candidate() {
            title += &format!(", with {} {:.3} µm", dg.verdict, k.holdout_rms_after_um);
        }
        let mut f =
            axcomp_plot::Figure::new(&title, &label, &axcomp_plot::label("radial residual", "µm"));
        f.points(&format!("model ({model})"), &xs, &before);
        if let Some(a) = after {
            let ys: Vec<f64> = c.holdout.iter().map(|&i| a[i]).collect();
            f.points(&format!("with {}", dg.verdict), &xs, &ys);
        }
        f.hline(0.0, "");
        let file = format!("holdout_vs_{name}.svg");
        files.push((dir.join(&file), f.to_svg().into_bytes()));
        figs.push(file);
    }
    let mut md = String::from("# Diagnosis of probe touches\n\n");
    md += &format!(
        "Target: the radial residual of each touch about its artefact (µm). Model holds: {}.\n\n",
        if d.model_holds.is_empty() {
            "one effective radius (probe_radius)".to_string()
        } else {
            d.model_holds.join(", ")
        }
    );
    md += &format!(
        "Gap: train RMS {:.3} µm, held-out RMS {:.3} µm, held-out max {:.3} µm ({} train / {} held-out touches).\n\n",
        dg.gap.train_rms_um, dg.gap.holdout_rms_um, dg.gap.holdout_max_um, dg.n_train, dg.n_holdout
    );
    md += &format!("**Verdict: {}** — {}\n\n", dg.verdict, dg.note);
    if !dg.ties.is_empty() {
        md += &format!("Ties: {}.\n\n", dg.ties.join(", "));
    }
    md += "| artefact | shape | train | held-out | placement |\n|---|---|---|---|---|\n";
    for a in &d.artefacts {
        md += &format!(
            "| {} | {} | {} | {} | {} |\n",
            a.name, a.shape, a.train_touches, a.holdout_touches, a.placement
        );
    }
    md += "\n| candidate | score | held-out RMS after (µm) | shrink | explains |\n|---|---|---|---|---|\n";
    for e in &dg.effects {
        md += &format!(
            "| {} | {:.1} | {:.3} | {:.1} % | {} |\n",
            e.kind, e.score, e.holdout_rms_after_um, e.shrink_pct, e.explains
        );
    }
    md += "\n| where | from | to | share |\n|---|---|---|---|\n";
    for r in &dg.where_ {
        md += &format!(
            "| {} | {:.4} | {:.4} | {:.1} % |\n",
            r.variable,
            r.from,
            r.to,
            100.0 * r.share
        );
    }
    if !d.cannot_tell.is_empty() {
        md += "\nWhat touches cannot tell:\n\n";
        for n in &d.cannot_tell {
            md += &format!("- {n}\n");
        }
    }
    md += &format!("\nVerdict rule: {}\n\n", dg.verdict_rule);
    for f in figs {
        md += &format!("![{f}]({f})\n\n");
    }
    files.push((dir.join("diagnosis.md"), md.into_bytes()));
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Touches of a sphere (centre `c`, latched radius `r` mm + `extra_um(n, v)` µm outward) on rings.
    fn sphere(
        c: [f64; 3],
        r: f64,
        name: &str,
        held_out: bool,
        feeds: &[f64],
        extra_um: &dyn Fn([f64; 3], f64) -> f64,
        d: &mut ProbeData,
    ) {
        for &f in feeds {
            for el in [0.0f64, 30.0, 60.0] {
                for k in 0..12 {
                    let (a, e) = ((30.0 * k as f64 + el).to_radians(), el.to_radians());
                    let n = [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()];
                    let l = r + extra_um(n, f / 60.0) * 1e-3;
                    d.touches.push(Touch {
                        position_mm: [c[0] + l * n[0], c[1] + l * n[1], c[2] + l * n[2]],
                        approach: [-n[0], -n[1], -n[2]],
                        feed_mm_min: f,
                    });
                    d.artefact.push(name.into());
                    d.held_out.push(held_out);
                    d.labels.push(format!("row {}", d.labels.len() + 2));
                }
            }
        }
    }

    fn empty() -> ProbeData {
        ProbeData {
            touches: vec![],
            artefact: vec![],
            run: None,
            time_s: None,
            temperatures: vec![],
            held_out: vec![],
            labels: vec![],
        }
    }

    #[test]
    fn model_names_parse_with_a_base_model_and_kinds() {
        let m = ProbeModelSpec::parse("probe_radius, lobing").unwrap();
        assert!(!m.pretravel);
        assert_eq!(m.extra, [ProbeEffect::Lobing]);
        assert!(ProbeModelSpec::parse("probe_pretravel").unwrap().pretravel);
        assert!(
            ProbeModelSpec::parse("lobing")
                .unwrap_err()
                .to_string()
                .contains("base model")
        );
        assert!(ProbeModelSpec::parse("probe_radius,probe_pretravel").is_err());
        assert!(
            ProbeModelSpec::parse("probe_radius,wobble")
                .unwrap_err()
                .to_string()
                .contains("wobble")
        );
    }

    #[test]
    fn held_out_sphere_placement_is_projected_out_and_columns_do_not_hold_the_target() {
        // Two exact spheres, a pretravel growing with speed (0.5 µm per mm/s along the approach): the
        // held-out sphere's own centre and size are unknown. Reference: the generating pretravel.
        let mut d = empty();
        let speed = |_: [f64; 3], v: f64| -0.5 * v;
        sphere(
            [100.0, 50.0, 20.0],
            14.0,
            "cal",
            false,
            &[100.0, 600.0],
            &speed,
            &mut d,
        );
        sphere(
            [160.0, 40.0, 15.0],
            11.0,
            "s2",
            true,
            &[200.0, 450.0],
            &speed,
            &mut d,
        );
        let c = build(&d, &ProbeModelSpec::parse("probe_radius").unwrap()).unwrap();
        assert_eq!(c.artefacts[1].placement, "projected");
        // The held-out target has zero mean (its size projected out) and is the speed term about its mean:
        // ±0.5·(450 − 200)/60/2 µm = ±1.0417 µm; tolerance 1e-6 µm (linearisation ~ δ²/R).
        let ho: Vec<f64> = c.holdout.iter().map(|&i| c.y[i]).collect();
        let m = ho.iter().sum::<f64>() / ho.len() as f64;
        assert!(m.abs() < 1e-6, "{m}");
        let peak = ho.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        assert!((peak - 0.5 * 250.0 / 120.0).abs() < 1e-6, "{peak}");
        // latch_latency's column explains it exactly (training fit, held-out prediction).
        let fam = c
            .families
            .iter()
            .find(|f| f.kind == ProbeEffect::LatchLatency)
            .unwrap();
        let mut cols = c.base_columns.clone();
        cols.extend(fam.variants[0].columns.iter().cloned());
        let fit = crate::lsq::fit(&cols, &c.y, &c.train);
        for &i in &c.holdout {
            assert!((c.y[i] - fit.predict(&cols, i)).abs() < 1e-6);
        }
        // Columns built from positions must not hold the target (`n·p = |p − C| + n·C` on a sphere): the
        // machine-geometry family cannot fit the speed term, its training residual stays > 0.5 µm RMS
        // (the term's RMS is ≈ 1.25 µm over 100 and 600 mm/min).
        let mg = c
            .families
            .iter()
            .find(|f| f.kind == ProbeEffect::MachineGeometry)
            .unwrap();
        let mut cols = c.base_columns.clone();
        cols.extend(mg.variants[0].columns.iter().cloned());
        let fit = crate::lsq::fit(&cols, &c.y, &c.train);
        let rms = (c
            .train
            .iter()
            .map(|&i| (c.y[i] - fit.predict(&cols, i)).powi(2))
            .sum::<f64>()
            / c.train.len() as f64)
            .sqrt();
        assert!(rms > 0.5, "{rms}");
        assert!(
            c.not_applicable
                .iter()
                .any(|(k, _)| *k == ProbeEffect::ThermalDrift)
        );
    }

    #[test]
    fn a_kind_in_the_model_is_no_candidate_and_bad_input_names_the_row() {
        let mut d = empty();
        sphere(
            [0.0; 3],
            10.0,
            "cal",
            false,
            &[100.0, 300.0],
            &|_, _| 0.0,
            &mut d,
        );
        sphere(
            [50.0, 0.0, 0.0],
            8.0,
            "s2",
            true,
            &[100.0],
            &|_, _| 0.0,
            &mut d,
        );
        let c = build(&d, &ProbeModelSpec::parse("probe_radius,lobing").unwrap()).unwrap();
        assert!(c.families.iter().all(|f| f.kind != ProbeEffect::Lobing));
        assert!(c.held.contains(&ProbeEffect::Lobing));
        d.touches[5].approach = [0.5, 0.5, 0.5];
        let e = build(&d, &ProbeModelSpec::parse("probe_radius").unwrap())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("row 7") && e.contains("not a unit vector"),
            "{e}"
        );
    }
}
