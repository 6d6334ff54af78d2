//! The drive around the control loop: what the board has ([`BoardCaps`]) and the check of every image
//! against it, the setpoint link with its supervisor ([`LinkSupervisor`]), deadline lateness
//! ([`LatenessMeter`]), the watchdog ([`Watchdog`]) and the status word of each cycle ([`Drive`]).
//!
//! Glossary:
//! - **Board capabilities** ([`BoardCaps`]): the scale counters' width, the axis ids wired (in the order of
//!   the board's scale inputs, which is also the order of the axes in the setpoint frame), and how many
//!   temperature sensors are wired (image sensor i = board sensor i).
//! - **Image refusal** ([`ImageRefusal`]): an image that is invalid, or valid but made for another board
//!   (counter width, axis, sensors); it is never applied and the running slot is kept.
//! - **Fresh frame**: a setpoint frame that passed its CRC and is not a repeat (see [`crate::setpoint`]).
//! - **Late cycle (link)**: a cycle that starts without a fresh frame since the previous one.
//! - **Hold / ramp-out / ramp-in**: the [`LinkSupervisor`]'s answer to late cycles: the last applied
//!   correction is held for `hold_cycles`, then moved to zero by `ramp_um_per_cycle` per cycle; once
//!   fresh frames return it moves back to the engine's correction at the same rate, then follows it
//!   exactly again.
//! - **Deadline**: when a cycle should start: the ticker's schedule, modelled as the first cycle's start
//!   plus k periods (re-anchored to any earlier start). **Lateness** = start − deadline; a cycle is
//!   **late** when its lateness exceeds the tolerance; an **overrun** is a cycle whose output is written
//!   after the next cycle's deadline (lateness + compute time > period).
//! - **Watchdog**: a hardware counter the loop feeds once per completed cycle; when it is not fed within
//!   its timeout it resets the chip, and the next boot reports it ([`ResetCause`], status
//!   [`Status::WATCHDOG_RESET`]).
//!
//! Everything here is host-testable with the fakes in [`crate::control::fake`] and `drive::fake` (tests and
//! feature `std`).

use axcomp_core::trace::OutputRecord;
use axcomp_core::{Compensator, Flags, ImageError, ImageInfo, MAX_FORCES, inspect_image};

use crate::control::{AxisIo, ControlLoop, CycleClock, CycleTimer, Inbox, LoopConfig};
use crate::setpoint::{
    CounterId, LinkCounters, MAX_REPLY_FRAME_LEN, ReplyFrame, SetpointDecoder, extend_command,
};
use crate::status::Status;

// ------------------------------------------------------------------------------------------------
// Board capabilities and the image check
// ------------------------------------------------------------------------------------------------

/// What a board has wired.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BoardCaps {
    /// Width of the scale counters in bits (16 for the STM32 timers in encoder mode).
    pub counter_bits: u8,
    /// Axis ids wired, in the order of the board's scale inputs (= the axes' order in the setpoint frame).
    pub axis_ids: &'static [u16],
    /// Temperature sensors wired.
    pub sensors: u16,
}

/// Why an image is not applied.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageRefusal {
    /// The image itself is invalid (structure, CRC, a value).
    Invalid(ImageError),
    /// The image's counter width differs from the board's (a 32-bit image on a 16-bit counter would
    /// jump by 65 536 counts at each wrap).
    CounterWidth { image: u8, board: u8 },
    /// The image is for an axis the board does not have.
    AxisNotWired { axis_id: u16 },
    /// The image needs more temperature sensors than the board has (its thermal term would stay frozen).
    SensorsNotWired { image: u16, board: u16 },
    /// Two axes of a group image have the same axis id (one scale input cannot feed both).
    AxisIdTwice { axis_id: u16 },
    /// A sensor of the image cannot be fed by the board's inputs (by name, see
    /// `axcomp_core::wiring`): e.g. a `warmup` input on a board that only has RTDs (°C).
    SensorNotOnBoard {
        axis_id: u16,
        why: axcomp_core::wiring::WiringError,
    },
    /// The group image is valid, but the core refused to load it (e.g. its tables exceed the pool).
    Group(axcomp_core::group::GroupError),
}

impl core::fmt::Display for ImageRefusal {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ImageRefusal::Invalid(e) => write!(f, "invalid image: {e}"),
            ImageRefusal::CounterWidth { image, board } => write!(
                f,
                "image counter width {image} bits, board counters are {board} bits"
            ),
            ImageRefusal::AxisNotWired { axis_id } => {
                write!(
                    f,
                    "image for axis {axis_id}, which this board does not wire"
                )
            }
            ImageRefusal::SensorsNotWired { image, board } => write!(
                f,
                "image needs {image} temperature sensors, the board wires {board}"
            ),
            ImageRefusal::AxisIdTwice { axis_id } => {
                write!(f, "group image has axis id {axis_id} on two axes")
            }
            ImageRefusal::SensorNotOnBoard { axis_id, why } => {
                write!(f, "image for axis {axis_id}: {why}")
            }
            ImageRefusal::Group(e) => write!(f, "group refused: {e}"),
        }
    }
}

impl core::error::Error for ImageRefusal {}

impl BoardCaps {
    /// Checks an image's requirements; on success returns the scale input (and frame slot) of its axis.
    pub fn check(
        &self,
        axis_id: u16,
        counter_bits: u8,
        sensors: usize,
    ) -> Result<usize, ImageRefusal> {
        if counter_bits != self.counter_bits {
            return Err(ImageRefusal::CounterWidth {
                image: counter_bits,
                board: self.counter_bits,
            });
        }
        let input = self
            .axis_ids
            .iter()
            .position(|&a| a == axis_id)
            .ok_or(ImageRefusal::AxisNotWired { axis_id })?;
        if sensors > usize::from(self.sensors) {
            return Err(ImageRefusal::SensorsNotWired {
                image: sensors.min(usize::from(u16::MAX)) as u16,
                board: self.sensors,
            });
        }
        Ok(input)
    }

    /// Validates `image` fully and checks it against the board, without loading it.
    pub fn check_image(&self, image: &[u8]) -> Result<(ImageInfo, usize), ImageRefusal> {
        let info = inspect_image(image).map_err(ImageRefusal::Invalid)?;
        let input = self.check(info.axis_id, info.counter_bits, info.n_sensors)?;
        Ok((info, input))
    }

    /// Checks a loaded compensator (e.g. the running slot) with its accessors; the identity passes.
    pub fn check_compensator(&self, c: &Compensator) -> Result<usize, ImageRefusal> {
        if !c.is_loaded() {
            return Ok(0);
        }
        self.check(c.axis_id(), c.counter_bits(), c.sensor_count())
    }
}

// ------------------------------------------------------------------------------------------------
// Link supervisor
// ------------------------------------------------------------------------------------------------

/// Time constants of the link supervisor, in cycles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkSettings {
    /// Late cycles during which the last correction is held unchanged.
    pub hold_cycles: u32,
    /// Change of the correction per cycle while ramping out (to zero) or back in, µm (> 0).
    pub ramp_um_per_cycle: f32,
}

impl LinkSettings {
    /// Hold 5 ms, then ramp at 1 mm/s (0.1 µm per cycle at 10 kHz): a 50 µm correction is gone 50 ms
    /// after the hold, a few CNC frames lost in a row never move the axis.
    pub const DEFAULT_HOLD_MS: u32 = 5;
    pub const DEFAULT_RAMP_UM_PER_S: f32 = 1000.0;

    /// Settings for a loop at `rate_hz` (hold rounded down to whole cycles).
    pub fn for_rate(rate_hz: u32, hold_ms: u32, ramp_um_per_s: f32) -> Self {
        LinkSettings {
            hold_cycles: (u64::from(hold_ms) * u64::from(rate_hz) / 1000) as u32,
            ramp_um_per_cycle: ramp_um_per_s / rate_hz.max(1) as f32,
        }
    }

    /// The defaults at `rate_hz`.
    pub fn defaults(rate_hz: u32) -> Self {
        Self::for_rate(rate_hz, Self::DEFAULT_HOLD_MS, Self::DEFAULT_RAMP_UM_PER_S)
    }
}

/// Where the supervisor is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LinkPhase {
    /// Fresh frames: the engine's correction is applied exactly.
    Following,
    /// Late cycles within the hold time: the last applied correction is held.
    Holding,
    /// Late cycles beyond the hold time: the correction moves towards zero.
    RampingOut,
    /// Fresh frames again: the correction moves back towards the engine's.
    RampingIn,
}

/// The supervisor's decision for one cycle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Applied {
    /// Correction applied, counts (corrected command = command − this).
    pub correction_counts: i32,
    /// The same in µm.
    pub correction_um: f32,
    pub phase: LinkPhase,
}

/// Decides, per cycle, which command the axis follows and which correction is applied when setpoint
/// frames are late, lost, corrupt or repeated.
#[derive(Clone, Copy, Debug)]
pub struct LinkSupervisor {
    settings: LinkSettings,
    command: i64,
    missing_cycles: u32,
    applied_um: f32,
    applied_counts: i32,
    overriding: bool,
}

impl LinkSupervisor {
    pub const fn new(settings: LinkSettings) -> Self {
        LinkSupervisor {
            settings,
            command: 0,
            missing_cycles: 0,
            applied_um: 0.0,
            applied_counts: 0,
            overriding: false,
        }
    }

    pub fn settings(&self) -> &LinkSettings {
        &self.settings
    }

    /// Start of a cycle: `fresh` is this axis's command (low 32 bits) from a fresh frame, if one
    /// arrived. Returns the command the axis follows (the last fresh one while frames are late).
    pub fn begin(&mut self, fresh: Option<i32>) -> i64 {
        match fresh {
            Some(low) => {
                self.command = extend_command(self.command, low);
                self.missing_cycles = 0;
            }
            None => self.missing_cycles = self.missing_cycles.saturating_add(1),
        }
        self.command
    }

    /// Consecutive cycles without a fresh frame.
    pub fn missing_cycles(&self) -> u32 {
        self.missing_cycles
    }

    /// End of a cycle: the engine's correction (µm and counts) → the correction to apply.
    pub fn finish(&mut self, engine_um: f32, engine_counts: i32, um_per_count: f32) -> Applied {
        let step = self.settings.ramp_um_per_cycle;
        let phase = if self.missing_cycles == 0 {
            if !self.overriding || libm::fabsf(engine_um - self.applied_um) <= step {
                self.overriding = false;
                self.applied_um = engine_um;
                self.applied_counts = engine_counts;
                LinkPhase::Following
            } else {
                self.move_towards(engine_um, step, um_per_count);
                LinkPhase::RampingIn
            }
        } else {
            self.overriding = true;
            if self.missing_cycles <= self.settings.hold_cycles {
                LinkPhase::Holding
            } else {
                self.move_towards(0.0, step, um_per_count);
                LinkPhase::RampingOut
            }
        };
        Applied {
            correction_counts: self.applied_counts,
            correction_um: self.applied_um,
            phase,
        }
    }

    fn move_towards(&mut self, target: f32, step: f32, um_per_count: f32) {
        let d = target - self.applied_um;
        self.applied_um = if libm::fabsf(d) <= step || !d.is_finite() {
            target
        } else if d > 0.0 {
            self.applied_um + step
        } else {
            self.applied_um - step
        };
        self.applied_counts =
            if self.applied_um == 0.0 || um_per_count.is_nan() || um_per_count <= 0.0 {
                0
            } else {
                axcomp_core::round_to_counts(self.applied_um / um_per_count)
            };
    }
}

// ------------------------------------------------------------------------------------------------
// Lateness
// ------------------------------------------------------------------------------------------------

/// Lateness statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LatenessStats {
    /// Cycles whose start was later than the deadline + tolerance.
    pub late_cycles: u32,
    /// Cycles whose output came after the next cycle's deadline.
    pub overruns: u32,
    pub last_lateness_ticks: u32,
    pub max_lateness_ticks: u32,
}

/// Measures each cycle's start against its deadline on a 32-bit up-counting [`CycleClock`] (DWT CYCCNT,
/// the host fakes).
#[derive(Clone, Copy, Debug)]
pub struct LatenessMeter {
    period_ticks: u32,
    tolerance_ticks: u32,
    deadline: Option<u32>,
    stats: LatenessStats,
}

impl LatenessMeter {
    /// Default tolerance: a tenth of the period (10 µs at 10 kHz).
    pub const fn new(period_ticks: u32) -> Self {
        Self::with_tolerance(period_ticks, period_ticks / 10)
    }

    pub const fn with_tolerance(period_ticks: u32, tolerance_ticks: u32) -> Self {
        LatenessMeter {
            period_ticks,
            tolerance_ticks,
            deadline: None,
            stats: LatenessStats {
                late_cycles: 0,
                overruns: 0,
                last_lateness_ticks: 0,
                max_lateness_ticks: 0,
            },
        }
    }

    pub fn stats(&self) -> &LatenessStats {
        &self.stats
    }

    /// A cycle starts at `now`; returns its lateness and whether it counts as late.
    pub fn start(&mut self, now: u32) -> (u32, bool) {
        let deadline = self.deadline.unwrap_or(now);
        let l = now.wrapping_sub(deadline) as i32;
        let lateness = if l < 0 {
            // Earlier than the modelled schedule: the schedule's phase was later than assumed.
            self.deadline = Some(now);
            0
        } else {
            self.deadline = Some(deadline);
            l as u32
        };
        let s = &mut self.stats;
        s.last_lateness_ticks = lateness;
        s.max_lateness_ticks = s.max_lateness_ticks.max(lateness);
        let late = lateness > self.tolerance_ticks;
        if late {
            s.late_cycles = s.late_cycles.saturating_add(1);
        }
        (lateness, late)
    }

    /// The cycle wrote its output at `now`; returns true for an overrun. Advances the deadline.
    pub fn finish(&mut self, now: u32) -> bool {
        let Some(deadline) = self.deadline else {
            return false;
        };
        let overrun = now.wrapping_sub(deadline) as i32 > self.period_ticks as i32;
        if overrun {
            self.stats.overruns = self.stats.overruns.saturating_add(1);
        }
        self.deadline = Some(deadline.wrapping_add(self.period_ticks));
        overrun
    }
}

// ------------------------------------------------------------------------------------------------
// Watchdog
// ------------------------------------------------------------------------------------------------

/// A watchdog the loop feeds once per completed cycle.
pub trait Watchdog {
    fn feed(&mut self);
}

/// No watchdog (QEMU, host simulation).
#[derive(Clone, Copy, Debug, Default)]
pub struct NoWatchdog;

impl Watchdog for NoWatchdog {
    fn feed(&mut self) {}
}

/// Why the chip last reset, as far as the drive cares.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ResetCause {
    /// The (independent or window) watchdog reset the chip.
    pub watchdog: bool,
}

// ------------------------------------------------------------------------------------------------
// The drive
// ------------------------------------------------------------------------------------------------

/// The status bits of a core cycle's flags, except `SENSOR_FAULT` (stale or implausible: the drive
/// asks the state which).
pub fn core_status(flags: Flags) -> Status {
    let mut status = Status::NONE;
    for (core_flag, bit) in [
        (Flags::THERMAL_FROZEN, Status::THERMAL_FROZEN),
        (Flags::THERMAL_RAMP_OUT, Status::THERMAL_RAMPING),
        (Flags::CLAMPED, Status::CLAMP_ACTIVE),
        (Flags::SLEWED, Status::SLEWED),
        (Flags::TABLE_OUTSIDE, Status::TABLE_OUTSIDE),
        (Flags::FORCE_INVALID, Status::FORCE_INVALID),
        (Flags::NON_FINITE, Status::NON_FINITE),
        (Flags::IDENTITY, Status::NO_IMAGE),
    ] {
        if flags.contains(core_flag) {
            status.insert(bit);
        }
    }
    status
}

/// Board I/O of the drive: scale inputs and the setpoint link, never blocking.
pub trait DriveIo {
    /// Raw counter of scale input `input` (board wiring order, see [`BoardCaps::axis_ids`]).
    fn read_scale(&mut self, input: usize) -> u32;
    /// Measured axis forces in newton (zeros without force sensing).
    fn read_forces(&mut self) -> [f32; MAX_FORCES] {
        [0.0; MAX_FORCES]
    }
    /// Moves bytes received on the link into `buf` without waiting; returns how many (0: none).
    fn read_link(&mut self, buf: &mut [u8]) -> usize;
    /// Queues one reply frame without waiting; false if the transmit buffer had no room (dropped).
    fn write_link(&mut self, frame: &[u8]) -> bool;
}

/// Counters of a [`Drive`] (wrapping or saturating `u32`s since boot).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct DriveCounters {
    pub cycles: u32,
    pub link: LinkCounters,
    /// Fresh frames without an entry for this drive's axis (too few axes).
    pub short_frames: u32,
    /// Cycles that started without a fresh frame.
    pub cycles_without_frame: u32,
    pub lateness: LatenessStats,
    pub images_refused: u32,
    pub replies_dropped: u32,
}

/// One cycle's result.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveCycle {
    /// The command the axis followed (the last fresh one while frames are late).
    pub command_counts: i64,
    /// What went to the drive: command − applied correction.
    pub corrected_command_counts: i64,
    pub applied: Applied,
    pub status: Status,
    /// The engine's record of this cycle (the engine's own correction, before the link supervisor).
    pub engine: Option<OutputRecord>,
}

/// The control loop's view of one axis in a drive cycle.
struct CycleAxis {
    scale_raw: u32,
    command: i64,
    forces: [f32; MAX_FORCES],
}

impl AxisIo for CycleAxis {
    fn read_scale(&mut self) -> u32 {
        self.scale_raw
    }
    fn read_command(&mut self) -> i64 {
        self.command
    }
    fn read_forces(&mut self) -> [f32; MAX_FORCES] {
        self.forces
    }
    fn write_command(&mut self, _counts: i64) {
        // The drive writes after the link supervisor (see `Drive::cycle`).
    }
}

/// The drive: link decoding and supervision, the engine's cycle, the status word and the reply frame.
pub struct Drive {
    caps: BoardCaps,
    input: usize,
    decoder: SetpointDecoder,
    link: LinkSupervisor,
    meter: LatenessMeter,
    latched: Status,
    last_seq: u8,
    reply_seq: u8,
    prev_overrun: bool,
    prev_reply_dropped: bool,
    next_counter: u8,
    counters: DriveCounters,
    last_status: Status,
}

impl Drive {
    pub fn new(
        caps: BoardCaps,
        config: &LoopConfig,
        link: LinkSettings,
        reset: ResetCause,
    ) -> Self {
        let mut latched = Status::NONE;
        latched.set(Status::WATCHDOG_RESET, reset.watchdog);
        Drive {
            caps,
            input: 0,
            decoder: SetpointDecoder::new(),
            link: LinkSupervisor::new(link),
            meter: LatenessMeter::new(config.period_ticks),
            latched,
            last_seq: 0,
            reply_seq: 0,
            prev_overrun: false,
            prev_reply_dropped: false,
            next_counter: 0,
            counters: DriveCounters::default(),
            last_status: Status::NONE,
        }
    }

    /// Replaces the lateness meter (e.g. another tolerance).
    pub fn set_lateness_meter(&mut self, meter: LatenessMeter) {
        self.meter = meter;
    }

    pub fn caps(&self) -> &BoardCaps {
        &self.caps
    }

    /// Scale input (and frame slot) of the running image's axis.
    pub fn input(&self) -> usize {
        self.input
    }

    /// Cycles run since construction (wrapping).
    pub fn cycles(&self) -> u32 {
        self.counters.cycles
    }

    pub fn counters(&self) -> DriveCounters {
        let mut c = self.counters;
        c.link = *self.decoder.counters();
        c.lateness = *self.meter.stats();
        c
    }

    /// Status word of the last cycle.
    pub fn status(&self) -> Status {
        self.last_status
    }

    pub fn supervisor(&self) -> &LinkSupervisor {
        &self.link
    }

    /// Checks `image` against the board, then loads it into the spare slot. A refused image is never
    /// loaded (the running slot is kept) and latches [`Status::IMAGE_REFUSED`] until an image is accepted.
    pub fn offer_image(
        &mut self,
        ctl: &mut ControlLoop<'_>,
        image: &[u8],
    ) -> Result<(), ImageRefusal> {
        let result = self.caps.check_image(image).and_then(|(_, input)| {
            ctl.load_image(image)
                .map(|()| input)
                .map_err(ImageRefusal::Invalid)
        });
        match result {
            Ok(input) => {
                self.input = input;
                self.latched.set(Status::IMAGE_REFUSED, false);
                Ok(())
            }
            Err(e) => {
                self.latched.insert(Status::IMAGE_REFUSED);
                self.counters.images_refused = self.counters.images_refused.saturating_add(1);
                Err(e)
            }
        }
    }

    /// One cycle: lateness, link bytes → fresh frame, supervised command, the engine's cycle, the applied
    /// correction, the status word and the reply frame; feeds the watchdog at the end.
    pub fn cycle<Io: DriveIo, C: CycleClock, W: Watchdog>(
        &mut self,
        ctl: &mut ControlLoop<'_>,
        io: &mut Io,
        clock: &C,
        watchdog: &mut W,
    ) -> DriveCycle {
        let (_, late_start) = self.meter.start(clock.now());
        self.counters.cycles = self.counters.cycles.wrapping_add(1);

        // ---- link: every byte received since the last cycle; the newest fresh frame wins ----
        let mut fresh = None;
        let mut buf = [0u8; 32];
        // Bounded: a flooded line cannot hold the cycle (at 2 Mbaud 20 bytes arrive per cycle).
        for _ in 0..8 {
            let n = io.read_link(&mut buf);
            if n == 0 {
                break;
            }
            if let Some(f) = self.decoder.push_bytes(&buf[..n.min(buf.len())]) {
                fresh = Some(f);
            }
        }
        let events = self.decoder.take_events();
        let mut status = self.latched;
        let mut own = None;
        if let Some(f) = fresh {
            self.last_seq = f.seq;
            own = f.commands().get(self.input).copied();
            if own.is_none() {
                self.counters.short_frames = self.counters.short_frames.wrapping_add(1);
                status.insert(Status::FRAME_CORRUPT);
            }
        }
        if own.is_none() {
            self.counters.cycles_without_frame = self.counters.cycles_without_frame.wrapping_add(1);
            status.insert(Status::FRAME_LATE);
        }
        status.set(
            Status::FRAME_CORRUPT,
            status.contains(Status::FRAME_CORRUPT) || events.corrupt,
        );
        status.set(Status::FRAME_REPEATED, events.repeated);
        status.set(Status::FRAME_MISSING, events.lost);
        let command = self.link.begin(own);

        // ---- the engine ----
        let mut axis = CycleAxis {
            scale_raw: io.read_scale(self.input),
            command,
            forces: io.read_forces(),
        };
        let out = ctl.cycle(&mut axis, clock);
        let (engine_um, engine_counts, flags) = match &out {
            Some(o) => (o.correction_um(), o.correction_counts, Flags(o.flags)),
            None => (0.0, 0, Flags::NONE),
        };
        let um_per_count = ctl.engine().active().um_per_count();
        let applied = self.link.finish(engine_um, engine_counts, um_per_count);
        let corrected = command.saturating_sub(i64::from(applied.correction_counts));

        // ---- status word ----
        match applied.phase {
            LinkPhase::Following => {}
            LinkPhase::Holding => status.insert(Status::LINK_HOLD),
            LinkPhase::RampingOut | LinkPhase::RampingIn => status.insert(Status::LINK_RAMP),
        }
        if flags.contains(Flags::SENSOR_FAULT) {
            let comp = ctl.engine().active();
            let st = ctl.engine().state();
            let stale = (0..comp.sensor_count()).any(|i| st.sensor_stale(i));
            status.insert(if stale {
                Status::SENSOR_STALE
            } else {
                Status::SENSOR_IMPLAUSIBLE
            });
        }
        status.insert(core_status(flags));
        status.set(Status::CYCLE_LATE, late_start);
        status.set(Status::OVERRUN, self.prev_overrun);
        status.set(Status::REPLY_DROPPED, self.prev_reply_dropped);
        self.last_status = status;

        // ---- reply frame: corrected command, status, one counter ----
        let (id, value) = self.next_counter_value(ctl);
        let mut frame = [0u8; MAX_REPLY_FRAME_LEN];
        let n = ReplyFrame::new(
            self.reply_seq,
            self.last_seq,
            &[corrected as i32],
            status.bits(),
            id,
            value,
        )
        .map(|r| r.encode_into(&mut frame))
        .unwrap_or(0);
        self.reply_seq = self.reply_seq.wrapping_add(1);
        self.prev_reply_dropped = !io.write_link(&frame[..n]);
        if self.prev_reply_dropped {
            self.counters.replies_dropped = self.counters.replies_dropped.wrapping_add(1);
        }

        watchdog.feed();
        self.prev_overrun = self.meter.finish(clock.now());
        DriveCycle {
            command_counts: command,
            corrected_command_counts: corrected,
            applied,
            status,
            engine: out,
        }
    }

    fn next_counter_value(&mut self, ctl: &ControlLoop<'_>) -> (CounterId, u16) {
        let id = CounterId::ALL[usize::from(self.next_counter) % CounterId::ALL.len()];
        self.next_counter = ((usize::from(self.next_counter) + 1) % CounterId::ALL.len()) as u8;
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
                .wrapping_add(ctl.engine().stats().images_rejected),
            CounterId::SensorRejected => {
                let comp = ctl.engine().active();
                let st = ctl.engine().state();
                (0..comp.sensor_count()).fold(0u32, |a, i| a.wrapping_add(st.rejected_readings(i)))
            }
            CounterId::MaxLatenessTicks => late.max_lateness_ticks,
            CounterId::SkippedBytes => link.skipped_bytes,
        };
        (id, v as u16)
    }

    /// Runs forever at the timer's pace; `between` runs before each cycle with the loop's [`Inbox`]
    /// (temperatures, process parameters) and the drive (the previous cycle's status, the counters).
    pub async fn run<Io, C, T, W, F>(
        &mut self,
        ctl: &mut ControlLoop<'_>,
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
        F: FnMut(&mut Inbox<'_>, &Drive),
    {
        loop {
            timer.next_cycle().await;
            between(&mut ctl.inbox(), self);
            self.cycle(ctl, io, clock, watchdog);
        }
    }
}

/// Host fakes of the drive's board traits (tests and feature `std`).
#[cfg(any(test, feature = "std"))]
pub mod fake {
    extern crate std;
    use super::*;
    use std::collections::VecDeque;
    use std::vec::Vec;

    /// A link and scale inputs driven by a test: bytes to receive, frames sent.
    #[derive(Debug, Default)]
    pub struct FakeDriveIo {
        pub scales: [u32; crate::setpoint::MAX_AXES],
        pub forces_n: [f32; MAX_FORCES],
        /// Bytes the next `read_link` calls deliver.
        pub rx: VecDeque<u8>,
        /// Frames written, in order.
        pub tx: Vec<Vec<u8>>,
        /// Make `write_link` report a full transmit buffer.
        pub tx_full: bool,
    }

    impl DriveIo for FakeDriveIo {
        fn read_scale(&mut self, input: usize) -> u32 {
            self.scales.get(input).copied().unwrap_or(0)
        }
        fn read_forces(&mut self) -> [f32; MAX_FORCES] {
            self.forces_n
        }
        fn read_link(&mut self, buf: &mut [u8]) -> usize {
            let n = buf.len().min(self.rx.len());
            for (d, s) in buf.iter_mut().zip(self.rx.drain(..n)) {
                *d = s;
            }
            n
        }
        fn write_link(&mut self, frame: &[u8]) -> bool {
            if self.tx_full {
                return false;
            }
            self.tx.push(frame.to_vec());
            true
        }
    }

    /// Models a hardware watchdog: a down-counter of `timeout_ticks` that [`FakeWatchdog::advance`]
    /// runs and [`Watchdog::feed`] reloads; when it reaches zero the chip "resets" (`expired`).
    #[derive(Clone, Copy, Debug)]
    pub struct FakeWatchdog {
        pub timeout_ticks: u32,
        pub remaining: u32,
        pub feeds: u32,
        pub expired: bool,
    }

    impl FakeWatchdog {
        pub fn new(timeout_ticks: u32) -> Self {
            FakeWatchdog {
                timeout_ticks,
                remaining: timeout_ticks,
                feeds: 0,
                expired: false,
            }
        }

        /// Time passes.
        pub fn advance(&mut self, ticks: u32) {
            self.remaining = self.remaining.saturating_sub(ticks);
            if self.remaining == 0 {
                self.expired = true;
            }
        }

        /// What the next boot reads from the reset flags.
        pub fn reset_cause(&self) -> ResetCause {
            ResetCause {
                watchdog: self.expired,
            }
        }
    }

    impl Watchdog for FakeWatchdog {
        fn feed(&mut self) {
            if !self.expired {
                self.remaining = self.timeout_ticks;
                self.feeds = self.feeds.wrapping_add(1);
            }
        }
    }
}

pub mod group;
pub mod link_trace;
pub mod probe;

#[cfg(test)]
mod tests;
#[cfg(test)]
mod wiring_tests;
