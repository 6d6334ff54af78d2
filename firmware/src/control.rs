//! The fixed-rate control loop, generic over the board.
//!
//! Glossary:
//! - **Axis I/O** ([`AxisIo`]): where the loop gets the raw scale counter, the command (setpoint) and the
//!   measured axis forces, and where it puts the corrected command.
//! - **Cycle clock** ([`CycleClock`]): a free-running wrapping tick counter used only to measure how long a
//!   cycle's computation took (DWT CYCCNT on the board, SysTick under QEMU `-icount`, a fake on the host).
//! - **Cycle timer** ([`CycleTimer`]): what paces the loop at the cycle rate (an embassy `Ticker` on the board;
//!   the trace itself under QEMU, where every cycle record is one tick).
//! - **Compute time**: clock ticks from reading the inputs to writing the corrected command.
//! - **Overrun**: a cycle whose compute time exceeded the cycle period (in clock ticks).
//! - **Engine**: `axcomp_core::Engine`, the core's replay/runtime object (A/B compensator slots + state); the
//!   loop feeds it the same `trace::Record`s the host replays, so board, QEMU and host share one code path.

use core::future::Future;

use axcomp_core::trace::{OutputRecord, Record};
use axcomp_core::{CycleInput, Engine, MAX_FORCES};

/// Board inputs and outputs of one axis.
pub trait AxisIo {
    /// Raw hardware scale counter (wraps at the counter width given in the image).
    fn read_scale(&mut self) -> u32;
    /// Commanded position in scale counts.
    fn read_command(&mut self) -> i64;
    /// Measured axis forces in newton (boards without force sensing return zeros).
    fn read_forces(&mut self) -> [f32; MAX_FORCES] {
        [0.0; MAX_FORCES]
    }
    /// Corrected command in scale counts, to the drive.
    fn write_command(&mut self, counts: i64);
}

/// Free-running wrapping tick counter for compute-time measurement.
pub trait CycleClock {
    fn now(&self) -> u32;
    /// Ticks elapsed since an earlier [`CycleClock::now`] (override for counters narrower than 32 bits).
    fn elapsed_since(&self, earlier: u32) -> u32 {
        self.now().wrapping_sub(earlier)
    }
}

/// Paces the loop: resolves once per cycle period.
pub trait CycleTimer {
    fn next_cycle(&mut self) -> impl Future<Output = ()>;
}

/// Loop settings before validation.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoopSettings {
    /// Cycle rate; 10 kHz by default.
    pub rate_hz: u32,
    /// Rate of the [`CycleClock`] (e.g. the core clock for DWT CYCCNT).
    pub clock_hz: u32,
}

impl LoopSettings {
    pub const DEFAULT_RATE_HZ: u32 = 10_000;

    pub const fn new(clock_hz: u32) -> Self {
        LoopSettings {
            rate_hz: Self::DEFAULT_RATE_HZ,
            clock_hz,
        }
    }

    /// Validates: rate in 1 Hz..=100 kHz, clock at least 100 ticks per cycle.
    pub fn build(self) -> Result<LoopConfig, LoopError> {
        if self.rate_hz == 0 || self.rate_hz > 100_000 {
            return Err(LoopError::RateOutOfRange(self.rate_hz));
        }
        let period = self.clock_hz / self.rate_hz;
        if period < 100 {
            return Err(LoopError::ClockTooSlow(self.clock_hz));
        }
        Ok(LoopConfig {
            rate_hz: self.rate_hz,
            period_ticks: period,
        })
    }
}

/// Invalid [`LoopSettings`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum LoopError {
    /// Cycle rate (Hz) outside 1..=100000.
    RateOutOfRange(u32),
    /// Cycle clock (Hz) gives fewer than 100 ticks per cycle.
    ClockTooSlow(u32),
}

impl core::fmt::Display for LoopError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LoopError::RateOutOfRange(r) => write!(f, "cycle rate {r} Hz outside 1..=100000 Hz"),
            LoopError::ClockTooSlow(c) => {
                write!(f, "cycle clock {c} Hz gives fewer than 100 ticks per cycle")
            }
        }
    }
}

impl core::error::Error for LoopError {}

/// Validated loop configuration.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LoopConfig {
    pub rate_hz: u32,
    /// Cycle period in [`CycleClock`] ticks; a compute time above it is an overrun.
    pub period_ticks: u32,
}

impl LoopConfig {
    /// Cycle period in microseconds (rounded down).
    pub fn period_us(&self) -> u32 {
        1_000_000 / self.rate_hz
    }
}

/// Cycle statistics kept by the loop.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct CycleStats {
    pub cycles: u64,
    pub last_compute_ticks: u32,
    pub max_compute_ticks: u32,
    pub total_compute_ticks: u64,
    pub overruns: u32,
}

impl CycleStats {
    pub const fn new() -> Self {
        CycleStats {
            cycles: 0,
            last_compute_ticks: 0,
            max_compute_ticks: 0,
            total_compute_ticks: 0,
            overruns: 0,
        }
    }

    /// Records one cycle's compute time.
    pub fn record(&mut self, compute_ticks: u32, period_ticks: u32) {
        self.cycles += 1;
        self.last_compute_ticks = compute_ticks;
        self.max_compute_ticks = self.max_compute_ticks.max(compute_ticks);
        self.total_compute_ticks += u64::from(compute_ticks);
        if compute_ticks > period_ticks {
            self.overruns = self.overruns.saturating_add(1);
        }
    }

    /// Mean compute time in ticks (0 before the first cycle).
    pub fn mean_compute_ticks(&self) -> u32 {
        self.total_compute_ticks
            .checked_div(self.cycles)
            .unwrap_or(0) as u32
    }
}

/// The control loop: owns the cycle statistics, borrows the core's [`Engine`] (which lives in a `static`).
pub struct ControlLoop<'e> {
    engine: &'e mut Engine,
    config: LoopConfig,
    stats: CycleStats,
}

impl<'e> ControlLoop<'e> {
    pub fn new(engine: &'e mut Engine, config: LoopConfig) -> Self {
        ControlLoop {
            engine,
            config,
            stats: CycleStats::new(),
        }
    }

    pub fn config(&self) -> &LoopConfig {
        &self.config
    }

    pub fn stats(&self) -> &CycleStats {
        &self.stats
    }

    pub fn engine(&self) -> &Engine {
        self.engine
    }

    /// One cycle: read scale, command and forces, run the core pipeline, write the corrected command, and
    /// record the compute time. Returns the engine's output record.
    ///
    /// Should the engine ever return no output for a cycle, the command is passed through uncorrected.
    pub fn cycle<Io: AxisIo, C: CycleClock>(
        &mut self,
        io: &mut Io,
        clock: &C,
    ) -> Option<OutputRecord> {
        let t0 = clock.now();
        let input = CycleInput {
            scale_raw: io.read_scale(),
            command_counts: io.read_command(),
            forces_n: io.read_forces(),
        };
        let out = self.engine.step(&Record::Cycle(input));
        io.write_command(match &out {
            Some(o) => o.corrected_command_counts,
            None => input.command_counts,
        });
        self.stats
            .record(clock.elapsed_since(t0), self.config.period_ticks);
        out
    }

    /// Loads an image into the engine's spare slot (A/B swap on success; on error the running slot is
    /// kept). The board's drive checks an image against the board first
    /// ([`crate::drive::group::GroupDrive::offer_image`]).
    pub fn load_image(&mut self, image: &[u8]) -> Result<(), axcomp_core::ImageError> {
        self.engine.load_image(image)
    }

    /// The between-cycles access ([`Inbox`]) outside [`ControlLoop::run`] (e.g. for a loop paced by
    /// the caller).
    pub fn inbox(&mut self) -> Inbox<'_> {
        Inbox {
            engine: self.engine,
            stats: &self.stats,
        }
    }

    /// Applies a non-cycle record (temperatures, process parameters, a new image, a reset) between cycles.
    /// Returns the engine's output (always `None` for these records; a `Cycle` record is run as one).
    pub fn apply(&mut self, record: &Record) -> Option<OutputRecord> {
        self.engine.step(record)
    }

    /// Runs forever at the timer's pace. Before each cycle `between` may apply pending records (e.g.
    /// temperature readings from the sensor task) through the [`Inbox`].
    pub async fn run<Io, C, T, F>(
        &mut self,
        io: &mut Io,
        clock: &C,
        timer: &mut T,
        mut between: F,
    ) -> !
    where
        Io: AxisIo,
        C: CycleClock,
        T: CycleTimer,
        F: FnMut(&mut Inbox<'_>),
    {
        loop {
            timer.next_cycle().await;
            between(&mut Inbox {
                engine: self.engine,
                stats: &self.stats,
            });
            self.cycle(io, clock);
        }
    }
}

/// Applies records between two cycles (see [`ControlLoop::run`]).
pub struct Inbox<'a> {
    engine: &'a mut Engine,
    stats: &'a CycleStats,
}

impl Inbox<'_> {
    pub fn apply(&mut self, record: &Record) {
        let _ = self.engine.step(record);
    }

    pub fn engine(&self) -> &Engine {
        self.engine
    }

    /// The loop's statistics up to the previous cycle (e.g. for periodic logging).
    pub fn stats(&self) -> &CycleStats {
        self.stats
    }
}

/// Host fakes of the board traits, for tests and host simulation.
pub mod fake {
    use super::*;
    use core::cell::Cell;

    /// An axis whose inputs are set by the test and whose last output is kept.
    #[derive(Clone, Copy, Debug, Default, PartialEq)]
    pub struct FakeAxis {
        pub scale_raw: u32,
        pub command_counts: i64,
        pub forces_n: [f32; MAX_FORCES],
        pub written: Option<i64>,
    }

    impl FakeAxis {
        pub fn from_input(input: &CycleInput) -> Self {
            FakeAxis {
                scale_raw: input.scale_raw,
                command_counts: input.command_counts,
                forces_n: input.forces_n,
                written: None,
            }
        }
    }

    impl AxisIo for FakeAxis {
        fn read_scale(&mut self) -> u32 {
            self.scale_raw
        }
        fn read_command(&mut self) -> i64 {
            self.command_counts
        }
        fn read_forces(&mut self) -> [f32; MAX_FORCES] {
            self.forces_n
        }
        fn write_command(&mut self, counts: i64) {
            self.written = Some(counts);
        }
    }

    /// A clock that advances by `step` ticks on every read.
    #[derive(Debug, Default)]
    pub struct SteppingClock {
        pub ticks: Cell<u32>,
        pub step: Cell<u32>,
    }

    impl CycleClock for SteppingClock {
        fn now(&self) -> u32 {
            let t = self.ticks.get();
            self.ticks.set(t.wrapping_add(self.step.get()));
            t
        }
    }

    /// A timer that is always due (the caller paces the loop, e.g. a trace).
    #[derive(Debug, Default)]
    pub struct ImmediateTimer {
        pub ticks: u64,
    }

    impl CycleTimer for ImmediateTimer {
        fn next_cycle(&mut self) -> impl Future<Output = ()> {
            self.ticks += 1;
            core::future::ready(())
        }
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::fake::*;
    use super::*;
    use axcomp_core::bench;
    use std::boxed::Box;
    use std::vec;

    #[test]
    fn settings_are_validated() {
        assert_eq!(
            LoopSettings::new(170_000_000).build().unwrap(),
            LoopConfig {
                rate_hz: 10_000,
                period_ticks: 17_000
            }
        );
        let mut s = LoopSettings::new(1_000_000);
        s.rate_hz = 0;
        assert_eq!(s.build(), Err(LoopError::RateOutOfRange(0)));
        s.rate_hz = 20_000;
        assert_eq!(s.build(), Err(LoopError::ClockTooSlow(1_000_000)));
    }

    #[test]
    fn loop_cycle_equals_engine_step_and_counts_overruns() {
        // Reference: the core's Engine fed the same records directly; outputs must be identical (bit for bit).
        let mut image = vec![0u8; bench::reference_image_len()];
        let n = bench::write_reference_image(&mut image).unwrap();
        let mut engine = Box::new(Engine::new());
        let mut reference = Box::new(Engine::new());
        let cfg = LoopConfig {
            rate_hz: 10_000,
            period_ticks: 1000,
        };
        let mut ctl = ControlLoop::new(&mut engine, cfg);
        let img = Record::Image(&image[..n]);
        assert_eq!(ctl.apply(&img), None);
        let _ = reference.step(&img);
        let p = Record::Process(bench::PROCESS);
        ctl.apply(&p);
        reference.step(&p);
        let clock = SteppingClock::default();
        for i in 0..500u32 {
            if i % 100 == 0 {
                let t = axcomp_core::trace::Temperatures::new(
                    i / 10,
                    &bench::reference_temperatures(i),
                );
                ctl.apply(&Record::Temperatures(t));
                reference.step(&Record::Temperatures(t));
            }
            // Compute time alternates 600 / 1400 ticks: every second cycle overruns the 1000-tick period.
            clock.step.set(if i % 2 == 0 { 600 } else { 1400 });
            let input = bench::reference_input(i);
            let mut io = FakeAxis::from_input(&input);
            let got = ctl.cycle(&mut io, &clock).expect("cycle output");
            let want = reference.step(&Record::Cycle(input)).expect("cycle output");
            assert_eq!(got.encode(), want.encode(), "cycle {i}");
            assert_eq!(io.written, Some(want.corrected_command_counts));
        }
        let st = *ctl.stats();
        assert_eq!(st.cycles, 500);
        assert_eq!(st.overruns, 250);
        assert_eq!(st.max_compute_ticks, 1400);
        assert_eq!(st.mean_compute_ticks(), 1000);
        assert_eq!(ctl.engine().stats().images_accepted, 1);
    }

    /// A timer that is due `remaining` times, then never again.
    struct CountdownTimer {
        remaining: u32,
    }

    struct Due(bool);

    impl Future for Due {
        type Output = ();
        fn poll(
            self: core::pin::Pin<&mut Self>,
            _: &mut core::task::Context<'_>,
        ) -> core::task::Poll<()> {
            if self.0 {
                core::task::Poll::Ready(())
            } else {
                core::task::Poll::Pending
            }
        }
    }

    impl CycleTimer for CountdownTimer {
        fn next_cycle(&mut self) -> impl Future<Output = ()> {
            let due = self.remaining > 0;
            self.remaining = self.remaining.saturating_sub(1);
            Due(due)
        }
    }

    #[test]
    fn run_paces_on_timer_and_applies_inbox_before_each_cycle() {
        use core::pin::pin;
        use core::task::{Context, Poll, Waker};
        let mut image = vec![0u8; bench::reference_image_len()];
        let n = bench::write_reference_image(&mut image).unwrap();
        let mut engine = Box::new(Engine::new());
        let cfg = LoopSettings::new(100_000_000).build().unwrap();
        let mut ctl = ControlLoop::new(&mut engine, cfg);
        let mut io = FakeAxis {
            scale_raw: 100,
            command_counts: 250,
            ..FakeAxis::default()
        };
        let clock = SteppingClock::default();
        let mut timer = CountdownTimer { remaining: 5 };
        let mut inbox_calls = 0u32;
        let mut cycles_seen = vec![];
        {
            let fut = ctl.run(&mut io, &clock, &mut timer, |inbox| {
                inbox_calls += 1;
                cycles_seen.push(inbox.stats().cycles);
                if inbox_calls == 3 {
                    // A new image arrives before the third cycle.
                    inbox.apply(&Record::Image(&image[..n]));
                }
            });
            let mut fut = pin!(fut);
            let mut cx = Context::from_waker(Waker::noop());
            // Five due ticks, then the timer pends: one poll runs exactly five cycles.
            assert!(matches!(fut.as_mut().poll(&mut cx), Poll::Pending));
        }
        assert_eq!(inbox_calls, 5);
        assert_eq!(
            cycles_seen,
            [0, 1, 2, 3, 4],
            "the inbox runs before each cycle"
        );
        assert_eq!(ctl.stats().cycles, 5);
        assert_eq!(ctl.engine().stats().cycles, 5);
        assert_eq!(ctl.engine().stats().images_accepted, 1);
        assert_eq!(
            ctl.engine().active_slot(),
            1,
            "the new image went to slot B"
        );
    }
}
