//! Host tests of the drive: board capabilities, link faults, lateness, watchdog, status word, and the
//! fault matrix (every fault of the table in `docs/firmware.md` ends in its documented state), on a
//! one-axis [`GroupDrive`] (a schema-1 image is a group of one axis). The multi-axis cases are in
//! `drive::group` and `drive::wiring_tests`.

extern crate std;
use std::boxed::Box;
use std::vec;
use std::vec::Vec;

use axcomp_core::group::GroupEngine;
use axcomp_core::trace::Record;
use axcomp_core::{
    CycleOutput, Engine, ImageError, ImageSpec, LimitSpec, OutsideStroke, SensorSpec, TableSpec,
    ThermoForceSpec, write_image,
};

use super::fake::{FakeDriveIo, FakeWatchdog};
use super::group::{GroupDrive, GroupDriveCycle};
use super::*;
use crate::control::fake::SteppingClock;
use crate::control::{LoopConfig, LoopSettings};
use crate::setpoint::{
    CounterId, MAX_SETPOINT_FRAME_LEN, ReplyDecoder, SetpointFrame, reply_frame_len,
};

/// Coefficient pool of the tests' engine (segments; the images have 4).
const POOL: usize = 64;
type Eng = GroupEngine<POOL>;

/// The board of these tests: 16-bit counters, axes 1, 2, 3 on inputs 0, 1, 2, two RTDs.
const CAPS: BoardCaps = BoardCaps {
    counter_bits: 16,
    axis_ids: &[1, 2, 3],
    sensors: 2,
};

/// A constant forward table of `table_um` (one segment per 1000 counts over ±1e6 counts is not needed:
/// `Hold` outside the stroke keeps the value everywhere), `n_sensors` sensors with b = 0.
struct ImageArgs {
    axis_id: u16,
    counter_bits: u8,
    n_sensors: usize,
    table_um: f32,
    max_correction_um: f32,
}

const BASE: ImageArgs = ImageArgs {
    axis_id: 1,
    counter_bits: 16,
    n_sensors: 0,
    table_um: 2.0,
    max_correction_um: 100.0,
};

const SENSOR: SensorSpec = SensorSpec {
    reference_degc: 20.0,
    min_degc: 0.0,
    max_degc: 60.0,
    max_rate_degc_per_s: 5.0,
    lag_tau_s: 0.0,
    stale_timeout_ms: 500,
};

fn image(a: ImageArgs) -> Vec<u8> {
    let fwd = [[a.table_um, 0.0, 0.0, 0.0]; 4];
    let sensors = [SENSOR; 4];
    let b = [0.0f32; 4];
    let spec = ImageSpec {
        axis_id: a.axis_id,
        um_per_count: 0.1,
        counter_bits: a.counter_bits,
        table: Some(TableSpec {
            start_counts: 0,
            segment_counts: 1000,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        }),
        thermo: (a.n_sensors > 0).then_some(ThermoForceSpec {
            sensor_period_ms: 100,
            sensors: &sensors[..a.n_sensors],
            b0_um: 0.0,
            b_um_per_k: &b[..a.n_sensors],
            expansion: None,
            forces: &[],
            reference: axcomp_core::ThermoReference::Fixed,
            rise_bounds_k: &[],
        }),
        limits: LimitSpec {
            max_correction_um: a.max_correction_um,
            max_slew_um_per_cycle: 10.0,
            direction_hysteresis_counts: 5,
        },
    };
    let mut buf = vec![0u8; 4096];
    let n = write_image(&spec, &mut buf).expect("test image");
    buf.truncate(n);
    buf
}

/// 10 kHz loop on a 10 MHz clock: 1000 ticks per cycle (lateness tolerance 100 ticks).
fn config() -> LoopConfig {
    LoopSettings::new(10_000_000).build().unwrap()
}

/// Hold 5 cycles, ramp 0.5 µm per cycle.
const LINK: LinkSettings = LinkSettings {
    hold_cycles: 5,
    ramp_um_per_cycle: 0.5,
};

fn frame(seq: u8, cmds: &[i32]) -> Vec<u8> {
    let mut b = [0u8; MAX_SETPOINT_FRAME_LEN];
    let n = SetpointFrame::new(seq, cmds).unwrap().encode_into(&mut b);
    b[..n].to_vec()
}

fn send(io: &mut FakeDriveIo, seq: u8, cmds: &[i32]) {
    io.rx.extend(frame(seq, cmds));
}

/// One cycle of the drive as the tests see it: group slot 0, the one axis.
#[derive(Clone, Copy, Debug)]
struct DriveCycle {
    command_counts: i64,
    corrected_command_counts: i64,
    applied: Applied,
    status: Status,
    /// The engine's output for the axis (before the link supervisor).
    engine: Option<CycleOutput>,
}

impl From<GroupDriveCycle> for DriveCycle {
    fn from(c: GroupDriveCycle) -> Self {
        DriveCycle {
            command_counts: c.command_counts[0],
            corrected_command_counts: c.corrected_command_counts[0],
            applied: c.applied[0],
            status: c.status,
            engine: (c.n_axes > 0).then_some(c.engine.axes[0]),
        }
    }
}

/// Everything one drive needs; the engine is boxed outside, each test passes it in.
struct Rig {
    drive: GroupDrive,
    io: FakeDriveIo,
    clock: SteppingClock,
}

impl Rig {
    fn new(reset: ResetCause) -> Self {
        Rig {
            drive: GroupDrive::new(CAPS, &config(), LINK, reset),
            io: FakeDriveIo::default(),
            clock: SteppingClock::default(),
        }
    }
    fn cycle(&mut self, e: &mut Eng) -> DriveCycle {
        self.drive
            .cycle(e, &mut self.io, &self.clock, &mut NoWatchdog)
            .into()
    }
}

fn engine() -> Box<Eng> {
    Box::new(GroupEngine::new())
}

/// Axis id of the running image's axis (0 without one).
fn axis_id(e: &Eng) -> u16 {
    e.active().axis(0).map_or(0, |a| a.axis_id())
}

/// Sensors of the running image's axis.
fn sensor_count(e: &Eng) -> usize {
    e.active().axis(0).map_or(0, |a| a.sensor_count())
}

const LINK_FLAGS: Status = Status(
    Status::FRAME_LATE.0
        | Status::FRAME_CORRUPT.0
        | Status::FRAME_REPEATED.0
        | Status::FRAME_MISSING.0
        | Status::LINK_HOLD.0
        | Status::LINK_RAMP.0,
);

// ---- board capabilities -------------------------------------------------------------------------

#[test]
fn images_that_do_not_fit_the_board_are_refused_and_the_running_slot_kept() {
    let mut eng = engine();
    let e = &mut *eng;
    let mut rig = Rig::new(ResetCause::default());
    rig.drive.offer_image(e, &image(BASE)).unwrap();
    assert_eq!(e.active_slot(), 1);
    let good_crc = inspect_image(&image(BASE)).unwrap().crc;

    let cases: [(Vec<u8>, ImageRefusal); 4] = [
        // The case to catch: a default (32-bit) image on the board's 16-bit timer.
        (
            image(ImageArgs {
                counter_bits: 32,
                ..BASE
            }),
            ImageRefusal::CounterWidth {
                image: 32,
                board: 16,
            },
        ),
        (
            image(ImageArgs { axis_id: 9, ..BASE }),
            ImageRefusal::AxisNotWired { axis_id: 9 },
        ),
        (
            image(ImageArgs {
                n_sensors: 3,
                ..BASE
            }),
            ImageRefusal::SensorsNotWired { image: 3, board: 2 },
        ),
        (
            {
                let mut b = image(ImageArgs {
                    table_um: 3.0,
                    ..BASE
                });
                let mid = b.len() / 2;
                b[mid] ^= 0x01;
                b
            },
            ImageRefusal::Invalid(ImageError::BadCrc),
        ),
    ];
    for (i, (bytes, want)) in cases.iter().enumerate() {
        assert_eq!(rig.drive.offer_image(e, bytes), Err(*want), "case {i}");
        // Never loaded: same slot, same image, the engine saw no image at all for the board refusals.
        assert_eq!(e.active_slot(), 1, "case {i}");
        assert_eq!(e.stats().images_accepted, 1, "case {i}");
        assert_eq!(axis_id(e), 1);
        send(&mut rig.io, i as u8, &[1000]);
        let c = rig.cycle(e);
        assert!(
            c.status.contains(Status::IMAGE_REFUSED),
            "case {i}: latched"
        );
        assert_eq!(
            c.corrected_command_counts,
            1000 - 20,
            "case {i}: old table runs"
        );
    }
    assert_eq!(rig.drive.counters().images_refused, 4);
    assert_eq!(e.stats().images_rejected, 0, "refused before the engine");
    assert_eq!(
        CAPS.check_compensator(e.active().axis(0).expect("an axis")),
        Ok(0),
        "running image fits"
    );
    let _ = good_crc;
    // An image for axis 3 fits: accepted, the flag clears, the drive follows frame slot / input 2.
    rig.drive
        .offer_image(e, &image(ImageArgs { axis_id: 3, ..BASE }))
        .unwrap();
    assert_eq!(rig.drive.inputs(), &[2]);
    send(&mut rig.io, 10, &[5, 6, 7000]);
    rig.io.scales = [0, 0, 100, 0, 0];
    let c = rig.cycle(e);
    assert!(!c.status.contains(Status::IMAGE_REFUSED));
    assert_eq!(c.command_counts, 7000);
    assert_eq!(c.engine.unwrap().position_counts, 100, "input 2's scale");
}

/// Deterministic xorshift32 (test input generator only).
fn xorshift(state: &mut u32) -> u32 {
    let mut x = *state;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *state = x;
    x
}

#[test]
fn board_counter_width_extends_exactly_and_a_32_bit_image_would_jump() {
    // Reference: the true position, integrated from the steps; the board delivers it as a wrapping
    // 16-bit counter (`truth as u16`). Any step below half the counter range (|step| < 2^15) must be
    // extended exactly by the image the board accepts (counter_bits = 16).
    let mut eng = engine();
    let e = &mut *eng;
    let mut rig = Rig::new(ResetCause::default());
    rig.drive.offer_image(e, &image(BASE)).unwrap();
    let mut rng = 0x1234_5678u32;
    let mut truth: i64 = 0;
    for k in 0..20_000u32 {
        let max_step = [3, 300, 32_767][(k / 1000 % 3) as usize];
        let step = i64::from(xorshift(&mut rng) % (2 * max_step + 1)) - i64::from(max_step);
        truth += step;
        rig.io.scales[0] = truth as u16 as u32;
        send(&mut rig.io, k as u8, &[0]);
        let c = rig.cycle(e);
        assert_eq!(c.engine.unwrap().position_counts, truth, "cycle {k}");
    }
    assert!(
        truth.unsigned_abs() > 1 << 16,
        "the walk wrapped the counter"
    );

    // The case to catch: a 32-bit image (an older `image build` default) on this 16-bit counter, loaded
    // without the board check, is 65 536 counts off after one wrap — silently. The drive refuses it.
    let img32 = image(ImageArgs {
        counter_bits: 32,
        ..BASE
    });
    // The single-axis engine of the core shows what the board check prevents.
    let mut e32 = Box::new(Engine::new());
    e32.load_image(&img32).unwrap();
    let mut pos = 0i64;
    let mut last = None;
    for raw in (0..=70_000i64).step_by(1000) {
        pos = raw;
        let input = axcomp_core::CycleInput {
            scale_raw: raw as u16 as u32,
            command_counts: 0,
            forces_n: [0.0; MAX_FORCES],
        };
        last = e32.step(&Record::Cycle(input));
    }
    assert_eq!(pos - last.unwrap().position_counts, 65_536);
    assert_eq!(
        rig.drive.offer_image(e, &img32),
        Err(ImageRefusal::CounterWidth {
            image: 32,
            board: 16
        })
    );
}

/// A timer that is due `remaining` times, then pends forever.
struct CountdownTimer {
    remaining: u32,
}

impl crate::control::CycleTimer for CountdownTimer {
    fn next_cycle(&mut self) -> impl core::future::Future<Output = ()> {
        let due = self.remaining > 0;
        self.remaining = self.remaining.saturating_sub(1);
        core::future::poll_fn(move |_| {
            if due {
                core::task::Poll::Ready(())
            } else {
                core::task::Poll::Pending
            }
        })
    }
}

#[test]
fn run_paces_on_the_timer_and_shows_the_board_each_status_between_cycles() {
    use core::pin::pin;
    use core::task::{Context, Poll, Waker};
    let mut eng = engine();
    let e = &mut *eng;
    let mut rig = Rig::new(ResetCause::default());
    // One sensor: the temperatures handed over between cycles reach the engine's axis.
    rig.drive
        .offer_image(
            e,
            &image(ImageArgs {
                n_sensors: 1,
                ..BASE
            }),
        )
        .unwrap();
    assert_eq!(e.state().axes[0].filtered_delta_t(0), None);
    // A frame for the first cycle only: the later ones are late.
    send(&mut rig.io, 0, &[100]);
    let mut timer = CountdownTimer { remaining: 4 };
    let mut watchdog = NoWatchdog;
    let mut seen = vec![];
    {
        let fut = rig.drive.run(
            e,
            &mut rig.io,
            &rig.clock,
            &mut timer,
            &mut watchdog,
            |engine, drive| {
                seen.push((drive.cycles(), drive.status()));
                if drive.cycles() == 1 {
                    // Between cycles the board hands over what arrived (here: a temperature
                    // reading) through the drive's sensor wiring to the engine.
                    drive.update_temperatures(engine, 0, &[20.0]);
                }
            },
        );
        let mut fut = pin!(fut);
        let mut cx = Context::from_waker(Waker::noop());
        // Four due ticks, then the timer pends: one poll runs exactly four cycles.
        assert!(matches!(fut.as_mut().poll(&mut cx), Poll::Pending));
    }
    let cycles: Vec<u32> = seen.iter().map(|(c, _)| *c).collect();
    assert_eq!(cycles, [0, 1, 2, 3], "between runs before each cycle");
    assert!(
        !seen[1].1.contains(Status::FRAME_LATE),
        "cycle 1 had its frame"
    );
    assert!(
        seen[2].1.contains(Status::FRAME_LATE | Status::LINK_HOLD),
        "cycle 2 had none"
    );
    assert_eq!(rig.drive.cycles(), 4);
    assert_eq!(rig.io.tx.len(), 4);
    assert_eq!(
        e.state().axes[0].filtered_delta_t(0),
        Some(0.0),
        "the reading handed over between cycles (20 °C = the reference)"
    );
}

// ---- link faults -----------------------------------------------------------------------------

#[test]
fn late_frames_hold_then_ramp_out_then_ramp_back_in() {
    let mut eng = engine();
    let e = &mut *eng;
    let mut rig = Rig::new(ResetCause::default());
    rig.drive.offer_image(e, &image(BASE)).unwrap();
    // Reference: table 2.0 µm / 0.1 µm per count = 20 counts, subtracted from the command.
    for seq in 0..10u8 {
        send(&mut rig.io, seq, &[1000 + i32::from(seq)]);
        let c = rig.cycle(e);
        assert_eq!(c.corrected_command_counts, 1000 + i64::from(seq) - 20);
        assert_eq!(c.applied.phase, LinkPhase::Following);
        assert!(!c.status.intersects(LINK_FLAGS), "seq {seq}: {}", c.status);
    }
    // The CNC goes silent. Hold 5 cycles (LINK.hold_cycles) at exactly the last correction and command.
    for k in 1..=5 {
        let c = rig.cycle(e);
        assert_eq!(c.command_counts, 1009, "late {k}: last fresh command");
        assert_eq!(c.corrected_command_counts, 1009 - 20, "late {k}");
        assert_eq!(c.applied.phase, LinkPhase::Holding);
        assert!(
            c.status.contains(Status::FRAME_LATE | Status::LINK_HOLD),
            "late {k}: {}",
            c.status
        );
        // The engine itself keeps running (counter extension) with its own correction.
        assert_eq!(c.engine.unwrap().correction_counts, 20);
    }
    // Then 0.5 µm per cycle towards zero: 15, 10, 5, 0 counts, and 0 from then on.
    for (k, want) in [15, 10, 5, 0, 0, 0].into_iter().enumerate() {
        let c = rig.cycle(e);
        assert_eq!(c.applied.correction_counts, want, "ramp-out cycle {k}");
        assert_eq!(c.corrected_command_counts, 1009 - i64::from(want));
        assert_eq!(c.applied.phase, LinkPhase::RampingOut);
        assert!(c.status.contains(Status::FRAME_LATE | Status::LINK_RAMP));
        assert!(!c.status.contains(Status::LINK_HOLD));
    }
    assert_eq!(rig.drive.counters().cycles_without_frame, 11);
    // Frames return (seq 21: 11 frames were lost): applied at once, the correction ramps back in.
    for (k, want) in [5, 10, 15].into_iter().enumerate() {
        let seq = 21 + k as u8;
        send(&mut rig.io, seq, &[2000]);
        let c = rig.cycle(e);
        assert_eq!(c.command_counts, 2000);
        assert_eq!(c.applied.correction_counts, want, "ramp-in cycle {k}");
        assert_eq!(c.applied.phase, LinkPhase::RampingIn);
        assert!(c.status.contains(Status::LINK_RAMP));
        assert!(!c.status.contains(Status::FRAME_LATE));
        assert_eq!(c.status.contains(Status::FRAME_MISSING), k == 0);
    }
    send(&mut rig.io, 24, &[2000]);
    let c = rig.cycle(e);
    assert_eq!(c.applied.phase, LinkPhase::Following);
    assert_eq!(c.corrected_command_counts, 2000 - 20);
    assert!(!c.status.intersects(LINK_FLAGS));
    assert_eq!(rig.drive.counters().link.lost, 11);
}

#[test]
fn corrupt_repeated_and_short_frames_are_never_applied() {
    let mut eng = engine();
    let e = &mut *eng;
    let mut rig = Rig::new(ResetCause::default());
    rig.drive
        .offer_image(e, &image(ImageArgs { axis_id: 2, ..BASE }))
        .unwrap();
    send(&mut rig.io, 1, &[111, 1000]);
    assert_eq!(rig.cycle(e).command_counts, 1000);

    // Corrupt: one bit of axis 2's command flipped.
    let mut bad = frame(2, &[111, 5000]);
    bad[8] ^= 0x10;
    rig.io.rx.extend(bad);
    let c = rig.cycle(e);
    assert_eq!(c.command_counts, 1000, "corrupt frame not applied");
    assert!(
        c.status
            .contains(Status::FRAME_CORRUPT | Status::FRAME_LATE | Status::LINK_HOLD)
    );

    // Repeated: sequence 1 again, with other contents.
    send(&mut rig.io, 1, &[111, 7000]);
    let c = rig.cycle(e);
    assert_eq!(c.command_counts, 1000, "repeated frame not applied");
    assert!(
        c.status
            .contains(Status::FRAME_REPEATED | Status::FRAME_LATE)
    );
    assert!(!c.status.contains(Status::FRAME_CORRUPT));

    // Short: a one-axis frame has nothing for axis 2 (input 1).
    send(&mut rig.io, 2, &[9999]);
    let c = rig.cycle(e);
    assert_eq!(c.command_counts, 1000, "short frame not applied");
    assert!(
        c.status
            .contains(Status::FRAME_CORRUPT | Status::FRAME_LATE)
    );

    // In order again: applied, no flags.
    send(&mut rig.io, 3, &[111, 1200]);
    let c = rig.cycle(e);
    assert_eq!(c.command_counts, 1200);
    assert_eq!(c.corrected_command_counts, 1200 - 20);
    assert!(!c.status.intersects(LINK_FLAGS), "{}", c.status);
    let n = rig.drive.counters();
    assert_eq!((n.link.corrupt, n.link.repeated, n.short_frames), (1, 1, 1));
}

#[test]
fn several_frames_in_one_cycle_the_newest_wins() {
    let mut eng = engine();
    let e = &mut *eng;
    let mut rig = Rig::new(ResetCause::default());
    rig.drive.offer_image(e, &image(BASE)).unwrap();
    send(&mut rig.io, 1, &[100]);
    send(&mut rig.io, 2, &[200]);
    let c = rig.cycle(e);
    assert_eq!(c.command_counts, 200);
    assert!(!c.status.intersects(LINK_FLAGS));
}

#[test]
fn commands_are_extended_past_the_32_bit_wire_range() {
    let mut eng = engine();
    let e = &mut *eng;
    let mut rig = Rig::new(ResetCause::default());
    rig.drive.offer_image(e, &image(BASE)).unwrap();
    let mut truth = i64::from(i32::MAX) - 3_000;
    for seq in 0..6u8 {
        send(&mut rig.io, seq, &[truth as i32]);
        assert_eq!(rig.cycle(e).command_counts, truth);
        truth += 1_000;
    }
}

// ---- lateness and overrun -------------------------------------------------------------------------

#[test]
fn lateness_is_measured_against_the_deadline_not_the_compute_time() {
    let mut eng = engine();
    let e = &mut *eng;
    let cfg = config();
    let mut rig = Rig::new(ResetCause::default());
    assert_eq!(cfg.period_ticks, 1000);
    // (start tick, ticks per clock read): the drive reads the clock at the start and at the end
    // (= start + 1 step: the step is the cycle's compute time).
    let plan = [
        (0, 1),       // defines the schedule
        (1000, 1),    // on time
        (2250, 1),    // 250 late > tolerance 100: late
        (3050, 1),    // 50 late: within tolerance
        (4950, 60), // 950 late, output at 5010 > next deadline 5000: overrun with 60 ticks compute
        (5000, 1),  // reports the overrun of the previous cycle
        (6000, 1200), // compute 1200, done at 7200 > 7000: overrun without being late
        (7000, 1),
    ];
    let mut got = vec![];
    for (start, step) in plan {
        rig.clock.ticks.set(start);
        rig.clock.step.set(step);
        send(&mut rig.io, (start / 1000) as u8, &[0]);
        let c = rig.cycle(e);
        got.push((
            c.status.contains(Status::CYCLE_LATE),
            c.status.contains(Status::OVERRUN),
        ));
    }
    assert_eq!(
        got,
        [
            (false, false),
            (false, false),
            (true, false),
            (false, false),
            (true, false),
            (false, true),
            (false, false),
            (false, true),
        ]
    );
    let s = rig.drive.counters().lateness;
    assert_eq!(s.late_cycles, 2);
    assert_eq!(s.overruns, 2);
    assert_eq!(s.max_lateness_ticks, 950);
}

// ---- watchdog ----------------------------------------------------------------------------------

#[test]
fn a_hung_loop_is_reset_by_the_watchdog_and_the_next_boot_reports_it() {
    let mut wd = FakeWatchdog::new(3_000); // 3 cycles of 1000 ticks
    {
        let mut eng = engine();
        let e = &mut *eng;
        let mut rig = Rig::new(ResetCause::default());
        for seq in 0..100u8 {
            wd.advance(1_000);
            send(&mut rig.io, seq, &[0]);
            let c = rig.drive.cycle(e, &mut rig.io, &rig.clock, &mut wd);
            assert!(!c.status.contains(Status::WATCHDOG_RESET));
        }
        assert!(!wd.expired);
        assert_eq!(wd.feeds, 100, "fed once per completed cycle");
        // The loop hangs (no more cycles) while time goes on.
        wd.advance(2_999);
        assert!(!wd.expired, "within the timeout");
        wd.advance(1);
        assert!(wd.expired, "reset after the timeout");
    }
    // Next boot: the reset flags say watchdog; the status word carries it on every cycle.
    let mut eng = engine();
    let e = &mut *eng;
    let mut rig = Rig::new(wd.reset_cause());
    for seq in 0..20u8 {
        send(&mut rig.io, seq, &[0]);
        assert!(rig.cycle(e).status.contains(Status::WATCHDOG_RESET));
    }
    // A boot by another cause does not.
    let mut rig = Rig::new(ResetCause::default());
    assert!(!rig.cycle(e).status.contains(Status::WATCHDOG_RESET));
}

// ---- status word on the link ----------------------------------------------------------------------

#[test]
fn every_cycle_sends_one_reply_with_the_status_word_and_a_counter() {
    let mut eng = engine();
    let e = &mut *eng;
    let mut rig = Rig::new(ResetCause::default());
    rig.drive.offer_image(e, &image(BASE)).unwrap();
    let mut bad = frame(0, &[1]);
    bad[4] ^= 1;
    rig.io.rx.extend(bad); // one corrupt frame before the first good one
    let mut statuses = vec![];
    for seq in 0..24u8 {
        if seq != 5 {
            send(&mut rig.io, seq, &[500 + i32::from(seq)]);
        }
        let c = rig.cycle(e);
        statuses.push((c.status, c.corrected_command_counts));
    }
    assert_eq!(rig.io.tx.len(), 24, "one reply per cycle");
    let mut d = ReplyDecoder::new();
    let mut seen = [None; CounterId::ALL.len()];
    for (k, bytes) in rig.io.tx.iter().enumerate() {
        assert_eq!(bytes.len(), reply_frame_len(1));
        let got: Vec<_> = bytes.iter().filter_map(|&b| d.push(b)).collect();
        assert_eq!(got.len(), 1, "reply {k} decodes");
        let r = got[0];
        assert_eq!(r.status, statuses[k].0.bits(), "reply {k}");
        assert_eq!(i64::from(r.corrected()[0]), statuses[k].1);
        assert_eq!(r.seq, k as u8, "the drive's reply counter");
        // Echo: the setpoint the correction answers (seq 4 again in the late cycle 5).
        assert_eq!(r.echo, if k == 5 { 4 } else { k as u8 });
        let id = r.counter_id.expect("known counter id");
        seen[id as usize] = Some(r.counter_value);
    }
    assert!(
        seen.iter().all(Option::is_some),
        "every counter sent within 12 cycles"
    );
    assert_eq!(seen[CounterId::FramesCorrupt as usize], Some(1));
    assert!(statuses[0].0.contains(Status::FRAME_CORRUPT));
    assert!(
        statuses[5]
            .0
            .contains(Status::FRAME_LATE | Status::LINK_HOLD)
    );
    assert!(
        statuses[6].0.contains(Status::FRAME_MISSING),
        "seq 5 never came"
    );
    // A full transmit buffer drops the reply and says so in the next one.
    rig.io.tx_full = true;
    send(&mut rig.io, 24, &[0]);
    rig.cycle(e);
    rig.io.tx_full = false;
    send(&mut rig.io, 25, &[0]);
    assert!(rig.cycle(e).status.contains(Status::REPLY_DROPPED));
    assert_eq!(rig.drive.counters().replies_dropped, 1);
}

// ---- the fault matrix ----------------------------------------------------------------------------

/// One fault of the table in `docs/firmware.md`: what is done to the drive, and the state it must end in.
struct Fault {
    name: &'static str,
    /// Status bits that must be set in the last cycle.
    flags: Status,
    run: fn(&mut Eng, &mut Rig) -> DriveCycle,
    /// The documented end state, checked on the last cycle.
    check: fn(&Eng, &Rig, &DriveCycle) -> bool,
}

fn good_cycles(e: &mut Eng, rig: &mut Rig, n: u8) -> DriveCycle {
    let mut last = None;
    for seq in 0..n {
        send(&mut rig.io, seq, &[1000]);
        last = Some(rig.cycle(e));
    }
    last.expect("n > 0")
}

/// A set of readings through the drive's wiring (sensor `j` = input `j`) to the engine.
fn temps(e: &mut Eng, rig: &Rig, now_ms: u32, r: &[f32]) {
    rig.drive.update_temperatures(e, now_ms, r);
}

const FAULTS: &[Fault] = &[
    Fault {
        name: "counter-width mismatch",
        flags: Status::IMAGE_REFUSED,
        run: |e, rig| {
            let r = rig.drive.offer_image(
                e,
                &image(ImageArgs {
                    counter_bits: 32,
                    ..BASE
                }),
            );
            assert!(matches!(r, Err(ImageRefusal::CounterWidth { .. })));
            good_cycles(e, rig, 3)
        },
        check: |e, _, c| axis_id(e) == 1 && c.corrected_command_counts == 980,
    },
    Fault {
        name: "axis-id mismatch",
        flags: Status::IMAGE_REFUSED,
        run: |e, rig| {
            let r = rig
                .drive
                .offer_image(e, &image(ImageArgs { axis_id: 7, ..BASE }));
            assert_eq!(r, Err(ImageRefusal::AxisNotWired { axis_id: 7 }));
            good_cycles(e, rig, 3)
        },
        check: |e, _, c| axis_id(e) == 1 && c.corrected_command_counts == 980,
    },
    Fault {
        name: "sensor-count mismatch",
        flags: Status::IMAGE_REFUSED,
        run: |e, rig| {
            let r = rig.drive.offer_image(
                e,
                &image(ImageArgs {
                    n_sensors: 4,
                    ..BASE
                }),
            );
            assert_eq!(r, Err(ImageRefusal::SensorsNotWired { image: 4, board: 2 }));
            good_cycles(e, rig, 3)
        },
        check: |e, _, _| sensor_count(e) == 0,
    },
    Fault {
        name: "corrupt image",
        flags: Status::IMAGE_REFUSED,
        run: |e, rig| {
            let mut b = image(BASE);
            b[20] ^= 0x40;
            assert!(matches!(
                rig.drive.offer_image(e, &b),
                Err(ImageRefusal::Invalid(_))
            ));
            good_cycles(e, rig, 3)
        },
        check: |e, _, c| e.stats().images_accepted == 1 && c.corrected_command_counts == 980,
    },
    Fault {
        name: "stale sensor",
        flags: Status(Status::SENSOR_STALE.0 | Status::THERMAL_FROZEN.0),
        run: |e, rig| {
            assert!(
                rig.drive
                    .offer_image(
                        e,
                        &image(ImageArgs {
                            n_sensors: 2,
                            ..BASE
                        })
                    )
                    .is_ok()
            );
            for k in 0..5 {
                temps(e, rig, k * 100, &[21.0, 21.0]);
            }
            // Sensor 1 stops reporting; stale after its 500 ms timeout.
            for k in 5..12 {
                temps(e, rig, k * 100, &[21.0, f32::NAN]);
            }
            good_cycles(e, rig, 3)
        },
        check: |e, _, _| e.state().axes[0].sensor_stale(1) && !e.state().axes[0].thermal_live(),
    },
    Fault {
        name: "out-of-range (implausible) input",
        flags: Status::SENSOR_IMPLAUSIBLE,
        run: |e, rig| {
            assert!(
                rig.drive
                    .offer_image(
                        e,
                        &image(ImageArgs {
                            n_sensors: 2,
                            ..BASE
                        })
                    )
                    .is_ok()
            );
            temps(e, rig, 0, &[21.0, 21.0]);
            temps(e, rig, 100, &[21.0, 99.0]); // above max_degc 60
            good_cycles(e, rig, 3)
        },
        check: |e, _, c| {
            e.state().axes[0].rejected_readings(1) == 1 && !c.status.contains(Status::SENSOR_STALE)
        },
    },
    Fault {
        name: "late setpoint frame",
        flags: Status(Status::FRAME_LATE.0 | Status::LINK_HOLD.0),
        run: |e, rig| {
            good_cycles(e, rig, 3);
            rig.cycle(e)
        },
        check: |_, _, c| c.corrected_command_counts == 980 && c.applied.phase == LinkPhase::Holding,
    },
    Fault {
        name: "setpoint link lost beyond the hold time",
        flags: Status(Status::FRAME_LATE.0 | Status::LINK_RAMP.0),
        run: |e, rig| {
            good_cycles(e, rig, 3);
            let mut c = rig.cycle(e);
            for _ in 0..20 {
                c = rig.cycle(e);
            }
            c
        },
        check: |_, _, c| c.corrected_command_counts == 1000 && c.applied.correction_counts == 0,
    },
    Fault {
        name: "corrupt setpoint frame",
        flags: Status(Status::FRAME_CORRUPT.0 | Status::FRAME_LATE.0),
        run: |e, rig| {
            good_cycles(e, rig, 3);
            let mut b = frame(3, &[5000]);
            b[5] ^= 0x80;
            rig.io.rx.extend(b);
            rig.cycle(e)
        },
        check: |_, _, c| c.command_counts == 1000,
    },
    Fault {
        name: "repeated setpoint frame",
        flags: Status(Status::FRAME_REPEATED.0 | Status::FRAME_LATE.0),
        run: |e, rig| {
            good_cycles(e, rig, 3);
            send(&mut rig.io, 2, &[5000]);
            rig.cycle(e)
        },
        check: |_, _, c| c.command_counts == 1000,
    },
    Fault {
        name: "missing (lost) setpoint frames",
        flags: Status::FRAME_MISSING,
        run: |e, rig| {
            good_cycles(e, rig, 3);
            send(&mut rig.io, 9, &[1500]);
            rig.cycle(e)
        },
        check: |_, rig, c| c.command_counts == 1500 && rig.drive.counters().link.lost == 6,
    },
    Fault {
        name: "overrun",
        flags: Status::OVERRUN,
        run: |e, rig| {
            good_cycles(e, rig, 1);
            rig.clock.ticks.set(1000);
            rig.clock.step.set(1500); // done at 2500 > next deadline 2000
            send(&mut rig.io, 1, &[1000]);
            rig.cycle(e);
            rig.clock.ticks.set(2600);
            rig.clock.step.set(0);
            send(&mut rig.io, 2, &[1000]);
            rig.cycle(e)
        },
        check: |_, rig, c| {
            rig.drive.counters().lateness.overruns == 1
                && c.status.contains(Status::CYCLE_LATE)
                && c.corrected_command_counts == 980
        },
    },
    Fault {
        name: "hung loop (watchdog reset)",
        flags: Status::WATCHDOG_RESET,
        run: |e, rig| {
            let mut wd = FakeWatchdog::new(3_000);
            for seq in 0..10u8 {
                wd.advance(1_000);
                send(&mut rig.io, seq, &[1000]);
                rig.drive.cycle(e, &mut rig.io, &rig.clock, &mut wd);
            }
            wd.advance(3_000); // no cycle completes for three periods
            assert!(wd.expired);
            // Reboot: a new drive with the reset cause read at boot, the same image offered again.
            rig.drive = GroupDrive::new(CAPS, &config(), LINK, wd.reset_cause());
            rig.io.tx.clear();
            rig.drive.offer_image(e, &image(BASE)).unwrap();
            good_cycles(e, rig, 3)
        },
        check: |_, rig, c| rig.drive.counters().cycles == 3 && c.corrected_command_counts == 980,
    },
    Fault {
        name: "clamp active",
        flags: Status::CLAMP_ACTIVE,
        run: |e, rig| {
            assert!(
                rig.drive
                    .offer_image(
                        e,
                        &image(ImageArgs {
                            max_correction_um: 1.0,
                            ..BASE
                        })
                    )
                    .is_ok()
            );
            good_cycles(e, rig, 3)
        },
        check: |_, _, c| c.corrected_command_counts == 1000 - 10,
    },
];

#[test]
fn fault_matrix() {
    std::println!("{:<40} {:<60} state", "fault", "status word");
    for f in FAULTS {
        let mut eng = engine();
        let e = &mut *eng;
        let mut rig = Rig::new(ResetCause::default());
        rig.drive.offer_image(e, &image(BASE)).unwrap();
        let c = (f.run)(e, &mut rig);
        let ok = (f.check)(e, &rig, &c);
        std::println!(
            "{:<40} {:<60} {}",
            f.name,
            std::format!("{}", c.status),
            if ok { "ok" } else { "WRONG" }
        );
        assert!(
            c.status.contains(f.flags),
            "{}: status {} lacks {}",
            f.name,
            c.status,
            f.flags
        );
        assert!(ok, "{}: end state", f.name);
        assert_eq!(
            rig.io.tx.len() as u32,
            rig.drive.counters().cycles,
            "{}: a reply every cycle",
            f.name
        );
        // The status word leaves the drive: the last reply frame carries it.
        let mut d = ReplyDecoder::new();
        let last = rig.io.tx.last().expect("a reply");
        let r = last
            .iter()
            .filter_map(|&b| d.push(b))
            .last()
            .expect("reply decodes");
        assert_eq!(Status(r.status), c.status, "{}: reply status", f.name);
        assert_eq!(i64::from(r.corrected()[0]), c.corrected_command_counts);
    }
}

/// The run loop's cycle without a record (`cycle_status`, what the board runs) is the recorded
/// cycle (`cycle`, what the replay and these tests run): on the same link bytes, scales and images,
/// every cycle's status word, every reply frame (bytes), the counters and each supervisor's state
/// are identical. Exact comparison: both run the same code.
#[test]
fn the_run_loops_cycle_without_a_record_is_the_recorded_cycle() {
    let (mut e_rec, mut e_run) = (engine(), engine());
    let (mut rec, mut run) = (
        Rig::new(ResetCause::default()),
        Rig::new(ResetCause::default()),
    );
    for (rig, e) in [(&mut rec, &mut *e_rec), (&mut run, &mut *e_run)] {
        rig.drive.offer_image(e, &image(BASE)).unwrap();
    }
    let mut seq = 0u8;
    for k in 0..400u32 {
        let cmd = 1000 + (k as i32) * 37 - 5000 * ((k / 90) % 2) as i32;
        let scale = (cmd as u32).wrapping_mul(3) & 0xFFFF;
        for (rig, e) in [(&mut rec, &mut *e_rec), (&mut run, &mut *e_run)] {
            rig.io.scales[0] = scale;
            match k {
                // late frames: hold, then ramp out, then back in
                60..=90 => {}
                // garbage before a frame, a repeated frame, a corrupt frame
                120 => rig.io.rx.extend([0x55u8, 0x00, 0xAA]),
                150 => {
                    send(&mut rig.io, seq.wrapping_sub(1), &[cmd]);
                }
                180 => {
                    let mut f = frame(seq, &[cmd]);
                    f[3] ^= 0x10;
                    rig.io.rx.extend(f);
                }
                // a refused image (32-bit counters on the 16-bit board), then the same one again
                200 => {
                    let bad = image(ImageArgs {
                        counter_bits: 32,
                        ..BASE
                    });
                    assert!(rig.drive.offer_image(e, &bad).is_err());
                }
                _ => send(&mut rig.io, seq, &[cmd]),
            }
            if k == 300 {
                rig.io.tx_full = true;
            }
        }
        if !(60..=90).contains(&k) && k != 150 && k != 120 {
            seq = seq.wrapping_add(1);
        }
        let a = rec
            .drive
            .cycle(&mut e_rec, &mut rec.io, &rec.clock, &mut NoWatchdog);
        let b = run
            .drive
            .cycle_status(&mut e_run, &mut run.io, &run.clock, &mut NoWatchdog);
        assert_eq!(a.status, b, "cycle {k}: status word");
        assert_eq!(rec.drive.status(), run.drive.status(), "cycle {k}");
        assert_eq!(rec.io.tx, run.io.tx, "cycle {k}: reply frames");
        assert_eq!(rec.drive.counters(), run.drive.counters(), "cycle {k}");
        let (sa, sb) = (
            rec.drive.supervisor(0).unwrap(),
            run.drive.supervisor(0).unwrap(),
        );
        assert_eq!(
            format!("{sa:?}"),
            format!("{sb:?}"),
            "cycle {k}: supervisor"
        );
    }
    // The sequence went through every link phase and both fault kinds.
    let c = rec.drive.counters();
    assert!(c.cycles_without_frame >= 31 && c.link.corrupt >= 1 && c.link.repeated >= 1);
    assert!(c.images_refused == 1 && c.replies_dropped > 0);
}

/// The same for the `group3` workload (three linear axes with bidirectional tables and clamps) on a
/// board whose inputs are in another order than the group's slots (Z, X, Y), with late and corrupt
/// frames: the run loop's cycle and the recorded cycle answer with the same bytes.
#[test]
fn the_run_loops_cycle_without_a_record_is_the_recorded_cycle_for_three_axes() {
    use axcomp_core::group_image::{AxisSectionSpec, write_group_image};
    type Eng3 = GroupEngine<2048>;
    const CAPS3: BoardCaps = BoardCaps {
        counter_bits: 32,
        axis_ids: &[3, 1, 2],
        sensors: 0,
    };
    let mut axis_buf = vec![0u8; 24 * 1024];
    let (axes, n) = axcomp_core::bench::write_group_images(3, &mut axis_buf).unwrap();
    let specs: Vec<AxisSectionSpec> = axes[..n]
        .iter()
        .map(|a| AxisSectionSpec {
            name: a.name,
            counts_per_rev: a.counts_per_rev,
            stroke_counts: None,
            image: a.image,
            sensor_names: &[],
        })
        .collect();
    let mut group = vec![0u8; 12 * 1024];
    let len = write_group_image(&specs, None, &mut group).unwrap();
    let mut engines: [Box<Eng3>; 2] = [Box::new(GroupEngine::new()), Box::new(GroupEngine::new())];
    let mut rigs = [0, 1].map(|_| Rig {
        drive: GroupDrive::new(CAPS3, &config(), LINK, ResetCause::default()),
        io: FakeDriveIo::default(),
        clock: SteppingClock::default(),
    });
    for (rig, e) in rigs.iter_mut().zip(engines.iter_mut()) {
        rig.drive.offer_image(e, &group[..len]).unwrap();
        assert_eq!(rig.drive.inputs(), &[1, 2, 0]);
    }
    let mut seq = 0u8;
    let mut corrected_cycles = 0;
    for k in 0..600u32 {
        let g = axcomp_core::bench::group_input(k * 7);
        let by_input = [2, 0, 1];
        let cmds = by_input.map(|slot| g.axes[slot].command_counts as i32);
        for rig in rigs.iter_mut() {
            for (input, &slot) in by_input.iter().enumerate() {
                rig.io.scales[input] = g.axes[slot].scale_raw;
            }
            match k {
                100..=180 => {}
                300 => {
                    let mut f = frame(seq, &cmds);
                    f[4] ^= 0x01;
                    rig.io.rx.extend(f);
                }
                // a frame short of one of the group's inputs
                400 => send(&mut rig.io, seq, &cmds[..2]),
                _ => send(&mut rig.io, seq, &cmds),
            }
        }
        if !(100..=180).contains(&k) {
            seq = seq.wrapping_add(1);
        }
        let [rec, run] = &mut rigs;
        let [e_rec, e_run] = &mut engines;
        let a = rec
            .drive
            .cycle(e_rec, &mut rec.io, &rec.clock, &mut NoWatchdog);
        let b = run
            .drive
            .cycle_status(e_run, &mut run.io, &run.clock, &mut NoWatchdog);
        assert_eq!(a.status, b, "cycle {k}: status word");
        assert_eq!(rec.io.tx, run.io.tx, "cycle {k}: reply frames");
        assert_eq!(rec.drive.counters(), run.drive.counters(), "cycle {k}");
        if a.applied[..3].iter().all(|x| x.correction_counts != 0) {
            corrected_cycles += 1;
        }
        for i in 0..3 {
            let (sa, sb) = (
                rec.drive.supervisor(i).unwrap(),
                run.drive.supervisor(i).unwrap(),
            );
            assert_eq!(
                format!("{sa:?}"),
                format!("{sb:?}"),
                "cycle {k}: supervisor {i}"
            );
        }
    }
    let c = rigs[0].drive.counters();
    assert!(c.cycles_without_frame >= 81 && c.link.corrupt >= 1 && c.short_frames == 1);
    // The tables and clamps ran: every axis corrected in most cycles.
    assert!(
        corrected_cycles > 300,
        "{corrected_cycles} cycles with every axis corrected"
    );
}
