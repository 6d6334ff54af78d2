//! Group images (schema 2): round trip, typed refusals, board capabilities, schema-1 images as
//! single-axis groups, the stale-sensor ramp-out, and property tests of the parser (random bytes,
//! bit flips and mutations are never accepted and never panic).

mod common;

use axcomp_core::group::{AxisName, Group, GroupEngine, GroupInput, GroupOutput, GroupState};
use axcomp_core::group_image::{
    self, AxisSectionSpec, BoardCaps, DIR_ENTRY_LEN, GROUP_HEADER_LEN, write_group_image,
};
use axcomp_core::rotary::RotaryLocationSpec;
use axcomp_core::*;
use common::*;
use proptest::prelude::*;

const STAGE: RotaryLocationSpec = RotaryLocationSpec {
    ex0c_um: 10.0,
    ey0c_um: -4.0,
    ea0c_urad: 12.0,
    eb0c_urad: -7.0,
    ey0a_um: 3.0,
    ez0a_um: 8.0,
    eb0a_urad: 5.0,
    ec0a_urad: -9.0,
    pivot_counts: [0, 0, 0],
    tool_length_um: 50_000.0,
    ..RotaryLocationSpec::ZERO_AC
};

struct Images {
    lin: [Vec<u8>; 3],
    rot: [Vec<u8>; 2],
}

fn images() -> Images {
    Images {
        lin: [linear_image(1, 2), linear_image(2, 0), linear_image(3, 0)],
        rot: [rotary_image(4), rotary_image(6)],
    }
}

const NAMES: [&str; 2] = ["spindle", "bed"];

fn five_axes(im: &Images) -> Vec<AxisSectionSpec<'_>> {
    vec![
        AxisSectionSpec {
            name: AxisName::X,
            counts_per_rev: 0,
            stroke_counts: Some((-4000, 4000)),
            image: &im.lin[0],
            sensor_names: &NAMES,
        },
        AxisSectionSpec {
            name: AxisName::Y,
            counts_per_rev: 0,
            stroke_counts: None,
            image: &im.lin[1],
            sensor_names: &[],
        },
        AxisSectionSpec {
            name: AxisName::Z,
            counts_per_rev: 0,
            stroke_counts: None,
            image: &im.lin[2],
            sensor_names: &[],
        },
        AxisSectionSpec {
            name: AxisName::A,
            counts_per_rev: CPR,
            stroke_counts: None,
            image: &im.rot[0],
            sensor_names: &[],
        },
        AxisSectionSpec {
            name: AxisName::C,
            counts_per_rev: CPR,
            stroke_counts: None,
            image: &im.rot[1],
            sensor_names: &[],
        },
    ]
}

fn write(axes: &[AxisSectionSpec], rotary: Option<&RotaryLocationSpec>) -> Vec<u8> {
    let mut buf = vec![0u8; group_image::group_image_len(axes, rotary)];
    let n = write_group_image(axes, rotary, &mut buf).expect("valid group");
    assert_eq!(n, buf.len());
    buf
}

fn good_image() -> Vec<u8> {
    let im = images();
    write(&five_axes(&im), Some(&STAGE))
}

#[test]
fn round_trip_and_load() {
    let im = images();
    let bytes = write(&five_axes(&im), Some(&STAGE));
    let view = group_image::parse(&bytes).unwrap();
    assert_eq!(view.version, 2);
    assert_eq!(view.axis_count(), 5);
    assert_eq!(view.rotary, Some(STAGE));
    let x = view.axes().next().unwrap();
    assert_eq!(x.axis.name, AxisName::X);
    assert_eq!(x.stroke_counts, Some((-4000, 4000)));
    assert_eq!(x.axis.image, &im.lin[0][..]);
    assert_eq!(x.sensor_name(0), Some("spindle"));
    assert_eq!(x.sensor_name(1), Some("bed"));
    let mut g: Box<Group<512>> = Box::new(Group::new());
    g.load_image(&bytes).unwrap();
    assert_eq!(g.axis_count(), 5);
    assert!(g.has_rotary_stage());
    assert_eq!(g.slot_of(AxisName::C), Some(4));
}

/// A schema-1 image loads as a single-axis group (axis X) and computes what the single-axis
/// compensator computes (reference: `Compensator::cycle`, exact).
#[test]
fn schema_1_images_still_load() {
    let img = linear_image(1, 0);
    let view = group_image::parse(&img).unwrap();
    assert_eq!((view.version, view.axis_count()), (1, 1));
    let mut engine: Box<GroupEngine<64>> = Box::new(GroupEngine::new());
    engine.load_image(&img).unwrap();
    let mut single = Box::new(Compensator::IDENTITY);
    single.load(&img).unwrap();
    let mut st = State::new();
    let mut input = GroupInput::ZERO;
    let mut out = GroupOutput::ZERO;
    for i in 0..200u32 {
        let raw = (i * 97) as u16 as u32; // a 16-bit counter wrapping
        input.axes[0] = common::input(raw, i as i64 * 97);
        engine.cycle(&input, &mut out);
        let want = single.cycle(&mut st, &input.axes[0]);
        assert_eq!(out.axes[0], want, "cycle {i}");
    }
    // Trailing bytes after a schema-1 image are refused by the group parser.
    let mut long = img.clone();
    long.extend_from_slice(&[0u8; 100]);
    assert_eq!(
        group_image::parse(&long).unwrap_err(),
        ImageError::TrailingBytes
    );
}

/// Re-seal a schema-2 image after an edit: section CRCs of the directory, then the whole CRC.
fn reseal(b: &mut [u8]) {
    let n = u16::from_le_bytes([b[12], b[13]]) as usize;
    for i in 0..n {
        let at = GROUP_HEADER_LEN + DIR_ENTRY_LEN * i;
        if at + DIR_ENTRY_LEN > b.len() - 4 {
            break;
        }
        let off = u32::from_le_bytes(b[at + 8..at + 12].try_into().unwrap()) as usize;
        let len = u32::from_le_bytes(b[at + 12..at + 16].try_into().unwrap()) as usize;
        if off.checked_add(len).is_some_and(|e| e <= b.len()) {
            let c = crc32(&b[off..off + len]);
            b[at + 16..at + 20].copy_from_slice(&c.to_le_bytes());
        }
    }
    let body = b.len() - 4;
    let c = crc32(&b[..body]);
    b[body..].copy_from_slice(&c.to_le_bytes());
}

fn dir_at(i: usize) -> usize {
    GROUP_HEADER_LEN + DIR_ENTRY_LEN * i
}

#[test]
fn typed_refusals() {
    let good = good_image();
    let err = |b: &[u8]| group_image::parse(b).unwrap_err();
    // Trailing bytes.
    let mut t = good.clone();
    t.extend_from_slice(&[0; 100]);
    assert_eq!(err(&t), ImageError::TrailingBytes);
    // Truncated.
    assert_eq!(err(&good[..good.len() - 1]), ImageError::TooShort);
    // A flipped bit anywhere in a section: the whole CRC catches it; resealing only the whole
    // CRC leaves the section CRC to catch it.
    let mut f = good.clone();
    let off0 = u32::from_le_bytes(good[dir_at(0) + 8..dir_at(0) + 12].try_into().unwrap()) as usize;
    f[off0 + 40] ^= 1;
    assert_eq!(err(&f), ImageError::BadCrc);
    let body = f.len() - 4;
    let c = crc32(&f[..body]);
    f[body..].copy_from_slice(&c.to_le_bytes());
    assert_eq!(err(&f), ImageError::SectionCrc { index: 0 });
    // Offset + length overflowing u32 / usize arithmetic.
    let mut o = good.clone();
    o[dir_at(1) + 8..dir_at(1) + 12].copy_from_slice(&u32::MAX.to_le_bytes());
    o[dir_at(1) + 12..dir_at(1) + 16].copy_from_slice(&u32::MAX.to_le_bytes());
    reseal(&mut o);
    assert_eq!(err(&o), ImageError::SectionBounds { index: 1 });
    // Unknown mandatory section type; the same type optional is skipped.
    let mut u = good.clone();
    u[dir_at(2)..dir_at(2) + 2].copy_from_slice(&77u16.to_le_bytes());
    reseal(&mut u);
    assert_eq!(err(&u), ImageError::UnknownSection { kind: 77 });
    // A known type in a version this reader does not support, mandatory: refused as unsupported.
    // (Types 2, the geometric model, and 4, the probe settings, are supported: an axis section retyped as one is refused as malformed; their own refusals are in
    // tests/geometric.rs and tests/probe_image.rs.)
    let mut r = good.clone();
    r[dir_at(2) + 2..dir_at(2) + 4].copy_from_slice(&9u16.to_le_bytes());
    reseal(&mut r);
    assert_eq!(err(&r), ImageError::UnsupportedSection { kind: 1 });
    for kind in [2u16, 4] {
        let mut r = good.clone();
        r[dir_at(2)..dir_at(2) + 2].copy_from_slice(&kind.to_le_bytes());
        reseal(&mut r);
        assert_eq!(
            err(&r),
            ImageError::SectionBounds { index: 2 },
            "kind {kind}"
        );
    }
    // A section for an axis the group lacks: sensor names of B.
    let mut s = good.clone();
    s[dir_at(1) + 4] = AxisName::B.code();
    reseal(&mut s);
    assert_eq!(
        err(&s),
        ImageError::AxisNotInGroup {
            axis: AxisName::B.code()
        }
    );
    // The same axis twice.
    let mut d = good.clone();
    d[dir_at(2) + 4] = AxisName::X.code();
    reseal(&mut d);
    assert_eq!(err(&d), ImageError::DuplicateAxis { axis: 0 });
    // A knot grid that does not match the axis's stroke.
    let im = images();
    let mut axes = five_axes(&im);
    axes[0].stroke_counts = Some((-4000, 5000));
    let mut buf = vec![0u8; group_image::group_image_len(&axes, Some(&STAGE))];
    assert_eq!(
        write_group_image(&axes, Some(&STAGE), &mut buf).unwrap_err(),
        ImageError::GridMismatch { axis: 0 }
    );
    assert!(buf.iter().all(|&b| b == 0), "nothing half-written");
    // Sensor names not one per sensor.
    let mut axes = five_axes(&im);
    axes[0].sensor_names = &["only-one"];
    assert_eq!(
        write_group_image(&axes, Some(&STAGE), &mut buf).unwrap_err(),
        ImageError::SensorNames { axis: 0 }
    );
    // The rotary model without a C axis.
    let axes = five_axes(&im);
    assert_eq!(
        write_group_image(&axes[..4], Some(&STAGE), &mut buf).unwrap_err(),
        ImageError::AxisNotInGroup { axis: 5 }
    );
}

#[test]
fn board_capabilities_are_checked() {
    let bytes = good_image();
    let view = group_image::parse(&bytes).unwrap();
    let board = BoardCaps {
        counter_bits: 16,
        axis_ids: [1, 2, 3, 4, 6],
        n_axes: 5,
        sensor_inputs: 2,
    };
    view.check_against(&board).unwrap();
    assert_eq!(
        view.check_against(&BoardCaps {
            counter_bits: 32,
            ..board
        }),
        Err(ImageError::CounterWidthMismatch {
            image: 16,
            board: 32
        })
    );
    assert_eq!(
        view.check_against(&BoardCaps {
            axis_ids: [1, 2, 3, 4, 5],
            ..board
        }),
        Err(ImageError::AxisIdMismatch { image: 6 })
    );
    assert_eq!(
        view.check_against(&BoardCaps {
            sensor_inputs: 1,
            ..board
        }),
        Err(ImageError::TooFewSensorInputs {
            needed: 2,
            wired: 1
        })
    );
}

/// One axis id on two axes: the image itself is valid (the core loads it), but no board can feed
/// both axes from one scale input, so the board check (and the host's `image group` / `inspect`,
/// which call `GroupImageView::check_group`) refuse it naming the id.
#[test]
fn one_axis_id_on_two_axes_is_refused_by_the_board_check() {
    let mut im = images();
    im.lin[1] = linear_image(1, 0);
    let bytes = write(&five_axes(&im), Some(&STAGE));
    let view = group_image::parse(&bytes).unwrap();
    assert_eq!(
        view.check_axis_ids(),
        Err(ImageError::AxisIdTwice { axis_id: 1 })
    );
    let board = BoardCaps {
        counter_bits: 16,
        axis_ids: [1, 2, 3, 4, 6],
        n_axes: 5,
        sensor_inputs: 2,
    };
    assert_eq!(
        view.check_against(&board),
        Err(ImageError::AxisIdTwice { axis_id: 1 })
    );
    group_image::parse(&good_image())
        .unwrap()
        .check_axis_ids()
        .unwrap();
}

/// A rotary pivot far outside the strokes (mm taken for counts, a sign error): the core's board
/// check (`check_against`) and `image group` / `inspect` (which call `GroupImageView::check_group`)
/// refuse it naming the axis (the drive's own image check does not run it: code budget). X's stated stroke is −4000..4000 counts (8000 long): the pivot's X may lie in
/// −12000..12000. Y and Z state no stroke: their tables' spans are used (a pivot at 1e10 counts
/// on Y is refused naming Y).
#[test]
fn a_pivot_far_outside_the_strokes_is_refused_by_the_board_check() {
    let im = images();
    let board = BoardCaps {
        counter_bits: 16,
        axis_ids: [1, 2, 3, 4, 6],
        n_axes: 5,
        sensor_inputs: 2,
    };
    for (x, ok) in [
        (12_000, true),
        (-12_000, true),
        (12_001, false),
        (-12_001, false),
        (4_000_000_000, false),
    ] {
        let stage = RotaryLocationSpec {
            pivot_counts: [x, 0, 0],
            ..STAGE
        };
        let bytes = write(&five_axes(&im), Some(&stage));
        let view = group_image::parse(&bytes).unwrap();
        let want = if ok {
            Ok(())
        } else {
            Err(ImageError::PivotOutsideStroke { axis: 0 })
        };
        assert_eq!(view.check_pivot(), want, "pivot X {x}");
        assert_eq!(view.check_against(&board), want, "pivot X {x}");
    }
    let stage = RotaryLocationSpec {
        pivot_counts: [0, 10_000_000_000, 0],
        ..STAGE
    };
    let bytes = write(&five_axes(&im), Some(&stage));
    assert_eq!(
        group_image::parse(&bytes).unwrap().check_pivot(),
        Err(ImageError::PivotOutsideStroke { axis: 1 })
    );
}

/// Reference: the documented rule — a stale sensor's frozen Σ b_i·ΔT_i is held for
/// STALE_HOLD_MS, then ramps linearly to 0 over STALE_RAMP_MS, leaving b0; exact values at the
/// hold's end, mid-ramp (±1e-4 µm: one f32 division) and after the ramp.
#[test]
fn stale_sensor_term_ramps_out_to_b0() {
    // b0 = 0.25 µm, b = 0.5 µm/K per sensor, stale after 1000 ms.
    let img = linear_image(1, 2);
    let comp = {
        let mut c = Box::new(Compensator::IDENTITY);
        c.load(&img).unwrap();
        c
    };
    let mut st = State::new();
    comp.update_temperatures(&mut st, 0, &[30.0, 24.0]); // ΔT 10 and 4 K: 7 µm
    assert_eq!(st.sensor_term_um(), 7.0);
    // Sensor 1 stops reporting at t = 0; it is stale from t > 1000 ms.
    let mut t = 0;
    let at = |st: &mut State, t: u32| {
        comp.update_temperatures(st, t, &[30.0, f32::NAN]);
        comp.cycle(st, &input(0, 0))
    };
    while t < 1100 {
        t += 100;
        at(&mut st, t);
    }
    assert!(st.sensor_stale(1));
    let stale_at = 1100u32;
    // Held until STALE_HOLD_MS after going stale.
    let o = at(&mut st, stale_at + STALE_HOLD_MS);
    assert!(o.flags.contains(Flags::THERMAL_FROZEN));
    assert!(!o.flags.contains(Flags::THERMAL_RAMP_OUT));
    assert_eq!(st.sensor_term_um(), 7.0);
    // Half way through the ramp: half the term.
    let o = at(&mut st, stale_at + STALE_HOLD_MS + STALE_RAMP_MS / 2);
    assert!(o.flags.contains(Flags::THERMAL_RAMP_OUT));
    assert!(
        (st.sensor_term_um() - 3.5).abs() < 1e-4,
        "{}",
        st.sensor_term_um()
    );
    // After the ramp: b0 only, flagged.
    let o = at(&mut st, stale_at + STALE_HOLD_MS + STALE_RAMP_MS);
    assert_eq!(st.sensor_term_um(), 0.0);
    assert!(
        o.flags
            .contains(Flags::THERMAL_RAMP_OUT | Flags::SENSOR_FAULT)
    );
    // The table adds 1.0 + t·0.5 at position 0 (segment 4 of 8, t = 0): 1.0 + b0.
    assert_eq!(o.correction_um, 1.0 + 0.25);
    // Recovery: live again, flag gone.
    for k in 1..=RECOVERY_READINGS as u32 {
        comp.update_temperatures(&mut st, stale_at + 130_000 + 100 * k, &[30.0, 24.0]);
    }
    let o = comp.cycle(&mut st, &input(0, 0));
    assert!(!o.flags.contains(Flags::THERMAL_RAMP_OUT));
    assert_eq!(st.sensor_term_um(), 7.0);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// Random bytes behind a valid header prefix are never accepted and never panic.
    #[test]
    fn random_bytes_are_refused(tail in proptest::collection::vec(any::<u8>(), 0..600)) {
        let mut b = good_image()[..GROUP_HEADER_LEN].to_vec();
        b.extend_from_slice(&tail);
        prop_assert!(group_image::parse(&b).is_err());
        let mut g: Box<Group<512>> = Box::new(Group::new());
        prop_assert!(g.load_image(&b).is_err());
    }

    /// Any bit flip (also in the directory, the CRCs or the trailer) is refused.
    #[test]
    fn bit_flips_are_refused(bit in 0usize..(8 * 4096)) {
        let good = good_image();
        let bit = bit % (8 * good.len());
        let mut b = good.clone();
        b[bit / 8] ^= 1 << (bit % 8);
        prop_assert!(group_image::parse(&b).is_err());
    }

    /// Mutations re-sealed with correct CRCs (so that the structure checks, not the CRCs, must
    /// catch them) never panic; an accepted mutant is a valid group that loads and runs.
    #[test]
    fn resealed_mutations_never_panic(
        edits in proptest::collection::vec((0usize..4096, any::<u8>()), 1..6),
        cut in 0usize..64,
    ) {
        let mut b = good_image();
        for (at, v) in edits {
            let at = at % b.len().saturating_sub(4).max(1);
            b[at] = v;
        }
        let new_len = b.len().saturating_sub(cut).max(GROUP_HEADER_LEN + 4);
        b.truncate(new_len);
        let total = (b.len() as u32).to_le_bytes();
        b[8..12].copy_from_slice(&total);
        reseal(&mut b);
        if let Ok(view) = group_image::parse(&b) {
            let mut g: Box<Group<512>> = Box::new(Group::new());
            let (axes, n) = view.axis_images();
            if g.load(&axes[..n], view.rotary.as_ref()).is_ok() {
                let mut st = Box::new(GroupState::new());
                let mut out = GroupOutput::ZERO;
                g.cycle(&mut st, &GroupInput::ZERO, &mut out);
            }
        }
    }
}
