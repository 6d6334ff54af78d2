//! A binary trace run through the firmware's compensation logic (`axcomp_core::Engine`, or
//! `axcomp_core::group::GroupEngine` for a group trace: the same code the QEMU firmware runs), and
//! its output records as CSV and a summary.
//!
//! Glossary:
//! - *trace*: binary records (cycle inputs, temperatures, process parameters, images), `axcomp trace`.
//! - *output record*: 32 bytes per cycle record (`axcomp_core::trace::OutputRecord`, little endian).
//! - *flags*: per-cycle condition bits (table outside, clamped, slewed, sensor fault, ...).

use std::fmt::Write as _;

use axcomp_core::group::{GroupEngine, MAX_AXES};
use axcomp_core::trace::{OutputRecord, Reader, Record, TraceError};
use axcomp_core::{Engine, EngineStats, Flags};

/// Coefficient pool of the host's group engine (segments): room for 5 axes × 2 × 1024.
const HOST_GROUP_POOL: usize = 10 * 1024;

/// Why a trace cannot be replayed.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// Not a trace at all.
    #[error("not an axcomp trace: {0}")]
    NotATrace(TraceError),
    /// A trace that fails the whole-trace check (a bad record, no `End`, a CRC mismatch).
    #[error("damaged trace: {0}")]
    Damaged(TraceError),
    /// The image given with the trace does not load.
    #[error("the image is not valid: {0}")]
    Image(String),
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
pub fn replay(image: Option<&[u8]>, trace: &[u8]) -> Result<Replay, ReplayError> {
    let check = axcomp_core::trace::verify(trace).map_err(|e| match e {
        TraceError::TooShort | TraceError::BadMagic => ReplayError::NotATrace(e),
        _ => ReplayError::Damaged(e),
    })?;
    if check.is_group {
        return replay_group(image, trace);
    }
    let mut engine = Box::new(Engine::new());
    if let Some(img) = image {
        engine
            .load_image(img)
            .map_err(|e| ReplayError::Image(e.to_string()))?;
    }
    let reader = Reader::new(trace).map_err(ReplayError::NotATrace)?;
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
fn replay_group(image: Option<&[u8]>, trace: &[u8]) -> Result<Replay, ReplayError> {
    let mut engine: Box<GroupEngine<HOST_GROUP_POOL>> = Box::new(GroupEngine::new());
    if let Some(img) = image {
        engine
            .load_image(img)
            .map_err(|e| ReplayError::Image(e.to_string()))?;
    }
    let mut outputs = Vec::new();
    let mut trace_errors = Vec::new();
    let mut axes = 0;
    let mut out = [OutputRecord::ZERO; MAX_AXES];
    for rec in Reader::new(trace).map_err(ReplayError::NotATrace)? {
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
