//! `axcomp trace`: write a binary trace (cycles, temperatures, process parameters, table images) for replay
//! on the host or in the QEMU firmware.
//!
//! Glossary:
//! - *trace*: the `axcomp_core::trace` format (header `AXTR`, tagged little-endian records).
//! - *scenario*: a named deterministic generator; `equivalence` is the one the QEMU equivalence test replays
//!   (reversals, counter wrap, temperature ramps, stale sensor, force steps, corrupt and replacement images),
//!   `reference` the core's benchmark workload, `group3`/`group5` axis groups (group records, a group image).
//!   All run at 10 kHz with temperatures every 100 ms; every trace ends with a CRC-32 record.
//!
//! The trace is written through [`crate::output::OutputSet`] (checked before the work, all or nothing), so a
//! failed run leaves nothing.

use std::path::PathBuf;

use anyhow::{Context, bail};
use axcomp_core::trace::{self, Record};

// The scenario generator lives with the firmware (feature `std`), where the QEMU equivalence test uses it too.
use axcomp_scenario as scenario;

use crate::output::OutputSet;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Write the trace here.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Scenario: `equivalence` (every firmware path), `reference` (the benchmark workload), `group3` or
    /// `group5` (axis groups: three linear axes, or also rotary A and C with the rotary stage).
    #[arg(long, value_name = "NAME", default_value = "equivalence")]
    pub scenario: String,
    /// Number of cycle records (10 kHz).
    #[arg(long, value_name = "N", default_value_t = scenario::DEFAULT_CYCLES)]
    pub cycles: u32,
    /// A table image (`axcomp image build`) to load first instead of the scenario's own.
    #[arg(long, value_name = "IMG")]
    pub image: Option<PathBuf>,
}

/// Validated `trace` configuration.
struct Config {
    out: PathBuf,
    scenario: String,
    cycles: u32,
    image: Option<Vec<u8>>,
}

fn validate(args: Args) -> anyhow::Result<Config> {
    if !scenario::NAMES.contains(&args.scenario.as_str()) {
        bail!(
            "--scenario {}: unknown scenario (known: {})",
            args.scenario,
            scenario::NAMES.join(", ")
        );
    }
    if args.cycles == 0 {
        bail!("--cycles must be at least 1");
    }
    let image = match &args.image {
        Some(path) => {
            let bytes = std::fs::read(path)
                .with_context(|| format!("--image {}: cannot read", path.display()))?;
            let info = axcomp_core::inspect_image(&bytes).map_err(|e| {
                anyhow::anyhow!("--image {}: not a valid table image: {e}", path.display())
            })?;
            if bytes.len() != info.len {
                bail!(
                    "--image {}: {} bytes, but the image header says {} (trailing bytes?)",
                    path.display(),
                    bytes.len(),
                    info.len
                );
            }
            Some(bytes)
        }
        None => None,
    };
    Ok(Config {
        out: args.out,
        scenario: args.scenario,
        cycles: args.cycles,
        image,
    })
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let image_path = args.image.clone();
    let cfg = validate(args)?;
    let mut outputs = OutputSet::new();
    outputs.planned(&cfg.out);
    if let Some(p) = &image_path {
        outputs.input(p);
    }
    outputs.check()?;
    let bytes = scenario::generate(&cfg.scenario, cfg.cycles, cfg.image.as_deref())
        .map_err(|e| anyhow::anyhow!("--scenario {}: {e}", cfg.scenario))?;

    // Count what was written (and prove it reads back cleanly) before touching the output path.
    let mut records = 0usize;
    let mut cycles = 0usize;
    let mut images = 0usize;
    for r in trace::Reader::new(&bytes).context("generated trace header")? {
        let rec = r.context("generated trace record")?;
        records += 1;
        match rec {
            Record::Cycle(_) | Record::GroupCycle { .. } => cycles += 1,
            Record::Image(_) => images += 1,
            _ => {}
        }
    }

    outputs.file(&cfg.out, bytes.as_slice());
    outputs.commit()?;
    println!(
        "wrote {}: scenario {}, {} records ({} cycles, {} images), {} bytes",
        cfg.out.display(),
        cfg.scenario,
        records,
        cycles,
        images,
        bytes.len()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(out: PathBuf) -> Args {
        Args {
            out,
            scenario: "equivalence".into(),
            cycles: 12_000,
            image: None,
        }
    }

    #[test]
    fn writes_a_trace_that_reads_back() {
        let dir = std::env::temp_dir().join(format!("axcomp-trace-cmd-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let out = dir.join("t.bin");
        run(args(out.clone())).unwrap();
        let bytes = std::fs::read(&out).unwrap();
        let n = trace::Reader::new(&bytes)
            .unwrap()
            .filter(|r| matches!(r, Ok(Record::Cycle(_))))
            .count();
        assert_eq!(n, 12_000);
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn bad_inputs_are_clear_errors_and_write_nothing() {
        let dir = std::env::temp_dir().join(format!("axcomp-trace-bad-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let out = dir.join("t.bin");
        let mut a = args(out.clone());
        a.scenario = "nope".into();
        let e = run(a).unwrap_err().to_string();
        assert!(
            e.contains("--scenario nope") && e.contains("equivalence"),
            "{e}"
        );

        let img = dir.join("bad.img");
        std::fs::write(&img, b"not an image at all").unwrap();
        let mut a = args(out.clone());
        a.image = Some(img.clone());
        let e = format!("{:#}", run(a).unwrap_err());
        assert!(
            e.contains("bad.img") && e.contains("not a valid table image"),
            "{e}"
        );

        let mut a = args(out.clone());
        a.cycles = 10;
        let e = format!("{:#}", run(a).unwrap_err());
        assert!(e.contains("at least"), "{e}");
        assert!(!out.exists(), "nothing written on error");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
