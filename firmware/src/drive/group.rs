//! The drive of an axis group: one setpoint frame per cycle carries every axis's command, one
//! [`GroupEngine`] cycle corrects them all, one reply frame carries every axis's corrected command and
//! the status word (the flags of every axis merged).
//!
//! - **Axis ↔ board input**: group axis `i` (its slot in the image) runs on the board's scale input at
//!   the position of its image's axis id in [`BoardCaps::axis_ids`]; its command is the setpoint frame's
//!   entry at that same position (frame order = board input order). The reply frame carries the
//!   corrected commands in the same order, one per board input the frame addressed (`n_inputs`).
//! - **Without an image** (identity): every board input is an axis and is passed through uncorrected.
//! - **Link faults**: each axis has its own [`LinkSupervisor`] fed by the same frames, so a late,
//!   corrupt or repeated frame holds every axis's correction, then ramps every one out at the same
//!   rate (each in its own units), then back in.
//! - **Image check**: every axis of a group image is checked against the board (counter width, axis id
//!   wired, sensors wired; an axis id on two axes is refused) before the engine sees it; the engine then
//!   swaps A/B for the whole group at once, or keeps the running group.
//! - **Temperatures**: the board declares its inputs by name and unit ([`GroupDrive::with_sensor_inputs`],
//!   `axcomp_core::wiring`); at load every sensor of every axis is wired to the input of its name (an
//!   image without names: sensor `j` = input `j`, temperatures only), and a sensor no input can feed is
//!   a refusal ([`ImageRefusal::SensorNotOnBoard`]). A reading set goes to every axis through its
//!   wiring ([`GroupDrive::update_temperatures`]). A drive without declared inputs wires by position
//!   and checks only the count ([`BoardCaps::sensors`]).
//! - **Touch probe** ([`super::probe`]): with probe settings in the image, [`GroupDrive::cycle_with_probe`]
//!   reads the board's [`ProbeIo`] after the engine's cycle, latches the corrected point, sets the
//!   `PROBE_*` status flags and answers with v3 reply frames; [`GroupDrive::cycle`] is the same with
//!   no probe input.
//! - **Cycle record**: [`GroupDrive::cycle`] returns the cycle's per-axis record
//!   ([`GroupDriveCycle`], the replay's and the tests' path); the run loop ([`GroupDrive::run`],
//!   the board) runs the same cycle without it ([`GroupDrive::cycle_status`]: the status word
//!   only, no 5-slot record initialised and written each cycle).

use axcomp_core::group::{GroupEngine, GroupInput, GroupOutput, MAX_AXES};
use axcomp_core::wiring::{self, BoardInput, SensorWiring};
use axcomp_core::{
    CycleInput, CycleOutput, Flags, MAX_FORCES, MAX_SENSORS, group_image, inspect_image,
};

use super::probe::{NoProbe, ProbeDrive, ProbeIo};
use super::{
    Applied, BoardCaps, DriveCounters, DriveIo, ImageRefusal, LINK_CHUNK, LINK_READS_PER_CYCLE,
    LatenessMeter, LinkPhase, LinkSettings, LinkSupervisor, ResetCause, Watchdog, core_status,
};
use crate::control::{CycleClock, CycleTimer, LoopConfig};
use crate::setpoint::{CounterId, MAX_REPLY_FRAME_LEN, ReplyFields, SetpointDecoder, encode_reply};
use crate::status::Status;

/// Board inputs of a group image's axes (by group slot) and how many axes it has.
pub type AxisInputs = ([u8; MAX_AXES], usize);

/// Validates a group image (schema 2, or schema 1 as one axis) and checks every axis against the
/// board; returns the board input of each axis. The image is never loaded here.
pub fn check_group_image(caps: &BoardCaps, image: &[u8]) -> Result<AxisInputs, ImageRefusal> {
    check_group_image_wired(caps, None, image).map(|(inputs, _)| inputs)
}

/// [`check_group_image`] with the board's named sensor inputs (`None`: by position, count only);
/// also returns each axis's sensor wiring (by group slot).
pub fn check_group_image_wired(
    caps: &BoardCaps,
    sensor_inputs: Option<&[BoardInput]>,
    image: &[u8],
) -> Result<(AxisInputs, [SensorWiring; MAX_AXES]), ImageRefusal> {
    let view = group_image::parse(image).map_err(ImageRefusal::Invalid)?;
    // The pivot check (`check_group`) is the host's (`image group`, `inspect`): the QEMU group
    // firmware's code budget has no room for it (+300 … 600 B measured).
    view.check_axis_ids().map_err(ImageRefusal::Invalid)?;
    let mut inputs = [0u8; MAX_AXES];
    let mut wirings = [wiring::POSITIONAL; MAX_AXES];
    let mut n = 0;
    for a in view.axes() {
        let info = inspect_image(a.axis.image).map_err(ImageRefusal::Invalid)?;
        // The count first (more sensors than the board has inputs), then each sensor by name.
        let input = caps.check(info.axis_id, info.counter_bits, info.n_sensors)?;
        let w = match sensor_inputs {
            Some(board) => wiring::wire_axis(a, info.n_sensors, board).map_err(|why| {
                ImageRefusal::SensorNotOnBoard {
                    axis_id: info.axis_id,
                    why,
                }
            })?,
            None => wiring::POSITIONAL,
        };
        if n >= MAX_AXES {
            return Err(ImageRefusal::Invalid(axcomp_core::ImageError::AxisCount));
        }
        inputs[n] = input as u8;
        wirings[n] = w;
        n += 1;
    }
    Ok(((inputs, n), wirings))
}

/// One group cycle's result, by group slot (entries `n_axes..` are zero).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GroupDriveCycle {
    /// Axes corrected this cycle.
    pub n_axes: usize,
    /// Board inputs addressed by the frame and the reply (the largest input used + 1).
    pub n_inputs: usize,
    /// The command each axis followed (the last fresh one while frames are late).
    pub command_counts: [i64; MAX_AXES],
    /// What went to each axis: command − applied correction.
    pub corrected_command_counts: [i64; MAX_AXES],
    pub applied: [Applied; MAX_AXES],
    /// The merged status word.
    pub status: Status,
    /// The engine's outputs (before the link supervisor).
    pub engine: GroupOutput,
    /// This cycle's probe flags (none without probe settings).
    pub probe: axcomp_core::probe::ProbeFlags,
}

const APPLIED_ZERO: Applied = Applied {
    correction_counts: 0,
    correction_um: 0.0,
    phase: LinkPhase::Following,
};

/// Where a cycle puts each axis's command, applied correction and corrected command.
trait AxisResults {
    fn axis(&mut self, i: usize, command: i64, applied: Applied, corrected: i64);
}

/// Into the cycle's record ([`GroupDrive::cycle`]).
struct Record<'a> {
    command_counts: &'a mut [i64; MAX_AXES],
    corrected_command_counts: &'a mut [i64; MAX_AXES],
    applied: &'a mut [Applied; MAX_AXES],
}

impl AxisResults for Record<'_> {
    #[inline(always)]
    fn axis(&mut self, i: usize, command: i64, applied: Applied, corrected: i64) {
        self.command_counts[i] = command;
        self.corrected_command_counts[i] = corrected;
        self.applied[i] = applied;
    }
}

/// Nowhere: the status word is all the caller keeps ([`GroupDrive::cycle_status`], the run loop).
struct Discard;

impl AxisResults for Discard {
    #[inline(always)]
    fn axis(&mut self, _: usize, _: i64, _: Applied, _: i64) {}
}

/// Sensor readings rejected by every axis of the active group (one reply in twelve: out of line).
#[cold]
#[inline(never)]
fn sensor_readings_rejected<const POOL: usize>(engine: &GroupEngine<POOL>) -> u32 {
    let g = engine.active();
    let st = engine.state();
    (0..g.axis_count()).fold(0u32, |acc, i| {
        let sensors = g.axis(i).map_or(0, |a| a.sensor_count());
        (0..sensors).fold(acc, |a, j| a.wrapping_add(st.axes[i].rejected_readings(j)))
    })
}

/// Board inputs a frame of this group addresses: the largest input used + 1 (1 without axes).
fn inputs_addressed(inputs: &[u8]) -> u8 {
    inputs.iter().fold(0, |m: u8, &i| m.max(i)) + 1
}

/// The drive of a group: link decoding, one supervisor per axis, the group engine's cycle, the merged
/// status word and the reply frame.
pub struct GroupDrive {
    caps: BoardCaps,
    inputs: [u8; MAX_AXES],
    /// Board inputs a setpoint frame must carry and the reply carries (set with the group; a
    /// byte next to `inputs`: no static RAM added).
    n_inputs: u8,
    n_axes: usize,
    sensor_inputs: Option<&'static [BoardInput<'static>]>,
    wiring: [SensorWiring; MAX_AXES],
    decoder: SetpointDecoder,
    links: [LinkSupervisor; MAX_AXES],
    meter: LatenessMeter,
    latched: Status,
    last_seq: u8,
    reply_seq: u8,
    prev_overrun: bool,
    prev_reply_dropped: bool,
    next_counter: u8,
    counters: OwnCounters,
    last_status: Status,
    probe: ProbeDrive,
    /// The reply frame of the last cycle, encoded in place (bytes past its length are stale).
    reply: ReplyBuffer,
}

/// A reply frame's bytes, word aligned (copied out whole words at a time).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(4))]
struct ReplyBuffer([u8; MAX_REPLY_FRAME_LEN]);

/// The counters the drive keeps itself (the link's are the decoder's, the lateness the meter's:
/// [`GroupDrive::counters`] puts them together).
#[derive(Clone, Copy, Debug, Default)]
struct OwnCounters {
    cycles: u32,
    short_frames: u32,
    cycles_without_frame: u32,
    images_refused: u32,
    replies_dropped: u32,
}

impl GroupDrive {
    pub fn new(
        caps: BoardCaps,
        config: &LoopConfig,
        link: LinkSettings,
        reset: ResetCause,
    ) -> Self {
        let mut latched = Status::NONE;
        latched.set(Status::WATCHDOG_RESET, reset.watchdog);
        let (inputs, n_axes) = Self::identity_inputs(&caps);
        GroupDrive {
            caps,
            inputs,
            n_axes,
            n_inputs: inputs_addressed(&inputs[..n_axes]),
            sensor_inputs: None,
            wiring: [wiring::POSITIONAL; MAX_AXES],
            decoder: SetpointDecoder::new(),
            links: [LinkSupervisor::new(link); MAX_AXES],
            meter: LatenessMeter::new(config.period_ticks),
            latched,
            last_seq: 0,
            reply_seq: 0,
            prev_overrun: false,
            prev_reply_dropped: false,
            next_counter: 0,
            counters: OwnCounters::default(),
            last_status: Status::NONE,
            probe: ProbeDrive::new(config.period_ticks.saturating_mul(config.rate_hz)),
            reply: ReplyBuffer([0; MAX_REPLY_FRAME_LEN]),
        }
    }

    /// The probe latch (phase, latched point, counters).
    pub fn probe(&self) -> &ProbeDrive {
        &self.probe
    }

    fn identity_inputs(caps: &BoardCaps) -> AxisInputs {
        let n = caps.axis_ids.len().clamp(1, MAX_AXES);
        let mut inputs = [0u8; MAX_AXES];
        for (i, v) in inputs.iter_mut().enumerate() {
            *v = i as u8;
        }
        (inputs, n)
    }

    /// Declares the board's sensor inputs by name and unit (reading `k` of a set = input `k`): images
    /// are then wired by sensor name and a sensor no input can feed is refused at load. Set it before
    /// the first image is offered.
    pub fn with_sensor_inputs(mut self, inputs: &'static [BoardInput<'static>]) -> Self {
        self.sensor_inputs = Some(inputs);
        self
    }

    /// The declared sensor inputs, if any.
    pub fn sensor_inputs(&self) -> Option<&'static [BoardInput<'static>]> {
        self.sensor_inputs
    }

    /// The board input each sensor of group slot `i` reads (first `n_sensors` entries apply).
    pub fn sensor_wiring(&self, i: usize) -> Option<&SensorWiring> {
        self.wiring.get(i).filter(|_| i < self.n_axes)
    }

    /// Replaces the lateness meter (e.g. another tolerance).
    pub fn set_lateness_meter(&mut self, meter: LatenessMeter) {
        self.meter = meter;
    }

    pub fn caps(&self) -> &BoardCaps {
        &self.caps
    }

    /// Board input of each group slot (first [`GroupDrive::axis_count`]).
    pub fn inputs(&self) -> &[u8] {
        &self.inputs[..self.n_axes]
    }

    /// Axes the drive corrects (the board's inputs while no image runs).
    pub fn axis_count(&self) -> usize {
        self.n_axes
    }

    pub fn cycles(&self) -> u32 {
        self.counters.cycles
    }

    pub fn counters(&self) -> DriveCounters {
        let c = &self.counters;
        DriveCounters {
            cycles: c.cycles,
            link: *self.decoder.counters(),
            short_frames: c.short_frames,
            cycles_without_frame: c.cycles_without_frame,
            lateness: *self.meter.stats(),
            images_refused: c.images_refused,
            replies_dropped: c.replies_dropped,
        }
    }

    /// Status word of the last cycle.
    pub fn status(&self) -> Status {
        self.last_status
    }

    /// The link supervisor of group slot `i`.
    pub fn supervisor(&self, i: usize) -> Option<&LinkSupervisor> {
        self.links.get(i)
    }

    /// Checks `image` against the board for every axis, then offers it to the engine (A/B swap of the
    /// whole group). A refused image is never loaded (the running group is kept) and latches
    /// [`Status::IMAGE_REFUSED`] until an image is accepted.
    pub fn offer_image<const POOL: usize>(
        &mut self,
        engine: &mut GroupEngine<POOL>,
        image: &[u8],
    ) -> Result<(), ImageRefusal> {
        let result =
            check_group_image_wired(&self.caps, self.sensor_inputs, image).and_then(|ins| {
                engine
                    .load_image(image)
                    .map(|()| ins)
                    .map_err(ImageRefusal::Group)
            });
        match result {
            Ok(((inputs, n), wiring)) => {
                self.wiring = wiring;
                // Each axis's supervisor keeps following its own command: slots are re-mapped only
                // when the group's wiring changes.
                if (inputs, n) != (self.inputs, self.n_axes) {
                    let settings = *self.links[0].settings();
                    let old = self.links;
                    for (i, l) in self.links.iter_mut().enumerate() {
                        *l = self.inputs[..self.n_axes]
                            .iter()
                            .position(|&x| i < n && x == inputs[i])
                            .map_or(LinkSupervisor::new(settings), |j| old[j]);
                    }
                }
                self.inputs = inputs;
                self.n_axes = n;
                self.n_inputs = inputs_addressed(&inputs[..n]);
                self.latched.set(Status::IMAGE_REFUSED, false);
                self.probe
                    .configure(group_image::parse(image).ok().and_then(|v| v.probe));
                Ok(())
            }
            Err(e) => {
                self.latched.insert(Status::IMAGE_REFUSED);
                self.counters.images_refused = self.counters.images_refused.saturating_add(1);
                Err(e)
            }
        }
    }

    /// A set of board readings (reading `k` = board input `k`), to every axis through its wiring
    /// (a sensor whose input is missing from the set reads NaN, as the core treats a missing reading).
    // Not inlined: one copy for every caller (replay and board), not on the cycle's path.
    #[inline(never)]
    pub fn update_temperatures<const POOL: usize>(
        &self,
        engine: &mut GroupEngine<POOL>,
        now_ms: u32,
        readings: &[f32],
    ) {
        for i in 0..engine.active().axis_count() {
            let w = self.wiring.get(i).unwrap_or(&wiring::POSITIONAL);
            let mut axis = [f32::NAN; MAX_SENSORS];
            for (r, &k) in axis.iter_mut().zip(w.iter()) {
                *r = readings.get(usize::from(k)).copied().unwrap_or(f32::NAN);
            }
            engine.update_temperatures(i, now_ms, &axis);
        }
    }

    /// One cycle: lateness, link bytes → fresh frame, a supervised command per axis, the group
    /// engine's cycle, the applied corrections, the status word and the reply frame; feeds the
    /// watchdog at the end.
    pub fn cycle<const POOL: usize, Io: DriveIo, C: CycleClock, W: Watchdog>(
        &mut self,
        engine: &mut GroupEngine<POOL>,
        io: &mut Io,
        clock: &C,
        watchdog: &mut W,
    ) -> GroupDriveCycle {
        self.cycle_with_probe(engine, io, &mut NoProbe, clock, watchdog)
    }

    /// [`GroupDrive::cycle`] with the board's probe input: after the engine's cycle, the probe's edges
    /// since the last cycle go through the latch ([`ProbeDrive::cycle`]), its events into the status
    /// word, and (with probe settings) the reply is a v3 frame with the probe block.
    pub fn cycle_with_probe<
        const POOL: usize,
        Io: DriveIo,
        P: ProbeIo,
        C: CycleClock,
        W: Watchdog,
    >(
        &mut self,
        engine: &mut GroupEngine<POOL>,
        io: &mut Io,
        probe_io: &mut P,
        clock: &C,
        watchdog: &mut W,
    ) -> GroupDriveCycle {
        // The cycle's record is built in place (the caller's return slot): the engine writes its
        // outputs into it and the per-axis results go straight into its arrays, no copy on return.
        let mut r = GroupDriveCycle {
            n_axes: self.n_axes,
            n_inputs: usize::from(self.n_inputs),
            command_counts: [0; MAX_AXES],
            corrected_command_counts: [0; MAX_AXES],
            applied: [APPLIED_ZERO; MAX_AXES],
            status: Status::NONE,
            engine: GroupOutput::ZERO,
            probe: axcomp_core::probe::ProbeFlags::NONE,
        };
        let GroupDriveCycle {
            command_counts,
            corrected_command_counts,
            applied,
            engine: out,
            ..
        } = &mut r;
        let mut record = Record {
            command_counts,
            corrected_command_counts,
            applied,
        };
        let (status, probe) =
            self.cycle_recorded(engine, io, probe_io, clock, watchdog, out, &mut record);
        r.status = status;
        r.probe = probe;
        r
    }

    /// [`GroupDrive::cycle`] without the cycle's record: the same cycle (frames, supervisors,
    /// engine, status word, reply frame, watchdog), only the status word is returned and no
    /// per-axis record is built. What [`GroupDrive::run`] runs.
    pub fn cycle_status<const POOL: usize, Io: DriveIo, C: CycleClock, W: Watchdog>(
        &mut self,
        engine: &mut GroupEngine<POOL>,
        io: &mut Io,
        clock: &C,
        watchdog: &mut W,
    ) -> Status {
        self.cycle_status_with_probe(engine, io, &mut NoProbe, clock, watchdog)
    }

    /// [`GroupDrive::cycle_with_probe`] without the cycle's record (see
    /// [`GroupDrive::cycle_status`]). What [`GroupDrive::run_with_probe`] runs.
    pub fn cycle_status_with_probe<
        const POOL: usize,
        Io: DriveIo,
        P: ProbeIo,
        C: CycleClock,
        W: Watchdog,
    >(
        &mut self,
        engine: &mut GroupEngine<POOL>,
        io: &mut Io,
        probe_io: &mut P,
        clock: &C,
        watchdog: &mut W,
    ) -> Status {
        // Slots the engine does not write (beyond the group) read as identity outputs; only the
        // group's are read. (Not all zero: a pattern of stores, no 160-byte clear.)
        let mut out = GroupOutput {
            axes: [CycleOutput {
                position_counts: 0,
                corrected_command_counts: 0,
                correction_counts: 0,
                correction_um: 0.0,
                flags: Flags::IDENTITY,
            }; MAX_AXES],
        };
        self.cycle_in(
            engine,
            io,
            probe_io,
            clock,
            watchdog,
            &mut out,
            &mut Discard,
        )
        .0
    }

    /// [`GroupDrive::cycle_in`] into a record, not inlined into its caller (the replay loop):
    /// one copy of the cycle, less code flash; the record is still written in place.
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    fn cycle_recorded<const POOL: usize, Io: DriveIo, P: ProbeIo, C: CycleClock, W: Watchdog>(
        &mut self,
        engine: &mut GroupEngine<POOL>,
        io: &mut Io,
        probe_io: &mut P,
        clock: &C,
        watchdog: &mut W,
        out: &mut GroupOutput,
        record: &mut Record<'_>,
    ) -> (Status, axcomp_core::probe::ProbeFlags) {
        self.cycle_in(engine, io, probe_io, clock, watchdog, out, record)
    }

    /// The cycle itself (see [`GroupDrive::cycle`]): the engine's outputs go to `out`, each axis's
    /// command, applied correction and corrected command to `results`; returns the status word and
    /// the probe flags.
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn cycle_in<
        const POOL: usize,
        Io: DriveIo,
        P: ProbeIo,
        C: CycleClock,
        W: Watchdog,
        R: AxisResults,
    >(
        &mut self,
        engine: &mut GroupEngine<POOL>,
        io: &mut Io,
        probe_io: &mut P,
        clock: &C,
        watchdog: &mut W,
        out: &mut GroupOutput,
        results: &mut R,
    ) -> (Status, axcomp_core::probe::ProbeFlags) {
        let start_tick = clock.now();
        let (_, late_start) = self.meter.start(start_tick);
        self.counters.cycles = self.counters.cycles.wrapping_add(1);
        let n = self.n_axes.min(MAX_AXES);
        // Set with the group (`offer_image`): the largest board input of the group + 1.
        let n_inputs = usize::from(self.n_inputs);

        // ---- link: every byte received since the last cycle; the newest fresh frame wins ----
        let mut fresh = None;
        for _ in 0..LINK_READS_PER_CYCLE {
            let decoder = &mut self.decoder;
            let got = io.take_link(LINK_CHUNK, |bytes| {
                decoder.push_bytes_into(bytes, &mut fresh)
            });
            if got == 0 {
                break;
            }
        }
        let events = self.decoder.take_events();
        let mut status = self.latched;
        // The fresh frame's commands by board input (every input of the group present).
        let mut commands: Option<&[i32]> = None;
        if let Some(f) = &fresh {
            self.last_seq = f.seq;
            self.probe.take_frame(f);
            let c = f.commands();
            if c.len() >= n_inputs {
                commands = Some(c);
            } else {
                self.counters.short_frames = self.counters.short_frames.wrapping_add(1);
                status.insert(Status::FRAME_CORRUPT);
            }
        }
        if commands.is_none() {
            self.counters.cycles_without_frame = self.counters.cycles_without_frame.wrapping_add(1);
            status.insert(Status::FRAME_LATE);
        }
        if events.corrupt {
            status.insert(Status::FRAME_CORRUPT);
        }
        status.set(Status::FRAME_REPEATED, events.repeated);
        status.set(Status::FRAME_MISSING, events.lost);

        // ---- the engine: one cycle for every axis ----
        let forces = io.read_forces();
        // Slots beyond the group read counter 0, command 0 and no force readings (NaN: read only by
        // axes with a force term, so by none of them; as a pattern of stores, not a 120-byte clear
        // of an all-zero array); each of the group's slots gets its command, scale and the forces.
        let mut input = GroupInput {
            axes: [CycleInput {
                scale_raw: 0,
                command_counts: 0,
                forces_n: [f32::NAN; MAX_FORCES],
            }; MAX_AXES],
        };
        for i in 0..n {
            let board_input = usize::from(self.inputs[i]);
            let a = &mut input.axes[i];
            a.command_counts =
                self.links[i].begin(commands.and_then(|c| c.get(board_input).copied()));
            a.scale_raw = io.read_scale(board_input);
            a.forces_n = forces;
        }
        engine.cycle(&input, out);
        // Without probe settings (the common case) nothing of the probe runs.
        let probe_on = self.probe.enabled();
        let probe_flags = if probe_on {
            self.probe
                .cycle(engine, probe_io, start_tick, &self.inputs[..n])
        } else {
            axcomp_core::probe::ProbeFlags::NONE
        };

        // ---- supervisors, status word, the reply's corrected commands by board input ----
        let group = engine.active();
        let (mut flags, reply) = self.supervise_axes(engine, n, out, &input, results, &mut status);
        if !group.is_loaded() {
            flags.insert(Flags::IDENTITY);
        }
        status.insert(core_status(flags));
        status.set(Status::CYCLE_LATE, late_start);
        status.set(Status::OVERRUN, self.prev_overrun);
        status.set(Status::REPLY_DROPPED, self.prev_reply_dropped);
        if probe_on {
            status.insert(ProbeDrive::status(probe_flags));
        }
        self.last_status = status;

        // ---- reply frame: corrected commands by board input, status, one counter ----
        self.send_reply(
            engine,
            io,
            status,
            probe_flags,
            probe_on,
            &reply,
            n,
            n_inputs,
        );

        watchdog.feed();
        self.prev_overrun = self.meter.finish(clock.now());
        (status, probe_flags)
    }

    /// Each axis's link supervisor on the engine's output, its corrected command into the reply
    /// (by board input) and into `results`, the axes' flags and sensor status into `status`: the
    /// union of the axes' flags and the reply's corrected commands. Part of [`Self::cycle_in`].
    #[inline(always)]
    fn supervise_axes<const POOL: usize, R: AxisResults>(
        &mut self,
        engine: &GroupEngine<POOL>,
        n: usize,
        out: &GroupOutput,
        input: &GroupInput,
        results: &mut R,
        status: &mut Status,
    ) -> (Flags, [i32; MAX_AXES]) {
        let group = engine.active();
        let mut flags = Flags::NONE;
        let mut reply = [0i32; MAX_AXES];
        for i in 0..n {
            let o = &out.axes[i];
            let um_per_count = group.axis(i).map_or(0.0, |a| a.um_per_count());
            let a = self.links[i].finish(o.correction_um, o.correction_counts, um_per_count);
            match a.phase {
                LinkPhase::Following => {}
                LinkPhase::Holding => status.insert(Status::LINK_HOLD),
                LinkPhase::RampingOut | LinkPhase::RampingIn => status.insert(Status::LINK_RAMP),
            }
            let cmd = input.axes[i].command_counts;
            let corrected = cmd.saturating_sub(i64::from(a.correction_counts));
            reply[usize::from(self.inputs[i])] = corrected as i32;
            results.axis(i, cmd, a, corrected);
            flags.insert(o.flags);
            if o.flags.contains(Flags::SENSOR_FAULT) {
                let st = &engine.state().axes[i];
                let sensors = group.axis(i).map_or(0, |a| a.sensor_count());
                let stale = (0..sensors).any(|j| st.sensor_stale(j));
                status.insert(if stale {
                    Status::SENSOR_STALE
                } else {
                    Status::SENSOR_IMPLAUSIBLE
                });
            }
        }
        (flags, reply)
    }

    /// The reply frame (corrected commands by board input, status, one counter, the probe's
    /// block) encoded in the drive's reply buffer and written to the link. Part of
    /// [`Self::cycle_in`].
    #[allow(clippy::too_many_arguments)]
    #[inline(always)]
    fn send_reply<const POOL: usize, Io: DriveIo>(
        &mut self,
        engine: &GroupEngine<POOL>,
        io: &mut Io,
        status: Status,
        probe_flags: axcomp_core::probe::ProbeFlags,
        probe_on: bool,
        reply: &[i32; MAX_AXES],
        n: usize,
        n_inputs: usize,
    ) {
        let (id, value) = self.next_counter_value(engine);
        let probe_block =
            probe_on.then(|| self.probe.reply(probe_flags, &self.inputs[..n], n_inputs));
        let fields = ReplyFields {
            seq: self.reply_seq,
            echo: self.last_seq,
            status: status.bits(),
            counter_id: id as u8,
            counter_value: value,
        };
        // Encoded where it is sent from (the drive's reply buffer: no frame cleared each cycle).
        let len = encode_reply(
            &mut self.reply.0,
            &fields,
            reply.get(..n_inputs).unwrap_or(&[]),
            probe_block.as_ref(),
        );
        self.reply_seq = self.reply_seq.wrapping_add(1);
        self.prev_reply_dropped = !io.write_link(&self.reply.0[..len]);
        if self.prev_reply_dropped {
            self.counters.replies_dropped = self.counters.replies_dropped.wrapping_add(1);
        }
    }

    fn next_counter_value<const POOL: usize>(
        &mut self,
        engine: &GroupEngine<POOL>,
    ) -> (CounterId, u16) {
        // Round robin (`next_counter` < 12 always: a compare, no division).
        let k = usize::from(self.next_counter);
        let id = CounterId::ALL.get(k).copied().unwrap_or(CounterId::Cycles);
        self.next_counter = if k + 1 < CounterId::ALL.len() {
            (k + 1) as u8
        } else {
            0
        };
        let c = &self.counters;
        let link = self.decoder.counters();
        let late = self.meter.stats();
        let v = match id {
            CounterId::Cycles => c.cycles,
            CounterId::FramesApplied => link.frames_ok,
            CounterId::FramesCorrupt => link.corrupt.wrapping_add(c.short_frames),
            CounterId::FramesLost => link.lost,
            CounterId::FramesRepeated => link.repeated,
            CounterId::CyclesWithoutFrame => c.cycles_without_frame,
            CounterId::LateCycles => late.late_cycles,
            CounterId::Overruns => late.overruns,
            CounterId::ImagesRefused => c
                .images_refused
                .wrapping_add(engine.stats().images_rejected),
            CounterId::SensorRejected => sensor_readings_rejected(engine),
            CounterId::MaxLatenessTicks => late.max_lateness_ticks,
            CounterId::SkippedBytes => link.skipped_bytes,
        };
        (id, v as u16)
    }

    /// [`GroupDrive::run`] with the board's probe input ([`GroupDrive::cycle_with_probe`]).
    #[allow(clippy::too_many_arguments)]
    pub async fn run_with_probe<const POOL: usize, Io, P, C, T, W, F>(
        &mut self,
        engine: &mut GroupEngine<POOL>,
        io: &mut Io,
        probe: &mut P,
        clock: &C,
        timer: &mut T,
        watchdog: &mut W,
        mut between: F,
    ) -> !
    where
        Io: DriveIo,
        P: ProbeIo,
        C: CycleClock,
        T: CycleTimer,
        W: Watchdog,
        F: FnMut(&mut GroupEngine<POOL>, &GroupDrive),
    {
        loop {
            timer.next_cycle().await;
            between(engine, self);
            self.cycle_status_with_probe(engine, io, probe, clock, watchdog);
        }
    }

    /// Runs forever at the timer's pace; `between` runs before each cycle with the engine (to hand it
    /// temperatures) and the drive (the previous cycle's status, the counters).
    pub async fn run<const POOL: usize, Io, C, T, W, F>(
        &mut self,
        engine: &mut GroupEngine<POOL>,
        io: &mut Io,
        clock: &C,
        timer: &mut T,
        watchdog: &mut W,
        mut between: F,
    ) -> !
    where
        Io: DriveIo,
        C: CycleClock,
        T: CycleTimer,
        W: Watchdog,
        F: FnMut(&mut GroupEngine<POOL>, &GroupDrive),
    {
        loop {
            timer.next_cycle().await;
            between(engine, self);
            self.cycle_status(engine, io, clock, watchdog);
        }
    }
}
