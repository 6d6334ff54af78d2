//! `axcomp diagnose` on laser-line data (`x_mm`, `y_mm`, `z_mm`, `line`, `deviation_um`): the geometry
//! model named by `--model` (`geometry` = the rigid 21-term model, or ISO names) fitted on the training
//! rows, the gap on the held-out lines, and which unmodelled effect of the contract's line vocabulary
//! explains it (`axcomp_diagnose::lines`; the verdict rule is `axcomp_diagnose::judge`'s).

use anyhow::Context;
use axcomp_data::HoldoutSpec;
use axcomp_diagnose::lines::{self, LineObservations, LineOptions};
use axcomp_diagnose::obs::{Named, Observations};
use axcomp_diagnose::{DiagnoseOptions, report};
use axcomp_geometry::LineData;
use axcomp_kinematics::Topology;

use crate::commands::diagnose_shared::{Args, print_candidates, write_diagnosis};
use crate::output::OutputSet;

/// The line observations of a dataset (checks of `axcomp-geometry`: ≥ 3 targets per line, unit beams
/// along their lines, finite cells).
pub fn observations(
    ds: &axcomp_data::Dataset,
    target: &str,
    holdout: &str,
    topology: Topology,
) -> anyhow::Result<LineObservations> {
    let mut data = LineData::from_dataset(ds, true)?;
    if target != "deviation_um" {
        let y = ds.numeric(target)?;
        if let Some(i) = y.iter().position(|v| !v.is_finite()) {
            anyhow::bail!("{}: not a finite number", ds.locate(target, i));
        }
        for (r, v) in data.readings.iter_mut().zip(y) {
            r.deviation_um = *v;
        }
    }
    let held_out = HoldoutSpec::parse(holdout)?.mask(ds)?;
    let time_s = if ds.has("time_s") {
        Some(ds.numeric("time_s")?.to_vec())
    } else {
        ds.time_s().map(<[f64]>::to_vec)
    };
    let mut temperatures = Vec::new();
    for s in ds.sensors() {
        let col = format!("{s}_degC");
        temperatures.push(Named {
            name: s,
            values: ds.numeric(&col)?.to_vec(),
        });
    }
    let obs = LineObservations {
        data,
        target_name: target.to_string(),
        held_out,
        time_s,
        temperatures,
        topology,
    };
    obs.validate().with_context(|| ds.source().to_string())?;
    Ok(obs)
}

pub fn run(args: &Args, ds: axcomp_data::Dataset) -> anyhow::Result<()> {
    let model = lines::parse_model(&args.model).context("--model")?;
    let topology = Topology::parse(&args.work_axes, &args.tool_axes)?;
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
    let obs = observations(&ds, &args.target, &args.holdout, topology)
        .with_context(|| format!("{}", args.data.data.display()))?;
    drop(ds);
    let opts = DiagnoseOptions {
        progress: obs.n_rows() >= 20_000,
        ..DiagnoseOptions::default()
    }
    .build()?;
    let ld = lines::diagnose_lines(&obs, &model, &opts, &LineOptions::default())
        .with_context(|| args.data.data.display().to_string())?;
    let d = &ld.diagnosis;
    println!(
        "gap of `{}` (model: {}, {} terms, axes {}): train RMS {:.3} µm, held-out RMS {:.3} µm, held-out max {:.3} µm ({} train / {} held-out readings)",
        d.target,
        args.model.trim(),
        d.model.len(),
        ld.topology,
        d.gap.train_rms_um,
        d.gap.holdout_rms_um,
        d.gap.holdout_max_um,
        d.n_train,
        d.n_holdout
    );
    for l in &ld.holdout_lines {
        println!(
            "  held-out line {:<8} {:>4} readings  RMS {:.3} µm → {:.3} µm after the verdict",
            l.line, l.rows, l.rms_before_um, l.rms_after_um
        );
    }
    for r in d.where_.iter().take(4) {
        println!(
            "  where: {} {:.4} … {:.4} holds {:.1} % of the held-out gap",
            r.variable,
            r.from,
            r.to,
            100.0 * r.share
        );
    }
    print_candidates(&d.effects, 6, opts.alpha);
    for n in &d.not_applicable {
        println!("  not applicable: {n}");
    }
    for n in &ld.notes {
        println!("  note: {n}");
    }
    println!("verdict: {} — {}", d.verdict, d.note);
    let mut report = None;
    if let Some(dir) = &args.report {
        // The axis report's figures over time (the gap before / after the verdict), plus the held-out lines.
        let pseudo = Observations {
            target_name: obs.target_name.clone(),
            target: obs.target(),
            held_out: obs.held_out.clone(),
            time_s: obs.time_s.clone(),
            ..Default::default()
        };
        let mut files = report::report_files(dir, &pseudo, d)?;
        if let Some((_, md)) = files.last_mut() {
            let mut extra = String::from(
                "\n## Held-out lines\n\n| line | readings | RMS before (µm) | RMS after the verdict (µm) |\n|---|---|---|---|\n",
            );
            for l in &ld.holdout_lines {
                extra.push_str(&format!(
                    "| {} | {} | {:.3} | {:.3} |\n",
                    l.line, l.rows, l.rms_before_um, l.rms_after_um
                ));
            }
            extra.push_str(&format!(
                "\nModel: {} ({} terms), axis stacking {}.\n",
                args.model.trim(),
                d.model.len(),
                ld.topology
            ));
            for n in &ld.notes {
                extra.push_str(&format!("\nNote: {n}\n"));
            }
            md.extend_from_slice(extra.as_bytes());
        }
        report = Some((dir.as_path(), files));
    }
    write_diagnosis(outputs, report, args.json.as_deref(), &ld)
}
