//! The touch-probe settings section of group images (kind 4) and the loop's correction at the
//! latched counts (`Group::error_at`), against the loop itself.

mod common;

use axcomp_core::group::{AxisName, Group, GroupInput, GroupOutput, GroupState, MAX_AXES};
use axcomp_core::group_image::{
    self, AxisSectionSpec, DIR_ENTRY_LEN, GROUP_HEADER_LEN, write_group_image_with_probe,
};
use axcomp_core::probe::{PROBE_SECTION_LEN, ProbeSettings};
use axcomp_core::rotary::RotaryLocationSpec;
use axcomp_core::*;
use common::*;

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

const SETTINGS: ProbeSettings = ProbeSettings {
    min_pulse_us: 2_000,
    latency_ns: 850_000,
    lockout_us: 20_000,
    moving_um_per_s: 50.0,
};

fn group_image(probe: Option<&ProbeSettings>) -> Vec<u8> {
    let lin = [linear_image(1, 2), linear_image(2, 0), linear_image(3, 0)];
    let rot = [rotary_image(4), rotary_image(6)];
    let spec = |name, cpr, image| AxisSectionSpec {
        name,
        counts_per_rev: cpr,
        stroke_counts: None,
        image,
        sensor_names: &[],
    };
    let axes = [
        spec(AxisName::X, 0, &lin[0][..]),
        spec(AxisName::Y, 0, &lin[1][..]),
        spec(AxisName::Z, 0, &lin[2][..]),
        spec(AxisName::A, CPR, &rot[0][..]),
        spec(AxisName::C, CPR, &rot[1][..]),
    ];
    let mut buf = vec![0u8; group_image::group_image_len_with_probe(&axes, Some(&STAGE), probe)];
    let n = write_group_image_with_probe(&axes, Some(&STAGE), probe, &mut buf).expect("valid");
    assert_eq!(n, buf.len());
    buf
}

fn reseal(b: &mut [u8]) {
    let n = u16::from_le_bytes([b[12], b[13]]) as usize;
    for i in 0..n {
        let at = GROUP_HEADER_LEN + DIR_ENTRY_LEN * i;
        let off = u32::from_le_bytes(b[at + 8..at + 12].try_into().unwrap()) as usize;
        let len = u32::from_le_bytes(b[at + 12..at + 16].try_into().unwrap()) as usize;
        let c = crc32(&b[off..off + len]);
        b[at + 16..at + 20].copy_from_slice(&c.to_le_bytes());
    }
    let body = b.len() - 4;
    let c = crc32(&b[..body]);
    b[body..].copy_from_slice(&c.to_le_bytes());
}

/// Offset of the probe section (the last directory entry).
fn probe_section(b: &[u8]) -> (usize, usize) {
    let n = u16::from_le_bytes([b[12], b[13]]) as usize;
    let at = GROUP_HEADER_LEN + DIR_ENTRY_LEN * (n - 1);
    assert_eq!(u16::from_le_bytes([b[at], b[at + 1]]), 4, "kind 4 last");
    (
        at,
        u32::from_le_bytes(b[at + 8..at + 12].try_into().unwrap()) as usize,
    )
}

#[test]
fn probe_settings_round_trip_and_images_without_them_are_unchanged() {
    let with = group_image(Some(&SETTINGS));
    let view = group_image::parse(&with).unwrap();
    assert_eq!(view.probe, Some(SETTINGS));
    let without = group_image(None);
    assert_eq!(group_image::parse(&without).unwrap().probe, None);
    assert_eq!(
        with.len(),
        without.len() + DIR_ENTRY_LEN + PROBE_SECTION_LEN
    );
    let mut g: Box<Group<512>> = Box::new(Group::new());
    g.load_image(&with).unwrap();
    assert_eq!(g.axis_count(), 5);
}

#[test]
fn bad_probe_sections_are_typed_refusals() {
    let good = group_image(Some(&SETTINGS));
    let (dir, off) = probe_section(&good);
    let refused = |patch: &dyn Fn(&mut Vec<u8>)| {
        let mut b = good.clone();
        patch(&mut b);
        reseal(&mut b);
        group_image::parse(&b).unwrap_err()
    };
    // Lockout shorter than the filter.
    assert_eq!(
        refused(&|b| b[off + 8..off + 12].copy_from_slice(&1_000u32.to_le_bytes())),
        ImageError::OutOfRange {
            field: Field::ProbeLockout,
            index: 0
        }
    );
    // Filter beyond 100 ms; latency beyond 100 ms; a NaN speed; reserved bytes.
    assert_eq!(
        refused(&|b| b[off..off + 4].copy_from_slice(&200_000u32.to_le_bytes())),
        ImageError::OutOfRange {
            field: Field::ProbeMinPulse,
            index: 0
        }
    );
    assert_eq!(
        refused(&|b| b[off + 4..off + 8].copy_from_slice(&u32::MAX.to_le_bytes())),
        ImageError::OutOfRange {
            field: Field::ProbeLatency,
            index: 0
        }
    );
    assert_eq!(
        refused(&|b| b[off + 12..off + 16].copy_from_slice(&f32::NAN.to_bits().to_le_bytes())),
        ImageError::NonFinite {
            field: Field::ProbeMovingSpeed,
            index: 0
        }
    );
    assert!(matches!(
        refused(&|b| b[off + 16] = 1),
        ImageError::OutOfRange {
            field: Field::Reserved,
            ..
        }
    ));
    // Belonging to an axis, or a newer version while mandatory.
    let n_sections = u16::from_le_bytes([good[12], good[13]]);
    assert_eq!(
        refused(&|b| b[dir + 4] = AxisName::X.code()),
        ImageError::SectionBounds {
            index: n_sections - 1
        }
    );
    assert_eq!(
        refused(&|b| b[dir + 2] = 2),
        ImageError::UnsupportedSection { kind: 4 }
    );
    // Invalid settings are never written.
    let mut bad = SETTINGS;
    bad.lockout_us = 10;
    let mut buf = vec![0u8; good.len()];
    assert!(write_group_image_with_probe(&[], None, Some(&bad), &mut buf).is_err());
}

/// `Group::error_at` at the positions the axes stand at is exactly the correction the loop
/// applies there once the slew has settled (reference: `Group::cycle`'s `correction_um`, every
/// slot, bit for bit: the same table, thermo-force term and rotary-stage deviation in the same
/// order), with a thermal term live on X and the rotary stage on X, Y, Z.
#[test]
fn error_at_is_the_loops_correction() {
    let bytes = group_image(None);
    let mut g: Box<Group<512>> = Box::new(Group::new());
    g.load_image(&bytes).unwrap();
    let mut st = GroupState::new();
    let positions: [i64; MAX_AXES] = [1_234, 2_100, 3_333, 30_000, 21_000];
    let mut input = GroupInput::ZERO;
    for (a, &p) in input.axes.iter_mut().zip(positions.iter()) {
        a.scale_raw = (p as u32) & 0xFFFF;
        a.command_counts = p;
    }
    let mut out = GroupOutput::ZERO;
    for k in 0..400u32 {
        if k % 10 == 0 {
            g.update_temperatures(&mut st, 0, k * 10, &[23.0, 25.5]);
        }
        g.cycle(&mut st, &input, &mut out);
    }
    let mut ext = [0i64; MAX_AXES];
    for (i, e) in ext.iter_mut().enumerate() {
        *e = st.axes[i].position_counts();
    }
    // A and C are within the 16-bit counter's first half: the extended position is the raw one.
    let (err, limited) = g.error_at(&st, &ext);
    assert!(!limited);
    assert!(out.axes[0].correction_um.abs() > 1.0, "a real correction");
    for (i, (e, o)) in err.iter().zip(out.axes.iter()).enumerate() {
        assert_eq!(
            e.to_bits(),
            o.correction_um.to_bits(),
            "slot {i}: {e} vs {}",
            o.correction_um
        );
    }
}

proptest::proptest! {
    /// Any 20 bytes in the probe section (resealed, so only the values are wrong): the parser never
    /// panics and accepts exactly the settings `ProbeSettings::from_bytes` accepts, unchanged.
    #[test]
    fn any_probe_section_is_parsed_or_refused_never_half(payload in proptest::collection::vec(proptest::num::u8::ANY, PROBE_SECTION_LEN)) {
        let mut b = group_image(Some(&SETTINGS));
        let (_, off) = probe_section(&b);
        b[off..off + PROBE_SECTION_LEN].copy_from_slice(&payload);
        reseal(&mut b);
        match (group_image::parse(&b), ProbeSettings::from_bytes(&payload)) {
            (Ok(view), Ok(s)) => proptest::prop_assert_eq!(view.probe, Some(s)),
            (Err(e), Err(f)) => proptest::prop_assert_eq!(e, f),
            (got, want) => proptest::prop_assert!(false, "parse {:?} vs settings {:?}", got.map(|v| v.probe), want),
        }
    }
}
