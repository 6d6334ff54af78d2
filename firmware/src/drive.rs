//! The drive around the engine: what the board has ([`BoardCaps`]) and the check of every image
//! against it, the setpoint link with its supervisor ([`LinkSupervisor`]), deadline lateness
//! ([`LatenessMeter`]), the watchdog ([`Watchdog`]) and the status word of each cycle; one drive for
//! one to five axes ([`group::GroupDrive`]: a single-axis machine runs a group of one axis).
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

use axcomp_core::{
    AxisCompensator, Flags, ImageError, ImageInfo, MAX_FORCES, TableStore, inspect_image,
};

use crate::setpoint::{LinkCounters, extend_command};
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

    /// Checks a loaded compensator (e.g. an axis of the running group) with its accessors; the
    /// identity passes.
    pub fn check_compensator<S: TableStore>(
        &self,
        c: &AxisCompensator<S>,
    ) -> Result<usize, ImageRefusal> {
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

/// Measures each cycle's start against its deadline on a 32-bit up-counting [`CycleClock`](crate::control::CycleClock) (DWT CYCCNT,
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

/// Most bytes the drive takes from the link per read, and reads per cycle ([`group::GroupDrive`]):
/// 8 × 32 = 256 bytes, over ten 25-byte frames, so a backlog is worked off within a cycle or two.
pub const LINK_CHUNK: usize = 32;
/// Reads of the link per cycle (see [`LINK_CHUNK`]).
pub const LINK_READS_PER_CYCLE: usize = 8;

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
    /// Hands at most `max` bytes received on the link to `take` without waiting, and drops them from
    /// the receive buffer; returns how many (0: none, `take` not called). A board whose driver
    /// exposes its receive buffer hands them where they lie (no copy: the drive decodes them
    /// there); the default reads them through [`DriveIo::read_link`] into a buffer of
    /// [`LINK_CHUNK`] bytes.
    fn take_link(&mut self, max: usize, take: impl FnOnce(&[u8])) -> usize {
        let mut buf = [0u8; LINK_CHUNK];
        let got = self.read_link(&mut buf[..max.min(LINK_CHUNK)]);
        let bytes = &buf[..got.min(max).min(LINK_CHUNK)];
        if !bytes.is_empty() {
            take(bytes);
        }
        bytes.len()
    }
    /// Queues one reply frame without waiting; false if the transmit buffer had no room (dropped).
    fn write_link(&mut self, frame: &[u8]) -> bool;
}

/// Counters of a [`group::GroupDrive`] (wrapping or saturating `u32`s since boot).
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
