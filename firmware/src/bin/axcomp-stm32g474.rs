//! STM32G474RE board firmware: the 10 kHz compensation drive, the RTD temperature task and the status log.
//!
//! Flash and run: `cargo board-run` (probe-rs, chip STM32G474RETx). Table images are programmed into the
//! flash slots A/B (see `memory.x`); at boot the firmware offers slot A, else slot B, to the drive, which
//! checks each against the board ([`axcomp_firmware::drive::BoardCaps`]) before loading it; with neither
//! it runs the identity.
//!
//! Priorities: the drive (setpoint link, engine, status word, watchdog) runs on an interrupt-mode executor
//! above thread mode; the RTD task (blocking SPI reads, about 50 µs per sensor at 1 MHz) and the status log
//! run in thread mode, so they never delay a cycle; the drive's lateness counters show it on the board.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod firmware {
    use core::cell::Cell;
    use core::sync::atomic::{AtomicU32, Ordering};

    use axcomp_core::MAX_SENSORS;
    use axcomp_core::group::GroupEngine;
    use axcomp_core::trace::Temperatures;
    use axcomp_firmware::board::stm32g474::{
        self, BoardIo, CORE_CLOCK_HZ, DwtClock, Iwdg, LOOP_PRIORITY, RTD_COUNT, Rtd,
    };
    use axcomp_firmware::control::{CycleTimer, LoopConfig, LoopSettings};
    use axcomp_firmware::drive::group::GroupDrive;
    use axcomp_firmware::drive::{DriveCounters, LinkSettings};
    use axcomp_firmware::max31865;
    use axcomp_firmware::status::Status;
    use defmt_rtt as _;
    use embassy_executor::{InterruptExecutor, Spawner};
    use embassy_stm32::interrupt;
    use embassy_stm32::interrupt::InterruptExt;
    use embassy_sync::blocking_mutex::Mutex;
    use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
    use embassy_sync::channel::Channel;
    use embassy_time::{Duration, Instant, Ticker};
    use panic_probe as _;
    use static_cell::ConstStaticCell;

    /// The engine (two compensator slots with their tables) is built by the const constructor in the static.
    /// Table segments of the group (per A/B slot, shared by its axes): `stm32g474::POOL`.
    const POOL: usize = stm32g474::POOL;
    static ENGINE: ConstStaticCell<GroupEngine<POOL>> = ConstStaticCell::new(GroupEngine::new());
    /// Temperature readings from the sensor task to the control loop (applied between two cycles).
    static READINGS: Channel<CriticalSectionRawMutex, Temperatures, 2> = Channel::new();
    /// The loop's executor, pended through the (otherwise unused) UART4 interrupt.
    static LOOP_EXECUTOR: InterruptExecutor = InterruptExecutor::new();
    /// OR of the status words since the status task last looked (so a one-cycle fault is logged too).
    static STATUS_SEEN: AtomicU32 = AtomicU32::new(0);
    /// The drive's counters, published every [`PUBLISH_EVERY_CYCLES`].
    static COUNTERS: Mutex<CriticalSectionRawMutex, Cell<Option<DriveCounters>>> =
        Mutex::new(Cell::new(None));

    #[interrupt]
    unsafe fn UART4() {
        // SAFETY: the executor's interrupt handler, and only that; started before the interrupt is unmasked.
        unsafe { LOOP_EXECUTOR.on_interrupt() }
    }

    /// The touch probe's capture interrupt (TIM3_CH3 captured a probe edge; enabled only with
    /// `stm32g474::PROBE_INPUT_CAPTURE`): reads the three encoder timers' captures into the queue
    /// the drive takes each cycle.
    #[interrupt]
    fn TIM3() {
        stm32g474::on_probe_capture_interrupt();
    }

    /// Publish the counters this often (10 Hz at 10 kHz).
    const PUBLISH_EVERY_CYCLES: u32 = 1_000;
    /// The status task looks this often.
    const STATUS_LOG_MS: u64 = 100;
    /// Log the counters this often even without a change.
    const COUNTERS_LOG_MS: u64 = 10_000;

    /// Default sensor period when the image has no thermo-force term.
    const DEFAULT_SENSOR_PERIOD_MS: u32 = 100;

    /// The loop's pace: an embassy ticker at the cycle rate.
    struct TickerTimer(Ticker);

    impl CycleTimer for TickerTimer {
        fn next_cycle(&mut self) -> impl core::future::Future<Output = ()> {
            self.0.next()
        }
    }

    #[embassy_executor::task]
    async fn temperature_task(mut rtds: [Rtd; RTD_COUNT], period_ms: u32) {
        for (i, rtd) in rtds.iter_mut().enumerate() {
            if let Err(e) = rtd.init() {
                defmt::warn!("RTD {}: init failed: {}", i, e);
            }
            // Wiring check at start-up: the chip's automatic fault-detection cycle (busy-waits at most 1 ms
            // per sensor, once, in thread mode: the drive preempts it).
            match rtd.run_fault_detection(&mut embassy_time::Delay) {
                Ok(s) if s.0 == 0 => {}
                Ok(s) => defmt::warn!("RTD {}: fault detection found 0x{:02x}", i, s.0),
                Err(e) => defmt::warn!("RTD {}: fault detection failed: {}", i, e),
            }
        }
        let mut ticker = Ticker::every(Duration::from_millis(u64::from(period_ms)));
        loop {
            ticker.next().await;
            let mut readings = [f32::NAN; RTD_COUNT];
            for (i, rtd) in rtds.iter_mut().enumerate() {
                match rtd.read_temperature_degc() {
                    Ok(t) => readings[i] = t,
                    Err(max31865::Error::Fault(s)) => {
                        defmt::warn!("RTD {}: fault 0x{:02x}", i, s.0)
                    }
                    Err(max31865::Error::Spi(_)) => defmt::warn!("RTD {}: SPI error", i),
                    Err(max31865::Error::FaultDetectionTimeout) => {
                        defmt::warn!("RTD {}: fault detection timed out", i)
                    }
                }
            }
            let now_ms = Instant::now().as_millis() as u32;
            // A full channel means the loop has not consumed the previous set: drop this one (the core's
            // staleness check covers lost readings).
            let _ = READINGS.try_send(Temperatures::new(
                now_ms,
                &readings[..RTD_COUNT.min(MAX_SENSORS)],
            ));
        }
    }

    /// The status word out through defmt: every change of the flags seen (OR over the last
    /// [`STATUS_LOG_MS`]), and the counters every [`COUNTERS_LOG_MS`].
    #[embassy_executor::task]
    async fn status_task() {
        let mut ticker = Ticker::every(Duration::from_millis(STATUS_LOG_MS));
        let mut last = None;
        let mut since_counters = 0u64;
        loop {
            ticker.next().await;
            let seen = Status(STATUS_SEEN.swap(0, Ordering::Relaxed));
            if last != Some(seen) {
                if !seen.is_empty() {
                    defmt::warn!("status {}", seen);
                } else {
                    defmt::info!("status OK");
                }
                last = Some(seen);
            }
            since_counters += STATUS_LOG_MS;
            if since_counters >= COUNTERS_LOG_MS {
                since_counters = 0;
                if let Some(c) = COUNTERS.lock(|c| c.get()) {
                    defmt::info!("counters {}", c);
                }
            }
        }
    }

    #[embassy_executor::task]
    async fn drive_task(
        engine: &'static mut GroupEngine<POOL>,
        cfg: LoopConfig,
        mut drive: GroupDrive,
        mut io: BoardIo,
        mut probe: stm32g474::BoardProbe,
        clock: DwtClock,
        mut watchdog: Iwdg,
    ) {
        let mut timer = TickerTimer(Ticker::every(Duration::from_hz(u64::from(cfg.rate_hz))));
        watchdog.start();
        defmt::info!(
            "drive at {} Hz, watchdog {} us",
            cfg.rate_hz,
            stm32g474::WATCHDOG_TIMEOUT_US
        );
        drive
            .run_with_probe(
                engine,
                &mut io,
                &mut probe,
                &clock,
                &mut timer,
                &mut watchdog,
                |engine, drive| {
                    while let Ok(t) = READINGS.try_receive() {
                        drive.update_temperatures(engine, t.now_ms, t.readings());
                    }
                    STATUS_SEEN.fetch_or(drive.status().bits(), Ordering::Relaxed);
                    if drive.cycles() % PUBLISH_EVERY_CYCLES == 0 {
                        COUNTERS.lock(|c| c.set(Some(drive.counters())));
                    }
                },
            )
            .await
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let board = stm32g474::init();
        if board.reset_cause.watchdog {
            defmt::error!("reset by the watchdog");
        }
        let cfg = LoopSettings::new(CORE_CLOCK_HZ)
            .build()
            .expect("10 kHz at 170 MHz is valid");
        let engine = ENGINE.take();
        let mut drive = GroupDrive::new(
            stm32g474::CAPS,
            &cfg,
            LinkSettings::defaults(cfg.rate_hz),
            board.reset_cause,
        )
        .with_sensor_inputs(&stm32g474::SENSOR_INPUTS);
        // Each slot (128 KiB of flash) is offered cut to the length its image header declares
        // (`image_slots`); trailing bytes would be refused by the loader.
        for (name, slot) in ["A", "B"].iter().zip(stm32g474::image_slots()) {
            match drive.offer_image(engine, slot) {
                Ok(()) => {
                    defmt::info!(
                        "image slot {} loaded ({} axes, scale inputs {})",
                        name,
                        drive.axis_count(),
                        drive.inputs()
                    );
                    break;
                }
                Err(e) => {
                    defmt::warn!("image slot {} refused: {}", name, defmt::Display2Format(&e))
                }
            }
        }
        let g = engine.active();
        let period_ms = match (0..g.axis_count())
            .filter_map(|i| g.axis(i).map(|a| a.sensor_period_ms()))
            .filter(|&p| p > 0)
            .min()
        {
            None => DEFAULT_SENSOR_PERIOD_MS,
            Some(p) => p,
        };
        spawner
            .spawn(temperature_task(board.rtds, period_ms).expect("temperature task spawns once"));
        spawner.spawn(status_task().expect("status task spawns once"));

        interrupt::UART4.set_priority(LOOP_PRIORITY);
        let loop_spawner = LOOP_EXECUTOR.start(interrupt::UART4);
        loop_spawner.spawn(
            drive_task(
                engine,
                cfg,
                drive,
                board.io,
                board.probe,
                board.clock,
                board.watchdog,
            )
            .expect("drive task spawns once"),
        );
    }
}

/// Host builds (e.g. `cargo build --all-features`) get a stub: this program only runs on the target.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "axcomp-stm32g474 is firmware: build it with `cargo board-build` (thumbv7em-none-eabihf)"
    );
    std::process::exit(2);
}
