//! QEMU instruction-count benchmark of one drive cycle (`GroupDrive::cycle`: setpoint bytes → decoder
//! with CRC and sequence check → a link supervisor per axis → one `GroupEngine` cycle → the merged
//! status word → reply frame → watchdog), run with `-icount shift=0` like `axcomp-qemu-bench`.
//!
//! Workloads (one drive implementation, two machines):
//! - `frame1` / `frame3`: a single-axis machine (a group of one axis) with the core's reference image
//!   (table + 8 sensors + forces + clamps), one fresh setpoint frame per cycle carrying 1 or 3 axes'
//!   commands (the axis is input 0);
//! - `group3`: the core's `group3` workload (three linear axes with bidirectional tables and clamps),
//!   a 3-axis frame in, a 3-axis reply out.
//!
//! Method: as `axcomp-qemu-bench` (SysTick calibrated against 1 002 001 instructions,
//! `board::instruction_clock`; batches of `BATCH` calls with varying inputs through a function pointer,
//! minus the same loop calling an empty function of the same signature). Frames are pre-encoded outside
//! the timed loop; replies go to a RAM sink. Prints `bench NAME VALUE UNIT` lines and exits.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod firmware {
    use core::hint::black_box;

    use axcomp_core::bench;
    use axcomp_core::group::{GroupEngine, MAX_AXES};
    use axcomp_core::group_image::{AxisSectionSpec, write_group_image};
    use axcomp_firmware::board::instruction_clock::{self, now, ticks_since};
    use axcomp_firmware::board::semihosting;
    use axcomp_firmware::control::{LoopConfig, LoopSettings, fake::SteppingClock};
    use axcomp_firmware::drive::group::GroupDrive;
    use axcomp_firmware::drive::{BoardCaps, DriveIo, LinkSettings, NoWatchdog, ResetCause};
    use axcomp_firmware::setpoint::{MAX_SETPOINT_FRAME_LEN, SetpointFrame};
    use cortex_m_rt::entry;
    use cortex_m_semihosting::hprintln;
    use static_cell::ConstStaticCell;

    const BATCH: usize = 100;
    const BATCHES: u32 = 100;
    /// Coefficient pool (segments): the reference image's bidirectional 1024-segment table.
    const POOL: usize = 2048;
    const IMAGE_BUF_LEN: usize = 36 * 1024;

    static ENGINE: ConstStaticCell<GroupEngine<POOL>> = ConstStaticCell::new(GroupEngine::new());
    /// The reference image; for `group3` the group image and, behind it, its axes' images.
    static IMAGE: ConstStaticCell<[u8; IMAGE_BUF_LEN]> = ConstStaticCell::new([0; IMAGE_BUF_LEN]);
    const GROUP_IMAGE_LEN: usize = 12 * 1024;

    /// The single-axis machine's board: 32-bit counters, axis 1 (2 and 3 for the three-axis
    /// frame), 8 sensors.
    const CAPS_ONE: BoardCaps = BoardCaps {
        counter_bits: 32,
        axis_ids: &[1, 2, 3],
        sensors: 8,
    };

    /// The `group3` workload's board: 32-bit counters, axes 1, 2, 3, no sensors.
    const CAPS_GROUP3: BoardCaps = BoardCaps {
        counter_bits: 32,
        axis_ids: &[1, 2, 3],
        sensors: 0,
    };

    type Engine = GroupEngine<POOL>;

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
        /// The frame where it lies (as the board's UART driver hands its receive buffer).
        fn take_link(&mut self, max: usize, take: impl FnOnce(&[u8])) -> usize {
            if self.delivered {
                return 0;
            }
            self.delivered = true;
            let n = self.frame_len.min(max);
            if n > 0 {
                take(&self.frames[self.next % BATCH][..n]);
            }
            n
        }
        fn write_link(&mut self, frame: &[u8]) -> bool {
            let n = frame.len().min(self.sink.len());
            self.sink[..n].copy_from_slice(&frame[..n]);
            true
        }
    }

    type DriveCall = fn(&mut GroupDrive, &mut Engine, &mut BenchIo, &SteppingClock);

    /// The cycle the board runs (`GroupDrive::run` → `cycle_status`): no per-axis record, the
    /// status word kept (so that nothing is optimised out).
    #[inline(never)]
    fn drive_cycle(d: &mut GroupDrive, e: &mut Engine, io: &mut BenchIo, c: &SteppingClock) {
        black_box(d.cycle_status(e, io, c, &mut NoWatchdog));
    }

    /// The same cycle with its record (`GroupDrive::cycle`: the replay's and the tests' path), the
    /// record built in place and only its status word kept.
    #[inline(never)]
    fn record_cycle(d: &mut GroupDrive, e: &mut Engine, io: &mut BenchIo, c: &SteppingClock) {
        black_box(d.cycle(e, io, c, &mut NoWatchdog).status);
    }

    #[inline(never)]
    fn empty_cycle(_: &mut GroupDrive, _: &mut Engine, _: &mut BenchIo, _: &SteppingClock) {}

    /// A workload: cycle `i`'s commands by frame slot (`.1` of them in the frame) and its scale
    /// readings by board input; `between(batch, drive, engine)` runs before each batch, untimed.
    struct Workload<'a> {
        commands: &'a dyn Fn(u32) -> ([i32; MAX_AXES], usize),
        scales: &'a dyn Fn(u32, &mut [u32; MAX_AXES]),
        between: &'a dyn Fn(u32, &GroupDrive, &mut Engine),
    }

    /// Mean instructions per drive cycle (`call`: `drive_cycle` or `record_cycle`) over `BATCHES` ×
    /// `BATCH` cycles of `w`.
    fn measure(
        drive: &mut GroupDrive,
        engine: &mut Engine,
        w: &Workload<'_>,
        call: DriveCall,
        ipt: f32,
    ) -> f32 {
        let clock = SteppingClock::default();
        let mut io = BenchIo {
            frames: [[0; MAX_SETPOINT_FRAME_LEN]; BATCH],
            frame_len: 0,
            next: 0,
            delivered: false,
            scales: [0; MAX_AXES],
            sink: [0; 40],
        };
        let run: DriveCall = black_box(call);
        let skip: DriveCall = black_box(empty_cycle);
        let mut full: u64 = 0;
        let mut empty: u64 = 0;
        // Continues the sequence of an earlier call (the drive checks it across calls).
        let mut seq = drive.counters().link.frames_ok as u8;
        for b in 0..BATCHES {
            (w.between)(b, drive, engine);
            // Untimed: this batch's frames (fresh sequence numbers).
            for k in 0..BATCH {
                let (c, n) = (w.commands)(b * BATCH as u32 + k as u32);
                let f = match SetpointFrame::new(seq, &c[..n]) {
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
                    (w.scales)(b * BATCH as u32 + k as u32, &mut io.scales);
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

    fn new_drive(caps: BoardCaps, cfg: &LoopConfig) -> GroupDrive {
        GroupDrive::new(
            caps,
            cfg,
            LinkSettings::defaults(cfg.rate_hz),
            ResetCause::default(),
        )
    }

    /// Panics unless every frame of `frames` workloads' cycles was applied.
    fn check_link(drive: &GroupDrive, frames: u32) {
        let c = drive.counters();
        if c.link.frames_ok != frames || c.link.corrupt != 0 || c.link.lost != 0 {
            panic!("bench link counters wrong: {:?}", c.link);
        }
    }

    /// The single-axis machine (a group of one axis, the reference image): `frame1`, `frame3`.
    #[inline(never)]
    fn single_axis(engine: &mut Engine, image: &mut [u8], cfg: &LoopConfig, ipt: f32) -> [f32; 3] {
        let n = match bench::write_reference_image(image) {
            Ok(n) => n,
            Err(e) => panic!("writing the bench image: {}", e),
        };
        let mut drive = new_drive(CAPS_ONE, cfg);
        if let Err(e) = drive.offer_image(engine, &image[..n]) {
            panic!("bench image refused: {}", e);
        }
        engine.set_process(&bench::PROCESS);
        let temperatures = |b: u32, d: &GroupDrive, e: &mut Engine| {
            d.update_temperatures(e, b * 100, &bench::reference_temperatures(b));
        };
        let scale = |i: u32, s: &mut [u32; MAX_AXES]| s[0] = bench::reference_input(i).scale_raw;
        let mut per_cycle = [0.0f32; 3];
        let runs: [(usize, DriveCall); 3] = [(1, drive_cycle), (3, drive_cycle), (1, record_cycle)];
        for (k, (width, call)) in runs.into_iter().enumerate() {
            // The axis's command in slot 0; the three-axis frame carries two more.
            let commands = move |i: u32| {
                let c = bench::reference_input(i).command_counts as i32;
                ([c, c / 2, -c, 0, 0], width)
            };
            let w = Workload {
                commands: &commands,
                scales: &scale,
                between: &temperatures,
            };
            per_cycle[k] = measure(&mut drive, engine, &w, call, ipt);
        }
        check_link(&drive, 3 * BATCHES * BATCH as u32);
        if drive.axis_count() != 1 {
            panic!("the single-axis drive runs {} axes", drive.axis_count());
        }
        per_cycle
    }

    /// The `group3` workload: three linear axes, a 3-axis frame and reply.
    #[inline(never)]
    fn group3(engine: &mut Engine, image: &mut [u8], cfg: &LoopConfig, ipt: f32) -> [f32; 2] {
        let (group_buf, axis_buf) = image.split_at_mut(GROUP_IMAGE_LEN);
        let (axes, n) = match bench::write_group_images(3, axis_buf) {
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
        let len = match write_group_image(&specs[..n], None, group_buf) {
            Ok(l) => l,
            Err(e) => panic!("writing the group image: {}", e),
        };
        let mut drive = new_drive(CAPS_GROUP3, cfg);
        if let Err(e) = drive.offer_image(engine, &group_buf[..len]) {
            panic!("bench image refused: {}", e);
        }
        let commands = |i: u32| {
            let g = bench::group_input(i);
            let c = [0, 1, 2].map(|a| g.axes[a].command_counts as i32);
            ([c[0], c[1], c[2], 0, 0], 3)
        };
        let scales = |i: u32, s: &mut [u32; MAX_AXES]| {
            let g = bench::group_input(i);
            for a in 0..3 {
                s[a] = g.axes[a].scale_raw;
            }
        };
        let w = Workload {
            commands: &commands,
            scales: &scales,
            between: &|_, _, _| {},
        };
        let per_cycle =
            [drive_cycle, record_cycle].map(|call| measure(&mut drive, engine, &w, call, ipt));
        check_link(&drive, 2 * BATCHES * BATCH as u32);
        if drive.axis_count() != 3 {
            panic!("the group drive runs {} axes", drive.axis_count());
        }
        per_cycle
    }

    #[entry]
    fn main() -> ! {
        let mut core = cortex_m::Peripherals::take().expect("core peripherals taken once");
        instruction_clock::start(&mut core.SYST);
        let ipt = instruction_clock::instructions_per_tick();
        let cfg = match LoopSettings::new(168_000_000).build() {
            Ok(c) => c,
            Err(e) => panic!("{}", e),
        };
        let engine = ENGINE.take();
        let image = IMAGE.take();
        let one_axis = single_axis(engine, image, &cfg, ipt);
        let group3 = group3(engine, image, &cfg, ipt);

        hprintln!("calls per workload: {}", BATCHES * BATCH as u32);
        hprintln!(
            "bench qemu_instructions_per_drive_cycle_frame1 {:.1} instructions",
            one_axis[0]
        );
        hprintln!(
            "bench qemu_instructions_per_drive_cycle_frame3 {:.1} instructions",
            one_axis[1]
        );
        hprintln!(
            "bench qemu_instructions_per_drive_cycle_group3 {:.1} instructions",
            group3[0]
        );
        hprintln!(
            "bench qemu_instructions_per_drive_cycle_frame1_record {:.1} instructions",
            one_axis[2]
        );
        hprintln!(
            "bench qemu_instructions_per_drive_cycle_group3_record {:.1} instructions",
            group3[1]
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
