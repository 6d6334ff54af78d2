//! The group drive (`GroupDrive`: setpoint link v2, one link supervisor per axis, the group engine, the
//! status word, the reply frame) replayed from drive traces (`axcomp_firmware::drive::link_trace`) on
//! the host and in QEMU (`axcomp-qemu-group`), and the drive fault matrix.
//!
//! Reference: `axcomp_firmware::drive::link_trace::replay_link` on the host (the same code QEMU runs).
//! Tolerance: none — every 128-byte drive output record (status word, the reply frame as sent, every
//! axis's corrected command, applied and engine correction bits) must match byte for byte, and the
//! record count must equal the trace's cycle count; one ULP in one record or one dropped cycle fails
//! (`link_comparison_fails_on_one_ulp_and_on_a_dropped_cycle`).
//!
//! The fault matrix (`drive_fault_matrix_on_host_and_in_qemu`) asserts each fault's documented end state
//! (docs/firmware.md, "Setpoint link and faults") on the host replay, then requires QEMU to produce the
//! same bytes.

use axcomp_core::group::GroupEngine;
use axcomp_core::wiring::WiringError;
use axcomp_firmware::drive::ImageRefusal;
use axcomp_firmware::drive::group::{check_group_image, check_group_image_wired};
use axcomp_firmware::drive::link_trace::{
    self, DRIVE_OUTPUT_LEN, DecodedDriveOutput, LinkReplaySummary, LinkStream, REPLAY_CAPS,
    REPLAY_SENSOR_INPUTS,
};
use axcomp_firmware::scenario::{self, DriveFault, GroupImageVariant};
use axcomp_firmware::status::Status;
use axcomp_system_tests::{build_qemu_firmware, qemu_replay, require_tool};

const LINK_CYCLES: u32 = 4_500;
/// The firmware's pool (`axcomp-qemu-group`).
const POOL: usize = 1024;

fn host_replay(trace: &[u8]) -> (Vec<u8>, LinkReplaySummary) {
    let mut engine: Box<GroupEngine<POOL>> = Box::new(GroupEngine::new());
    let mut drive = link_trace::replay_drive();
    let mut buf = vec![0u8; 24 * 1024];
    let mut stream = LinkStream::new(trace, &mut buf).expect("drive trace header");
    let mut out = Vec::new();
    let sum = link_trace::replay_link(
        &mut drive,
        &mut engine,
        &mut stream,
        |o| out.extend_from_slice(&o.encode()),
        |e| panic!("host replay: {e}"),
    );
    (out, sum)
}

fn decode_all(bytes: &[u8]) -> Vec<DecodedDriveOutput> {
    bytes
        .chunks_exact(DRIVE_OUTPUT_LEN)
        .map(|c| DecodedDriveOutput::decode(c.try_into().unwrap()))
        .collect()
}

fn assert_same_records(got: &[u8], want: &[u8]) {
    assert_eq!(
        got.len() % DRIVE_OUTPUT_LEN,
        0,
        "whole drive output records"
    );
    let first_diff = got
        .chunks(DRIVE_OUTPUT_LEN)
        .zip(want.chunks(DRIVE_OUTPUT_LEN))
        .position(|(a, b)| a != b);
    if let Some(k) = first_diff {
        let r = |b: &[u8]| DecodedDriveOutput::decode(b[..DRIVE_OUTPUT_LEN].try_into().unwrap());
        panic!(
            "first differing drive output record #{k}:\n  got:  {:?}\n  want: {:?}",
            r(&got[k * DRIVE_OUTPUT_LEN..]),
            r(&want[k * DRIVE_OUTPUT_LEN..])
        );
    }
    assert_eq!(
        got.len() / DRIVE_OUTPUT_LEN,
        want.len() / DRIVE_OUTPUT_LEN,
        "record count"
    );
}

fn has(o: &DecodedDriveOutput, s: Status) -> bool {
    Status(o.status).contains(s)
}

const LINK_FLAGS: Status = Status(
    Status::FRAME_LATE.0
        | Status::FRAME_CORRUPT.0
        | Status::FRAME_REPEATED.0
        | Status::FRAME_MISSING.0
        | Status::LINK_HOLD.0
        | Status::LINK_RAMP.0,
);

/// The setpoint-link trace exercises what it claims (host), and QEMU replays it byte for byte.
#[test]
fn group_link_trace_matches_host_byte_for_byte() {
    let trace = scenario::group_link(LINK_CYCLES).expect("scenario");
    let (want, sum) = host_replay(&trace);
    assert_eq!(
        (sum.cycles, sum.errors, sum.images_refused),
        (LINK_CYCLES, 0, 2)
    );
    let o = decode_all(&want);
    assert!(
        o[..5]
            .iter()
            .all(|c| has(c, Status::NO_IMAGE) && has(c, Status::FRAME_LATE))
    );
    assert!(
        o[5..500]
            .iter()
            .all(|c| c.n_axes == 3 && !has(c, Status::NO_IMAGE))
    );
    let hold = Status(Status::FRAME_LATE.0 | Status::LINK_HOLD.0);
    assert!(has(&o[500], hold));
    assert!(o[600..650].iter().all(|c| has(c, hold)));
    assert!(has(&o[650], Status::LINK_RAMP) && has(&o[650], Status::FRAME_LATE));
    assert!(has(&o[800], Status::FRAME_CORRUPT) && has(&o[800], hold));
    assert!(has(&o[900], Status::FRAME_REPEATED) && has(&o[900], hold));
    assert!(has(&o[1000], Status::FRAME_MISSING) && !has(&o[1000], Status::FRAME_LATE));
    assert!(has(&o[1100], Status::FRAME_CORRUPT) && has(&o[1100], Status::FRAME_LATE));
    println!("cycle 1200: {}", Status(o[1200].status));
    assert!(
        !has(&o[1200], Status::FRAME_LATE),
        "a frame after garbage is applied"
    );
    assert!(has(&o[1300], Status::CYCLE_LATE) && !has(&o[1299], Status::CYCLE_LATE));
    assert!(has(&o[1401], Status::OVERRUN) && !has(&o[1400], Status::OVERRUN));
    for (bit, name) in Status::NAMES {
        let n = o.iter().filter(|c| has(c, bit)).count();
        println!("link trace: {name} in {n} cycles");
    }
    let refused_from = (LINK_CYCLES / 3) as usize;
    let accepted_at = (LINK_CYCLES / 2) as usize;
    assert!(!has(&o[refused_from - 1], Status::IMAGE_REFUSED));
    assert!(
        o[refused_from..accepted_at]
            .iter()
            .all(|c| has(c, Status::IMAGE_REFUSED))
    );
    assert!(!has(&o[accepted_at], Status::IMAGE_REFUSED));

    if !require_tool("qemu-system-arm") {
        return;
    }
    let elf = build_qemu_firmware("axcomp-qemu-group");
    let (status, stdout, got) = qemu_replay(&elf, "qemu-drive-link", &trace);
    println!("{stdout}");
    assert!(
        status.success(),
        "QEMU firmware failed ({status})\n{stdout}"
    );
    assert_same_records(&got, &want);
    assert!(
        stdout.contains(&format!("cycles={LINK_CYCLES} images_refused=2 errors=0")),
        "summary line: {stdout}"
    );
}

/// The comparison is strict: one ULP in one record's correction, or one dropped cycle, fails it.
#[test]
fn link_comparison_fails_on_one_ulp_and_on_a_dropped_cycle() {
    let trace = scenario::group_link(3_000).expect("scenario");
    let (want, _) = host_replay(&trace);
    assert_same_records(&want, &want);
    let k = want.len() / DRIVE_OUTPUT_LEN / 2;
    // The engine correction of slot 0: bytes 12 + 36 + 12 .. + 16 of the record.
    let at = k * DRIVE_OUTPUT_LEN + 12 + 36 + 12;
    let bits = u32::from_le_bytes(want[at..at + 4].try_into().unwrap());
    let mut one_ulp = want.clone();
    one_ulp[at..at + 4].copy_from_slice(&bits.wrapping_add(1).to_le_bytes());
    assert!(std::panic::catch_unwind(|| assert_same_records(&one_ulp, &want)).is_err());
    let dropped = &want[..want.len() - DRIVE_OUTPUT_LEN];
    assert!(std::panic::catch_unwind(|| assert_same_records(dropped, &want)).is_err());
}

/// Each fault's documented end state, on the host; then the same bytes in QEMU.
#[test]
fn drive_fault_matrix_on_host_and_in_qemu() {
    let qemu = require_tool("qemu-system-arm").then(|| build_qemu_firmware("axcomp-qemu-group"));
    let at = DriveFault::AT as usize;
    for fault in DriveFault::ALL {
        let trace = scenario::drive_fault_trace(fault, true).expect("scenario");
        let (bytes, sum) = host_replay(&trace);
        let (ref_bytes, _) = host_replay(&scenario::drive_fault_trace(fault, false).unwrap());
        let f = decode_all(&bytes);
        let r = decode_all(&ref_bytes);
        assert_eq!(sum.cycles, fault.cycles(), "{fault:?}");
        assert_eq!(f[..at], r[..at], "{fault:?}: identical before the fault");
        let all = |s: Status| f.iter().skip(at).all(|c| has(c, s));
        match fault {
            DriveFault::CounterWidthMismatch
            | DriveFault::AxisIdMismatch
            | DriveFault::SensorCountMismatch
            | DriveFault::ImageWithTrailingBytes
            | DriveFault::CorruptImage
            | DriveFault::SensorNotOnBoard => {
                // Documented: never loaded, the running group keeps running, IMAGE_REFUSED latched.
                assert_eq!(sum.images_refused, 1, "{fault:?}");
                assert!(all(Status::IMAGE_REFUSED), "{fault:?}");
                for (a, b) in f.iter().zip(r.iter()).skip(at) {
                    assert_eq!(a.status, b.status | Status::IMAGE_REFUSED.0, "{fault:?}");
                    assert_eq!(
                        a.corrected_command_counts, b.corrected_command_counts,
                        "{fault:?}"
                    );
                    assert_eq!(a.engine_um.map(f32::to_bits), b.engine_um.map(f32::to_bits));
                }
                let bad = match fault {
                    DriveFault::CounterWidthMismatch => {
                        scenario::group_image_variant(3, true, GroupImageVariant::CounterBits(32))
                    }
                    DriveFault::AxisIdMismatch => scenario::group_image_variant(
                        3,
                        true,
                        GroupImageVariant::AxisId { slot: 1, id: 9 },
                    ),
                    DriveFault::SensorCountMismatch => {
                        scenario::group_image_variant(3, true, GroupImageVariant::Sensors(3))
                    }
                    DriveFault::SensorNotOnBoard => {
                        scenario::group_image_variant(3, true, GroupImageVariant::WarmupSensor)
                    }
                    _ => scenario::group_image(3, true),
                }
                .unwrap();
                let refusal = match fault {
                    DriveFault::ImageWithTrailingBytes => {
                        let mut b = bad.clone();
                        b.extend_from_slice(&[0u8; 100]);
                        check_group_image(&REPLAY_CAPS, &b)
                    }
                    DriveFault::CorruptImage => {
                        let mut b = bad.clone();
                        let m = b.len() / 2;
                        b[m] ^= 0x10;
                        check_group_image(&REPLAY_CAPS, &b)
                    }
                    // The replay's board declares its sensor inputs by name (as the STM32G474 does).
                    DriveFault::SensorNotOnBoard => {
                        check_group_image_wired(&REPLAY_CAPS, Some(&REPLAY_SENSOR_INPUTS), &bad)
                            .map(|(inputs, _)| inputs)
                    }
                    _ => check_group_image(&REPLAY_CAPS, &bad),
                };
                match (fault, refusal) {
                    (
                        DriveFault::CounterWidthMismatch,
                        Err(ImageRefusal::CounterWidth {
                            image: 32,
                            board: 16,
                        }),
                    )
                    | (
                        DriveFault::AxisIdMismatch,
                        Err(ImageRefusal::AxisNotWired { axis_id: 9 }),
                    )
                    | (
                        DriveFault::SensorCountMismatch,
                        Err(ImageRefusal::SensorsNotWired { image: 3, board: 2 }),
                    )
                    | (
                        DriveFault::SensorNotOnBoard,
                        Err(ImageRefusal::SensorNotOnBoard {
                            axis_id: 1,
                            why: WiringError::NotOnBoard { sensor: 0 },
                        }),
                    )
                    | (DriveFault::ImageWithTrailingBytes, Err(ImageRefusal::Invalid(_)))
                    | (DriveFault::CorruptImage, Err(ImageRefusal::Invalid(_))) => {}
                    (f, other) => panic!("{f:?}: unexpected refusal {other:?}"),
                }
            }
            DriveFault::StaleSensor => {
                // Last good reading at cycle AT − 1 (now 19.9 s); stale when more than the image's
                // stale_timeout_ms = 500 ms passed: the reading of cycle AT + 5 (20.5 s). Then the core
                // holds the frozen term STALE_HOLD_MS = 60 s (600 readings) and ramps it out linearly
                // over STALE_RAMP_MS = 60 s.
                let stale_at = at + 5;
                for k in at..stale_at {
                    assert_eq!(
                        f[k].status, r[k].status,
                        "no new flag before the timeout ({k})"
                    );
                }
                let first_stale = f.iter().position(|c| has(c, Status::SENSOR_STALE)).unwrap();
                assert_eq!(first_stale, stale_at);
                assert!(
                    f[stale_at..]
                        .iter()
                        .all(|c| has(c, Status::SENSOR_STALE) && has(c, Status::THERMAL_FROZEN))
                );
                let first_ramp = f
                    .iter()
                    .position(|c| has(c, Status::THERMAL_RAMPING))
                    .unwrap();
                assert_eq!(first_ramp, stale_at + 601, "ramp starts after 60 s of hold");
                let x = |k: usize| f[k].engine_um[0];
                // Held: the X correction does not move (standing axes) during the hold.
                assert!((stale_at..first_ramp).all(|k| x(k) == x(stale_at)), "held");
                // Ramp: 600 linear steps, then constant (sensor term gone, b0 stays). Tolerance: the
                // step varies by f32 rounding of the correction only (1e-3 of the step).
                let end = stale_at + 600 + 600;
                let step = (x(end) - x(stale_at)) / 600.0;
                let frozen = x(stale_at) - x(end);
                println!(
                    "stale sensor: frozen thermal term {frozen} um ramped out over 600 readings"
                );
                assert!(
                    frozen.abs() > 0.5,
                    "a frozen term worth ramping out: {frozen} um"
                );
                for k in first_ramp..=end {
                    let d = x(k) - x(k - 1);
                    assert!(
                        (d - step).abs() <= 1e-3 * step.abs() + 1e-5,
                        "linear ramp at {k}: {d} vs {step}"
                    );
                }
                assert!(
                    (end..f.len()).all(|k| x(k) == x(end)),
                    "ramped out at 120 s"
                );
                // Y and Z have no sensors: unaffected.
                for (a, b) in f.iter().zip(r.iter()) {
                    assert_eq!(a.engine_um[1..3], b.engine_um[1..3]);
                }
            }
            DriveFault::OutOfRangeInput => {
                // 150 °C > max_degc 80: rejected, last good value held, flagged for that cycle only.
                assert!(has(&f[at], Status::SENSOR_IMPLAUSIBLE));
                assert!(!has(&f[at], Status::SENSOR_STALE));
                assert_eq!(f[at + 1].status, r[at + 1].status);
                for (a, b) in f.iter().zip(r.iter()) {
                    assert_eq!(a.corrected_command_counts, b.corrected_command_counts);
                }
            }
            DriveFault::LateFrames => {
                let held = f[at - 1];
                let hold = Status(Status::FRAME_LATE.0 | Status::LINK_HOLD.0);
                for c in &f[at..at + 50] {
                    assert!(has(c, hold), "hold 50 cycles");
                    assert_eq!(c.applied_um, held.applied_um, "correction held");
                }
                for k in at + 50..at + DriveFault::LATE_CYCLES as usize {
                    assert!(has(&f[k], Status::LINK_RAMP) && has(&f[k], Status::FRAME_LATE));
                    for axis in 0..3 {
                        let (p, n) = (f[k - 1].applied_um[axis], f[k].applied_um[axis]);
                        let want = if p.abs() <= 0.1 {
                            0.0
                        } else {
                            p - 0.1 * p.signum()
                        };
                        assert!((n - want).abs() < 1e-5, "ramp-out 0.1 um/cycle at {k}");
                    }
                }
                let back = at + DriveFault::LATE_CYCLES as usize;
                assert!(f[back..].iter().all(|c| !has(c, Status::FRAME_LATE)));
                let following = f[back..]
                    .iter()
                    .position(|c| !Status(c.status).intersects(LINK_FLAGS))
                    .expect("the correction ramps back in");
                let k = back + following;
                assert_eq!(
                    f[k].applied_um, f[k].engine_um,
                    "following the engine again"
                );
            }
            DriveFault::CorruptFrame | DriveFault::RepeatedFrame => {
                let flag = if fault == DriveFault::CorruptFrame {
                    Status::FRAME_CORRUPT
                } else {
                    Status::FRAME_REPEATED
                };
                let c = &f[at];
                assert!(has(c, flag) && has(c, Status::FRAME_LATE) && has(c, Status::LINK_HOLD));
                assert_eq!(c.applied_um, f[at - 1].applied_um, "never applied: held");
                assert!(!Status(f[at + 1].status).intersects(LINK_FLAGS));
                assert_eq!(f[at + 1].applied_um, f[at + 1].engine_um);
            }
            DriveFault::Overrun => {
                assert!(!has(&f[at], Status::OVERRUN));
                assert!(has(&f[at + 1], Status::OVERRUN));
                assert!(!has(&f[at + 2], Status::OVERRUN));
                assert_eq!(
                    f[at + 1].corrected_command_counts,
                    r[at + 1].corrected_command_counts
                );
            }
        }
        if let Some(elf) = &qemu {
            let (status, stdout, got) = qemu_replay(elf, &format!("fault-{fault:?}"), &trace);
            assert!(
                status.success(),
                "{fault:?}: QEMU failed ({status})\n{stdout}"
            );
            assert_same_records(&got, &bytes);
            println!(
                "{fault:?}: QEMU = host ({} cycles), last status {}",
                sum.cycles,
                Status(f[f.len() - 1].status)
            );
        }
    }
}

/// Each group axis runs on the board input of its axis id, takes its command from that frame entry and
/// answers in that reply entry; the corrections are the group engine's for the same inputs in slot order.
/// Board inputs wired to axes 3, 1, 2 (Z, X, Y).
#[test]
fn group_axes_map_to_board_inputs_by_axis_id() {
    use axcomp_core::group::{GroupInput, GroupOutput};
    use axcomp_firmware::control::LoopSettings;
    use axcomp_firmware::control::fake::SteppingClock;
    use axcomp_firmware::drive::fake::FakeDriveIo;
    use axcomp_firmware::drive::group::GroupDrive;
    use axcomp_firmware::drive::{BoardCaps, LinkSettings, NoWatchdog, ResetCause};
    use axcomp_firmware::setpoint::{MAX_SETPOINT_FRAME_LEN, ReplyDecoder, SetpointFrame};

    const CAPS: BoardCaps = BoardCaps {
        counter_bits: 16,
        axis_ids: &[3, 1, 2],
        sensors: 2,
    };
    let image = scenario::group_image(3, false).unwrap();
    assert_eq!(check_group_image(&CAPS, &image), Ok(([1, 2, 0, 0, 0], 3)));
    let cfg = LoopSettings::new(170_000_000).build().unwrap();
    let mut drive = GroupDrive::new(
        CAPS,
        &cfg,
        LinkSettings::defaults(cfg.rate_hz),
        ResetCause::default(),
    );
    let mut engine: Box<GroupEngine<POOL>> = Box::new(GroupEngine::new());
    let mut reference: Box<GroupEngine<POOL>> = Box::new(GroupEngine::new());
    drive.offer_image(&mut engine, &image).unwrap();
    reference.load_image(&image).unwrap();
    assert_eq!(drive.inputs(), &[1, 2, 0]);
    let mut io = FakeDriveIo::default();
    let clock = SteppingClock::default();
    let mut replies = ReplyDecoder::new();
    let mut changed = 0;
    for i in 0..2_000u32 {
        let g = axcomp_core::bench::group_input(i * 7);
        // Board input order: Z, X, Y.
        let by_input = [2, 0, 1];
        let cmds = by_input.map(|slot| g.axes[slot].command_counts as i32);
        for (input, &slot) in by_input.iter().enumerate() {
            io.scales[input] = g.axes[slot].scale_raw & 0xFFFF;
        }
        let mut b = [0u8; MAX_SETPOINT_FRAME_LEN];
        let n = SetpointFrame::new(i as u8, &cmds)
            .unwrap()
            .encode_into(&mut b);
        io.rx.extend(&b[..n]);
        let c = drive.cycle(&mut engine, &mut io, &clock, &mut NoWatchdog);
        let mut input = GroupInput::ZERO;
        for slot in 0..3 {
            input.axes[slot].scale_raw = g.axes[slot].scale_raw & 0xFFFF;
            input.axes[slot].command_counts = i64::from(g.axes[slot].command_counts as i32);
        }
        let mut want = GroupOutput::ZERO;
        reference.cycle(&input, &mut want);
        assert_eq!(c.engine, want, "cycle {i}");
        let reply = replies
            .push_bytes(io.tx.last().unwrap())
            .expect("a valid reply");
        for (input, &slot) in by_input.iter().enumerate() {
            assert_eq!(
                i64::from(reply.corrected()[input]),
                want.axes[slot].corrected_command_counts,
                "cycle {i} input {input}"
            );
        }
        assert_eq!(reply.status, c.status.bits());
        changed += usize::from(want.axes.iter().any(|a| a.correction_counts != 0));
    }
    assert!(
        changed > 1_000,
        "the corrections are not all zero ({changed} cycles)"
    );
}
