//! QEMU instruction-count benchmark of one group drive cycle (`GroupDrive::cycle` for the `group3`
//! workload: a 3-axis setpoint frame → decoder with CRC and sequence check → three link supervisors →
//! one `GroupEngine` cycle of three linear axes with bidirectional tables and clamps → the merged status
//! word → a 3-axis reply frame), run with `-icount shift=0` like `axcomp-qemu-drive-bench`.
//!
//! Method: as `axcomp-qemu-drive-bench` (SysTick calibrated against 1 002 001 instructions; batches of
//! `BATCH` calls with varying inputs (`axcomp_core::bench::group_input`) through a function pointer, minus
//! the same loop calling an empty function of the same signature). Prints `bench NAME VALUE UNIT`.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod firmware {
    use core::hint::black_box;

    use axcomp_core::bench;
    use axcomp_core::group::{GroupEngine, MAX_AXES};
    use axcomp_core::group_image::{AxisSectionSpec, write_group_image};
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
    const POOL: usize = 1024;

    static ENGINE: ConstStaticCell<GroupEngine<POOL>> = ConstStaticCell::new(GroupEngine::new());
    static AXIS_IMAGES: ConstStaticCell<[u8; 8 * 1024]> = ConstStaticCell::new([0; 8 * 1024]);
    static IMAGE: ConstStaticCell<[u8; 12 * 1024]> = ConstStaticCell::new([0; 12 * 1024]);

    /// The `group3` workload's board: 32-bit counters, axes 1, 2, 3, no sensors.
    const CAPS: BoardCaps = BoardCaps {
        counter_bits: 32,
        axis_ids: &[1, 2, 3],
        sensors: 0,
    };

    /// A link that delivers one pre-encoded frame per cycle and the scale inputs; replies go to a sink.
    struct BenchIo {
        frames: [[u8; MAX_SETPOINT_FRAME_LEN]; BATCH],
        frame_len: usize,
        next: usize,
        delivered: bool,
        scales: [u32; MAX_AXES],
        sink: [u8; 40],
    }

    impl DriveIo for BenchIo {
        fn read_scale(&mut self, input: usize) -> u32 {
            self.scales[input % MAX_AXES]
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

    type DriveCall = fn(&mut GroupDrive, &mut GroupEngine<POOL>, &mut BenchIo, &SteppingClock);

    #[inline(never)]
    fn drive_cycle(
        d: &mut GroupDrive,
        e: &mut GroupEngine<POOL>,
        io: &mut BenchIo,
        c: &SteppingClock,
    ) {
        // As the board's `GroupDrive::run` does, the cycle's record is not kept (only its status
        // word, so that nothing is optimised out): what the record holds is computed and stored
        // by the cycle anyway, while keeping the whole record would add a 312-byte copy of it
        // that the board never makes.
        black_box(d.cycle(e, io, c, &mut NoWatchdog).status);
    }

    #[inline(never)]
    fn empty_cycle(
        _: &mut GroupDrive,
        _: &mut GroupEngine<POOL>,
        _: &mut BenchIo,
        _: &SteppingClock,
    ) {
    }

    #[entry]
    fn main() -> ! {
        let mut core = cortex_m::Peripherals::take().expect("core peripherals taken once");
        instruction_clock::start(&mut core.SYST);
        let ipt = instruction_clock::instructions_per_tick();

        let engine = ENGINE.take();
        let (axes, n) = match bench::write_group_images(3, AXIS_IMAGES.take()) {
            Ok(a) => a,
            Err(e) => panic!("writing the group images: {}", e),
        };
        let specs = [0, 1, 2].map(|k| AxisSectionSpec {
            name: axes[k].name,
            counts_per_rev: axes[k].counts_per_rev,
            stroke_counts: None,
            image: axes[k].image,
            sensor_names: &[],
        });
        let image = IMAGE.take();
        let len = match write_group_image(&specs[..n], None, image) {
            Ok(l) => l,
            Err(e) => panic!("writing the group image: {}", e),
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
        if let Err(e) = drive.offer_image(engine, &image[..len]) {
            panic!("bench image refused: {}", e);
        }

        let clock = SteppingClock::default();
        let mut io = BenchIo {
            frames: [[0; MAX_SETPOINT_FRAME_LEN]; BATCH],
            frame_len: 0,
            next: 0,
            delivered: false,
            scales: [0; MAX_AXES],
            sink: [0; 40],
        };
        let run: DriveCall = black_box(drive_cycle);
        let skip: DriveCall = black_box(empty_cycle);
        let mut full: u64 = 0;
        let mut empty: u64 = 0;
        let mut seq = 0u8;
        for b in 0..BATCHES {
            for k in 0..BATCH {
                let g = bench::group_input(b * BATCH as u32 + k as u32);
                let c = [0, 1, 2].map(|a| g.axes[a].command_counts as i32);
                let f = match SetpointFrame::new(seq, &c) {
                    Ok(f) => f,
                    Err(e) => panic!("{}", e),
                };
                seq = seq.wrapping_add(1);
                io.frame_len = f.encode_into(&mut io.frames[k]);
            }
            for (call, acc) in [(run, &mut full), (skip, &mut empty)] {
                let t0 = now();
                for k in 0..BATCH {
                    let g = bench::group_input(b * BATCH as u32 + k as u32);
                    io.next = k;
                    io.delivered = false;
                    for a in 0..3 {
                        io.scales[a] = g.axes[a].scale_raw;
                    }
                    call(
                        black_box(&mut drive),
                        black_box(&mut *engine),
                        black_box(&mut io),
                        &clock,
                    );
                }
                *acc += u64::from(ticks_since(t0));
            }
        }
        let per_cycle = full.saturating_sub(empty) as f32 / (BATCHES as f32 * BATCH as f32) * ipt;
        let c = drive.counters();
        if c.link.frames_ok != BATCHES * BATCH as u32 || c.link.corrupt != 0 || c.link.lost != 0 {
            panic!("bench link counters wrong: {:?}", c.link);
        }
        if drive.axis_count() != 3 {
            panic!("the group drive runs {} axes", drive.axis_count());
        }
        hprintln!("calls per workload: {}", BATCHES * BATCH as u32);
        hprintln!(
            "bench qemu_instructions_per_drive_cycle_group3 {:.1} instructions",
            per_cycle
        );
        semihosting::exit_success()
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        semihosting::report_panic("axcomp-qemu-group-drive-bench", info)
    }
}

/// Host builds get a stub: this program only runs on the target.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "axcomp-qemu-group-drive-bench is firmware: build it with `cargo qemu-build` (thumbv7em-none-eabihf)"
    );
    std::process::exit(2);
}
