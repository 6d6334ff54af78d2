//! The rotary-model section (group image kind 3): version 2 (machine kind, squareness,
//! not-identified flags) round trips for the three machine kinds; a version-1 section (the AC
//! trunnion's 8 constants, written by earlier builds) still loads as an AC trunnion without
//! squareness; typed refusals; re-sealed mutations of the section never panic and never load a
//! stage that computes a non-finite correction.

mod common;

use axcomp_core::group::{AxisName, Group, GroupInput, GroupOutput, GroupState};
use axcomp_core::group_image::{
    self, AxisSectionSpec, DIR_ENTRY_LEN, GROUP_HEADER_LEN, ROTARY_SECTION_LEN,
    ROTARY_SECTION_V1_LEN, ROTARY_SECTION_VERSION, write_group_image,
};
use axcomp_core::rotary::{RotaryLocationSpec, RotaryMachine};
use axcomp_core::*;
use common::*;
use proptest::prelude::*;

const CPR: u32 = 3_600_000;

const LIMITS: LimitSpec = LimitSpec {
    max_correction_um: 1.0e4,
    max_slew_um_per_cycle: 1.0e4,
    direction_hysteresis_counts: 0,
};

fn bare(um_per_count: f32) -> Vec<u8> {
    image(&ImageSpec {
        axis_id: 1,
        um_per_count,
        counter_bits: 32,
        table: None,
        thermo: None,
        limits: LIMITS,
    })
}

fn spec(machine: RotaryMachine) -> RotaryLocationSpec {
    RotaryLocationSpec {
        machine,
        ex0c_um: 11.0,
        ey0c_um: -6.0,
        ea0c_urad: 21.0,
        eb0c_urad: -13.0,
        ey0a_um: 0.0,
        ez0a_um: 9.0,
        eb0a_urad: 17.0,
        ec0a_urad: -8.0,
        squareness_urad: [14.0, -22.0, 30.0],
        pivot_counts: [10_000, -20_000, 30_000],
        tool_length_um: 150_000.0,
        // The first tilt-axis offset was not identified (held at 0).
        not_identified: 1 << 4,
        wobble: axcomp_core::rotary::RotaryWobble::NONE,
    }
}

/// X, Y, Z, `tilt`, C: the images and their section specs.
fn group_bytes(tilt: AxisName, rotary: &RotaryLocationSpec) -> Vec<u8> {
    let lin = bare(0.1);
    let rot = bare((1_296_000.0 / CPR as f64) as f32);
    let names = [AxisName::X, AxisName::Y, AxisName::Z, tilt, AxisName::C];
    let axes: Vec<AxisSectionSpec> = names
        .iter()
        .map(|&name| AxisSectionSpec {
            name,
            counts_per_rev: if name.is_rotary() { CPR } else { 0 },
            stroke_counts: None,
            image: if name.is_rotary() { &rot } else { &lin },
            sensor_names: &[],
        })
        .collect();
    let mut buf = vec![0u8; group_image::group_image_len(&axes, Some(rotary))];
    let n = write_group_image(&axes, Some(rotary), &mut buf).unwrap();
    buf.truncate(n);
    buf
}

/// Directory entry and bytes of the image's rotary section (the last one).
fn rotary_entry(b: &[u8]) -> (usize, usize, usize) {
    let n = u16::from_le_bytes([b[12], b[13]]) as usize;
    let at = GROUP_HEADER_LEN + DIR_ENTRY_LEN * (n - 1);
    assert_eq!(u16::from_le_bytes([b[at], b[at + 1]]), 3, "kind 3");
    let off = u32::from_le_bytes(b[at + 8..at + 12].try_into().unwrap()) as usize;
    let len = u32::from_le_bytes(b[at + 12..at + 16].try_into().unwrap()) as usize;
    (at, off, len)
}

/// Re-seal the rotary section's CRC and the whole-image CRC after an edit.
fn reseal(b: &mut [u8]) {
    let (at, off, len) = rotary_entry(b);
    let c = crc32(&b[off..off + len]);
    b[at + 16..at + 20].copy_from_slice(&c.to_le_bytes());
    let body = b.len() - 4;
    let c = crc32(&b[..body]);
    b[body..].copy_from_slice(&c.to_le_bytes());
}

fn err(b: &[u8]) -> ImageError {
    group_image::parse(b).unwrap_err()
}

/// Reference: the spec written; exact (the section stores the f32 values and integers as they
/// are).
#[test]
fn version_2_round_trips_for_every_machine_kind() {
    for (machine, tilt) in [
        (RotaryMachine::AcTrunnion, AxisName::A),
        (RotaryMachine::BcTrunnion, AxisName::B),
        (RotaryMachine::BcHead, AxisName::B),
    ] {
        let s = spec(machine);
        let b = group_bytes(tilt, &s);
        let (at, _, len) = rotary_entry(&b);
        assert_eq!(len, ROTARY_SECTION_LEN);
        assert_eq!(
            u16::from_le_bytes([b[at + 2], b[at + 3]]),
            ROTARY_SECTION_VERSION
        );
        let view = group_image::parse(&b).unwrap();
        assert_eq!(view.rotary, Some(s));
        let mut g: Box<Group<64>> = Box::new(Group::new());
        g.load_image(&b).unwrap();
        assert!(g.has_rotary_stage());
    }
    // An AC trunnion without squareness and flags is written as version 1 (older readers load it).
    let plain = RotaryLocationSpec {
        squareness_urad: [0.0; 3],
        not_identified: 0,
        wobble: axcomp_core::rotary::RotaryWobble::NONE,
        ..spec(RotaryMachine::AcTrunnion)
    };
    let b = group_bytes(AxisName::A, &plain);
    let (at, _, len) = rotary_entry(&b);
    assert_eq!(
        (len, u16::from_le_bytes([b[at + 2], b[at + 3]])),
        (ROTARY_SECTION_V1_LEN, 1)
    );
    assert_eq!(group_image::parse(&b).unwrap().rotary, Some(plain));
}

/// A version-1 section built byte by byte as the earlier builds wrote it (8 × f32, 3 × i64, f32,
/// reserved u32) loads as an AC trunnion without squareness. Reference: the values written.
#[test]
fn version_1_sections_still_load_as_ac_trunnion() {
    let v2 = RotaryLocationSpec {
        squareness_urad: [0.0; 3],
        not_identified: 0,
        wobble: axcomp_core::rotary::RotaryWobble::NONE,
        ..spec(RotaryMachine::AcTrunnion)
    };
    let mut b = group_bytes(AxisName::A, &v2);
    let (_, off, _) = rotary_entry(&b);
    let mut v1 = Vec::new();
    for x in [11.0f32, -6.0, 21.0, -13.0, 0.0, 9.0, 17.0, -8.0] {
        v1.extend_from_slice(&x.to_le_bytes());
    }
    for p in [10_000i64, -20_000, 30_000] {
        v1.extend_from_slice(&p.to_le_bytes());
    }
    v1.extend_from_slice(&150_000.0f32.to_le_bytes());
    v1.extend_from_slice(&0u32.to_le_bytes());
    assert_eq!(v1.len(), ROTARY_SECTION_V1_LEN);
    b[off..off + 64].copy_from_slice(&v1);
    reseal(&mut b);
    let r = group_image::parse(&b).unwrap().rotary.unwrap();
    assert_eq!(r.machine, RotaryMachine::AcTrunnion);
    assert_eq!(r.squareness_urad, [0.0; 3]);
    assert_eq!(r, v2);
}

#[test]
fn typed_refusals_of_the_rotary_section() {
    let good = group_bytes(AxisName::B, &spec(RotaryMachine::BcTrunnion));
    let (at, off, _) = rotary_entry(&good);
    let edit = |f: &dyn Fn(&mut Vec<u8>)| {
        let mut b = good.clone();
        f(&mut b);
        reseal(&mut b);
        err(&b)
    };
    // Unknown machine kind.
    assert_eq!(
        edit(&|b| b[off] = 9),
        ImageError::OutOfRange {
            field: Field::RotaryMachine,
            index: 0
        }
    );
    // Reserved byte, reserved trailing word.
    assert!(matches!(
        edit(&|b| b[off + 1] = 1),
        ImageError::OutOfRange {
            field: Field::Reserved,
            ..
        }
    ));
    assert!(matches!(
        edit(&|b| b[off + 76] = 1),
        ImageError::OutOfRange {
            field: Field::Reserved,
            ..
        }
    ));
    // A not-identified flag beyond the 11 constants; a flagged constant that is not 0.
    assert!(matches!(
        edit(&|b| b[off + 3] = 0x80),
        ImageError::OutOfRange {
            field: Field::Reserved,
            ..
        }
    ));
    assert_eq!(
        edit(&|b| b[off + 2] |= 1),
        ImageError::OutOfRange {
            field: Field::RotaryLocation,
            index: 0
        }
    );
    // A squareness term that is NaN, one beyond the first-order range.
    assert_eq!(
        edit(&|b| b[off + 36..off + 40].copy_from_slice(&f32::NAN.to_le_bytes())),
        ImageError::NonFinite {
            field: Field::RotaryLocation,
            index: 8
        }
    );
    assert_eq!(
        edit(&|b| b[off + 44..off + 48].copy_from_slice(&2.0e4f32.to_le_bytes())),
        ImageError::OutOfRange {
            field: Field::RotaryLocation,
            index: 10
        }
    );
    // Version 4 of a mandatory rotary section: not supported by this build.
    assert_eq!(
        edit(&|b| b[at + 2] = 4),
        ImageError::UnsupportedSection { kind: 3 }
    );
    // A version-3 directory entry (with a wobble: 256 bytes) over an 80-byte section.
    assert!(matches!(
        edit(&|b| b[at + 2] = 3),
        ImageError::SectionBounds { .. }
    ));
    // A version-1 directory entry over an 80-byte section.
    assert!(matches!(
        edit(&|b| b[at + 2] = 1),
        ImageError::SectionBounds { .. }
    ));
    // A BC model in a group whose tilt axis is A: its B axis is not in the group.
    let ac_group = group_bytes(AxisName::A, &spec(RotaryMachine::AcTrunnion));
    let mut b = ac_group.clone();
    let (_, off_a, _) = rotary_entry(&b);
    b[off_a] = RotaryMachine::BcTrunnion.code();
    reseal(&mut b);
    assert_eq!(
        err(&b),
        ImageError::AxisNotInGroup {
            axis: AxisName::B.code()
        }
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    /// Re-sealed edits of the rotary section (so that the section's own checks, not the CRCs, must
    /// catch them) never panic; an accepted section gives a stage whose corrections are finite.
    #[test]
    fn resealed_rotary_mutations_never_panic(
        edits in proptest::collection::vec((0usize..80, any::<u8>()), 1..5),
        machine in 1u8..=3,
        cmd in proptest::collection::vec(-4_000_000i64..4_000_000, 5),
    ) {
        let m = RotaryMachine::from_code(machine).unwrap();
        let tilt = m.tilt_axis();
        let mut b = group_bytes(tilt, &spec(m));
        let (_, off, len) = rotary_entry(&b);
        for (at, v) in edits {
            b[off + at % len] = v;
        }
        reseal(&mut b);
        if group_image::parse(&b).is_ok() {
            let mut g: Box<Group<64>> = Box::new(Group::new());
            prop_assert!(g.load_image(&b).is_ok());
            let mut st = Box::new(GroupState::new());
            let mut input = GroupInput::ZERO;
            for (axis, &c) in input.axes.iter_mut().zip(cmd.iter()) {
                axis.command_counts = c;
                axis.scale_raw = c as u32;
            }
            let mut out = GroupOutput::ZERO;
            g.cycle(&mut st, &input, &mut out);
            for k in 0..3 {
                prop_assert!(out.axes[k].correction_um.is_finite());
            }
        }
    }
}
