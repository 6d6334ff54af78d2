//! `axcomp diagnose`: fits a model holding only the named effects on the training rows, measures the gap
//! on the held-out rows, finds where it lies and which unmodelled effect explains it (see
//! `axcomp_diagnose`). Contract: `../shared/spec/interfaces.md`.
//!
//! Terms: *model* = the `--model` effect kinds; *gap* = what the model misses on held-out rows; *verdict*
//! = the effect judged responsible, or `none`.

use std::path::PathBuf;

use axcomp_diagnose::{DiagnoseOptions, EffectKind, dataset, report};
use axcomp_effects::DataKind;

use crate::cli::DataArgs;
use crate::commands::common;
use crate::output::OutputSet;

#[derive(Debug, clap::Args)]
#[command(after_help = axcomp_diagnose::engine::VERDICT_HELP)]
pub struct Args {
    #[command(flatten)]
    pub data: DataArgs,
    /// Effects the model holds, comma separated (contract names, e.g. `pitch_error,reversal`); may be empty.
    #[arg(long, value_name = "K1,K2,..")]
    pub model: String,
    /// Rows held out from fitting and used only to judge: `COL=V1,V2`, `COL>=X`, `COL<X`.
    #[arg(long, value_name = "SPEC")]
    pub holdout: String,
    /// The error column to model.
    #[arg(long, value_name = "COL", default_value = "deviation_um")]
    pub target: String,
    /// Write the machine-readable result here.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write a Markdown report with SVG figures into this directory.
    #[arg(long, value_name = "DIR")]
    pub report: Option<PathBuf>,
    /// R-test data: machine kind, as for `axcomp fit rtest` (ac-trunnion, bc-trunnion, bc-head)
    /// [default: ac-trunnion].
    #[arg(long, value_name = "KIND")]
    pub machine: Option<String>,
    /// R-test data, bc-head: nominal distance from the B axis to the tool point, mm.
    #[arg(long, value_name = "L")]
    pub pivot_mm: Option<f64>,
    /// Laser-line data: axes carrying the workpiece, from the bed outward (the lever arms of the angular
    /// errors).
    #[arg(long, default_value = "YX", value_name = "AXES")]
    pub work_axes: String,
    /// Laser-line data: axes carrying the tool, from the bed outward.
    #[arg(long, default_value = "Z", value_name = "AXES")]
    pub tool_axes: String,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let ds = common::load_dataset(&args.data)?;
    // The file's columns say which kind of data it is (contract: "Effect kinds for geometry, rotary-axis
    // and probe data"); each machine-level kind has its own diagnosis module.
    match DataKind::detect(&ds.column_names()) {
        Some(DataKind::LaserLines) => super::diagnose_lines::run(&args, ds),
        Some(DataKind::RTest) => super::diagnose_rtest::run(&args, ds),
        Some(DataKind::ProbeTouches) => super::diagnose_probe::run(&args, ds),
        Some(DataKind::Axis) | None => run_axis(args, ds),
    }
}

/// Single-axis data (`target_mm`, `deviation_um`, ...): the effect kinds of the axis vocabulary.
fn run_axis(args: Args, ds: axcomp_data::Dataset) -> anyhow::Result<()> {
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
    .build()
    .map_err(anyhow::Error::msg)?;
    let d = axcomp_diagnose::diagnose(&obs, &model, &opts)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.data.data.display()))?;
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

/// The report's files: the directory and each file's path and bytes.
type ReportFiles<'a> = (&'a std::path::Path, Vec<(std::path::PathBuf, Vec<u8>)>);

/// The end of every `diagnose` data kind: the report's files (`--report DIR`, `None` without it) and the
/// JSON (`--json`) join the planned outputs, everything is written together, and the number of report
/// files is said.
pub(super) fn write_diagnosis<T: serde::Serialize>(
    mut outputs: OutputSet,
    report: Option<ReportFiles<'_>>,
    json: Option<&std::path::Path>,
    value: &T,
) -> anyhow::Result<()> {
    let mut report_files = 0;
    let report_dir = report.map(|(dir, files)| {
        for (path, bytes) in files {
            outputs.folder_file(dir, &crate::commands::common::file_name(&path), bytes);
            report_files += 1;
        }
        dir
    });
    if let Some(path) = json {
        outputs.json(path, value)?;
    }
    outputs.commit()?;
    if let Some(dir) = report_dir {
        println!("report: {report_files} files in {}", dir.display());
    }
    Ok(())
}

/// The console lines of the best `n` candidates: kind, score, held-out RMS after, shrink, and why a
/// candidate that does not explain the gap does not (one format for every data kind).
pub(super) fn print_candidates(effects: &[axcomp_diagnose::Candidate], n: usize, alpha: f64) {
    for c in effects.iter().take(n) {
        println!(
            "  candidate {:<20} score {:>9.1}  held-out RMS after {:.3} µm  shrink {:>6.1} %{}",
            c.kind,
            c.score,
            c.holdout_rms_after_um,
            c.shrink_pct,
            if c.explains {
                ""
            } else if c.train_p_value < alpha {
                "  (significant, not material)"
            } else {
                "  (not beyond noise)"
            }
        );
    }
}
