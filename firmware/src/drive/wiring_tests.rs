//! Sensor wiring by name on the STM32G474 board (two RTDs, °C, named `rtd0`, `rtd1`): the
//! "warm-up fed 22 °C" case, a named image refused at load, an old unnamed image flagged at run time,
//! and named sensors routed to their inputs in any order.

use axcomp_core::group::GroupEngine;
use axcomp_core::provenance::{self, SENSOR_NAMES_TAG};
use axcomp_core::wiring::{BoardInput, InputUnit, WiringError};
use axcomp_core::{
    ImageSpec, LimitSpec, OutsideStroke, SensorSpec, TableSpec, ThermoForceSpec, write_image,
};

use super::fake::FakeDriveIo;
use super::group::GroupDrive;
use super::link_trace::{REPLAY_CLOCK_HZ, replay_drive};
use super::{ImageRefusal, NoWatchdog};
use crate::control::fake::SteppingClock;
use crate::setpoint::{MAX_SETPOINT_FRAME_LEN, SetpointFrame};
use crate::status::Status;

const POOL: usize = 64;

/// The STM32G474 board's sensor inputs as shipped (`board::stm32g474::SENSOR_INPUTS`).
const BOARD: [BoardInput<'static>; 2] = [
    BoardInput {
        name: "rtd0",
        unit: InputUnit::DegC,
    },
    BoardInput {
        name: "rtd1",
        unit: InputUnit::DegC,
    },
];

/// The replays' drive (16-bit counters, axes 1, 2, 3, 170 MHz, default link settings) on [`BOARD`].
fn board_drive() -> GroupDrive {
    replay_drive().with_sensor_inputs(&BOARD)
}

/// A schema-1 image of axis 1: a 2 µm table and a thermo-force term over `sensors` with
/// coefficients `b` (µm per unit) and constant `b0`.
fn image(sensors: &[SensorSpec], b: &[f32], b0: f32) -> Vec<u8> {
    let fwd = [[2.0f32, 0.0, 0.0, 0.0]; 4];
    let spec = ImageSpec {
        axis_id: 1,
        um_per_count: 0.1,
        counter_bits: 16,
        table: Some(TableSpec {
            start_counts: 0,
            segment_counts: 1000,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        }),
        thermo: Some(ThermoForceSpec {
            sensor_period_ms: 100,
            sensors,
            b0_um: b0,
            b_um_per_k: b,
            expansion: None,
            forces: &[],
            reference: axcomp_core::ThermoReference::Fixed,
            rise_bounds_k: &[],
        }),
        limits: LimitSpec {
            max_correction_um: 100.0,
            max_slew_um_per_cycle: 100.0,
            direction_hysteresis_counts: 5,
        },
    };
    let mut buf = vec![0u8; 4096];
    let n = write_image(&spec, &mut buf).expect("test image");
    buf.truncate(n);
    buf
}

/// The image with sensor names in its header extension (what `axcomp image build` writes).
fn named(img: &[u8], names: &[&str]) -> Vec<u8> {
    let mut field = vec![0u8; 16 * names.len()];
    for (i, n) in names.iter().enumerate() {
        field[16 * i..16 * i + n.len()].copy_from_slice(n.as_bytes());
    }
    let blocks = [(SENSOR_NAMES_TAG, field.as_slice())];
    let mut out = vec![0u8; img.len() + provenance::extension_len(&blocks)];
    provenance::with_header_extension(img, &blocks, &mut out).expect("names");
    out
}

/// The warm-up drift input as `fit positioning --drift-model` writes it: range −0.5…1.5, any rate,
/// τ = 1960 s (README, ESS B02 X), b = −10.3 µm per unit of warm-up state, b0 = 4.43 µm.
const WARMUP: SensorSpec = SensorSpec {
    reference_degc: 0.0,
    min_degc: -0.5,
    max_degc: 1.5,
    max_rate_degc_per_s: 1.0e6,
    lag_tau_s: 1960.0,
    stale_timeout_ms: 10_000,
};

fn frame(io: &mut FakeDriveIo, seq: u8) {
    let mut b = [0u8; MAX_SETPOINT_FRAME_LEN];
    let n = SetpointFrame::new(seq, &[500]).unwrap().encode_into(&mut b);
    io.rx.extend(&b[..n]);
}

/// The warm-up input fed RTD readings: "the `warmup` input's range is −0.5…1.5, but the board feeds it RTD readings (~22 °C),
/// so the sensor goes stale, the thermal term freezes at 0 and b0 is never applied". An image that
/// names its sensor `warmup` (as `image build` now writes every image) is refused at load on this
/// board, typed, and the status word says `IMAGE_REFUSED` (the identity keeps running: `NO_IMAGE`).
#[test]
fn a_warmup_image_is_refused_on_a_board_with_only_rtds() {
    let img = named(&image(&[WARMUP], &[-10.3], 4.43), &["warmup"]);
    let mut drive = board_drive();
    let mut engine: Box<GroupEngine<POOL>> = Box::new(GroupEngine::new());
    assert_eq!(
        drive.offer_image(&mut engine, &img),
        Err(ImageRefusal::SensorNotOnBoard {
            axis_id: 1,
            why: WiringError::NotOnBoard { sensor: 0 },
        })
    );
    let mut io = FakeDriveIo::default();
    let clock = SteppingClock::default();
    clock.step.set(REPLAY_CLOCK_HZ / 20_000);
    frame(&mut io, 1);
    let c = drive.cycle(&mut engine, &mut io, &clock, &mut NoWatchdog);
    assert!(
        c.status.contains(Status::IMAGE_REFUSED) && c.status.contains(Status::NO_IMAGE),
        "{}",
        c.status
    );
    assert_eq!(c.engine.axes[0].correction_counts, 0, "nothing applied");
    assert_eq!(drive.counters().images_refused, 1);
    // The same image naming an input the board has loads.
    let img = named(&image(&[WARMUP], &[-10.3], 4.43), &["rtd0"]);
    assert_eq!(drive.offer_image(&mut engine, &img), Ok(()));
}

/// An image written before names existed (no sensor names) is wired by position: the warm-up sensor
/// reads rtd0 (22 °C). It is never silent: the reading is rejected (`SENSOR_IMPLAUSIBLE`) from the
/// first set on, and from the image's stale timeout (10 s) on the sensor is `SENSOR_STALE` and the
/// thermal term `THERMAL_FROZEN` (then ramped out, see the fault table).
#[test]
fn an_unnamed_warmup_image_fed_22_degc_is_flagged_every_cycle() {
    let img = image(&[WARMUP], &[-10.3], 4.43);
    let mut drive = board_drive();
    let mut engine: Box<GroupEngine<POOL>> = Box::new(GroupEngine::new());
    drive.offer_image(&mut engine, &img).unwrap();
    let mut io = FakeDriveIo::default();
    let clock = SteppingClock::default();
    clock.step.set(REPLAY_CLOCK_HZ / 20_000);
    let mut seen = Status::NONE;
    // One reading set per cycle, 100 ms apart (the sensor clock is independent of the cycle clock).
    for k in 0..150u32 {
        drive.update_temperatures(&mut engine, k * 100, &[22.0, 22.5]);
        frame(&mut io, k as u8);
        let c = drive.cycle(&mut engine, &mut io, &clock, &mut NoWatchdog);
        assert!(
            c.status.contains(Status::SENSOR_IMPLAUSIBLE)
                || c.status.contains(Status::SENSOR_STALE),
            "reading set {k}: {}",
            c.status
        );
        if k * 100 <= 10_000 {
            assert!(
                c.status.contains(Status::SENSOR_IMPLAUSIBLE),
                "reading set {k}: {}",
                c.status
            );
        } else {
            assert!(
                c.status.contains(Status::SENSOR_STALE)
                    && c.status.contains(Status::THERMAL_FROZEN),
                "reading set {k} ({} ms): {}",
                k * 100,
                c.status
            );
        }
        seen.insert(c.status);
    }
    assert!(!seen.contains(Status::IMAGE_REFUSED));
}

/// Named sensors read the input of their name, in any order: sensor 0 named `rtd1` follows rtd1.
/// Reference: table 2 µm + b·(T − 20 °C) with b = 1 µm/K, τ = 0: rtd1 = 30 °C → 12 µm (positional
/// wiring would read rtd0 = 20 °C → 2 µm); tolerance 1e-4 µm (f32).
#[test]
fn named_sensors_read_their_own_inputs_in_any_order() {
    let t = SensorSpec {
        reference_degc: 20.0,
        min_degc: 0.0,
        max_degc: 60.0,
        max_rate_degc_per_s: 1.0e3,
        lag_tau_s: 0.0,
        stale_timeout_ms: 10_000,
    };
    let img = named(&image(&[t, t], &[1.0, 0.0], 0.0), &["rtd1", "rtd0"]);
    let mut drive = board_drive();
    let mut engine: Box<GroupEngine<POOL>> = Box::new(GroupEngine::new());
    drive.offer_image(&mut engine, &img).unwrap();
    assert_eq!(&drive.sensor_wiring(0).unwrap()[..2], &[1, 0]);
    let mut io = FakeDriveIo::default();
    let clock = SteppingClock::default();
    clock.step.set(REPLAY_CLOCK_HZ / 20_000);
    let mut last = 0.0f32;
    for k in 0..5u32 {
        drive.update_temperatures(&mut engine, k * 100, &[20.0, 30.0]);
        frame(&mut io, k as u8);
        let c = drive.cycle(&mut engine, &mut io, &clock, &mut NoWatchdog);
        assert!(
            !c.status.contains(Status::SENSOR_IMPLAUSIBLE),
            "{}",
            c.status
        );
        last = c.engine.axes[0].correction_um;
    }
    assert!((last - 12.0).abs() < 1e-4, "correction {last} µm");
    // An unknown name and too many unnamed sensors are typed refusals.
    let img = named(&image(&[t], &[1.0], 0.0), &["spindle"]);
    assert_eq!(
        drive.offer_image(&mut engine, &img),
        Err(ImageRefusal::SensorNotOnBoard {
            axis_id: 1,
            why: WiringError::NotOnBoard { sensor: 0 },
        })
    );
    let img = image(&[t, t, t], &[1.0, 0.0, 0.0], 0.0);
    assert_eq!(
        drive.offer_image(&mut engine, &img),
        Err(ImageRefusal::SensorsNotWired { image: 3, board: 2 })
    );
}
