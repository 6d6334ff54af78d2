//! Image slots: the largest five-axis image fits one flash slot, and an image is cut out of a
//! slot (image, then erased flash) by the length its header declares.
mod common;
use axcomp_core::geometric::{GeometricCoefficients, GeometricGrid, GeometricSpec};
use axcomp_core::group::{AxisName, Group};
use axcomp_core::group_image::{
    AxisSectionSpec, GEOMETRIC_HEADER_LEN, group_image_len, group_image_len_with, parse,
    write_group_image_with,
};
use axcomp_core::rotary::RotaryLocationSpec;
use axcomp_core::*;
use common::*;

/// Segments per direction of the largest linear tables of the required five-axis image.
const LINEAR_SEGMENTS: usize = 512;
/// Geometric functions and their segments (the required capacity: 18 functions × 128 segments).
const GEOMETRIC_FUNCTIONS: usize = 18;
const GEOMETRIC_SEGMENTS: usize = 128;
/// Bytes per segment of one function: 4 f32 coefficients, as the axis tables.
const SEGMENT_BYTES: usize = 16;
const CPR: u32 = 512 * 7200;

fn table(n: usize, off: f32) -> Vec<[f32; 4]> {
    (0..n)
        .map(|s| [off + s as f32 * 1e-3, 1e-3, 0.0, 0.0])
        .collect()
}

/// The largest five-axis image required: X, Y, Z with bidirectional 512-segment tables and a
/// full thermo-force term (16 sensors with names, expansion, 3 forces); A and C with a
/// 512-segment table over the turn and 16 sensors too (more than required); the rotary
/// model; and an 18 × 128-segment geometric model (section kind 2). Every section is
/// written, parsed and loaded for real.
#[test]
fn largest_five_axis_image_fits_one_slot() {
    let fwd = table(LINEAR_SEGMENTS, 0.0);
    let bwd = table(LINEAR_SEGMENTS, 1.0);
    let sensors: Vec<SensorSpec> = (0..MAX_SENSORS).map(|i| sensor(20.0, i as f32)).collect();
    let b = vec![0.1f32; MAX_SENSORS];
    let forces = [ForceSpec {
        chi_um_per_n: 0.001,
        law: None,
    }; 3];
    let thermo = ThermoForceSpec {
        sensor_period_ms: 100,
        sensors: &sensors,
        b0_um: 0.0,
        b_um_per_k: &b,
        expansion: Some(ExpansionSpec {
            sensor: 0,
            x_ref_counts: 0,
            c_um_per_mm_k: 0.0115,
        }),
        forces: &forces,
        reference: ThermoReference::Fixed,
        rise_bounds_k: &[],
    };
    let linear = |id: u16| {
        let mut s = table_spec(
            TableSpec {
                start_counts: 0,
                segment_counts: 1000,
                forward: &fwd,
                backward: &bwd,
                outside: OutsideStroke::Hold,
            },
            LOOSE,
        );
        s.axis_id = id;
        s.thermo = Some(thermo);
        image(&s)
    };
    let rotary = |id: u16| {
        let mut s = table_spec(
            TableSpec {
                start_counts: 0,
                segment_counts: CPR / LINEAR_SEGMENTS as u32,
                forward: &fwd,
                backward: &[],
                outside: OutsideStroke::Hold,
            },
            LOOSE,
        );
        s.axis_id = id;
        s.um_per_count = 1_296_000.0 / CPR as f32;
        s.thermo = Some(thermo);
        image(&s)
    };
    let images = [linear(1), linear(2), linear(3), rotary(4), rotary(6)];
    let names_owned: Vec<String> = (0..MAX_SENSORS).map(|i| format!("sensor {i:02}")).collect();
    let names: Vec<&str> = names_owned.iter().map(String::as_str).collect();
    let axes: Vec<AxisSectionSpec> = [
        (AxisName::X, 0),
        (AxisName::Y, 0),
        (AxisName::Z, 0),
        (AxisName::A, CPR),
        (AxisName::C, CPR),
    ]
    .iter()
    .zip(images.iter())
    .map(|(&(name, counts_per_rev), img)| AxisSectionSpec {
        name,
        counts_per_rev,
        stroke_counts: None,
        image: img,
        sensor_names: &names,
    })
    .collect();
    let stage = RotaryLocationSpec {
        ex0c_um: 1.0,
        ey0c_um: 1.0,
        ea0c_urad: 1.0,
        eb0c_urad: 1.0,
        ey0a_um: 1.0,
        ez0a_um: 1.0,
        eb0a_urad: 1.0,
        ec0a_urad: 1.0,
        pivot_counts: [0; 3],
        tool_length_um: 0.0,
        // The largest rotary section: version 2 (machine kind, squareness).
        squareness_urad: [1.0; 3],
        ..RotaryLocationSpec::ZERO_AC
    };
    // The geometric model over the linear tables' stroke (512 × 1000 counts): 128 segments of
    // 4000 counts per axis, small smooth values.
    let geo_coef: Vec<[f32; 4]> = (0..3 * GEOMETRIC_SEGMENTS * 6)
        .map(|i| [(i % 7) as f32 * 0.1, 0.01, -0.002, 0.0005])
        .collect();
    assert_eq!(geo_coef.len(), GEOMETRIC_FUNCTIONS * GEOMETRIC_SEGMENTS);
    let geo = GeometricSpec {
        chain: [0, 1, 2],
        work_axes: 2,
        identified: (1 << 21) - 1,
        tool_offset_um: [0.0, 0.0, 100_000.0],
        squareness_urad: [20.0, -15.0, 30.0],
        grids: [GeometricGrid {
            start_counts: 0,
            segment_counts: 4000,
            n_segments: GEOMETRIC_SEGMENTS as u32,
        }; 3],
        coefficients: GeometricCoefficients::Values(&geo_coef),
    };
    let without = group_image_len(&axes, Some(&stage));
    let largest = group_image_len_with(&axes, Some(&stage), Some(&geo));
    let geometric = largest - without;
    assert!(
        geometric > GEOMETRIC_FUNCTIONS * GEOMETRIC_SEGMENTS * SEGMENT_BYTES + GEOMETRIC_HEADER_LEN,
        "the section holds every function and segment (and its directory entry)"
    );
    eprintln!("largest five-axis image: {largest} B ({without} B + {geometric} B geometric)");
    // The slot size comes from the same constant as the memory map's (`memory.x`: 128K slots).
    assert_eq!(IMAGE_SLOT_LEN, 128 * 1024);
    assert!(
        largest <= IMAGE_SLOT_LEN,
        "largest five-axis image {largest} B > slot {IMAGE_SLOT_LEN} B"
    );
    assert!(
        largest > 64 * 1024,
        "{largest} B: the old 64 KiB slots were too small"
    );
    // It is a real image: it parses and loads as a group (pool: 4096 table segments and 14
    // folded geometric functions × 128 segments).
    let mut buf = vec![0u8; IMAGE_SLOT_LEN];
    let n = write_group_image_with(&axes, Some(&stage), Some(&geo), &mut buf).unwrap();
    assert_eq!(n, largest);
    let view = parse(&buf[..n]).unwrap();
    assert_eq!(view.axis_count(), 5);
    assert!(view.geometric.is_some());
    let mut g = Box::new(Group::<{ 4096 + 14 * GEOMETRIC_SEGMENTS }>::new());
    g.load_image(&buf[..n]).unwrap();
    assert!(g.has_rotary_stage() && g.has_geometric_stage());
    // In the slot, followed by erased flash: cut by its declared length.
    buf[n..].fill(0xFF);
    assert_eq!(declared_image_len(&buf), Ok(n));
}

/// A schema-1 image in a slot of erased flash: the declared length cuts it exactly; the
/// single-axis loader refuses the trailing bytes and takes the cut image.
#[test]
fn single_axis_image_cut_from_slot_by_declared_length() {
    let fwd = table(64, 0.0);
    let spec = table_spec(
        TableSpec {
            start_counts: 0,
            segment_counts: 100,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        },
        LOOSE,
    );
    let img = image(&spec);
    let mut slot = vec![0xFFu8; IMAGE_SLOT_LEN];
    slot[..img.len()].copy_from_slice(&img);
    assert_eq!(declared_image_len(&slot), Ok(img.len()));
    let mut c = Box::new(Compensator::IDENTITY);
    assert_eq!(c.load(&slot), Err(ImageError::TrailingBytes));
    assert!(
        !c.is_loaded(),
        "a refused image leaves the compensator untouched"
    );
    c.load(&slot[..img.len()]).unwrap();
    assert!(c.is_loaded());
    // Erased flash, a short slot, a length beyond the slot: typed errors.
    assert_eq!(declared_image_len(&[0xFF; 64]), Err(ImageError::BadMagic));
    assert_eq!(declared_image_len(&img[..8]), Err(ImageError::TooShort));
    assert_eq!(
        declared_image_len(&img[..img.len() - 1]),
        Err(ImageError::TooShort)
    );
    let mut big = img.clone();
    big[8..12].copy_from_slice(&((IMAGE_SLOT_LEN + 1) as u32).to_le_bytes());
    assert_eq!(declared_image_len(&big), Err(ImageError::BadLength));
}
