//! QEMU instruction-count benchmark of one single-axis drive cycle (`GroupDrive::cycle` with a group of
//! one axis: setpoint bytes → decoder with CRC and sequence check → link supervisor → `GroupEngine`
//! cycle → status word → reply frame → watchdog), run with `-icount shift=0` like `axcomp-qemu-bench`.
//!
//! Method: as `axcomp-qemu-bench` (SysTick calibrated against 1 002 001 instructions; batches of `BATCH`
//! calls with varying inputs through a function pointer, minus the same loop calling an empty function of
//! the same signature). Workload: the core's reference image (table + 8 sensors + forces + clamps), one
//! fresh setpoint frame per cycle (1 or 3 axes, pre-encoded outside the timed loop), one reply frame
//! written to a RAM sink. Prints `bench NAME VALUE UNIT` lines and exits.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod firmware {
    use core::hint::black_box;

    use axcomp_core::bench;
    use axcomp_core::group::GroupEngine;
    use axcomp_firmware::board::instruction_clock::{self, now, ticks_since};
    use axcomp_firmware::board::semihosting;
    use axcomp_firmware::control::{LoopSettings, fake::SteppingClock};
    use axcomp_firmware::drive::group::GroupDrive;
    use axcomp_firmware::drive::{BoardCaps, DriveIo, LinkSettings, NoWatchdog, ResetCause};
    use axcomp_firmware::setpoint::{MAX_SETPOINT_FRAME_LEN, SetpointFrame};
    use cortex_m_rt::entry;
    use cortex_m_semihosting::hprintln;
    use static_cell::ConstStaticCell;

    const BATCH: usize = 100;
    const BATCHES: u32 = 100;
    const IMAGE_BUF_LEN: usize = 36 * 1024;

    /// Coefficient pool (segments): the reference image's bidirectional 1024-segment table.
    const POOL: usize = 2048;

    static ENGINE: ConstStaticCell<GroupEngine<POOL>> = ConstStaticCell::new(GroupEngine::new());
    static IMAGE: ConstStaticCell<[u8; IMAGE_BUF_LEN]> = ConstStaticCell::new([0; IMAGE_BUF_LEN]);

    /// The reference image's board: 32-bit counter, axis 1 (plus 2 and 3 for the three-axis frame), 8 sensors.
    const CAPS: BoardCaps = BoardCaps {
        counter_bits: 32,
        axis_ids: &[1, 2, 3],
        sensors: 8,
    };

    /// A link that delivers one pre-encoded frame per cycle and a scale input; replies go to a RAM sink.
    struct BenchIo {
        frames: [[u8; MAX_SETPOINT_FRAME_LEN]; BATCH],
        frame_len: usize,
        next: usize,
        delivered: bool,
        scale_raw: u32,
        sink: [u8; 32],
    }

    impl DriveIo for BenchIo {
        fn read_scale(&mut self, _input: usize) -> u32 {
            self.scale_raw
        }
        fn read_link(&mut self, buf: &mut [u8]) -> usize {
            if self.delivered {
                return 0;
            }
            self.delivered = true;
            let n = self.frame_len.min(buf.len());
            buf[..n].copy_from_slice(&self.frames[self.next % BATCH][..n]);
            n
        }
        fn write_link(&mut self, frame: &[u8]) -> bool {
            let n = frame.len().min(self.sink.len());
            self.sink[..n].copy_from_slice(&frame[..n]);
            true
        }
    }

    type Engine = GroupEngine<POOL>;
    type DriveCall = fn(&mut GroupDrive, &mut Engine, &mut BenchIo, &SteppingClock);

    #[inline(never)]
    fn drive_cycle(d: &mut GroupDrive, e: &mut Engine, io: &mut BenchIo, c: &SteppingClock) {
        // As in `axcomp-qemu-group-drive-bench` (and the board's `GroupDrive::run`): only the
        // status word is kept, not a copy of the whole cycle record.
        black_box(d.cycle(e, io, c, &mut NoWatchdog).status);
    }

    #[inline(never)]
    fn empty_cycle(_: &mut GroupDrive, _: &mut Engine, _: &mut BenchIo, _: &SteppingClock) {}

    /// Mean instructions per `GroupDrive::cycle` (one axis) with `n_axes` in the setpoint frame.
    fn measure(drive: &mut GroupDrive, engine: &mut Engine, n_axes: usize, ipt: f32) -> f32 {
        let clock = SteppingClock::default();
        let mut io = BenchIo {
            frames: [[0; MAX_SETPOINT_FRAME_LEN]; BATCH],
            frame_len: 0,
            next: 0,
            delivered: false,
            scale_raw: 0,
            sink: [0; 32],
        };
        let run: DriveCall = black_box(drive_cycle);
        let skip: DriveCall = black_box(empty_cycle);
        let mut full: u64 = 0;
        let mut empty: u64 = 0;
        // Continues the sequence of an earlier call (the drive checks it across calls).
        let mut seq = drive.counters().link.frames_ok as u8;
        for b in 0..BATCHES {
            drive.update_temperatures(engine, b * 100, &bench::reference_temperatures(b));
            // Untimed: this batch's frames (fresh sequence numbers, the reference commands).
            for k in 0..BATCH {
                let input = bench::reference_input(b * BATCH as u32 + k as u32);
                let c = input.command_counts as i32;
                let f = match SetpointFrame::new(seq, &[c, c / 2, -c][..n_axes]) {
                    Ok(f) => f,
                    Err(e) => panic!("{}", e),
                };
                seq = seq.wrapping_add(1);
                io.frame_len = f.encode_into(&mut io.frames[k]);
            }
            for (call, acc) in [(run, &mut full), (skip, &mut empty)] {
                let t0 = now();
                for k in 0..BATCH {
                    io.next = k;
                    io.delivered = false;
                    io.scale_raw = bench::reference_input(b * BATCH as u32 + k as u32).scale_raw;
                    call(
                        black_box(&mut *drive),
                        black_box(&mut *engine),
                        black_box(&mut io),
                        &clock,
                    );
                }
                *acc += u64::from(ticks_since(t0));
            }
        }
        full.saturating_sub(empty) as f32 / (BATCHES as f32 * BATCH as f32) * ipt
    }

    #[entry]
    fn main() -> ! {
        let mut core = cortex_m::Peripherals::take().expect("core peripherals taken once");
        instruction_clock::start(&mut core.SYST);
        let ipt = instruction_clock::instructions_per_tick();

        let engine = ENGINE.take();
        let image = IMAGE.take();
        let n = match bench::write_reference_image(image) {
            Ok(n) => n,
            Err(e) => panic!("writing the bench image: {}", e),
        };
        let cfg = match LoopSettings::new(168_000_000).build() {
            Ok(c) => c,
            Err(e) => panic!("{}", e),
        };
        let mut drive = GroupDrive::new(
            CAPS,
            &cfg,
            LinkSettings::defaults(cfg.rate_hz),
            ResetCause::default(),
        );
        if let Err(e) = drive.offer_image(engine, &image[..n]) {
            panic!("bench image refused: {}", e);
        }
        engine.set_process(&bench::PROCESS);

        let one = measure(&mut drive, engine, 1, ipt);
        let three = measure(&mut drive, engine, 3, ipt);
        let c = drive.counters();
        if c.link.frames_ok != 2 * BATCHES * BATCH as u32 || c.link.corrupt != 0 || c.link.lost != 0
        {
            panic!("bench link counters wrong: {:?}", c.link);
        }
        hprintln!("calls per workload: {}", BATCHES * BATCH as u32);
        hprintln!(
            "bench qemu_instructions_per_drive_cycle_frame1 {:.1} instructions",
            one
        );
        hprintln!(
            "bench qemu_instructions_per_drive_cycle_frame3 {:.1} instructions",
            three
        );
        semihosting::exit_success()
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        semihosting::report_panic("axcomp-qemu-drive-bench", info)
    }
}

/// Host builds get a stub: this program only runs on the target.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "axcomp-qemu-drive-bench is firmware: build it with `cargo qemu-build` (thumbv7em-none-eabihf)"
    );
    std::process::exit(2);
}
