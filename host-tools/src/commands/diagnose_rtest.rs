//! `axcomp diagnose` on R-test / sphere-centre data (`dx_um`, `dy_um`, `dz_um` at rotary poses): the
//! location-error model fitted on the training poses, the held-out gap, and which unmodelled effect of the
//! contract's R-test vocabulary explains it (`axcomp_diagnose::rtest`; the verdict rule is
//! `axcomp_diagnose::judge`'s). `--machine` / `--pivot-mm` as for `axcomp fit rtest`.

use anyhow::Context;
use axcomp_diagnose::judge::DiagnoseOptions;
use axcomp_diagnose::rtest::{self, RtestObservations};

use crate::commands::common::machine_from;
use crate::commands::diagnose_shared::{Args, print_candidates, write_diagnosis};
use crate::output::OutputSet;

pub fn run(args: &Args, ds: axcomp_data::Dataset) -> anyhow::Result<()> {
    if args.target != "deviation_um" {
        anyhow::bail!(
            "--target {}: R-test data are judged on the three displacement components dx_um, dy_um, dz_um together; drop --target",
            args.target
        );
    }
    let machine = machine_from(
        args.machine.as_deref().unwrap_or("ac-trunnion"),
        args.pivot_mm,
    )?;
    let model = rtest::parse_model(&args.model).context("--model")?;
    // The outputs are planned and checked before the fit; written together at the end.
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
    let obs = RtestObservations::from_dataset(&ds, machine, &args.holdout)?;
    let opts = DiagnoseOptions::default().build()?;
    let (d, camp) =
        rtest::diagnose(&obs, &model, &opts).with_context(|| ds.source().to_string())?;
    let dg = &d.diagnosis;
    println!(
        "gap of dx/dy/dz (model: {}; machine {}): train RMS {:.3} µm, held-out RMS {:.3} µm, held-out max {:.3} µm ({} train / {} held-out poses)",
        args.model.trim(),
        machine.kind.name(),
        dg.gap.train_rms_um,
        dg.gap.holdout_rms_um,
        dg.gap.holdout_max_um,
        dg.n_train / 3,
        dg.n_holdout / 3
    );
    for r in dg.where_.iter().take(4) {
        println!(
            "  where: {} {:.4} … {:.4} holds {:.1} % of the held-out gap",
            r.variable,
            r.from,
            r.to,
            100.0 * r.share
        );
    }
    print_candidates(&dg.effects, usize::MAX, opts.alpha);
    for [a, b] in &d.same_signature {
        println!("  {a} and {b}: same signature on these poses (the data cannot tell them apart)");
    }
    println!("verdict: {} — {}", dg.verdict, dg.note);
    let report = args.report.as_deref().map(|dir| {
        let files = rtest::report_files(&d, &camp)
            .into_iter()
            .map(|(name, bytes)| (dir.join(name), bytes))
            .collect();
        (dir, files)
    });
    write_diagnosis(outputs, report, args.json.as_deref(), &d)
}
