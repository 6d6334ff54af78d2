//! `axcomp diagnose` on single-axis data: fits a model holding only the named effects on the training rows, measures the gap
//! on the held-out rows, finds where it lies and which unmodelled effect explains it (see
//! `axcomp_diagnose`). Contract: `../shared/spec/interfaces.md`.
//!
//! Terms: *model* = the `--model` effect kinds; *gap* = what the model misses on held-out rows; *verdict*
//! = the effect judged responsible, or `none`.

use anyhow::Context;
use axcomp_diagnose::{DiagnoseOptions, EffectKind, dataset, report};

use crate::commands::diagnose_shared::{Args, print_candidates, write_diagnosis};
use crate::output::OutputSet;

/// Single-axis data (`target_mm`, `deviation_um`, ...): the effect kinds of the axis vocabulary.
pub fn run(args: Args, ds: axcomp_data::Dataset) -> anyhow::Result<()> {
    let model = EffectKind::parse_list(&args.model).map_err(|e| anyhow::anyhow!("--model: {e}"))?;
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
    let obs = dataset::observations(&ds, &args.target, &args.holdout)?;
    // The observations hold every column the diagnosis uses: free the table before the search.
    drop(ds);
    let opts = DiagnoseOptions {
        // Progress on stderr where the search takes seconds (≳ 20,000 rows).
        progress: obs.n_rows() >= 20_000,
        ..DiagnoseOptions::default()
    }
    .build()?;
    let d = axcomp_diagnose::diagnose(&obs, &model, &opts)
        .with_context(|| args.data.data.display().to_string())?;
    println!(
        "gap of `{}` (model: {}): train RMS {:.3} µm, held-out RMS {:.3} µm, held-out max {:.3} µm ({} train / {} held-out rows)",
        d.target,
        if args.model.trim().is_empty() {
            "intercept only"
        } else {
            args.model.trim()
        },
        d.gap.train_rms_um,
        d.gap.holdout_rms_um,
        d.gap.holdout_max_um,
        d.n_train,
        d.n_holdout
    );
    for r in d.where_.iter().take(4) {
        println!(
            "  where: {} {:.4} … {:.4} holds {:.1} % of the held-out gap",
            r.variable,
            r.from,
            r.to,
            100.0 * r.share
        );
    }
    for r in d.verdict_where.iter().take(2) {
        println!(
            "  verdict acts: {} {:.4} … {:.4} holds {:.1} % of what {} removes from the held-out gap",
            r.variable,
            r.from,
            r.to,
            100.0 * r.share,
            d.verdict
        );
    }
    print_candidates(&d.effects, 5, opts.alpha);
    println!("verdict: {} — {}", d.verdict, d.note);
    let report = match &args.report {
        Some(dir) => Some((dir.as_path(), report::report_files(dir, &obs, &d)?)),
        None => None,
    };
    write_diagnosis(outputs, report, args.json.as_deref(), &d)
}
