//! The volumetric geometric stage in QEMU: the group firmware
//! (`axcomp-qemu-group`) and the host replay give byte-identical output records for a three-axis
//! trace that moves through the seed's seven laser lines (seed 000: line 1 along X, lines 2–3 the
//! XY face diagonals, lines 4–7 the body diagonals, the diagonals read step-wise: X step, reading,
//! Y step, reading, Z step, reading), with the lines extended 1 % beyond the model's volume at
//! their ends, 16-bit counters wrapping, an image whose geometric section is corrupt (refused by
//! its section CRC), an A/B swap to the same model with a 100 mm tool offset, and a swap to a
//! section converted by the host from a `fit rtest` model's `linear_geometry` (translational
//! components only, `axcomp_image::linear_geometry`).
//!
//! Reference: `axcomp_firmware::replay::replay_group` over `axcomp_core::group::GroupEngine` on the
//! host. Tolerance: none — every 32-byte output record must match bit for bit, and the record
//! count must be the group cycles times 3. The trace is checked to exercise the stage: against a
//! replay of the same motion without the geometric section, the commands differ in most cycles.

use axcomp_core::bench;
use axcomp_core::geometric::GeometricSpec;
use axcomp_core::group::GroupInput;
use axcomp_core::group_image::{
    self, AxisSectionSpec, DIR_ENTRY_LEN, GROUP_HEADER_LEN, write_group_image_with,
};
use axcomp_core::trace::{OUTPUT_RECORD_LEN, OutputRecord, Record};
use axcomp_firmware::scenario::{EQUIVALENCE_COUNTER_BITS, TraceBuilder};
use axcomp_system_tests::{build_qemu_firmware, host_group_replay, qemu_replay, require_tool};

/// Stroke of each axis and of the model's grids (`bench::group_geometric`), counts.
const STROKE: i64 = bench::GROUP_SEGMENT_COUNTS as i64 * bench::GROUP_SEGMENTS as i64;
/// Speed of a move, counts per cycle; dwell at a reading, cycles.
const SPEED: i64 = 2_500;
const DWELL: u32 = 10;
/// Targets per line.
const TARGETS: i64 = 10;

/// The `group3` workload's X, Y, Z images (16-bit counters).
fn axis_images() -> Vec<Vec<u8>> {
    (0..3)
        .map(|k| {
            let mut spec = bench::group_axis_spec(k);
            spec.counter_bits = EQUIVALENCE_COUNTER_BITS;
            let mut buf = vec![0u8; axcomp_core::image_len(&spec)];
            let n = axcomp_core::write_image(&spec, &mut buf).unwrap();
            buf.truncate(n);
            buf
        })
        .collect()
}

/// The group image: the `group3` workload axes and, if given, the geometric model.
fn image(geometric: Option<&GeometricSpec>) -> Vec<u8> {
    let images = axis_images();
    let axes: Vec<AxisSectionSpec> = (0..3)
        .map(|k| AxisSectionSpec {
            name: bench::group_axis(k).0,
            counts_per_rev: 0,
            stroke_counts: Some((0, STROKE)),
            image: &images[k],
            sensor_names: &[],
        })
        .collect();
    let mut out = vec![0u8; group_image::group_image_len_with(&axes, None, geometric)];
    let n = write_group_image_with(&axes, None, geometric, &mut out).unwrap();
    out.truncate(n);
    out
}

/// Commanded positions through the seven lines: straight moves between lines, step-wise moves
/// (one axis at a time) along the diagonals, a dwell at every reading.
fn path() -> Vec<[i64; 3]> {
    let l = STROKE;
    let ext = STROKE / 100;
    let lines: [([i64; 3], [i64; 3]); 7] = [
        ([-ext, 0, 0], [l + ext, 0, 0]),
        ([0, 0, 0], [l, l, 0]),
        ([0, l, 0], [l, 0, 0]),
        ([-ext, -ext, -ext], [l + ext, l + ext, l + ext]),
        ([l, 0, 0], [0, l, l]),
        ([0, l, 0], [l, 0, l]),
        ([l, l, 0], [0, 0, l]),
    ];
    let mut at = [0i64; 3];
    let mut out = Vec::new();
    let go = |out: &mut Vec<[i64; 3]>, at: &mut [i64; 3], to: [i64; 3], axes: &[usize]| {
        loop {
            let mut done = true;
            for &k in axes {
                let d = (to[k] - at[k]).clamp(-SPEED, SPEED);
                at[k] += d;
                done &= at[k] == to[k];
            }
            out.push(*at);
            if done {
                break;
            }
        }
        for _ in 0..DWELL {
            out.push(*at);
        }
    };
    for (start, end) in lines {
        go(&mut out, &mut at, start, &[0, 1, 2]);
        let stepwise = (0..3).filter(|&k| start[k] != end[k]).count() > 1;
        for s in 1..=TARGETS {
            let target: [i64; 3] =
                std::array::from_fn(|k| start[k] + (end[k] - start[k]) * s / TARGETS);
            if stepwise {
                for k in 0..3 {
                    if target[k] != at[k] {
                        go(&mut out, &mut at, target, &[k]);
                    }
                }
            } else {
                go(&mut out, &mut at, target, &[0, 1, 2]);
            }
        }
    }
    out
}

/// The trace: a few identity cycles, the image, the seven lines, a corrupt image (refused), the
/// swap to the model with a tool offset, the seven lines again, the swap to the converted linear
/// geometry, the seven lines a third time.
fn trace(first: &[u8], second: &[u8], corrupt: &[u8], third: &[u8]) -> (Vec<u8>, u32) {
    let p = path();
    let mut t = TraceBuilder::new();
    let mut cycles = 0u32;
    let mut cycle = |t: &mut TraceBuilder, q: [i64; 3], i: usize| {
        let mut input = GroupInput::ZERO;
        for (k, a) in input.axes.iter_mut().take(3).enumerate() {
            a.command_counts = q[k];
            // The scale lags the command by a few counts (moving) and wraps at 16 bits.
            a.scale_raw = (q[k] - ((i as i64 + k as i64) % 7) + 3) as u32 & 0xFFFF;
        }
        t.push(&Record::GroupCycle { n: 3, input });
        cycles += 1;
    };
    for i in 0..5 {
        cycle(&mut t, [0; 3], i);
    }
    t.push(&Record::Image(first));
    for (i, q) in p.iter().enumerate() {
        if i == p.len() / 2 {
            t.push(&Record::Image(corrupt));
        }
        cycle(&mut t, *q, i);
    }
    for image in [second, third] {
        t.push(&Record::Image(image));
        for (i, q) in p.iter().enumerate() {
            cycle(&mut t, *q, i);
        }
    }
    (t.finish(), cycles)
}

/// The images: the model, the model with a 100 mm tool offset, and the second with a bit
/// flipped inside its geometric section (whole-image CRC re-sealed: only the section CRC can
/// refuse it).
fn images() -> (Vec<u8>, Vec<u8>, Vec<u8>) {
    let geo = bench::group_geometric();
    let first = image(Some(&geo));
    let with_tool = GeometricSpec {
        tool_offset_um: [0.0, 30_000.0, -100_000.0],
        ..geo
    };
    let second = image(Some(&with_tool));
    let mut corrupt = second.clone();
    let dir = GROUP_HEADER_LEN + DIR_ENTRY_LEN * 3;
    assert_eq!(u16::from_le_bytes([corrupt[dir], corrupt[dir + 1]]), 2);
    let off = u32::from_le_bytes(corrupt[dir + 8..dir + 12].try_into().unwrap()) as usize;
    corrupt[off + 200] ^= 0x10;
    let body = corrupt.len() - 4;
    let crc = axcomp_core::crc32(&corrupt[..body]);
    corrupt[body..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(
        group_image::parse(&corrupt).unwrap_err(),
        axcomp_core::ImageError::SectionCrc { index: 3 }
    );
    (first, second, corrupt)
}

/// A group image whose geometric section is a `linear_geometry` effect (X, Y, Z each moving over
/// about 80 mm of the 100 mm stroke, 1–4 µm per Legendre degree along X, Y, Z) converted by the host
/// on the workload's grids (8 segments per axis), the pivot at mid-stroke.
fn linear_geometry_image() -> Vec<u8> {
    use axcomp_image::linear_geometry::{
        LinearAxisError, LinearGeometry, Placement, with_linear_geometry,
    };
    let axes: Vec<axcomp_image::group::GroupAxis> = axis_images()
        .into_iter()
        .enumerate()
        .map(|(k, image)| axcomp_image::group::GroupAxis {
            name: bench::group_axis(k).0,
            counts_per_rev: 0,
            image,
            given_as: format!("{k}"),
        })
        .collect();
    let lin = LinearGeometry {
        axes: (0..3)
            .map(|a| LinearAxisError {
                axis: a,
                range_mm: [-37.3 + a as f64, 41.9 - 2.0 * a as f64],
                legendre: vec![[3.0, -1.5, 1.0], [-2.0, 4.0, 0.5], [1.0, 0.7, -3.5]],
                identified: [true; 3],
            })
            .collect(),
        rms_over_fit_um: 0.0,
    };
    let geo = bench::group_geometric();
    let base = axcomp_image::GeometricSection {
        chain: geo.chain,
        work_axes: geo.work_axes,
        identified: 0,
        tool_offset_um: [0.0; 3],
        squareness_urad: [0.0; 3],
        grids: geo.grids,
        coefficients: vec![[0.0; 4]; geo.coefficients.len()],
    };
    let place = Placement {
        pivot_counts: [STROKE / 2; 3],
        tool_counts_z: 0,
    };
    let (section, _) = with_linear_geometry(&lin, &place, &axes, Some(base), "test").unwrap();
    image(Some(&section.spec()))
}

#[test]
fn geometric_stage_matches_host_bit_for_bit_through_the_seven_lines() {
    let (first, second, corrupt) = images();
    let third = linear_geometry_image();
    let (trace_bytes, cycles) = trace(&first, &second, &corrupt, &third);
    let (want, replayed, errors) = host_group_replay(&trace_bytes);
    assert_eq!((replayed, errors), (cycles, 0));
    assert_eq!(want.len(), cycles as usize * 3 * OUTPUT_RECORD_LEN);

    // The trace exercises the stage: without the geometric section the commands differ.
    let plain = image(None);
    let (plain_trace, _) = trace(&plain, &plain, &corrupt, &plain);
    let (without, _, _) = host_group_replay(&plain_trace);
    let records = |b: &[u8]| -> Vec<OutputRecord> {
        b.chunks(OUTPUT_RECORD_LEN)
            .map(|c| OutputRecord::decode(c).unwrap())
            .collect()
    };
    let (a, b) = (records(&want), records(&without));
    let differ = a
        .iter()
        .zip(&b)
        .filter(|(x, y)| x.corrected_command_counts != y.corrected_command_counts)
        .count();
    assert!(
        differ > a.len() / 2,
        "the geometric stage changes the commands in most records ({differ} of {})",
        a.len()
    );
    // The third pass (the converted linear geometry) too.
    let tail = path().len() * 3;
    let differ = a[a.len() - tail..]
        .iter()
        .zip(&b[b.len() - tail..])
        .filter(|(x, y)| x.corrected_command_counts != y.corrected_command_counts)
        .count();
    assert!(
        differ > tail / 2,
        "the linear geometry changes the commands in most records of its pass ({differ} of {tail})"
    );

    if !require_tool("qemu-system-arm") {
        return;
    }
    let elf = build_qemu_firmware("axcomp-qemu-group");
    let (status, stdout, got) = qemu_replay(&elf, "qemu-geometry", &trace_bytes);
    assert!(
        status.success(),
        "QEMU firmware failed ({status})\n{stdout}"
    );
    assert_eq!(
        got.len() % OUTPUT_RECORD_LEN,
        0,
        "QEMU output is whole records"
    );
    if let Some(k) = got
        .chunks(OUTPUT_RECORD_LEN)
        .zip(want.chunks(OUTPUT_RECORD_LEN))
        .position(|(x, y)| x != y)
    {
        let q = OutputRecord::decode(&got[k * OUTPUT_RECORD_LEN..]).unwrap();
        let h = OutputRecord::decode(&want[k * OUTPUT_RECORD_LEN..]).unwrap();
        panic!("first differing output record #{k}:\n  qemu: {q:?}\n  host: {h:?}");
    }
    assert_eq!(got.len(), want.len(), "record count (QEMU vs host)");
    let outputs = cycles as usize * 3;
    assert!(
        stdout.contains(&format!(
            "cycles={cycles} outputs={outputs} errors=0 images_accepted=3 images_rejected=1"
        )),
        "summary line: {stdout}"
    );
}
