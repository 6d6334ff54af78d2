//! What the `axcomp diagnose` modules share (one per data kind: `diagnose` for axis data,
//! `diagnose_lines`, `diagnose_rtest`, `diagnose_probe`): the arguments, the console lines of the
//! candidates and the writing of the report and the JSON.
//!
//! Terms: *model* = the `--model` effect kinds; *gap* = what the model misses on held-out rows; *verdict*
//! = the effect judged responsible, or `none`.

use std::path::PathBuf;

use crate::cli::DataArgs;
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

/// The report's files: the directory and each file's path and bytes.
pub type ReportFiles<'a> = (&'a std::path::Path, Vec<(std::path::PathBuf, Vec<u8>)>);

/// The end of every `diagnose` data kind: the report's files (`--report DIR`, `None` without it) and the
/// JSON (`--json`) join the planned outputs, everything is written together, and the number of report
/// files is said.
pub fn write_diagnosis<T: serde::Serialize>(
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
pub fn print_candidates(effects: &[axcomp_diagnose::Candidate], n: usize, alpha: f64) {
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
