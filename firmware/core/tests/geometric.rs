//! The volumetric geometric stage: the core's f32 stage against an f64
//! reference of the small-angle rigid-body model (every stacking, with tool offsets, beyond the
//! grid), the group cycle subtracting it from X, Y, Z, the image section's round trip and its
//! typed refusals.

mod common;

use axcomp_core::geometric::{GeometricCoefficients, GeometricError, GeometricGrid, GeometricSpec};
use axcomp_core::group::{AxisName, Group, GroupAxisImage, GroupInput, GroupOutput, GroupState};
use axcomp_core::group_image::{
    self, AxisSectionSpec, DIR_ENTRY_LEN, GEOMETRIC_HEADER_LEN, GROUP_HEADER_LEN,
    write_group_image_with,
};
use axcomp_core::*;
use common::*;

/// Grids of X, Y, Z: (start, segment, segments), µm per count 0.1 (X: −100 .. 700 mm, Y: 0 ..
/// 500 mm, Z: −400 .. 0 mm).
const GRIDS: [(i64, u32, u32); 3] = [
    (-1_000_000, 1_000_000, 8),
    (0, 625_000, 8),
    (-4_000_000, 500_000, 8),
];
const UPC: f32 = 0.1;

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn sym(&mut self, a: f64) -> f64 {
        a * (2.0 * self.next() - 1.0)
    }
}

/// Random smooth-ish functions: linear ±10 µm, angular ±30 µrad, continuous across knots.
fn random_coefficients(rng: &mut Lcg) -> Vec<[f32; 4]> {
    let mut out = Vec::new();
    for g in GRIDS {
        let mut start = [0.0f64; 6];
        let mut per_segment = vec![[[0.0f32; 4]; 6]; g.2 as usize];
        for f in 0..6 {
            let amp = if f < 3 { 10.0 } else { 30.0 };
            for seg in per_segment.iter_mut() {
                let c1 = rng.sym(amp / 4.0);
                let c2 = rng.sym(amp / 8.0);
                let c3 = rng.sym(amp / 16.0);
                seg[f] = [start[f] as f32, c1 as f32, c2 as f32, c3 as f32];
                start[f] = (start[f] + c1 + c2 + c3).clamp(-amp, amp);
            }
        }
        for seg in per_segment {
            out.extend_from_slice(&seg);
        }
    }
    out
}

fn spec<'a>(coef: &'a [[f32; 4]], chain: [u8; 3], work: u8, tool: [f32; 3]) -> GeometricSpec<'a> {
    GeometricSpec {
        chain,
        work_axes: work,
        identified: (1 << 21) - 1,
        tool_offset_um: tool,
        squareness_urad: [32.0, -21.0, 45.0],
        grids: GRIDS.map(|(s, seg, n)| GeometricGrid {
            start_counts: s,
            segment_counts: seg,
            n_segments: n,
        }),
        coefficients: GeometricCoefficients::Values(coef),
    }
}

/// f64 reference: e = Σ δ_k + Σ ε_k × arm_k + (−y·EC0Y + z·EB0Z, −z·EA0Z, 0) with arm_k = t +
/// Σ_{j after k in the chain} q_j e_j (the `axcomp-kinematics` linearised model, written out
/// independently in the original frame); beyond an axis's grid its position is clamped to it.
fn reference_um(s: &GeometricSpec, cmd: [i64; 3]) -> [f64; 3] {
    // Beyond a grid the model is evaluated at the nearest point of its volume.
    let q: [f64; 3] = core::array::from_fn(|k| {
        let g = s.grids[k];
        let end = g.start_counts + g.segment_counts as i64 * g.n_segments as i64;
        cmd[k].clamp(g.start_counts, end) as f64 * UPC as f64
    });
    let mut v = [[0.0f64; 6]; 3];
    for k in 0..3 {
        let g = s.grids[k];
        let x = (cmd[k] - g.start_counts) as f64 / g.segment_counts as f64;
        let x = x.clamp(0.0, g.n_segments as f64);
        let seg = (x.floor() as u32).min(g.n_segments - 1);
        let t = x - seg as f64;
        for (f, vf) in v[k].iter_mut().enumerate() {
            let c = s.segment(k, seg as usize, f).map(|c| c as f64);
            *vf = c[0] + t * (c[1] + t * (c[2] + t * c[3]));
        }
    }
    let tool = s.tool_offset_um.map(|t| t as f64);
    let mut e = [0.0f64; 3];
    for (pos, &a) in s.chain.iter().enumerate() {
        let a = a as usize;
        let mut arm = tool;
        for &b in &s.chain[pos + 1..] {
            arm[b as usize] += q[b as usize];
        }
        let d = [v[a][0], v[a][1], v[a][2]];
        let w = [v[a][3] * 1e-6, v[a][4] * 1e-6, v[a][5] * 1e-6];
        let cross = [
            w[1] * arm[2] - w[2] * arm[1],
            w[2] * arm[0] - w[0] * arm[2],
            w[0] * arm[1] - w[1] * arm[0],
        ];
        for i in 0..3 {
            e[i] += d[i] + cross[i];
        }
    }
    let [c0y, b0z, a0z] = s.squareness_urad.map(|v| v as f64 * 1e-6);
    e[0] += -q[1] * c0y + q[2] * b0z;
    e[1] += -q[2] * a0z;
    e
}

/// Axis images with zero tables over the model's grids and loose limits (the group output is
/// then the stage's correction alone).
fn axis_images() -> Vec<Vec<u8>> {
    (0..3)
        .map(|k| {
            let (start, seg, n) = GRIDS[k];
            let zeros = vec![[0.0f32; 4]; n as usize];
            let mut s = table_spec(
                TableSpec {
                    start_counts: start,
                    segment_counts: seg,
                    forward: &zeros,
                    backward: &[],
                    outside: OutsideStroke::Hold,
                },
                LOOSE,
            );
            s.axis_id = k as u16 + 1;
            s.um_per_count = UPC;
            image(&s)
        })
        .collect()
}

fn group_axes(images: &[Vec<u8>], order: [AxisName; 3]) -> Vec<GroupAxisImage<'_>> {
    order
        .iter()
        .map(|&name| GroupAxisImage {
            name,
            counts_per_rev: 0,
            image: &images[name.code() as usize],
        })
        .collect()
}

const CHAINS: [([u8; 3], u8); 6] = [
    ([0, 1, 2], 2), // YX / Z
    ([0, 2, 1], 1), // X / ZY
    ([1, 0, 2], 0), // / YXZ
    ([1, 2, 0], 3), // XZY /
    ([2, 0, 1], 1), // Z / XY
    ([2, 1, 0], 2), // YZ / X
];

/// Reference: `reference_um` (f64). Tolerance 0.002 µm: f32 rounding of positions up to 700 mm
/// times angles ≤ 30 µrad (≈ 1e-6 µm), of values ≤ 60 µm (≈ 1e-5 µm), and of the coefficients
/// folded at load (tool offset ≤ 250 mm × 30 µrad, squareness ≤ 45 µrad × 700 mm: ≤ 1e-4 µm);
/// observed 4e-6 µm. Positions cover each grid and 10 % beyond both ends (held values).
#[test]
fn stage_matches_f64_model_for_every_stacking() {
    let mut rng = Lcg(0x5eed_0010);
    let images = axis_images();
    let mut worst = 0.0f64;
    for (case, (chain, work)) in CHAINS.iter().enumerate() {
        let coef = random_coefficients(&mut rng);
        for tool in [[0.0f32; 3], [50_000.0, -80_000.0, 250_000.0]] {
            let s = spec(&coef, *chain, *work, tool);
            s.validate().unwrap();
            // Slot order differs from the axis order in every other case.
            let order = if case % 2 == 0 {
                [AxisName::X, AxisName::Y, AxisName::Z]
            } else {
                [AxisName::Z, AxisName::X, AxisName::Y]
            };
            let mut g = Box::new(Group::<256>::new());
            g.load_stages(&group_axes(&images, order), None, Some(&s))
                .unwrap();
            assert!(g.has_geometric_stage());
            for _ in 0..400 {
                let cmd: [i64; 3] = core::array::from_fn(|k| {
                    let (start, seg, n) = GRIDS[k];
                    let span = seg as f64 * n as f64;
                    start + (span * (1.2 * rng.next() - 0.1)) as i64
                });
                let got = g.geometric_error_um(cmd).unwrap();
                let want = reference_um(&s, cmd);
                for d in 0..3 {
                    let diff = (got[d] as f64 - want[d]).abs();
                    worst = worst.max(diff);
                    assert!(
                        diff <= 0.002,
                        "chain {chain:?} tool {tool:?} at {cmd:?}: axis {d}: core {} reference {}",
                        got[d],
                        want[d]
                    );
                }
            }
        }
    }
    eprintln!("largest |core − f64 reference|: {worst:.2e} µm");
}

/// The group subtracts the stage's error from X, Y, Z (zero axis tables, loose limits): the
/// corrected command is the command minus round(e / µm per count), `correction_um` = e.
#[test]
fn group_cycle_subtracts_the_model_error() {
    let mut rng = Lcg(7);
    let coef = random_coefficients(&mut rng);
    let s = spec(&coef, [0, 1, 2], 2, [0.0, 0.0, 120_000.0]);
    let images = axis_images();
    let order = [AxisName::Y, AxisName::Z, AxisName::X];
    let mut g = Box::new(Group::<256>::new());
    g.load_stages(&group_axes(&images, order), None, Some(&s))
        .unwrap();
    let mut st = GroupState::new();
    let mut moved = 0;
    for i in 0..200 {
        let cmd = [
            -900_000 + i * 31_000,
            5_000 + i * 23_000,
            -3_900_000 + i * 17_000,
        ];
        let mut input = GroupInput::ZERO;
        for (slot, name) in order.iter().enumerate() {
            let c = cmd[name.code() as usize];
            input.axes[slot].command_counts = c;
            input.axes[slot].scale_raw = c as u32;
        }
        let mut out = GroupOutput::ZERO;
        g.cycle(&mut st, &input, &mut out);
        let e = g.geometric_error_um(cmd).unwrap();
        for (slot, name) in order.iter().enumerate() {
            let k = name.code() as usize;
            let o = out.axes[slot];
            assert_eq!(o.correction_um, e[k], "cycle {i} axis {}", name.letter());
            let counts = round_to_counts(e[k] / UPC);
            assert_eq!(o.corrected_command_counts, cmd[k] - counts as i64);
            moved += (counts != 0) as u32;
        }
    }
    assert!(moved > 300, "the model moves the commands ({moved} of 600)");
}

fn write(axes: &[AxisSectionSpec], g: Option<&GeometricSpec>) -> Result<Vec<u8>, ImageError> {
    let mut buf = vec![0u8; group_image::group_image_len_with(axes, None, g)];
    let n = write_group_image_with(axes, None, g, &mut buf)?;
    assert_eq!(n, buf.len());
    Ok(buf)
}

fn sections(images: &[Vec<u8>]) -> Vec<AxisSectionSpec<'_>> {
    (0..3)
        .map(|k| AxisSectionSpec {
            name: AxisName::ALL[k],
            counts_per_rev: 0,
            stroke_counts: None,
            image: &images[k],
            sensor_names: &[],
        })
        .collect()
}

/// Written, parsed (coefficients as the image's bytes) and loaded: the same stage as loading the
/// spec directly, bit for bit.
#[test]
fn section_round_trip() {
    let mut rng = Lcg(99);
    let coef = random_coefficients(&mut rng);
    let mut s = spec(&coef, [1, 0, 2], 0, [1_000.0, 2_000.0, -3_000.0]);
    s.identified &= !(1 << 15 | 1 << 20);
    let images = axis_images();
    let bytes = write(&sections(&images), Some(&s)).unwrap();
    let view = group_image::parse(&bytes).unwrap();
    let g = view.geometric.expect("geometric section");
    assert_eq!(
        (g.chain, g.work_axes, g.identified),
        (s.chain, s.work_axes, s.identified)
    );
    assert_eq!(
        (g.tool_offset_um, g.squareness_urad, g.grids),
        (s.tool_offset_um, s.squareness_urad, s.grids)
    );
    assert_eq!(g.coefficients.len(), coef.len());
    for (i, c) in coef.iter().enumerate() {
        assert_eq!(g.coefficients.get(i), *c);
    }
    assert_eq!(&g.stacking_label(), b"/YXZ");
    let mut a = Box::new(Group::<256>::new());
    a.load_image(&bytes).unwrap();
    let mut b = Box::new(Group::<256>::new());
    b.load_stages(
        &group_axes(&images, [AxisName::X, AxisName::Y, AxisName::Z]),
        None,
        Some(&s),
    )
    .unwrap();
    for i in 0..50i64 {
        let cmd = [i * 150_000 - 900_000, i * 90_000, -i * 75_000];
        let (ea, eb) = (a.geometric_error_um(cmd), b.geometric_error_um(cmd));
        assert_eq!(
            ea.map(|e| e.map(f32::to_bits)),
            eb.map(|e| e.map(f32::to_bits))
        );
    }
}

fn reseal(b: &mut [u8]) {
    let n = u16::from_le_bytes([b[12], b[13]]) as usize;
    for i in 0..n {
        let at = GROUP_HEADER_LEN + DIR_ENTRY_LEN * i;
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

/// Every refusal is typed, names what is wrong, and leaves nothing half-written or loaded.
#[test]
fn geometric_section_refusals() {
    let mut rng = Lcg(3);
    let coef = random_coefficients(&mut rng);
    let good = spec(&coef, [0, 1, 2], 2, [0.0; 3]);
    let images = axis_images();
    let axes = sections(&images);
    let err = |axes: &[AxisSectionSpec], g: &GeometricSpec| {
        let mut buf = vec![0u8; group_image::group_image_len_with(axes, None, Some(g))];
        let e = write_group_image_with(axes, None, Some(g), &mut buf).unwrap_err();
        assert!(buf.iter().all(|&b| b == 0), "nothing half-written: {e}");
        e
    };
    // The group lacks Z.
    assert_eq!(
        err(&axes[..2], &good),
        ImageError::AxisNotInGroup { axis: 2 }
    );
    // A stacking naming X twice; more work axes than axes.
    let mut bad = good;
    bad.chain = [0, 0, 2];
    assert_eq!(
        err(&axes, &bad),
        ImageError::Geometric(GeometricError::Stacking)
    );
    bad = good;
    bad.work_axes = 4;
    assert_eq!(
        err(&axes, &bad),
        ImageError::Geometric(GeometricError::Stacking)
    );
    // A NaN coefficient: named by component and segment.
    let mut nan = coef.clone();
    let at = good.index(1, 3, 4);
    nan[at][2] = f32::NAN;
    let bad = GeometricSpec {
        coefficients: GeometricCoefficients::Values(&nan),
        ..good
    };
    let e = err(&axes, &bad);
    assert_eq!(
        e,
        ImageError::Geometric(GeometricError::Coefficient {
            axis: 1,
            function: 4,
            segment: 3
        })
    );
    assert!(e.to_string().contains("EBY segment 3"), "{e}");
    // Squareness beyond 10 mrad; a non-finite tool offset.
    let mut bad = good;
    bad.squareness_urad[1] = 2.0e4;
    let e = err(&axes, &bad);
    assert_eq!(
        e,
        ImageError::Geometric(GeometricError::Squareness { index: 1 })
    );
    assert!(e.to_string().contains("EB0Z"), "{e}");
    bad = good;
    bad.tool_offset_um[2] = f32::INFINITY;
    assert_eq!(
        err(&axes, &bad),
        ImageError::Geometric(GeometricError::ToolOffset { index: 2 })
    );
    // Too few coefficients for the grids; zero segments.
    let bad = GeometricSpec {
        coefficients: GeometricCoefficients::Values(&coef[1..]),
        ..good
    };
    assert_eq!(
        err(&axes, &bad),
        ImageError::Geometric(GeometricError::CoefficientCount)
    );
    let mut bad = good;
    bad.grids[2].n_segments = 0;
    assert_eq!(
        err(&axes, &bad),
        ImageError::Geometric(GeometricError::Grid { axis: 2 })
    );
    // A grid that does not span its axis's stroke: stated stroke, or the table's grid.
    let mut bad = good;
    bad.grids[1].start_counts += 1;
    assert_eq!(err(&axes, &bad), ImageError::GridMismatch { axis: 1 });
    let mut stated = sections(&images);
    stated[0].stroke_counts = Some((-1_000_000, 7_000_000));
    let with_stroke = write(&stated, Some(&good)).unwrap();
    assert!(group_image::parse(&with_stroke).is_ok());
    // An axis with neither a stated stroke nor a table: its stroke is unknown.
    let limits_only: Vec<u8> = {
        let mut s = table_spec(
            TableSpec {
                start_counts: 0,
                segment_counts: 1,
                forward: &[[0.0; 4]],
                backward: &[],
                outside: OutsideStroke::Hold,
            },
            LOOSE,
        );
        s.table = None;
        s.thermo = Some(ThermoForceSpec {
            sensor_period_ms: 100,
            sensors: &[],
            b0_um: 0.0,
            b_um_per_k: &[],
            expansion: None,
            forces: &[],
            reference: ThermoReference::Fixed,
            rise_bounds_k: &[],
        });
        image(&s)
    };
    let mut no_stroke = sections(&images);
    no_stroke[2].image = &limits_only;
    assert_eq!(err(&no_stroke, &good), ImageError::GridMismatch { axis: 2 });
    no_stroke[2].stroke_counts = Some((-4_000_000, 0));
    assert!(write(&no_stroke, Some(&good)).is_ok());

    // Edited bytes (resealed): reserved field, section for an axis, two geometric sections,
    // a cut coefficient block.
    let bytes = write(&axes, Some(&good)).unwrap();
    let dir = GROUP_HEADER_LEN + DIR_ENTRY_LEN * 3;
    let off = u32::from_le_bytes(bytes[dir + 8..dir + 12].try_into().unwrap()) as usize;
    assert_eq!(u16::from_le_bytes([bytes[dir], bytes[dir + 1]]), 2);
    let mut r = bytes.clone();
    r[off + 84] = 1;
    reseal(&mut r);
    assert_eq!(
        group_image::parse(&r).unwrap_err(),
        ImageError::OutOfRange {
            field: Field::Reserved,
            index: 0
        }
    );
    let mut a = bytes.clone();
    a[dir + 4] = 0;
    reseal(&mut a);
    assert_eq!(
        group_image::parse(&a).unwrap_err(),
        ImageError::SectionBounds { index: 3 }
    );
    let mut two = bytes.clone();
    two[dir - DIR_ENTRY_LEN..dir - DIR_ENTRY_LEN + 2].copy_from_slice(&2u16.to_le_bytes());
    two[dir - DIR_ENTRY_LEN + 4] = 0xFF;
    reseal(&mut two);
    assert!(group_image::parse(&two).is_err());
    let mut cut = bytes.clone();
    let len = u32::from_le_bytes(cut[dir + 12..dir + 16].try_into().unwrap());
    cut[dir + 12..dir + 16].copy_from_slice(&(len - 16).to_le_bytes());
    reseal(&mut cut);
    assert_eq!(
        group_image::parse(&cut).unwrap_err(),
        ImageError::Geometric(GeometricError::CoefficientCount)
    );
    let _ = GEOMETRIC_HEADER_LEN;

    // A pool too small for tables + the 14 folded functions per segment position: refused,
    // and the group keeps what it had.
    let mut small = Box::new(Group::<40>::new());
    let e = small.load_image(&bytes).unwrap_err();
    assert_eq!(
        e.error,
        ImageError::PoolTooSmall {
            needed: 24 + 14 * 8
        }
    );
    assert!(!small.is_loaded());
}

/// With the rotary stage too (X, Y, Z, A, C): each linear axis's error gains the geometric
/// error, the rotary axes are untouched. Reference: the same group with the rotary stage only,
/// plus `geometric_error_um`; tolerance 1e-4 µm (f32 rounding of sums of terms ≤ 60 µm, ≈ 2e-5),
/// compared in the cycles where neither output is clamped or slewed.
#[test]
fn geometric_and_rotary_stages_add() {
    let mut buf = vec![0u8; 16 * 1024];
    let (axes, n) = bench::write_group_images(5, &mut buf).unwrap();
    let geo = bench::group_geometric();
    let mut both = Box::new(Group::<1024>::new());
    both.load_stages(&axes[..n], Some(&bench::GROUP_ROTARY_STAGE), Some(&geo))
        .unwrap();
    let mut rot = Box::new(Group::<1024>::new());
    rot.load(&axes[..n], Some(&bench::GROUP_ROTARY_STAGE))
        .unwrap();
    assert!(both.has_rotary_stage() && both.has_geometric_stage());
    let (mut sb, mut sr) = (GroupState::new(), GroupState::new());
    let limited = Flags::CLAMPED.bits() | Flags::SLEWED.bits();
    let mut compared = 0;
    for i in 0..3000 {
        let input = bench::group_input(i);
        let (mut ob, mut or) = (GroupOutput::ZERO, GroupOutput::ZERO);
        both.cycle(&mut sb, &input, &mut ob);
        rot.cycle(&mut sr, &input, &mut or);
        for k in 3..5 {
            assert_eq!(ob.axes[k], or.axes[k], "cycle {i} rotary slot {k}");
        }
        let g = both
            .geometric_error_um([0, 1, 2].map(|k| input.axes[k].command_counts))
            .unwrap();
        for (k, gk) in g.iter().enumerate() {
            let (b, r) = (ob.axes[k], or.axes[k]);
            if (b.flags.bits() | r.flags.bits()) & limited == 0 {
                let diff = b.correction_um - r.correction_um;
                assert!(
                    (diff - gk).abs() <= 1e-4,
                    "cycle {i} axis {k}: with both {} rotary only {} geometric {gk}",
                    b.correction_um,
                    r.correction_um
                );
                compared += 1;
            }
        }
    }
    assert!(
        compared > 100,
        "compared {compared} unlimited linear outputs"
    );
}

proptest::proptest! {
    /// Any byte of the geometric section changed (image re-sealed, so only the section's own
    /// checks stand): parsing and loading never panic, and whatever is accepted loads and gives
    /// finite errors everywhere, beyond the grids too.
    #[test]
    fn geometric_section_mutations_never_panic(at in 0usize..4096, byte in 0u8..=255) {
        let mut rng = Lcg(17);
        let coef = random_coefficients(&mut rng);
        let good = spec(&coef, [0, 1, 2], 2, [0.0, 0.0, 100_000.0]);
        let images = axis_images();
        let mut b = write(&sections(&images), Some(&good)).unwrap();
        let dir = GROUP_HEADER_LEN + DIR_ENTRY_LEN * 3;
        let off = u32::from_le_bytes(b[dir + 8..dir + 12].try_into().unwrap()) as usize;
        let len = u32::from_le_bytes(b[dir + 12..dir + 16].try_into().unwrap()) as usize;
        b[off + at % len] = byte;
        reseal(&mut b);
        if group_image::parse(&b).is_ok() {
            let mut g = Box::new(Group::<256>::new());
            g.load_image(&b).unwrap();
            for cmd in [
                [0, 0, 0],
                [-2_000_000, 9_000_000, -9_000_000],
                [7_000_000, 5_000_000, 0],
                [i64::MAX, i64::MIN, 1 << 40],
            ] {
                let e = g.geometric_error_um(cmd).unwrap();
                proptest::prop_assert!(e.iter().all(|v| v.is_finite()), "{e:?} at {cmd:?}");
            }
        }
    }
}
