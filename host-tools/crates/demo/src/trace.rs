//! The compensated campaign's moves as the firmware would log them (a binary trace), by a closed loop
//! of the core's engine with an ideal servo.

use axcomp_core::trace::{OutputRecord, Record, Writer};
use axcomp_core::{CycleInput, Engine};
use axcomp_twin::{Axis, Campaign};

use crate::{DemoError, Result, StepContext};

/// Cycles per straight leg of an approach path in the recorded trace.
const LEG_CYCLES: i64 = 16;
/// Cycles at a target: at least this many, then until the corrected command is steady.
const MIN_DWELL_CYCLES: usize = 4;
const MAX_DWELL_CYCLES: usize = 2_000;

/// A recorded closed loop: the trace bytes, the engine's outputs and the index of the output at which
/// each campaign row was read.
pub(crate) struct ClosedLoop {
    pub trace: Vec<u8>,
    pub outputs: Vec<OutputRecord>,
    pub read_at: Vec<usize>,
}

fn trace_error(e: impl std::fmt::Display) -> DemoError {
    DemoError::Firmware(format!("trace: {e}"))
}

/// One record into the trace and through the engine.
fn push(w: &mut Writer<'_>, engine: &mut Engine, rec: Record<'_>) -> Result<Option<OutputRecord>> {
    w.push(&rec).map_err(trace_error)?;
    Ok(engine.step(&rec))
}

/// The path of one row: from `here` to the approach point `overshoot_mm` before the target on the
/// row's side, then to the target, [`LEG_CYCLES`] commands per leg.
fn approach_path(
    axis: &Axis,
    here: i64,
    target_mm: f64,
    direction: i8,
    overshoot_mm: f64,
) -> Vec<i64> {
    let target = axis.counts(target_mm);
    let approach = axis.counts(target_mm - direction as f64 * overshoot_mm);
    let mut path = Vec::new();
    for (from, to) in [(here, approach), (approach, target)] {
        path.extend((1..=LEG_CYCLES).map(|k| from + (to - from) * k / LEG_CYCLES));
    }
    path
}

/// The compensated campaign's moves as the firmware would log them: a closed loop of the core's
/// [`Engine`] (image record first) with an ideal servo (the scale reads the previous corrected command),
/// each row approached over `overshoot_mm` from its direction.
pub(crate) fn closed_loop_trace(
    axis: &Axis,
    image: &[u8],
    campaign: &Campaign,
    overshoot_mm: f64,
) -> Result<ClosedLoop> {
    let mut buf = vec![0u8; 64 + image.len() + campaign.rows.len() * 256 * 40];
    let mut w = Writer::new(&mut buf).map_err(trace_error)?;
    let mut engine = Box::new(Engine::new());
    let mut outputs = Vec::new();
    let mut read_at = Vec::with_capacity(campaign.rows.len());
    push(&mut w, &mut engine, Record::Image(image))?;
    let start = axis.counts(axis.start_mm - overshoot_mm);
    push(
        &mut w,
        &mut engine,
        Record::Reset {
            scale_raw: start as u32,
        },
    )?;
    let mut scale = start;
    let mut here = start;
    for row in &campaign.rows {
        let target = axis.counts(row.target_mm);
        let path = approach_path(axis, here, row.target_mm, row.direction, overshoot_mm);
        let mut steady = 0usize;
        let mut dwell = 0usize;
        let mut k = 0usize;
        loop {
            let command = path.get(k).copied().unwrap_or(target);
            k += 1;
            let input = CycleInput {
                scale_raw: scale as u32,
                command_counts: command,
                forces_n: [0.0; 3],
            };
            let out = push(&mut w, &mut engine, Record::Cycle(input))?
                .step(|| "a cycle record gives an output".into())?;
            let moved = out.corrected_command_counts != scale;
            scale = out.corrected_command_counts;
            outputs.push(out);
            if k > path.len() {
                dwell += 1;
                steady = if moved { 0 } else { steady + 1 };
                if (dwell >= MIN_DWELL_CYCLES && steady >= 2) || dwell >= MAX_DWELL_CYCLES {
                    break;
                }
            }
        }
        read_at.push(outputs.len() - 1);
        here = target;
    }
    push(&mut w, &mut engine, Record::End)?;
    let n = w.finish();
    buf.truncate(n);
    Ok(ClosedLoop {
        trace: buf,
        outputs,
        read_at,
    })
}
