//! QEMU instruction-count benchmark of the correction call (`Compensator::cycle`), run with `-icount shift=0`
//! so that SysTick advances deterministically with executed instructions.
//!
//! Method: SysTick (CLKSOURCE = core) is calibrated against a block of exactly 1 002 001 instructions
//! (assembly loop of 1000 × (1000 `nop` + `subs` + `bne`) + `mov`). Each workload is timed over batches of
//! `BATCH` calls with varying inputs (`axcomp_core::bench::reference_input`) through a function pointer, and
//! the same batch loop calling an empty function of the same signature is subtracted, so loop, call/return
//! and measurement overhead cancel: the figure is the work inside `Compensator::cycle` (prologue included). Prints
//! `bench NAME VALUE UNIT` lines (mean instructions per call) and exits.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod firmware {
    use core::hint::black_box;

    use axcomp_core::group::{Group, GroupInput, GroupOutput, GroupState};
    use axcomp_core::trace::{OutputRecord, Record};
    use axcomp_core::{
        Compensator, CycleInput, CycleOutput, Engine, Flags, ImageSpec, State, bench,
    };
    use axcomp_firmware::board::instruction_clock::{self, now, ticks_since};
    use axcomp_firmware::board::semihosting;
    use axcomp_firmware::control::{ControlLoop, LoopSettings, fake::SteppingClock};
    use axcomp_firmware::replay::TraceAxis;
    use cortex_m_rt::entry;
    use cortex_m_semihosting::hprintln;
    use static_cell::ConstStaticCell;

    const BATCH: usize = 100;
    const BATCHES: u32 = 100;
    const IMAGE_BUF_LEN: usize = 36 * 1024;

    static ENGINE: ConstStaticCell<Engine> = ConstStaticCell::new(Engine::new());
    static IMAGE: ConstStaticCell<[u8; IMAGE_BUF_LEN]> = ConstStaticCell::new([0; IMAGE_BUF_LEN]);
    static GROUP: ConstStaticCell<Group<{ bench::GROUP_POOL }>> =
        ConstStaticCell::new(Group::new());
    static GROUP_STATE: ConstStaticCell<GroupState> = ConstStaticCell::new(GroupState::new());

    type GroupCall =
        fn(&Group<{ bench::GROUP_POOL }>, &mut GroupState, &GroupInput, &mut GroupOutput);

    /// The measured group call.
    #[inline(never)]
    fn group_cycle(
        g: &Group<{ bench::GROUP_POOL }>,
        st: &mut GroupState,
        input: &GroupInput,
        out: &mut GroupOutput,
    ) {
        g.cycle(st, input, out)
    }

    /// Its stand-in for the overhead calibration.
    #[inline(never)]
    fn empty_group_cycle(
        _g: &Group<{ bench::GROUP_POOL }>,
        _st: &mut GroupState,
        _input: &GroupInput,
        _out: &mut GroupOutput,
    ) {
    }

    /// Ticks for `BATCH` group cycles from input `first` on (inputs generated in the same loop
    /// for the measured and the empty call, so their cost cancels).
    #[inline(never)]
    fn group_batch(
        g: &Group<{ bench::GROUP_POOL }>,
        st: &mut GroupState,
        first: u32,
        call: GroupCall,
        inputs: fn(u32) -> GroupInput,
    ) -> u32 {
        let call = black_box(call);
        let inputs = black_box(inputs);
        let mut out = GroupOutput::ZERO;
        let t0 = now();
        for k in 0..BATCH as u32 {
            let input = inputs(first + k);
            call(
                black_box(g),
                black_box(&mut *st),
                black_box(&input),
                black_box(&mut out),
            );
        }
        ticks_since(t0)
    }

    /// The group5 workload's input `i` with A and C held at one angle each (X, Y, Z moving as
    /// in [`bench::group_input`]): the rotary stage's cost when no commanded angle changes.
    fn group_input_steady_angles(i: u32) -> GroupInput {
        let mut g = bench::group_input(i);
        for (k, hold) in [(3, 123_457i64), (4, 2_345_679)] {
            g.axes[k].command_counts = hold + 3;
            g.axes[k].scale_raw = hold as u32;
        }
        g
    }

    /// Mean instructions per group cycle of the first `n` workload axes (with the rotary stage
    /// if `stage`).
    fn measure_group(
        g: &mut Group<{ bench::GROUP_POOL }>,
        st: &mut GroupState,
        image: &mut [u8],
        n: usize,
        stage: bool,
        instr_per_tick: f32,
    ) -> f32 {
        measure_group_with(
            g,
            st,
            image,
            n,
            stage,
            false,
            instr_per_tick,
            bench::group_input,
        )
    }

    /// [`measure_group`] with the geometric stage (`axcomp_core::bench::group_geometric`) if
    /// `geometric`, and other inputs.
    #[allow(clippy::too_many_arguments)]
    fn measure_group_with(
        g: &mut Group<{ bench::GROUP_POOL }>,
        st: &mut GroupState,
        image: &mut [u8],
        n: usize,
        stage: bool,
        geometric: bool,
        instr_per_tick: f32,
        inputs: fn(u32) -> GroupInput,
    ) -> f32 {
        let (axes, n) = match bench::write_group_images(n, image) {
            Ok(v) => v,
            Err(e) => panic!("writing the group images: {}", e),
        };
        let stage = stage.then_some(&bench::GROUP_ROTARY_STAGE);
        let geo = bench::group_geometric();
        if let Err(e) = g.load_stages(&axes[..n], stage, geometric.then_some(&geo)) {
            panic!("loading the group: {}", e);
        }
        *st = GroupState::new();
        let mut full: u64 = 0;
        let mut empty: u64 = 0;
        for b in 0..BATCHES {
            full += u64::from(group_batch(g, st, b * BATCH as u32, group_cycle, inputs));
            empty += u64::from(group_batch(
                g,
                st,
                b * BATCH as u32,
                empty_group_cycle,
                inputs,
            ));
        }
        full.saturating_sub(empty) as f32 / (BATCHES as f32 * BATCH as f32) * instr_per_tick
    }

    /// The measured call's stand-in for the overhead calibration: same signature, same call and return of a
    /// `CycleOutput`, no work.
    #[inline(never)]
    fn empty_cycle(_comp: &Compensator, _st: &mut State, input: &CycleInput) -> CycleOutput {
        CycleOutput {
            position_counts: 0,
            corrected_command_counts: input.command_counts,
            correction_counts: 0,
            correction_um: 0.0,
            flags: Flags::NONE,
        }
    }

    type LoopCall =
        fn(&mut ControlLoop<'_>, &mut TraceAxis, &SteppingClock) -> Option<OutputRecord>;

    /// One full control-loop cycle.
    #[inline(never)]
    fn loop_cycle(
        ctl: &mut ControlLoop<'_>,
        axis: &mut TraceAxis,
        clock: &SteppingClock,
    ) -> Option<OutputRecord> {
        ctl.cycle(axis, clock)
    }

    /// Its stand-in for the overhead calibration.
    #[inline(never)]
    fn empty_loop_cycle(
        _ctl: &mut ControlLoop<'_>,
        _axis: &mut TraceAxis,
        _clock: &SteppingClock,
    ) -> Option<OutputRecord> {
        None
    }

    /// Ticks for one batch of `call` over `inputs`. Not inlined: the measured call and the empty
    /// call run through the very same loop code (only the function pointer differs), so the
    /// loop's own instructions cancel exactly in the difference.
    #[inline(never)]
    fn batch(
        comp: &Compensator,
        st: &mut State,
        inputs: &[CycleInput; BATCH],
        call: fn(&Compensator, &mut State, &CycleInput) -> CycleOutput,
    ) -> u32 {
        let call = black_box(call);
        let t0 = now();
        for input in inputs {
            black_box(call(black_box(comp), black_box(&mut *st), black_box(input)));
        }
        ticks_since(t0)
    }

    /// Mean SysTick ticks per call of `Compensator::cycle` minus the empty call, over BATCHES × BATCH calls;
    /// temperatures are updated between batches (untimed), as the sensor task would.
    fn measure(comp: &Compensator, st: &mut State) -> f32 {
        let mut inputs = [bench::reference_input(0); BATCH];
        let mut full: u64 = 0;
        let mut empty: u64 = 0;
        for b in 0..BATCHES {
            for (k, x) in inputs.iter_mut().enumerate() {
                *x = bench::reference_input(b * BATCH as u32 + k as u32);
            }
            comp.update_temperatures(st, b * 100, &bench::reference_temperatures(b));
            full += u64::from(batch(comp, st, &inputs, Compensator::cycle));
            empty += u64::from(batch(comp, st, &inputs, empty_cycle));
        }
        (full.saturating_sub(empty)) as f32 / (BATCHES as f32 * BATCH as f32)
    }

    type SensorCall = fn(&Compensator, &mut State, u32, &[f32; bench::N_SENSORS]);

    /// The measured sensor-rate call.
    #[inline(never)]
    fn sensor_update(comp: &Compensator, st: &mut State, now_ms: u32, r: &[f32; bench::N_SENSORS]) {
        comp.update_temperatures(st, now_ms, r)
    }

    /// Its stand-in for the overhead calibration.
    #[inline(never)]
    fn empty_sensor_update(
        _comp: &Compensator,
        _st: &mut State,
        _now_ms: u32,
        _r: &[f32; bench::N_SENSORS],
    ) {
    }

    /// Ticks for one batch of sensor updates (readings `first..first + BATCH`, 100 ms apart;
    /// generated in the same loop for the measured and the empty call, so their cost cancels).
    #[inline(never)]
    fn sensor_batch(comp: &Compensator, st: &mut State, first: u32, call: SensorCall) -> u32 {
        let call = black_box(call);
        let t0 = now();
        for k in first..first + BATCH as u32 {
            let r = bench::reference_temperatures(k);
            call(
                black_box(comp),
                black_box(&mut *st),
                black_box(k * 100),
                black_box(&r),
            );
        }
        ticks_since(t0)
    }

    /// Mean SysTick ticks per `update_temperatures` call minus the empty call (the reference
    /// image's 8 lagged sensors, every reading accepted, the thermal term live).
    #[inline(never)]
    fn measure_sensor_update(comp: &Compensator, st: &mut State) -> f32 {
        let mut full: u64 = 0;
        let mut empty: u64 = 0;
        for b in 0..BATCHES {
            let first = b * BATCH as u32;
            full += u64::from(sensor_batch(comp, st, first, sensor_update));
            empty += u64::from(sensor_batch(comp, st, first, empty_sensor_update));
        }
        full.saturating_sub(empty) as f32 / (BATCHES as f32 * BATCH as f32)
    }

    /// Loads `spec` into the engine's spare slot (it becomes the active one).
    fn load(engine: &mut Engine, image: &mut [u8], spec: &ImageSpec) {
        let n = match axcomp_core::write_image(spec, image) {
            Ok(n) => n,
            Err(e) => panic!("writing the bench image: {}", e),
        };
        if let Err(e) = engine.load_image(&image[..n]) {
            panic!("loading the bench image: {}", e);
        }
    }

    #[entry]
    fn main() -> ! {
        let mut core = cortex_m::Peripherals::take().expect("core peripherals taken once");
        instruction_clock::start(&mut core.SYST);

        let instr_per_tick = instruction_clock::instructions_per_tick();

        // The engine's slots hold the images; the measured calls use their own State.
        let engine = ENGINE.take();
        let image = IMAGE.take();
        let mut st = State::new();

        // (a) table only (the reference 1024-segment bidirectional table, limits on, no thermo-force term).
        let spec_a = ImageSpec {
            thermo: None,
            ..bench::reference_spec()
        };
        load(engine, image, &spec_a);
        st.reset(bench::reference_input(0).scale_raw);
        let a = measure(engine.active(), &mut st) * instr_per_tick;

        // (b) table + 8 lagged sensors + scale expansion + 3 force terms (one predicted) + clamp and slew.
        load(engine, image, &bench::reference_spec());
        st.reset(bench::reference_input(0).scale_raw);
        engine.active().set_process(&mut st, &bench::PROCESS);
        let b = measure(engine.active(), &mut st) * instr_per_tick;
        // (g) one sensor-rate update of the reference image (8 lagged sensors, expansion).
        // (The measured calls' State is not used after this.)
        st = State::new();
        let g = measure_sensor_update(engine.active(), &mut st) * instr_per_tick;

        // (c) the whole control-loop cycle (trace axis I/O, Engine::step, output record, statistics), with the
        // reference image (already active in the engine).
        let mut ctl = ControlLoop::new(
            engine,
            match LoopSettings::new(168_000_000).build() {
                Ok(c) => c,
                Err(e) => panic!("{}", e),
            },
        );
        ctl.apply(&Record::Process(bench::PROCESS));
        let clock = SteppingClock::default();
        let mut axis = TraceAxis::new();
        let mut full: u64 = 0;
        let mut empty: u64 = 0;
        let run: LoopCall = black_box(loop_cycle);
        let skip: LoopCall = black_box(empty_loop_cycle);
        for b in 0..BATCHES {
            let t =
                axcomp_core::trace::Temperatures::new(b * 100, &bench::reference_temperatures(b));
            ctl.apply(&Record::Temperatures(t));
            for (call, acc) in [(run, &mut full), (skip, &mut empty)] {
                let t0 = now();
                for k in 0..BATCH as u32 {
                    axis.input = bench::reference_input(b * BATCH as u32 + k);
                    black_box(call(black_box(&mut ctl), black_box(&mut axis), &clock));
                }
                *acc += u64::from(ticks_since(t0));
            }
        }
        let c =
            full.saturating_sub(empty) as f32 / (BATCHES as f32 * BATCH as f32) * instr_per_tick;

        // (d), (e) axis groups: three linear axes (bidirectional tables, clamps), then the same plus A
        // and C (tables over the turn) with the rotary location-error stage (8 constants).
        let group = GROUP.take();
        let gst = GROUP_STATE.take();
        let g3 = measure_group(group, gst, image, 3, false, instr_per_tick);
        // (f) the rotary stage's added cost: group5 with minus without the rotary section, with A
        // and C held (no angle change: no sin/cos) and with the workload's angles (both change
        // every cycle: sin/cos and the angle terms recomputed every cycle).
        let steady = group_input_steady_angles;
        let g5_steady =
            measure_group_with(group, gst, image, 5, true, false, instr_per_tick, steady);
        let steady_refreshes = gst.angle_refreshes();
        let g5_steady_plain =
            measure_group_with(group, gst, image, 5, false, false, instr_per_tick, steady);
        let g5_plain = measure_group(group, gst, image, 5, false, instr_per_tick);
        let g5 = measure_group(group, gst, image, 5, true, instr_per_tick);
        let refreshes = gst.angle_refreshes();
        // (f) group3 plus the volumetric geometric stage (18 functions, 3 squareness, tool offset).
        let g3_geo = measure_group_with(
            group,
            gst,
            image,
            3,
            false,
            true,
            instr_per_tick,
            bench::group_input,
        );

        hprintln!("calls per workload: {}", BATCHES * BATCH as u32);
        hprintln!(
            "bench qemu_instructions_per_call_table {:.1} instructions",
            a
        );
        hprintln!(
            "bench qemu_instructions_per_call_table_thermo_force {:.1} instructions",
            b
        );
        hprintln!(
            "bench qemu_instructions_per_loop_cycle {:.1} instructions",
            c
        );
        hprintln!(
            "bench qemu_instructions_per_sensor_update {:.1} instructions",
            g
        );
        hprintln!(
            "bench qemu_instructions_per_cycle_group3 {:.1} instructions",
            g3
        );
        hprintln!(
            "bench qemu_instructions_per_cycle_group5 {:.1} instructions",
            g5
        );
        hprintln!(
            "bench qemu_instructions_per_cycle_group5_rotary {:.1} instructions",
            g5_steady - g5_steady_plain
        );
        hprintln!(
            "bench qemu_instructions_per_cycle_group5_rotary_angles_moving {:.1} instructions",
            g5 - g5_plain
        );
        hprintln!(
            "group5 without the rotary section: {:.1} instructions (angles held: {:.1} without, {:.1} with the section, sin/cos recomputed in {} cycles)",
            g5_plain,
            g5_steady_plain,
            g5_steady,
            steady_refreshes
        );
        hprintln!(
            "bench qemu_instructions_per_cycle_group3_geometry {:.1} instructions",
            g3_geo
        );
        hprintln!(
            "group5: sin/cos recomputed in {} of {} measured cycles",
            refreshes,
            BATCHES * BATCH as u32
        );
        semihosting::exit_success()
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        semihosting::report_panic("axcomp-qemu-bench", info)
    }
}

/// Host builds (e.g. `cargo build --all-features`) get a stub: this program only runs on the target.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "axcomp-qemu-bench is firmware: build it with `cargo qemu-build` (thumbv7em-none-eabihf)"
    );
    std::process::exit(2);
}
