//! `axcomp fit geometry`: the 21 ISO 230-1 geometric errors of a three-axis machine from laser lines.
//!
//! Glossary: see `axcomp-geometry` (components, topology, identifiability, seven-line method, smoothing).
//! Every output path is checked before the fit; all outputs are written together (or none) at the end.

use std::path::PathBuf;

use anyhow::{Context, bail};
use axcomp_data::sanity::{self, DataWarning};
use axcomp_data::{Dataset, Split, groups};
use axcomp_geometry::analysis::Analysis;
use axcomp_geometry::fit::{Prior, PriorGroups};
use axcomp_geometry::{FitOptions, GeometryError, Judge, LineData, Method, analyse};
use axcomp_kinematics::Topology;

use crate::cli::DataArgs;
use crate::commands::common::{
    check_range, load_dataset, report_warnings, split_from, with_warnings,
};
use crate::output::OutputSet;

const LONG_HELP: &str = "\
Model: rigid-body small-angle chain of the axes (--work-axes from the bed outward carry the workpiece, --tool-axes the tool; default YX / Z), the reflector offset (tool_*_mm) as the Abbe arm. The 18 error functions are cubic B-splines on a knot grid over each axis's measured range, zero at the axis's zero (straightness also with zero least-squares slope: the slope between axes is the squareness), plus EC0Y, EB0Z, EA0Z.

Identifiability: rank and singular values of the stacked design; components or combinations in its null space are reported identified: false with the reason and listed in not_separable; by default (auto) they are estimated at the damped minimum norm (what the lines determine, shared the least-norm way: a weak prior of size 0 that also keeps noise in barely separable directions from growing away from the lines), by --method plain fixed at 0. Next to the held-out figure, identifiable_floor gives what can be computed of the floor (the noise σ̂, and with --holdout the held-out RMS a model right in the lines' span would score); the floor itself needs the truth (computed on the twin). Smoothing λ by leave-one-line-out cross-validation (λ = 0, plain least squares, is a candidate). --prior evidence: instead of one λ by cross-validation, the smoothing and size of each component kind, the damping and (without --intervals) the knot grid are those that maximise the training readings' marginal likelihood, reported in model.prior; the roughness penalised is the third difference of the spline coefficients (--roughness-order; `chosen` lets the evidence compare 2, 3 and 4). On held-back twin lines this default is at most 6 % above the posterior mean under the twin generator's own prior (docs/figures.md). --method plain: no smoothing; --method seven-line: seed 000's 17 parameters (ECY, EAZ, EBZ, ECZ fixed: no lever arm at zero reflector offset).

Example:
  axcomp plan geometry --stroke 800,600,500 --lines 20 --simulate lines.csv
  axcomp fit geometry --data lines.csv --cv line --json fit.json --out model.json --report rep --export tables";

#[derive(Debug, clap::Args)]
#[command(after_long_help = LONG_HELP)]
pub struct Args {
    #[command(flatten)]
    pub data: DataArgs,
    /// Rows held out from fitting and used only to judge: COL=V1,V2 | COL>=X | COL<X (e.g. line=L4,L5).
    #[arg(long, value_name = "SPEC")]
    pub holdout: Option<String>,
    /// Leave-one-group-out over the values of COL (e.g. `line`): `cv_rms_um`.
    #[arg(long, value_name = "COL")]
    pub cv: Option<String>,
    /// Axes carrying the workpiece, from the bed outward.
    #[arg(long, default_value = "YX", value_name = "AXES")]
    pub work_axes: String,
    /// Axes carrying the tool, from the bed outward.
    #[arg(long, default_value = "Z", value_name = "AXES")]
    pub tool_axes: String,
    /// auto (smoothing by CV over lines), plain (no smoothing), seven-line (seed 000's 17 parameters).
    #[arg(long, default_value = "auto", value_name = "METHOD")]
    pub method: String,
    /// How auto chooses its smoothing: evidence (roughness and size precisions per component kind, damping
    /// and, without --intervals, the knot grid by the training readings' marginal likelihood) or line-cv
    /// (one λ by leave-one-line-out cross-validation, fixed damping).
    #[arg(long, default_value = "evidence", value_name = "PRIOR")]
    pub prior: String,
    /// The evidence prior's roughness penalty: the difference order of the spline coefficients it
    /// penalises (2 curvature, 3 the default: quadratics free, 4), or `chosen` (the evidence compares 2, 3
    /// and 4; three times the fit time).
    #[arg(long, default_value = "3", value_name = "ORDER")]
    pub roughness_order: String,
    /// Knot intervals per axis (default: distinct positions − 3, at most 12).
    #[arg(long, value_name = "N")]
    pub intervals: Option<usize>,
    /// Write the model file (input of `axcomp predict`).
    #[arg(long, value_name = "MODEL.json")]
    pub out: Option<PathBuf>,
    /// Machine-readable result.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write report.md and SVG plots into DIR.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// Write the model's component tables into DIR as plain CSV (µm, µrad; one file per component and per
    /// axis). Not a controller's format: `axcomp export --format tf5280|heidenhain` writes those.
    #[arg(long, value_name = "DIR")]
    pub export: Option<PathBuf>,
    /// Position step of the exported tables (mm; default 40 steps per axis).
    #[arg(long, default_value_t = 0.0, value_name = "MM")]
    pub export_step: f64,
    /// Refuse the data (exit 2) when a plausibility check warns (outliers, units, magnitudes).
    #[arg(long)]
    pub strict: bool,
}

/// Plausibility of laser line readings (see `axcomp_data::sanity`): a reading far from its neighbours
/// along its line (per line, run and direction, ordered along the beam), a unit mix or an implausible
/// median in `deviation_um` (nm taken for µm), positions beyond 10 m (µm taken for mm).
pub fn line_warnings(ds: &Dataset, data: &LineData) -> anyhow::Result<Vec<DataWarning>> {
    let dev = ds.numeric("deviation_um")?;
    let text = |c: &str| -> anyhow::Result<Vec<String>> {
        Ok(if ds.has(c) {
            ds.text(c)?.into_iter().map(str::to_string).collect()
        } else {
            vec![String::new(); ds.n_rows()]
        })
    };
    let (run, dir) = (text("run")?, text("direction")?);
    // (line, run, direction) → (position along the beam, row) of its readings.
    type Sequence = ((usize, String, String), Vec<(f64, usize)>);
    let mut sequences: Vec<Sequence> = Vec::new();
    for r in &data.readings {
        let key = (r.line, run[r.row].clone(), dir[r.row].clone());
        let along = axcomp_kinematics::dot(r.q, r.beam);
        match sequences.iter_mut().find(|(k, _)| *k == key) {
            Some((_, s)) => s.push((along, r.row)),
            None => sequences.push((key, vec![(along, r.row)])),
        }
    }
    let sequences: Vec<Vec<usize>> = sequences
        .into_iter()
        .map(|(_, mut s)| {
            s.sort_by(|a, b| a.0.total_cmp(&b.0));
            s.into_iter().map(|(_, row)| row).collect()
        })
        .collect();
    let mut w = Vec::new();
    w.extend(sanity::unit_mix(ds, "deviation_um", dev, None));
    if w.is_empty() {
        w.extend(sanity::neighbour_outliers(
            ds,
            "deviation_um",
            dev,
            &sequences,
        ));
    }
    w.extend(sanity::implausible_magnitude(
        ds,
        "deviation_um",
        dev,
        1000.0,
        "a geometric error of more than 1 mm is not plausible in µm: nm, or not a deviation column?",
    ));
    for c in ["x_mm", "y_mm", "z_mm"] {
        w.extend(sanity::implausible_magnitude(
            ds,
            c,
            ds.numeric(c)?,
            1.0e4,
            "axis positions beyond 10 m are not plausible in mm: µm?",
        ));
    }
    Ok(w)
}

/// Most exported positions per axis (`--export-step` over the axis's range).
const MAX_EXPORT_POSITIONS: f64 = 100_000.0;

/// `--export-step` gives at most [`MAX_EXPORT_POSITIONS`] positions on every axis (a step of 1e-9 mm
/// once exhausted the memory).
fn check_export_step(model: &axcomp_geometry::GeometryModel, step: f64) -> anyhow::Result<()> {
    for (k, g) in model.grids.iter().enumerate() {
        if step > 0.0 && (g.hi - g.lo) / step > MAX_EXPORT_POSITIONS {
            bail!(
                "--export-step {step}: {} positions over axis {}'s {} mm; at most {MAX_EXPORT_POSITIONS} \
                 (give a larger step)",
                ((g.hi - g.lo) / step).ceil(),
                ["X", "Y", "Z"][k],
                g.hi - g.lo
            );
        }
    }
    Ok(())
}

/// Largest `--intervals`: 18 functions × (N + 3) coefficients; at 200 the fit ran for minutes.
const MAX_INTERVALS: usize = 64;

/// Runs the fit and returns the analysis (used by the command and the tests).
/// The data, its plausibility warnings (already reported) and the analysis.
pub fn analyse_args(a: &Args) -> anyhow::Result<(LineData, Vec<DataWarning>, Analysis)> {
    let method = Method::parse(&a.method)
        .with_context(|| format!("--method {}: use auto, plain or seven-line", a.method))?;
    let prior = match a.prior.as_str() {
        "line-cv" => Prior::LineCv,
        "evidence" => Prior::Evidence(PriorGroups::Kind),
        other => bail!("--prior {other}: use line-cv or evidence"),
    };
    let roughness_order = match a.roughness_order.as_str() {
        "chosen" => None,
        o => match o.parse::<usize>() {
            Ok(k @ 1..=4) => Some(k),
            _ => bail!("--roughness-order {o}: use 1, 2, 3, 4 or chosen"),
        },
    };
    let topology = Topology::parse(&a.work_axes, &a.tool_axes)?;
    if let Some(n) = a.intervals.filter(|n| !(1..=MAX_INTERVALS).contains(n)) {
        bail!(
            "--intervals {n}: need 1 … {MAX_INTERVALS} knot intervals per axis (default: distinct positions − 3, at most 12)"
        );
    }
    let ds = load_dataset(&a.data)?;
    let data = LineData::from_dataset(&ds, true)?;
    let warnings = line_warnings(&ds, &data)?;
    report_warnings(&warnings, a.strict)?;
    let judge = match split_from(a.holdout.as_deref(), a.cv.as_deref())? {
        None => Judge::None,
        Some(Split::Holdout(spec)) => {
            let mask = spec.mask(&ds)?;
            if mask.iter().all(|m| *m) {
                bail!(
                    "--holdout {}: holds out every row; nothing left to fit",
                    spec.as_str()
                );
            }
            Judge::Holdout(mask)
        }
        Some(Split::Cv(col)) => {
            let (ids, labels) = groups(&ds, &col)?;
            if labels.len() < 2 {
                bail!(
                    "--cv {col}: {} has a single group `{}`, nothing to leave out",
                    ds.source(),
                    labels.first().cloned().unwrap_or_default()
                );
            }
            Judge::Cv(ids)
        }
    };
    let opts = FitOptions {
        topology,
        method,
        intervals: a.intervals,
        prior,
        roughness_order,
        ..FitOptions::default()
    };
    let an = analyse(&data, &judge, &opts).map_err(|e| match e {
        // errors about the whole file: say which file
        GeometryError::NothingIdentifiable | GeometryError::NoRows => {
            anyhow::anyhow!("{}: {e}", ds.source())
        }
        e => e.into(),
    })?;
    Ok((data, warnings, an))
}

pub fn run(a: Args) -> anyhow::Result<()> {
    // Every output path is checked before the fit; all files are written together at the end.
    let mut outputs = OutputSet::new();
    outputs.input(&a.data.data);
    for p in [&a.json, &a.out].into_iter().flatten() {
        outputs.planned(p);
    }
    if let Some(d) = &a.export {
        outputs.folder(d, "--export");
    }
    if let Some(d) = &a.report {
        outputs.folder(d, "--report");
    }
    outputs.check()?;
    check_range("--export-step", a.export_step, 0.0, 1e5)?;
    let (data, warnings, an) = analyse_args(&a)?;
    let rep = &an.report;
    // everything is computed; now write
    if let Some(p) = &a.json {
        outputs.json(p, &with_warnings(serde_json::to_value(rep)?, &warnings)?)?;
    }
    if let Some(p) = &a.out {
        let provenance = crate::provenance::of_data(
            &a.data,
            a.holdout.as_deref(),
            a.cv.as_deref(),
            "",
            "fit geometry",
        )?;
        outputs.file(
            p,
            crate::provenance::stamp_text(&an.fit.model.to_json(), &provenance)?,
        );
    }
    if let Some(dir) = &a.export {
        check_export_step(&an.fit.model, a.export_step)?;
        for (name, text) in axcomp_geometry::export::export_files(&an.fit.model, a.export_step) {
            outputs.folder_file(dir, &name, text);
        }
    }
    if let Some(dir) = &a.report {
        for (name, text) in axcomp_geometry::report::report_files(&data, &an) {
            outputs.folder_file(dir, &name, text);
        }
    }
    outputs.commit()?;
    println!("{}", an.fit.model.method);
    println!(
        "lines {}, readings {} ({} fitted); raw RMS {:.3} µm, fit RMS {:.3} µm{}{}",
        rep.lines,
        rep.rows,
        rep.train_rows,
        rep.raw_rms_um,
        rep.fit_rms_um,
        rep.holdout_rms_um
            .map(|h| {
                let fl = &rep.identifiable_floor;
                format!(
                    ", held-out RMS {h:.3} µm (noise σ̂ {:.3} µm{})",
                    fl.noise_um,
                    fl.expected_holdout_rms_um
                        .map(|e| format!(
                            ", a model right in the lines' span would score {e:.3} µm"
                        ))
                        .unwrap_or_default()
                )
            })
            .unwrap_or_default(),
        rep.cv_rms_um
            .map(|h| format!(", cross-validated RMS {h:.3} µm"))
            .unwrap_or_default()
    );
    println!(
        "identifiability: rank {} of {} parameters, condition number {:.1}",
        rep.identifiability.rank,
        rep.identifiability.parameters,
        rep.identifiability.condition_number
    );
    for g in &rep.identifiability.not_separable {
        println!("  not separable: {}", g.join(", "));
    }
    println!(
        "volumetric |e| over the measured volume: max {:.2} µm, RMS {:.2} µm",
        rep.volumetric.max_um, rep.volumetric.rms_um
    );
    for d in &rep.iso230_6_body_diagonals {
        println!(
            "ISO 230-6 {}: {:.2} µm before, {:.2} µm after ({})",
            d.line, d.before_um, d.after_um, d.basis
        );
    }
    let unidentified: Vec<&str> = rep
        .errors
        .iter()
        .filter(|(_, e)| !e.identified)
        .map(|(k, _)| k.as_str())
        .collect();
    if !unidentified.is_empty() {
        println!("not identified: {}", unidentified.join(", "));
    }
    Ok(())
}
