//! `axcomp replay`: runs the firmware's compensation logic (`axcomp_core::Engine`, the same code the
//! QEMU firmware runs) over a binary trace and writes the output records.
//!
//! Glossary:
//! - *trace*: binary records (cycle inputs, temperatures, process parameters, images), `axcomp trace`.
//! - *output record*: 32 bytes per cycle record (`axcomp_core::trace::OutputRecord`, little endian),
//!   written back to back without a header, exactly as the QEMU firmware writes them.
//! - *flags*: per-cycle condition bits (table outside, clamped, slewed, sensor fault, ...).
//!
//! Errors in the trace follow the firmware: a record with intact framing but bad content is reported and
//! skipped, a truncated record is reported and ends the replay. A rejected `--image` is an error.

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context;
use axcomp_core::trace::{OutputRecord, Reader, Record};
use axcomp_core::{Engine, EngineStats, Flags};

use super::common::write_atomic;

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
}

/// Runs `trace` through a fresh engine, after loading `image` if given.
pub fn replay(image: Option<&[u8]>, trace: &[u8]) -> anyhow::Result<Replay> {
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
    })
}

const FLAG_NAMES: [(Flags, &str); 9] = [
    (Flags::TABLE_OUTSIDE, "TABLE_OUTSIDE"),
    (Flags::CLAMPED, "CLAMPED"),
    (Flags::SLEWED, "SLEWED"),
    (Flags::SENSOR_FAULT, "SENSOR_FAULT"),
    (Flags::THERMAL_FROZEN, "THERMAL_FROZEN"),
    (Flags::FORCE_INVALID, "FORCE_INVALID"),
    (Flags::NON_FINITE, "NON_FINITE"),
    (Flags::BACKWARD, "BACKWARD"),
    (Flags::IDENTITY, "IDENTITY"),
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
    let mut s = format!(
        "cycles: {}, max |correction|: {max:.3} µm ({max_counts} counts), flags seen: {}\n",
        r.outputs.len(),
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
    write_atomic(&args.out, &bytes)?;
    if let Some(csv) = &args.csv {
        write_atomic(csv, to_csv(&r.outputs).as_bytes())?;
    }
    print!("{}", summary(&r));
    println!(
        "wrote {} ({} records × 32 bytes)",
        args.out.display(),
        r.outputs.len()
    );
    Ok(())
}
