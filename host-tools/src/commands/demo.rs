//! `axcomp demo`: the whole loop on a simulated axis, in seconds, with no input files (the work:
//! `axcomp_demo::axis`; with `--all`, every system's chain: `demo_all`). This module parses, calls
//! the library and writes its files all together (or none) before printing its summary.

use std::path::PathBuf;

use axcomp_demo::DemoError;

use crate::output::OutputSet;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Directory for the report, plots, measurement CSVs, table and image (written whole) [default:
    /// axcomp-demo, with --all axcomp-demo-all].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Seed of the simulated measurement noise (the compensated campaign uses seed + 1).
    #[arg(long, default_value_t = 2)]
    pub seed: u64,
    /// Every system's chain on the twin (positioning, thermo-force, three-axis geometry, five-axis
    /// rotary, touch probe): measure → fit → image → the firmware library applies it → before/after on
    /// data the fit never saw; one row per system.
    #[arg(long)]
    pub all: bool,
}

/// A demo's error for `main`: the guard's refusal keeps its exit code.
pub fn demo_error(e: DemoError) -> anyhow::Error {
    match e {
        DemoError::GuardRefused(_) => crate::Refused {
            code: crate::EXIT_GUARD_REFUSED,
            reason: e.to_string(),
        }
        .into(),
        e => e.into(),
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let out = &args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("axcomp-demo"));
    // Every output declared and its path checked before any work.
    let mut set = OutputSet::new();
    set.folder(out, "--out");
    for name in axcomp_demo::axis::FILES {
        set.planned_in(out, name);
    }
    set.check()?;

    let demo = axcomp_demo::axis::run(args.seed, crate::provenance::TOOL).map_err(demo_error)?;

    for (name, bytes) in demo.files {
        set.folder_file(out, &name, bytes);
    }
    set.commit()?;
    print!("{}", demo.console);
    println!(
        "wrote {}/{{report.md, demo.json, *.svg, *.csv, table.json, image.bin, trace.bin, replay.bin}}",
        out.display()
    );
    Ok(())
}
