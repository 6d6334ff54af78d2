//! `axcomp replay`: runs the firmware's compensation logic (`axcomp_core::Engine`, the same code the
//! QEMU firmware runs) over a binary trace and writes the output records.
//!
//! Glossary:
//! - *trace*: binary records (cycle inputs, temperatures, process parameters, images), `axcomp trace`.
//! - *output record*: 32 bytes per cycle record (`axcomp_core::trace::OutputRecord`, little endian),
//!   written back to back without a header, exactly as the QEMU firmware writes them.
//! - *flags*: per-cycle condition bits (table outside, clamped, slewed, sensor fault, ...).
//!
//! - *group trace*: a trace with group records (`GroupCycle`, …), e.g. `axcomp trace --scenario group5`;
//!   replayed through `axcomp_core::group::GroupEngine` (one output record per axis and cycle, in slot
//!   order; the CSV gets an `axis` column).
//!
//! The trace is checked whole before anything runs (`axcomp_core::trace::verify`): a malformed or
//! truncated record, a missing `End`, or a `Crc` record that does not match (every trace `axcomp trace`
//! writes carries one, so a flipped bit is caught) is an error, and nothing is written. A rejected
//! `--image` is an error too.

use std::path::PathBuf;

use anyhow::Context;
use axcomp_image::replay::{replay, summary, to_csv, to_group_csv};

use crate::output::OutputSet;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Table image loaded before the trace (a trace may also carry its own image records).
    #[arg(long, value_name = "IMAGE")]
    pub image: Option<PathBuf>,
    /// The binary trace (`axcomp trace`).
    #[arg(long, value_name = "TRACE")]
    pub trace: PathBuf,
    /// Output records (32 bytes per cycle, as the firmware writes them).
    #[arg(long, value_name = "OUT")]
    pub out: PathBuf,
    /// Also write the output records as CSV.
    #[arg(long, value_name = "OUT.csv")]
    pub csv: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // Both output paths are checked before the replay; both files are written together at the end.
    let mut outputs = OutputSet::new();
    outputs.planned(&args.out);
    if let Some(p) = &args.csv {
        outputs.planned(p);
    }
    outputs.input(&args.trace);
    if let Some(p) = &args.image {
        outputs.input(p);
    }
    outputs.check()?;
    let image = match &args.image {
        Some(p) => {
            Some(std::fs::read(p).with_context(|| format!("cannot read image {}", p.display()))?)
        }
        None => None,
    };
    let trace = std::fs::read(&args.trace)
        .with_context(|| format!("cannot read trace {}", args.trace.display()))?;
    let r = replay(image.as_deref(), &trace).with_context(|| match &args.image {
        Some(p) => format!("replaying {} with {}", args.trace.display(), p.display()),
        None => format!("replaying {}", args.trace.display()),
    })?;
    for e in &r.trace_errors {
        eprintln!("axcomp: warning: {}: {e}", args.trace.display());
    }
    let bytes: Vec<u8> = r.outputs.iter().flat_map(|o| o.encode()).collect();
    let csv = args.csv.as_ref().map(|p| {
        let text = match r.group_axes {
            Some(n) => to_group_csv(&r.outputs, n),
            None => to_csv(&r.outputs),
        };
        (p, text)
    });
    outputs.file(&args.out, bytes);
    if let Some((p, text)) = csv {
        outputs.file(p, text);
    }
    outputs.commit()?;
    print!("{}", summary(&r));
    println!(
        "wrote {} ({} records × 32 bytes)",
        args.out.display(),
        r.outputs.len()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use axcomp_scenario as scenario;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("axcomp-replay-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// Reference: the group engine's own step loop (`replay_group` over the same trace) — the
    /// CLI's records must be the same; a five-axis group trace gives 5 records per cycle.
    #[test]
    fn group_trace_replays_one_record_per_axis() {
        let t = scenario::group(5, 6000).unwrap();
        let r = replay(None, &t).unwrap();
        assert_eq!(r.group_axes, Some(5));
        assert_eq!(r.outputs.len(), 6000 * 5);
        assert_eq!((r.stats.images_accepted, r.stats.images_rejected), (2, 1));
        let csv = to_group_csv(&r.outputs, 5);
        assert!(csv.starts_with("axis,cycle,"));
        assert!(csv.lines().nth(5).unwrap().starts_with("4,"));
        assert!(summary(&r).starts_with("group of 5 axes, cycles: 6000"));
    }

    /// A truncated trace, one with a flipped bit (caught by its CRC record) and one with bytes
    /// after `End` are refused, and `run` writes nothing.
    #[test]
    fn damaged_traces_fail_and_write_nothing() {
        let dir = scratch("damaged");
        let good = scenario::group(3, 6000).unwrap();
        let mut flipped = good.clone();
        let k = good.len() / 2;
        flipped[k] ^= 0x08;
        let mut trailing = good.clone();
        trailing.extend_from_slice(&[0; 7]);
        for (name, bytes, want) in [
            ("truncated", &good[..good.len() - 9], "damaged trace"),
            ("cut-at-record", &good[..good.len() - 5], "damaged trace"),
            ("flipped", &flipped[..], "damaged trace"),
            ("trailing", &trailing[..], "damaged trace"),
        ] {
            let trace = dir.join(format!("{name}.bin"));
            std::fs::write(&trace, bytes).unwrap();
            let out = dir.join(format!("{name}.out"));
            let csv = dir.join(format!("{name}.csv"));
            let e = run(Args {
                image: None,
                trace: trace.clone(),
                out: out.clone(),
                csv: Some(csv.clone()),
            })
            .unwrap_err();
            assert!(format!("{e:#}").contains(want), "{name}: {e:#}");
            assert!(!out.exists() && !csv.exists(), "{name}: nothing written");
        }
        // The good one replays.
        let trace = dir.join("good.bin");
        std::fs::write(&trace, &good).unwrap();
        run(Args {
            image: None,
            trace,
            out: dir.join("good.out"),
            csv: None,
        })
        .unwrap();
        assert_eq!(
            std::fs::read(dir.join("good.out")).unwrap().len(),
            6000 * 3 * 32
        );
        let _ = std::fs::remove_dir_all(&dir);
    }
}
