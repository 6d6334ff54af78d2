//! `axcomp diagnose` on probe touches (`approach_x`, `approach_y`, `approach_z`): the base model fitted on the
//! training rows, the held-out gap, and which unmodelled effect of the contract's vocabulary explains it
//! (`axcomp_diagnose::probe`; the verdict rule is `axcomp_diagnose::judge`'s, the same for every data kind).
//!
//! Terms: *target* = the radial residual of each touch about its artefact (µm; `--target` is not used:
//! touches have no error column); *placement* = where an artefact stands and how big it is, fitted on the
//! training touches or, for an artefact touched only on held-out rows, projected out of them.

use anyhow::Context;
use axcomp_data::{Dataset, HoldoutSpec};
use axcomp_diagnose::probe::{self as dprobe, ProbeData, ProbeModelSpec};

use crate::commands::diagnose_shared::{Args, print_candidates, write_diagnosis};
use crate::output::OutputSet;
use axcomp_probe::touches::read_touches;

/// The touch columns as [`ProbeData`] (held-out rows from `--holdout`).
pub fn probe_data(ds: &Dataset, holdout: &str) -> anyhow::Result<ProbeData> {
    let spec = HoldoutSpec::parse(holdout).context("--holdout")?;
    let held_out = spec.mask(ds)?;
    let (touches, labels) = read_touches(ds)?;
    let artefact = if ds.has("artefact") {
        ds.text("artefact")?.iter().map(|s| s.to_string()).collect()
    } else {
        vec!["artefact".to_string(); ds.n_rows()]
    };
    let time_s = if ds.has("time_s") {
        Some(ds.numeric("time_s")?.to_vec())
    } else {
        ds.time_s().map(<[f64]>::to_vec)
    };
    let mut temperatures = Vec::new();
    for s in ds.sensors() {
        let v = ds.numeric(&format!("{s}_degC"))?.to_vec();
        temperatures.push((s, v));
    }
    let data = ProbeData {
        touches,
        artefact,
        run: ds.run(),
        time_s,
        temperatures,
        held_out,
        labels,
    };
    Ok(without_gross_outliers(data))
}

/// Robust σ threshold of a gross outlier (bounce, false trigger): `fit probe --outlier-mad`'s default.
const OUTLIER_ROBUST_SIGMA: f64 = axcomp_probe::DEFAULT_OUTLIER_MAD;

/// Flags of the touches of one sphere ([`axcomp_probe::iterated_sphere_outliers`], threshold
/// [`OUTLIER_ROBUST_SIGMA`]) about the free-radius sphere of the touches kept. A glitch of hundreds of µm
/// would otherwise dominate the gap and hide every effect. `None` when the touches do not determine a sphere
/// (ring gauge, plane).
fn sphere_outliers(points: &[[f64; 3]]) -> Option<Vec<bool>> {
    axcomp_probe::iterated_sphere_outliers(points.len(), OUTLIER_ROBUST_SIGMA, |kept| {
        let kept: Vec<[f64; 3]> = kept.iter().map(|&i| points[i]).collect();
        let s = axcomp_probe::geometry::geometric_sphere(&kept, None)?;
        Ok::<_, axcomp_probe::ProbeError>(
            points
                .iter()
                .map(|p| {
                    let d = (0..3).map(|k| (p[k] - s.center_mm[k]).powi(2)).sum::<f64>();
                    (d.sqrt() - s.radius_mm) * 1000.0
                })
                .collect(),
        )
    })
    .ok()
}

/// `d` without the gross outliers of each sphere artefact ([`sphere_outliers`]), listed on stderr.
fn without_gross_outliers(d: ProbeData) -> ProbeData {
    let n = d.touches.len();
    let mut flagged = vec![false; n];
    let mut names: Vec<&str> = Vec::new();
    for a in &d.artefact {
        if !names.contains(&a.as_str()) {
            names.push(a);
        }
    }
    for name in names {
        let rows: Vec<usize> = (0..n).filter(|&i| d.artefact[i] == name).collect();
        let pts: Vec<[f64; 3]> = rows.iter().map(|&i| d.touches[i].position_mm).collect();
        let sphere = rows.len() >= 8
            && axcomp_probe::geometry::check_not_coplanar(&pts, &vec![String::new(); pts.len()])
                .is_ok();
        if let Some(f) = sphere.then(|| sphere_outliers(&pts)).flatten() {
            for (k, &i) in rows.iter().enumerate() {
                flagged[i] = f[k];
            }
        }
    }
    if !flagged.iter().any(|f| *f) {
        return d;
    }
    let bad: Vec<&str> = (0..n)
        .filter(|&i| flagged[i])
        .map(|i| d.labels[i].as_str())
        .collect();
    eprintln!(
        "axcomp: note: {} touches left out as bounces / false triggers (radial residual more than {} robust σ \
         from their sphere's, as `fit probe` flags them): {}",
        bad.len(),
        OUTLIER_ROBUST_SIGMA,
        bad.join(", ")
    );
    let keep = |i: &usize| !flagged[*i];
    let pick =
        |v: &[String]| -> Vec<String> { (0..n).filter(keep).map(|i| v[i].clone()).collect() };
    ProbeData {
        touches: (0..n).filter(keep).map(|i| d.touches[i]).collect(),
        artefact: pick(&d.artefact),
        run: d.run.as_deref().map(pick),
        time_s: d
            .time_s
            .as_ref()
            .map(|t| (0..n).filter(keep).map(|i| t[i]).collect()),
        temperatures: d
            .temperatures
            .iter()
            .map(|(s, v)| (s.clone(), (0..n).filter(keep).map(|i| v[i]).collect()))
            .collect(),
        held_out: (0..n).filter(keep).map(|i| d.held_out[i]).collect(),
        labels: pick(&d.labels),
    }
}

pub fn run(args: &Args, ds: Dataset) -> anyhow::Result<()> {
    let model = ProbeModelSpec::parse(&args.model).context("--model")?;
    if args.target != "deviation_um" {
        anyhow::bail!(
            "--target {}: probe touches have no error column; the diagnosis models the radial residual of each \
             touch about its artefact",
            args.target
        );
    }
    // The outputs are planned and checked before the search; written together at the end.
    let mut outputs = OutputSet::new();
    outputs.input(&args.data.data);
    if let Some(dir) = &args.report {
        outputs
            .folder(dir, "--report")
            .planned_in(dir, "diagnosis.md");
    }
    if let Some(path) = &args.json {
        outputs.planned(path);
    }
    outputs.check()?;
    let data = probe_data(&ds, &args.holdout)?;
    let source = ds.source().to_string();
    drop(ds);
    let campaign = dprobe::build(&data, &model).with_context(|| source.clone())?;
    let opts = axcomp_diagnose::DiagnoseOptions::default().build()?;
    let d = dprobe::diagnose(&campaign, &opts).with_context(|| source.clone())?;
    let g = &d.diagnosis.gap;
    println!(
        "gap of the radial residual (model: {}): train RMS {:.3} µm, held-out RMS {:.3} µm, held-out max {:.3} µm ({} train / {} held-out touches)",
        args.model.trim(),
        g.train_rms_um,
        g.holdout_rms_um,
        g.holdout_max_um,
        d.diagnosis.n_train,
        d.diagnosis.n_holdout
    );
    for a in &d.artefacts {
        println!(
            "  artefact {}: {} ({} train / {} held-out touches), placement {}",
            a.name, a.shape, a.train_touches, a.holdout_touches, a.placement
        );
    }
    for r in d.diagnosis.where_.iter().take(4) {
        println!(
            "  where: {} {:.4} … {:.4} holds {:.1} % of the held-out gap",
            r.variable,
            r.from,
            r.to,
            100.0 * r.share
        );
    }
    print_candidates(&d.diagnosis.effects, 6, opts.alpha);
    println!("verdict: {} — {}", d.diagnosis.verdict, d.diagnosis.note);
    let report = match &args.report {
        Some(dir) => Some((dir.as_path(), dprobe::report_files(dir, &campaign, &d)?)),
        None => None,
    };
    write_diagnosis(outputs, report, args.json.as_deref(), &d)
}
