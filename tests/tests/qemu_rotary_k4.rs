//! The rotary location-error stage in QEMU: the group firmware (`axcomp-qemu-group`) and the host
//! replay give byte-identical output records on a five-axis trace (X, Y, Z, tilt, C) along the
//! ISO 10791-6 K4 path — C turning continuously (through 360° six times) while the tilt axis
//! swings 0 → −60° → 0 and X, Y, Z follow a sphere on the table, every axis moving every cycle —
//! with six rotary models loaded one after the other by A/B swaps: an AC trunnion (version-2
//! section with squareness and a not-identified constant), a BC trunnion and a BC head, then the
//! same three with a wobble (version-3 sections: C 1…4 per turn, the tilt axis to t³; the AC
//! trunnion then takes the general cycle).
//!
//! Reference: `axcomp_firmware::replay::replay_group` over `axcomp_core::group::GroupEngine` on the
//! host. Tolerance: none — every 32-byte output record must match bit for bit, and the record count
//! must be the number of group cycles times five.

use axcomp_core::bench::{GROUP_COUNTS_PER_REV, group_axis_spec};
use axcomp_core::group::{AxisName, GroupInput};
use axcomp_core::group_image::{
    self, AxisSectionSpec, ROTARY_SECTION_VERSION, ROTARY_SECTION_WOBBLE_VERSION,
};
use axcomp_core::rotary::{RotaryLocationSpec, RotaryMachine};
use axcomp_core::trace::{self, OUTPUT_RECORD_LEN, OutputRecord, Record};
use axcomp_system_tests::{build_qemu_firmware, host_group_replay, qemu_replay, require_tool};

/// Cycles per K4 turn (C 360°, the tilt 0 → −60° → 0).
const CYCLES_PER_TURN: u32 = 6_000;
/// One turn per rotary model.
const CYCLES: u32 = 6 * CYCLES_PER_TURN;
/// µm per count of X, Y, Z (the group workload's axes).
const UPC: f64 = 0.1;
/// Pivot (counts) and tool length (mm): the tool point stays inside the tables' 100 mm strokes.
const PIVOT: [i64; 3] = [500_000, 500_000, 250_000];
const TOOL_MM: f64 = 20.0;
/// The sphere on the table, mm from the pivot.
const SPHERE_MM: [f64; 3] = [30.0, -10.0, 15.0];

fn rotary(machine: RotaryMachine) -> RotaryLocationSpec {
    RotaryLocationSpec {
        machine,
        ex0c_um: 18.0,
        ey0c_um: -11.0,
        ea0c_urad: 35.0,
        eb0c_urad: -60.0,
        ey0a_um: 24.0,
        ez0a_um: -9.0,
        eb0a_urad: 0.0,
        ec0a_urad: 47.0,
        squareness_urad: [22.0, -15.0, 31.0],
        pivot_counts: PIVOT,
        tool_length_um: (TOOL_MM * 1000.0) as f32,
        // EB0A (or EA0B) not identified: fixed at 0.
        not_identified: 1 << 6,
        wobble: axcomp_core::rotary::RotaryWobble::NONE,
    }
}

/// The model of `machine` with a wobble: C tilting and moving radially 1…4 times per turn
/// (4–15 µrad, 0.5–3 µm), the tilt axis as t, t², t³ (2–12 µrad/rad^d, 0.3–2 µm/rad^d).
fn with_wobble(machine: RotaryMachine) -> RotaryLocationSpec {
    let mut w = axcomp_core::rotary::RotaryWobble::NONE;
    for (k, row) in w.c.iter_mut().enumerate() {
        for (i, v) in row.iter_mut().enumerate() {
            let sign = if (i + k) % 3 == 0 { -1.0 } else { 1.0 };
            *v = sign
                * if i % 2 == 0 {
                    15.0 - 3.0 * k as f32
                } else {
                    3.0 - 0.6 * k as f32
                };
        }
    }
    for (d, row) in w.tilt.iter_mut().enumerate() {
        *row = [12.0, -2.0, -8.0, 1.5].map(|v| v / (d + 1) as f32);
    }
    RotaryLocationSpec {
        wobble: w,
        ..rotary(machine)
    }
}

/// The five-axis group image with the workload's axis tables and `spec`'s rotary model.
fn image(spec: &RotaryLocationSpec) -> Vec<u8> {
    let machine = spec.machine;
    let images: Vec<Vec<u8>> = (0..5)
        .map(|k| {
            let spec = group_axis_spec(k);
            let mut buf = vec![0u8; axcomp_core::image_len(&spec)];
            let n = axcomp_core::write_image(&spec, &mut buf).unwrap();
            buf.truncate(n);
            buf
        })
        .collect();
    let names = [
        AxisName::X,
        AxisName::Y,
        AxisName::Z,
        machine.tilt_axis(),
        AxisName::C,
    ];
    let axes: Vec<AxisSectionSpec> = images
        .iter()
        .zip(names)
        .map(|(img, name)| AxisSectionSpec {
            name,
            counts_per_rev: if name.is_rotary() {
                GROUP_COUNTS_PER_REV
            } else {
                0
            },
            stroke_counts: None,
            image: img,
            sensor_names: &[],
        })
        .collect();
    let mut out = vec![0u8; group_image::group_image_len(&axes, Some(spec))];
    let n = group_image::write_group_image(&axes, Some(spec), &mut out).unwrap();
    out.truncate(n);
    out
}

/// K4 at cycle `i`: C = 360°·i/turn (continuing past 360°), tilt = −60°·(1 − cos C)/2, the tool
/// point on the sphere carried by the table (tilt about X for `tilt_axis` 0, about Y for 1);
/// commands in counts, the scale 2 counts behind.
fn k4_input(i: u32, tilt_axis: usize) -> GroupInput {
    let c = std::f64::consts::TAU * i as f64 / CYCLES_PER_TURN as f64;
    let t = (-60.0f64).to_radians() * (1.0 - c.cos()) / 2.0;
    let (sc, cc) = c.sin_cos();
    let (st, ct) = t.sin_cos();
    let s = SPHERE_MM;
    let w = [cc * s[0] - sc * s[1], sc * s[0] + cc * s[1], s[2]];
    let p = if tilt_axis == 0 {
        [w[0], ct * w[1] - st * w[2], st * w[1] + ct * w[2]]
    } else {
        [ct * w[0] + st * w[2], w[1], ct * w[2] - st * w[0]]
    };
    let lin = |k: usize, mm: f64| PIVOT[k] + (mm * 1000.0 / UPC).round() as i64;
    let cpr = GROUP_COUNTS_PER_REV as f64;
    let cmd = [
        lin(0, p[0]),
        lin(1, p[1]),
        lin(2, p[2] + TOOL_MM),
        (t / std::f64::consts::TAU * cpr).round() as i64,
        (c / std::f64::consts::TAU * cpr).round() as i64,
    ];
    let mut g = GroupInput::ZERO;
    for (a, c) in g.axes.iter_mut().zip(cmd) {
        a.command_counts = c;
        a.scale_raw = (c - 2) as u32;
    }
    g
}

fn push(bytes: &mut Vec<u8>, rec: &Record) {
    let at = bytes.len();
    bytes.resize(at + rec.encoded_len(), 0);
    trace::encode_record(rec, &mut bytes[at..]).unwrap();
}

const MACHINES: [RotaryMachine; 3] = [
    RotaryMachine::AcTrunnion,
    RotaryMachine::BcTrunnion,
    RotaryMachine::BcHead,
];

/// The six models: the three kinds, then the three with a wobble.
fn models() -> Vec<RotaryLocationSpec> {
    let plain = MACHINES.map(rotary);
    let wobbly = MACHINES.map(with_wobble);
    plain.into_iter().chain(wobbly).collect()
}

/// The trace: the AC image, one K4 turn, the BC-trunnion image, one turn, the BC-head image,
/// one turn; then the same with the wobble.
fn k4_trace() -> Vec<u8> {
    let mut t = vec![0u8; trace::TRACE_HEADER_LEN];
    trace::write_header(&mut t).unwrap();
    let models = models();
    for i in 0..CYCLES {
        let spec = &models[(i / CYCLES_PER_TURN) as usize];
        if i % CYCLES_PER_TURN == 0 {
            push(&mut t, &Record::Image(&image(spec)));
        }
        let tilt_axis = if spec.machine == RotaryMachine::AcTrunnion {
            0
        } else {
            1
        };
        push(
            &mut t,
            &Record::GroupCycle {
                n: 5,
                input: k4_input(i, tilt_axis),
            },
        );
    }
    let crc = axcomp_core::crc32(&t);
    push(&mut t, &Record::Crc(crc));
    push(&mut t, &Record::End);
    t
}

/// The trace exercises what it claims: three version-2 rotary sections of the three kinds and
/// three version-3 ones with a wobble, and the stage's corrections are large (tens of µm) and
/// change along the path; the wobble changes them by more than 1 µm on each kind.
#[test]
fn k4_trace_carries_the_six_rotary_models() {
    for (k, spec) in models().iter().enumerate() {
        let img = image(spec);
        let view = group_image::parse(&img).unwrap();
        assert_eq!(view.rotary.as_ref(), Some(spec));
        // The directory entry of the rotary section (the last) has version 2, 3 with a wobble.
        let n = u16::from_le_bytes([img[12], img[13]]) as usize;
        let at = group_image::GROUP_HEADER_LEN + group_image::DIR_ENTRY_LEN * (n - 1);
        let version = if k < 3 {
            ROTARY_SECTION_VERSION
        } else {
            ROTARY_SECTION_WOBBLE_VERSION
        };
        assert_eq!(u16::from_le_bytes([img[at + 2], img[at + 3]]), version);
    }
    let (out, cycles, errors) = host_group_replay(&k4_trace());
    assert_eq!((cycles, errors), (CYCLES, 0));
    let x: Vec<f32> = out
        .chunks(OUTPUT_RECORD_LEN)
        .step_by(5)
        .map(|r| OutputRecord::decode(r).unwrap().correction_um())
        .collect();
    let lo = x.iter().cloned().fold(f32::INFINITY, f32::min);
    let hi = x.iter().cloned().fold(f32::NEG_INFINITY, f32::max);
    assert!(hi - lo > 20.0, "X correction range {lo} .. {hi} µm");
    let turn = CYCLES_PER_TURN as usize;
    for m in 0..3 {
        let plain = &x[m * turn..(m + 1) * turn];
        let wobbly = &x[(m + 3) * turn..(m + 4) * turn];
        let most = plain
            .iter()
            .zip(wobbly)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(
            most > 1.0,
            "model {m}: the wobble moves X by at most {most} µm"
        );
    }
}

#[test]
fn five_axis_k4_trace_with_rotary_models_matches_host_bit_for_bit() {
    if !require_tool("qemu-system-arm") {
        return;
    }
    let elf = build_qemu_firmware("axcomp-qemu-group");
    let trace_bytes = k4_trace();
    let (want, cycles, errors) = host_group_replay(&trace_bytes);
    assert_eq!((cycles, errors), (CYCLES, 0));
    assert_eq!(want.len(), CYCLES as usize * 5 * OUTPUT_RECORD_LEN);
    let (status, stdout, got) = qemu_replay(&elf, "qemu-rotary-k4", &trace_bytes);
    assert!(
        status.success(),
        "QEMU firmware failed ({status})\n{stdout}"
    );
    assert_eq!(got.len() % OUTPUT_RECORD_LEN, 0, "whole records");
    if let Some(k) = got
        .chunks(OUTPUT_RECORD_LEN)
        .zip(want.chunks(OUTPUT_RECORD_LEN))
        .position(|(a, b)| a != b)
    {
        let a = OutputRecord::decode(&got[k * OUTPUT_RECORD_LEN..]).unwrap();
        let b = OutputRecord::decode(&want[k * OUTPUT_RECORD_LEN..]).unwrap();
        panic!("first differing output record #{k}:\n  qemu: {a:?}\n  host: {b:?}");
    }
    assert_eq!(got.len(), want.len(), "record count (QEMU vs host)");
    let outputs = CYCLES as usize * 5;
    assert!(
        stdout.contains(&format!(
            "cycles={CYCLES} outputs={outputs} errors=0 images_accepted=6 images_rejected=0"
        )),
        "summary line: {stdout}"
    );
}
