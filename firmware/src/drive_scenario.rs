//! Drive-trace scenarios (setpoint link, [`crate::drive::link_trace`]): the part of the scenario generator
//! that needs the firmware's own link and drive types, so it lives here rather than in the host crate
//! `axcomp-scenario`; [`crate::scenario`] re-exports both.

use std::vec::Vec;

use axcomp_core::bench;
use axcomp_scenario::*;

// ------------------------------------------------------------------------------------------------
// Drive traces (setpoint link, `crate::drive::link_trace`)
// ------------------------------------------------------------------------------------------------

/// Cycle-clock ticks per cycle of the drive traces (170 MHz / 10 kHz).
pub const LINK_TICKS_PER_CYCLE: u32 = 17_000;
/// Compute time of every drive-trace cycle, ticks (an overrun is made by a longer one).
pub const LINK_COMPUTE_TICKS: u32 = 2_000;

/// Builds a drive trace for the 3-axis group of [`crate::drive::link_trace::REPLAY_CAPS`].
struct LinkRig {
    t: crate::drive::link_trace::write::LinkTraceBuilder,
    seq: u8,
}

impl LinkRig {
    fn new() -> Self {
        LinkRig {
            t: crate::drive::link_trace::write::LinkTraceBuilder::new(),
            seq: 0,
        }
    }
    fn commands(i: u32) -> [i32; 3] {
        let g = bench::group_input(i);
        [0, 1, 2].map(|k| g.axes[k].command_counts as i32)
    }
    /// The encoded setpoint frame of cycle `i` with sequence `seq`.
    fn frame_bytes(seq: u8, cmds: &[i32]) -> Vec<u8> {
        let f = crate::setpoint::SetpointFrame::new(seq, cmds).expect("1..=5 axes");
        let mut b = [0u8; crate::setpoint::MAX_SETPOINT_FRAME_LEN];
        let n = f.encode_into(&mut b);
        b[..n].to_vec()
    }
    /// The next fresh frame with cycle `i`'s commands.
    fn frame(&mut self, i: u32) -> Vec<u8> {
        self.seq = self.seq.wrapping_add(1);
        let b = Self::frame_bytes(self.seq, &Self::commands(i));
        self.t.link(&b);
        b
    }
    /// Cycle `i` (16-bit counters, at its slot of the schedule + `late_ticks`, computing `compute_ticks`).
    fn cycle_at(&mut self, i: u32, moving: bool, late_ticks: u32, compute_ticks: u32) {
        let g = bench::group_input(if moving { i } else { 1234 });
        let mut scales = [0u32; axcomp_core::group::MAX_AXES];
        for (s, a) in scales.iter_mut().zip(g.axes.iter()).take(3) {
            *s = a.scale_raw & 0xFFFF;
        }
        let start = i
            .wrapping_mul(LINK_TICKS_PER_CYCLE)
            .wrapping_add(late_ticks);
        self.t
            .cycle(start, start.wrapping_add(compute_ticks), &scales);
    }
    fn cycle(&mut self, i: u32, moving: bool) {
        self.cycle_at(i, moving, 0, LINK_COMPUTE_TICKS);
    }
}

/// The setpoint-link equivalence trace of a 3-axis group (`cycles` ≥ 3000 cycles): cycles before any
/// image (identity, no frames), the `group3` image, every axis moving, temperatures every 100 ms;
/// one late cycle, 100 cycles without frames (hold, ramp-out, ramp-in), a corrupt frame, a repeated
/// frame, three lost frames, a frame with too few axes, garbage before a frame, two frames in one cycle,
/// a late cycle start, an overrun, a corrupt group image (refused), a 32-bit image (refused), the
/// replacement image (A/B swap of all three axes).
pub fn group_link(cycles: u32) -> Result<Vec<u8>, ScenarioError> {
    const MIN: u32 = 3000;
    if cycles < MIN {
        return Err(ScenarioError::TooFewCycles {
            scenario: "group_link",
            min: MIN,
        });
    }
    let first = group_image(3, false)?;
    let second = group_image(3, true)?;
    let wide = group_image_variant(3, false, GroupImageVariant::CounterBits(32))?;
    let mut corrupt = second.clone();
    let at = corrupt.len() / 2;
    corrupt[at] ^= 0x10;
    let mut r = LinkRig::new();
    for i in 0..5 {
        r.cycle(i, true);
    }
    r.t.image(&first);
    for i in 5..cycles {
        if i % CYCLES_PER_TEMPERATURE == 0 {
            let w = (i / CYCLES_PER_TEMPERATURE) as f32 * 0.05;
            r.t.temperatures(i / 10, &[20.0 + w, 21.0 + 0.5 * w]);
        }
        let k = i % 1500;
        match k {
            500 => {}
            600..700 => {}
            800 => {
                let mut b = LinkRig::frame_bytes(r.seq.wrapping_add(1), &LinkRig::commands(i));
                b[6] ^= 0x01;
                r.t.link(&b);
            }
            900 => {
                let b = LinkRig::frame_bytes(r.seq, &LinkRig::commands(i - 1));
                r.t.link(&b);
            }
            1000 => {
                r.seq = r.seq.wrapping_add(3);
                r.frame(i);
            }
            1100 => {
                r.seq = r.seq.wrapping_add(1);
                let c = LinkRig::commands(i);
                r.t.link(&LinkRig::frame_bytes(r.seq, &c[..2]));
            }
            1200 => {
                r.t.link(&[0x00, 0xA5, 0x13, 0xFF, 0x5A]);
                r.frame(i);
            }
            1250 => {
                r.frame(i - 1);
                r.frame(i);
            }
            _ => {
                r.frame(i);
            }
        }
        if i == cycles / 3 {
            r.t.image(&corrupt);
        }
        if i == cycles / 3 + 10 {
            r.t.image(&wide);
        }
        if i == cycles / 2 {
            r.t.image(&second);
        }
        match k {
            1300 => r.cycle_at(i, true, 5_000, LINK_COMPUTE_TICKS),
            1400 => r.cycle_at(i, true, 0, 20_000),
            _ => r.cycle(i, true),
        }
    }
    Ok(r.t.finish())
}

/// The faults of the drive fault matrix, each a drive trace of its own
/// ([`drive_fault_trace`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DriveFault {
    CounterWidthMismatch,
    AxisIdMismatch,
    SensorCountMismatch,
    StaleSensor,
    OutOfRangeInput,
    LateFrames,
    CorruptFrame,
    RepeatedFrame,
    Overrun,
    ImageWithTrailingBytes,
    CorruptImage,
    /// X's sensor 0 named `warmup`: not one of the board's inputs (the warm-up case).
    SensorNotOnBoard,
}

impl DriveFault {
    pub const ALL: [DriveFault; 12] = [
        DriveFault::CounterWidthMismatch,
        DriveFault::AxisIdMismatch,
        DriveFault::SensorCountMismatch,
        DriveFault::StaleSensor,
        DriveFault::OutOfRangeInput,
        DriveFault::LateFrames,
        DriveFault::CorruptFrame,
        DriveFault::RepeatedFrame,
        DriveFault::Overrun,
        DriveFault::ImageWithTrailingBytes,
        DriveFault::CorruptImage,
        DriveFault::SensorNotOnBoard,
    ];
    /// The cycle at which the fault starts.
    pub const AT: u32 = 200;
    /// Cycles of the trace (the stale sensor needs 60 s hold + 60 s ramp at one cycle per reading).
    pub fn cycles(self) -> u32 {
        match self {
            DriveFault::StaleSensor => 1_500,
            _ => 400,
        }
    }
    /// Cycles without a frame in [`DriveFault::LateFrames`].
    pub const LATE_CYCLES: u32 = 100;
}

/// The drive trace of one fault (`with_fault = false`: the same trace without it, the reference its
/// end state is compared with). Every trace: the `group3` image at the start, one fresh frame and one
/// temperature reading set (`now_ms` + 100 per cycle: one cycle per sensor period, so that the stale
/// sensor's 60 s hold and 60 s ramp take 1 200 cycles) before each cycle; the fault at cycle
/// [`DriveFault::AT`]. The axes move except in `StaleSensor` (standing axes: the correction changes only
/// by the thermal term).
pub fn drive_fault_trace(fault: DriveFault, with_fault: bool) -> Result<Vec<u8>, ScenarioError> {
    let first = group_image(3, false)?;
    let bad_image = match fault {
        DriveFault::CounterWidthMismatch => Some(group_image_variant(
            3,
            true,
            GroupImageVariant::CounterBits(32),
        )?),
        DriveFault::AxisIdMismatch => Some(group_image_variant(
            3,
            true,
            GroupImageVariant::AxisId { slot: 1, id: 9 },
        )?),
        DriveFault::SensorCountMismatch => {
            Some(group_image_variant(3, true, GroupImageVariant::Sensors(3))?)
        }
        DriveFault::SensorNotOnBoard => Some(group_image_variant(
            3,
            true,
            GroupImageVariant::WarmupSensor,
        )?),
        DriveFault::ImageWithTrailingBytes => {
            let mut b = group_image(3, true)?;
            b.extend_from_slice(&[0u8; 100]);
            Some(b)
        }
        DriveFault::CorruptImage => {
            let mut b = group_image(3, true)?;
            let at = b.len() / 2;
            b[at] ^= 0x10;
            Some(b)
        }
        _ => None,
    };
    let moving = fault != DriveFault::StaleSensor;
    let at = DriveFault::AT;
    let mut r = LinkRig::new();
    r.t.image(&first);
    for i in 0..fault.cycles() {
        let fault_now = with_fault && i >= at;
        // X's spindle sensor 5 K above its reference: a thermal term of about 2 µm to ramp out.
        let mut readings = [25.0 + i as f32 * 0.001, 21.0];
        if fault_now && fault == DriveFault::StaleSensor {
            readings[0] = f32::NAN;
        }
        if fault_now && i == at && fault == DriveFault::OutOfRangeInput {
            readings[1] = 150.0;
        }
        r.t.temperatures(i * 100, &readings);
        if fault_now && i == at {
            if let Some(b) = &bad_image {
                r.t.image(b);
            }
        }
        let late =
            fault == DriveFault::LateFrames && (at..at + DriveFault::LATE_CYCLES).contains(&i);
        if with_fault && i == at && fault == DriveFault::CorruptFrame {
            let mut b = LinkRig::frame_bytes(r.seq.wrapping_add(1), &LinkRig::commands(i));
            b[5] ^= 0x80;
            r.t.link(&b);
        } else if with_fault && i == at && fault == DriveFault::RepeatedFrame {
            r.t.link(&LinkRig::frame_bytes(r.seq, &LinkRig::commands(i - 1)));
        } else if !(with_fault && late) {
            r.frame(i);
        }
        if with_fault && i == at && fault == DriveFault::Overrun {
            r.cycle_at(i, moving, 0, 20_000);
        } else {
            r.cycle(i, moving);
        }
    }
    Ok(r.t.finish())
}
