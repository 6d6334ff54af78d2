//! `axcomp demo --all`: every system's chain on the twin, one row per system (the chains:
//! `axcomp_demo::all`). This module calls the library, writes the report folder whole and prints the
//! table.

use std::path::{Path, PathBuf};

use crate::output::OutputSet;

/// Runs every chain, prints one row per system and writes the report folder `out` whole
/// (`demo_all.json`, `report.md`, each chain's data and image).
pub fn run_all(out: &Path, seed: u64) -> anyhow::Result<()> {
    let mut set = OutputSet::new();
    set.folder(out, "--out");
    set.check()?;
    let demo = axcomp_demo::all::run(seed)?;
    for w in &demo.warnings {
        eprintln!("axcomp: warning: {w}");
    }
    print!("{}", demo.console);
    println!(
        "{} systems in {:.2} s; report in {}",
        demo.systems,
        demo.seconds,
        out.display()
    );
    for (name, bytes) in demo.files {
        set.folder_file(out, &name, bytes);
    }
    set.commit()?;
    Ok(())
}

/// Default report folder of `demo --all`.
pub fn default_out() -> PathBuf {
    PathBuf::from("axcomp-demo-all")
}
