//! Provenance in images: the schema-1 header extension (`PROV`, `SNAM`) and the
//! group image's provenance section (kind 6). An image with them corrects exactly as the same image
//! without them; their framing and CRCs are validated; a damaged block is refused.

mod common;

use axcomp_core::group::{AxisName, GroupEngine};
use axcomp_core::group_image::{self, AxisSectionSpec, DIR_ENTRY_LEN, GROUP_HEADER_LEN};
use axcomp_core::provenance::{
    self, PROVENANCE_TAG, ProvenanceRecord, ProvenanceView, SENSOR_NAMES_TAG, role,
};
use axcomp_core::*;
use common::*;

fn thermal_image(axis_id: u16) -> Vec<u8> {
    let fwd = [[1.0f32, 0.5, 0.0, 0.0]; 8];
    let sens = [sensor(20.0, 0.0), sensor(20.0, 30.0)];
    image(&ImageSpec {
        axis_id,
        um_per_count: 0.1,
        counter_bits: 16,
        table: Some(TableSpec {
            start_counts: -4000,
            segment_counts: 1000,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        }),
        thermo: Some(ThermoForceSpec {
            sensor_period_ms: 100,
            sensors: &sens,
            b0_um: 0.25,
            b_um_per_k: &[0.5, -0.3],
            expansion: None,
            forces: &[],
            reference: ThermoReference::Fixed,
            rise_bounds_k: &[],
        }),
        limits: LOOSE,
    })
}

fn records() -> [ProvenanceRecord; 2] {
    [
        ProvenanceRecord {
            axis: provenance::ANY_AXIS,
            role: role::POSITIONING_TABLE,
            model_sha256: [0xAB; 32],
            data_sha256: [0x12; 32],
        },
        ProvenanceRecord {
            axis: provenance::ANY_AXIS,
            role: role::THERMAL_MODEL,
            model_sha256: [0xCD; 32],
            data_sha256: [0; 32],
        },
    ]
}

fn block(recs: &[ProvenanceRecord]) -> Vec<u8> {
    let mut b = vec![0u8; provenance::provenance_len(recs.len())];
    let n = provenance::write_provenance("axcomp 0.1.0", "2026-11-24T05:30:00Z", recs, &mut b)
        .expect("valid block");
    assert_eq!(n, b.len());
    b
}

fn names(list: &[&str]) -> Vec<u8> {
    let mut v = vec![0u8; 16 * list.len()];
    for (i, n) in list.iter().enumerate() {
        v[16 * i..16 * i + n.len()].copy_from_slice(n.as_bytes());
    }
    v
}

fn extended(img: &[u8], blocks: &[([u8; 4], &[u8])]) -> Vec<u8> {
    let mut out = vec![0u8; img.len() + provenance::extension_len(blocks)];
    let n = provenance::with_header_extension(img, blocks, &mut out).expect("extension");
    assert_eq!(n, out.len());
    out
}

/// The schema-1 image with `PROV` and `SNAM` blocks: valid for every reader, the same correction bit
/// for bit as without them (2 000 cycles over the stroke with temperatures), and its names and
/// provenance read back.
#[test]
fn schema1_extension_loads_and_corrects_exactly_as_without() {
    let plain = thermal_image(1);
    let prov = block(&records());
    let nm = names(&["rtd0", "warmup"]);
    let ext = extended(&plain, &[(PROVENANCE_TAG, &prov), (SENSOR_NAMES_TAG, &nm)]);
    assert_eq!(ext.len(), plain.len() + 8 + prov.len() + 8 + nm.len());
    let (a, b) = (inspect_image(&plain).unwrap(), inspect_image(&ext).unwrap());
    assert_eq!(
        (a.axis_id, a.n_segments, a.n_sensors),
        (b.axis_id, b.n_segments, b.n_sensors)
    );
    let mut ca = Box::new(Compensator::IDENTITY);
    let mut cb = Box::new(Compensator::IDENTITY);
    ca.load(&plain).unwrap();
    cb.load(&ext).unwrap();
    let (mut sa, mut sb) = (State::new(), State::new());
    for k in 0..2000u32 {
        let now = k * 100;
        let t = [20.0 + k as f32 * 0.001, 22.0];
        ca.update_temperatures(&mut sa, now, &t);
        cb.update_temperatures(&mut sb, now, &t);
        let inp = input((k * 7) % 9000, (k as i64 * 7) % 9000 - 4000);
        let (oa, ob) = (ca.cycle(&mut sa, &inp), cb.cycle(&mut sb, &inp));
        assert_eq!(oa.correction_counts, ob.correction_counts, "cycle {k}");
        assert_eq!(
            oa.correction_um.to_bits(),
            ob.correction_um.to_bits(),
            "cycle {k}"
        );
    }
    let view = group_image::parse(&ext).unwrap();
    let axis = view.axes().next().unwrap();
    assert_eq!(axis.sensor_name(0), Some("rtd0"));
    assert_eq!(axis.sensor_name(1), Some("warmup"));
    let p = view.provenance.expect("provenance");
    assert_eq!(p.tool(), "axcomp 0.1.0");
    assert_eq!(p.built_utc(), "2026-11-24T05:30:00Z");
    assert_eq!(p.records().collect::<Vec<_>>(), records().to_vec());
    // Without an extension: no names, no provenance (older images).
    let view = group_image::parse(&plain).unwrap();
    assert!(view.provenance.is_none());
    assert_eq!(view.axes().next().unwrap().sensor_name(0), None);
}

/// Damaged extensions are refused: a block length past the extension, the wrong number of names, a
/// provenance block with a bad date; an unknown tag is skipped.
#[test]
fn damaged_extensions_are_refused_and_unknown_blocks_skipped() {
    let plain = thermal_image(2);
    let prov = block(&records());
    // One name for two sensors.
    let one = names(&["rtd0"]);
    let mut out = vec![0u8; plain.len() + provenance::extension_len(&[(SENSOR_NAMES_TAG, &one)])];
    assert_eq!(
        provenance::with_header_extension(&plain, &[(SENSOR_NAMES_TAG, &one)], &mut out),
        Err(ImageError::SensorNames { axis: 0 })
    );
    assert!(out.iter().all(|&b| b == 0), "nothing half-written");
    // A bad date inside the block (written by hand: the writer refuses it).
    let mut bad = prov.clone();
    bad[28] = b'x';
    let mut out = vec![0u8; plain.len() + provenance::extension_len(&[(PROVENANCE_TAG, &bad)])];
    assert_eq!(
        provenance::with_header_extension(&plain, &[(PROVENANCE_TAG, &bad)], &mut out),
        Err(ImageError::Provenance)
    );
    // An unknown tag is skipped.
    let other = [1u8, 2, 3, 4];
    let ext = extended(&plain, &[(*b"ZZZZ", &other), (PROVENANCE_TAG, &prov)]);
    assert!(group_image::parse(&ext).unwrap().provenance.is_some());
    // A block length that runs past the extension: the image's CRC is re-computed so only the framing
    // is wrong.
    let mut broken = ext.clone();
    let at = image::HEADER_LEN + 4;
    broken[at..at + 4].copy_from_slice(&400u32.to_le_bytes());
    let body = broken.len() - 4;
    let crc = crc32(&broken[..body]);
    broken[body..].copy_from_slice(&crc.to_le_bytes());
    assert!(inspect_image(&broken).is_ok(), "older readers ignore it");
    assert_eq!(group_image::parse(&broken), Err(ImageError::Provenance));
    // The writer refuses an over-long tool name and a malformed date.
    let mut b = vec![0u8; provenance::provenance_len(0)];
    assert_eq!(
        provenance::write_provenance(&"x".repeat(25), "2026-11-24T05:30:00Z", &[], &mut b),
        Err(ImageError::Provenance)
    );
    assert_eq!(
        provenance::write_provenance("axcomp", "2026-11-24 05:30:00", &[], &mut b),
        Err(ImageError::Provenance)
    );
}

fn group_with_provenance() -> (Vec<u8>, Vec<u8>) {
    let x = thermal_image(1);
    let y = thermal_image(2);
    let axes = [
        AxisSectionSpec {
            name: AxisName::X,
            counts_per_rev: 0,
            stroke_counts: None,
            image: &x,
            sensor_names: &["rtd0", "rtd1"],
        },
        AxisSectionSpec {
            name: AxisName::Y,
            counts_per_rev: 0,
            stroke_counts: None,
            image: &y,
            sensor_names: &[],
        },
    ];
    let mut plain = vec![0u8; group_image::group_image_len(&axes, None)];
    group_image::write_group_image(&axes, None, &mut plain).unwrap();
    let mut recs = records();
    recs[0].axis = AxisName::X.code();
    recs[1].axis = AxisName::Y.code();
    let prov = block(&recs);
    let mut out = vec![0u8; plain.len() + DIR_ENTRY_LEN + prov.len()];
    let n = provenance::with_group_section(
        &plain,
        group_image::SectionKind::Provenance as u16,
        group_image::NO_AXIS,
        0,
        &prov,
        &mut out,
    )
    .expect("section added");
    assert_eq!(n, out.len());
    (plain, out)
}

/// The group image with a provenance section: parsed with it, loaded by the group engine, and every
/// cycle equal to the same group without it.
#[test]
fn group_provenance_section_is_read_and_does_not_change_the_correction() {
    let (plain, with) = group_with_provenance();
    let view = group_image::parse(&with).unwrap();
    let p = view.provenance.expect("provenance section");
    let recs: Vec<_> = p.records().collect();
    assert_eq!(recs.len(), 2);
    assert_eq!(
        (recs[0].axis, recs[0].role, recs[0].model_sha256),
        (0, role::POSITIONING_TABLE, [0xAB; 32])
    );
    assert_eq!(recs[1].data_sha256, [0; 32]);
    assert_eq!(view.axes().next().unwrap().sensor_name(1), Some("rtd1"));
    // Written optional (flags 0): a reader that does not know kind 6 skips it.
    let n = u16_at(&with, 12) as usize;
    let last = GROUP_HEADER_LEN + DIR_ENTRY_LEN * (n - 1);
    assert_eq!((u16_at(&with, last), with[last + 5]), (6, 0));
    let mut ea: Box<GroupEngine<64>> = Box::new(GroupEngine::new());
    let mut eb: Box<GroupEngine<64>> = Box::new(GroupEngine::new());
    ea.load_image(&plain).unwrap();
    eb.load_image(&with).unwrap();
    assert!(format!("{:?}", ea.active()) == format!("{:?}", eb.active()));
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

/// Every single bit flip inside the provenance section is refused (section CRC or image CRC), and a
/// malformed block with correct CRCs is refused by its framing; a second provenance section too.
#[test]
fn damaged_provenance_sections_are_refused() {
    let (_, with) = group_with_provenance();
    let n = u16_at(&with, 12) as usize;
    let entry = GROUP_HEADER_LEN + DIR_ENTRY_LEN * (n - 1);
    let off = u32::from_le_bytes(with[entry + 8..entry + 12].try_into().unwrap()) as usize;
    let len = u32::from_le_bytes(with[entry + 12..entry + 16].try_into().unwrap()) as usize;
    for byte in off..off + len {
        for bit in 0..8 {
            let mut b = with.clone();
            b[byte] ^= 1 << bit;
            assert!(group_image::parse(&b).is_err(), "byte {byte} bit {bit}");
        }
    }
    // A malformed block with every CRC re-computed: record reserved byte set.
    let mut b = with.clone();
    b[off + provenance::PROVENANCE_HEADER_LEN + 2] = 1;
    let crc = crc32(&b[off..off + len]);
    b[entry + 16..entry + 20].copy_from_slice(&crc.to_le_bytes());
    let body = b.len() - 4;
    let crc = crc32(&b[..body]);
    b[body..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(group_image::parse(&b), Err(ImageError::Provenance));
    // A second provenance section.
    let prov = &with[off..off + len];
    let mut out = vec![0u8; with.len() + DIR_ENTRY_LEN + len];
    assert!(
        provenance::with_group_section(&with, 6, group_image::NO_AXIS, 0, prov, &mut out).is_err()
    );
    assert!(out.iter().all(|&x| x == 0), "nothing half-written");
    // The view of a valid block reads what was written.
    let v = ProvenanceView::parse(prov).unwrap();
    assert_eq!(v.len(), 2);
}
