//! STM32G474RE board firmware: the 10 kHz compensation loop and the RTD temperature task.
//!
//! Flash and run: `cargo board-run` (probe-rs, chip STM32G474RETx). Table images are programmed into the
//! flash slots A/B (see `memory.x`); at boot the firmware loads slot A, else slot B, else runs the identity.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod firmware {
    use axcomp_core::trace::{Record, Temperatures};
    use axcomp_core::{Engine, MAX_SENSORS};
    use axcomp_firmware::board::stm32g474::{self, CORE_CLOCK_HZ, RTD_COUNT, Rtd};
    use axcomp_firmware::control::{ControlLoop, CycleTimer, LoopSettings};
    use axcomp_firmware::max31865;
    use defmt_rtt as _;
    use embassy_executor::Spawner;
    use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
    use embassy_sync::channel::Channel;
    use embassy_time::{Duration, Instant, Ticker};
    use panic_probe as _;
    use static_cell::ConstStaticCell;

    /// The engine (two compensator slots with their tables) is built by the const constructor in the static.
    static ENGINE: ConstStaticCell<Engine> = ConstStaticCell::new(Engine::new());
    /// Temperature readings from the sensor task to the control loop (applied between two cycles).
    static READINGS: Channel<CriticalSectionRawMutex, Temperatures, 2> = Channel::new();

    /// Log the loop statistics this often (10 s at 10 kHz).
    const STATS_EVERY_CYCLES: u64 = 100_000;

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
            // per sensor, once; the loop's ticker catches up afterwards).
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

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let board = stm32g474::init();
        let engine = ENGINE.take();
        for (name, slot) in ["A", "B"].iter().zip(stm32g474::image_slots()) {
            match engine.load_image(slot) {
                Ok(()) => {
                    defmt::info!(
                        "image slot {} loaded (axis {})",
                        name,
                        engine.active().axis_id()
                    );
                    break;
                }
                Err(e) => defmt::warn!("image slot {} rejected: {}", name, defmt::Debug2Format(&e)),
            }
        }
        let period_ms = match engine.active().sensor_period_ms() {
            0 => DEFAULT_SENSOR_PERIOD_MS,
            p => p,
        };
        spawner
            .spawn(temperature_task(board.rtds, period_ms).expect("temperature task spawns once"));

        let cfg = LoopSettings::new(CORE_CLOCK_HZ)
            .build()
            .expect("10 kHz at 170 MHz is valid");
        let mut timer = TickerTimer(Ticker::every(Duration::from_hz(u64::from(cfg.rate_hz))));
        let mut axis = board.axis;
        let clock = board.clock;
        let mut ctl = ControlLoop::new(engine, cfg);
        defmt::info!("control loop at {} Hz", cfg.rate_hz);
        ctl.run(&mut axis, &clock, &mut timer, |inbox| {
            while let Ok(t) = READINGS.try_receive() {
                inbox.apply(&Record::Temperatures(t));
            }
            let st = inbox.stats();
            if st.cycles % STATS_EVERY_CYCLES == 0 && st.cycles > 0 {
                defmt::info!(
                    "cycles {} compute max {} mean {} ticks (period {}), overruns {}",
                    st.cycles,
                    st.max_compute_ticks,
                    st.mean_compute_ticks(),
                    cfg.period_ticks,
                    st.overruns
                );
            }
        })
        .await
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
