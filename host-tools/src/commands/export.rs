//! `axcomp export`: a fitted positioning table in formats other tools read.
//!
//! Glossary:
//! - *linuxcnc0*: LinuxCNC `COMP_FILE_TYPE = 0`, `nominal forward reverse` (positions reached, mm).
//! - *linuxcnc1*: LinuxCNC `COMP_FILE_TYPE = 1`, `nominal forward-trim reverse-trim` (trim = −deviation, mm).
//! - *csv*: `position_mm,forward_um,backward_um`, the predicted deviation in µm.
//!
//! See `axcomp_positioning::export` for the exact semantics.

use std::path::PathBuf;

use anyhow::Context;
use axcomp_positioning::TableFile;
use axcomp_positioning::export::{ExportFormat, export};

use crate::output::OutputSet;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Positioning table (JSON from `fit positioning --out`).
    #[arg(long, value_name = "TABLE.json")]
    pub table: PathBuf,
    /// Output format.
    #[arg(long, value_parser = ["linuxcnc0", "linuxcnc1", "csv"])]
    pub format: String,
    /// Spacing of the exported positions, mm (the last one sits at the table end).
    #[arg(long, value_name = "MM")]
    pub step: f64,
    /// Output file.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let format: ExportFormat = args.format.parse()?;
    let mut output = OutputSet::new();
    output.planned(&args.out).input(&args.table);
    output.check()?;
    let table = TableFile::load(&args.table)
        .with_context(|| format!("reading table {}", args.table.display()))?;
    let text = export(&table, format, args.step)
        .with_context(|| format!("exporting {}", args.table.display()))?;
    output.file(&args.out, text.as_bytes());
    output.commit()?;
    let lines = text.lines().count() - usize::from(format == ExportFormat::Csv);
    println!(
        "wrote {} ({} entries, {:.4} .. {:.4} mm, format {})",
        args.out.display(),
        lines,
        table.start_mm,
        table.end_mm(),
        args.format
    );
    if matches!(format, ExportFormat::LinuxCnc0 | ExportFormat::LinuxCnc1) {
        println!(
            "LinuxCNC: [JOINT_n] COMP_FILE = {} and COMP_FILE_TYPE = {} (machine units mm)",
            args.out.display(),
            if format == ExportFormat::LinuxCnc0 {
                0
            } else {
                1
            }
        );
    }
    Ok(())
}
