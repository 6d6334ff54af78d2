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

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context;
use axcomp_core::group::{GroupEngine, MAX_AXES};
use axcomp_core::trace::{OutputRecord, Reader, Record};
use axcomp_core::{Engine, EngineStats, Flags};

/// Coefficient pool of the host's group engine (segments): room for 5 axes × 2 × 1024.
const HOST_GROUP_POOL: usize = 10 * 1024;

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

/// What a replay produced.
#[derive(Debug, Clone)]
pub struct Replay {
    pub outputs: Vec<OutputRecord>,
    /// Trace records that were reported and skipped (or ended the replay), as messages.
    pub trace_errors: Vec<String>,
    pub stats: EngineStats,
    /// Axes per cycle of a group trace (None for a single-axis trace).
    pub group_axes: Option<usize>,
}

/// Runs `trace` through a fresh engine, after loading `image` if given. The trace must pass
/// `axcomp_core::trace::verify` first.
pub fn replay(image: Option<&[u8]>, trace: &[u8]) -> anyhow::Result<Replay> {
    let check = axcomp_core::trace::verify(trace).map_err(|e| match e {
        axcomp_core::trace::TraceError::TooShort | axcomp_core::trace::TraceError::BadMagic => {
            anyhow::anyhow!("not an axcomp trace: {e}")
        }
        _ => anyhow::anyhow!("damaged trace: {e}"),
    })?;
    if check.is_group {
        return replay_group(image, trace);
    }
    let mut engine = Box::new(Engine::new());
    if let Some(img) = image {
        engine.load_image(img).context("the image is not valid")?;
    }
    let reader = Reader::new(trace).context("not an axcomp trace")?;
    let mut outputs = Vec::new();
    let mut trace_errors = Vec::new();
    for rec in reader {
        match rec {
            Ok(r) => {
                if let Some(o) = engine.step(&r) {
                    outputs.push(o);
                }
                if r == Record::End {
                    break;
                }
            }
            Err(e) => trace_errors.push(e.to_string()),
        }
    }
    Ok(Replay {
        outputs,
        trace_errors,
        stats: *engine.stats(),
        group_axes: None,
    })
}

/// [`replay`] of a group trace through a `GroupEngine` (`image`: a group image or a schema-1 one).
fn replay_group(image: Option<&[u8]>, trace: &[u8]) -> anyhow::Result<Replay> {
    let mut engine: Box<GroupEngine<HOST_GROUP_POOL>> = Box::new(GroupEngine::new());
    if let Some(img) = image {
        engine
            .load_image(img)
            .map_err(|e| anyhow::anyhow!("the image is not valid: {e}"))?;
    }
    let mut outputs = Vec::new();
    let mut trace_errors = Vec::new();
    let mut axes = 0;
    let mut out = [OutputRecord::ZERO; MAX_AXES];
    for rec in Reader::new(trace).context("not an axcomp trace")? {
        match rec {
            Ok(r) => {
                let n = engine.step(&r, &mut out);
                if n > 0 {
                    axes = axes.max(n);
                    outputs.extend_from_slice(&out[..n]);
                }
                if r == Record::End {
                    break;
                }
            }
            Err(e) => trace_errors.push(e.to_string()),
        }
    }
    let g = engine.stats();
    Ok(Replay {
        outputs,
        trace_errors,
        stats: EngineStats {
            cycles: g.cycles,
            temperature_updates: 0,
            images_accepted: g.images_accepted,
            images_rejected: g.images_rejected,
            last_image_error: g.last_error,
        },
        group_axes: Some(axes.max(1)),
    })
}

const FLAG_NAMES: [(Flags, &str); 11] = [
    (Flags::TABLE_OUTSIDE, "TABLE_OUTSIDE"),
    (Flags::CLAMPED, "CLAMPED"),
    (Flags::SLEWED, "SLEWED"),
    (Flags::SENSOR_FAULT, "SENSOR_FAULT"),
    (Flags::THERMAL_FROZEN, "THERMAL_FROZEN"),
    (Flags::FORCE_INVALID, "FORCE_INVALID"),
    (Flags::NON_FINITE, "NON_FINITE"),
    (Flags::BACKWARD, "BACKWARD"),
    (Flags::IDENTITY, "IDENTITY"),
    (Flags::THERMAL_RAMP_OUT, "THERMAL_RAMP_OUT"),
    (Flags::THERMAL_GUARDED, "THERMAL_GUARDED"),
];

/// Names of the flags set in `bits`, `|`-separated (empty string for none).
pub fn flag_names(bits: u16) -> String {
    let f = Flags::from_bits(bits);
    FLAG_NAMES
        .iter()
        .filter(|(flag, _)| f.contains(*flag))
        .map(|(_, n)| *n)
        .collect::<Vec<_>>()
        .join("|")
}

/// The output records of a group replay as CSV: an `axis` column (slot) first.
pub fn to_group_csv(outputs: &[OutputRecord], axes: usize) -> String {
    let single = to_csv(outputs);
    let mut s = String::new();
    for (k, line) in single.lines().enumerate() {
        if k == 0 {
            let _ = writeln!(s, "axis,{line}");
        } else {
            let _ = writeln!(s, "{},{line}", (k - 1) % axes.max(1));
        }
    }
    s
}

/// The output records as CSV.
pub fn to_csv(outputs: &[OutputRecord]) -> String {
    let mut s = String::from(
        "cycle,position_counts,corrected_command_counts,correction_counts,correction_um,flags,flag_names,slot,status\n",
    );
    for o in outputs {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{}",
            o.cycle,
            o.position_counts,
            o.corrected_command_counts,
            o.correction_counts,
            o.correction_um(),
            o.flags,
            flag_names(o.flags),
            o.slot,
            o.status
        );
    }
    s
}

/// One-paragraph summary: cycles, largest |correction|, flags seen, images, trace errors.
pub fn summary(r: &Replay) -> String {
    let max = r
        .outputs
        .iter()
        .map(|o| o.correction_um().abs())
        .fold(0.0f32, f32::max);
    let max_counts = r
        .outputs
        .iter()
        .map(|o| o.correction_counts.unsigned_abs())
        .max()
        .unwrap_or(0);
    let mut seen = 0u16;
    let mut counts = [0usize; FLAG_NAMES.len()];
    for o in &r.outputs {
        seen |= o.flags;
        for (k, (flag, _)) in FLAG_NAMES.iter().enumerate() {
            if Flags::from_bits(o.flags).contains(*flag) {
                counts[k] += 1;
            }
        }
    }
    let flags: Vec<String> = FLAG_NAMES
        .iter()
        .zip(counts)
        .filter(|(_, c)| *c > 0)
        .map(|((_, n), c)| format!("{n}×{c}"))
        .collect();
    let axes = r.group_axes.unwrap_or(1);
    let mut s = format!(
        "{}cycles: {}, max |correction|: {max:.3} µm ({max_counts} counts), flags seen: {}\n",
        match r.group_axes {
            Some(n) => format!("group of {n} axes, "),
            None => String::new(),
        },
        r.outputs.len() / axes,
        if seen == 0 {
            "none".to_string()
        } else {
            flags.join(", ")
        }
    );
    let _ = writeln!(
        s,
        "images accepted: {}, rejected: {}{}, temperature updates: {}, trace errors: {}",
        r.stats.images_accepted,
        r.stats.images_rejected,
        r.stats
            .last_image_error
            .map(|e| format!(" (last: {e})"))
            .unwrap_or_default(),
        r.stats.temperature_updates,
        r.trace_errors.len()
    );
    s
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
