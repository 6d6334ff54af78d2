//! Axis groups: a single-axis group equals the single-axis compensator bit for bit, rotary turn
//! tracking, the rotary location-error stage against exact homogeneous transforms, A/B atomicity
//! and the typed refusals of a group.

#![allow(clippy::needless_range_loop)]

mod common;

use axcomp_core::group::{
    AxisName, Group, GroupAxisImage, GroupEngine, GroupInput, GroupOutput, GroupState, MAX_AXES,
};
use axcomp_core::rotary::RotaryLocationSpec;
use axcomp_core::*;
use common::*;

/// Pool of the test groups: the reference single-axis table (2 × 1024 segments) fits.
const POOL: usize = 2048;

fn boxed_group() -> Box<Group<POOL>> {
    Box::new(Group::new())
}

/// The single-axis compensator of `img` and a group of two slots running the same image: X
/// (linear) and C (rotary, `cpr` counts per revolution) — the pair the counter and priming
/// proptests compare.
fn single_axis_and_x_c_group(img: &[u8], cpr: u32) -> (Box<Compensator>, Box<Group<POOL>>) {
    let mut comp = Box::new(Compensator::IDENTITY);
    comp.load(img).unwrap();
    let mut group = boxed_group();
    group
        .load(
            &[
                GroupAxisImage {
                    name: AxisName::X,
                    counts_per_rev: 0,
                    image: img,
                },
                GroupAxisImage {
                    name: AxisName::C,
                    counts_per_rev: cpr,
                    image: img,
                },
            ],
            None,
        )
        .unwrap();
    (comp, group)
}

/// Reference: `Compensator::cycle` on the same image, inputs, temperatures and process parameters;
/// tolerance: none (every output bit for bit), over 20 000 cycles of the bench workload (table,
/// 8 lagged sensors, expansion, 3 forces, clamp and slew acting).
#[test]
fn single_axis_group_equals_compensator_bit_for_bit() {
    let mut buf = vec![0u8; bench::reference_image_len()];
    bench::write_reference_image(&mut buf).unwrap();
    let mut comp = Box::new(Compensator::IDENTITY);
    comp.load(&buf).unwrap();
    let mut group = boxed_group();
    group
        .load(
            &[GroupAxisImage {
                name: AxisName::X,
                counts_per_rev: 0,
                image: &buf,
            }],
            None,
        )
        .unwrap();
    let mut st = State::new();
    let mut gst = Box::new(GroupState::new());
    comp.set_process(&mut st, &bench::PROCESS);
    group.set_process(&mut gst, &bench::PROCESS);
    let mut input = GroupInput::ZERO;
    let mut out = GroupOutput::ZERO;
    let mut seen = Flags::NONE;
    for i in 0..20_000u32 {
        if i % 100 == 0 {
            let t = bench::reference_temperatures(i / 100);
            comp.update_temperatures(&mut st, i, &t);
            group.update_temperatures(&mut gst, 0, i, &t);
        }
        input.axes[0] = bench::reference_input(i);
        if i == 10_000 {
            // A reset mid-stroke: the correction restarts from 0 and the slew limit acts.
            st.reset(input.axes[0].scale_raw);
            gst.reset(&[input.axes[0].scale_raw; MAX_AXES]);
            comp.set_process(&mut st, &bench::PROCESS);
            group.set_process(&mut gst, &bench::PROCESS);
        }
        let want = comp.cycle(&mut st, &input.axes[0]);
        group.cycle(&mut gst, &input, &mut out);
        let got = out.axes[0];
        assert_eq!(got.position_counts, want.position_counts, "cycle {i}");
        assert_eq!(got.corrected_command_counts, want.corrected_command_counts);
        assert_eq!(got.correction_counts, want.correction_counts);
        assert_eq!(got.correction_um.to_bits(), want.correction_um.to_bits());
        assert_eq!(got.flags, want.flags, "cycle {i}");
        seen |= want.flags;
        // Slots beyond the group are left as they are.
        assert_eq!(out.axes[1], GroupOutput::ZERO.axes[1]);
    }
    // The workload runs both directions, beyond the stroke, with the slew limit acting.
    for f in [Flags::BACKWARD, Flags::TABLE_OUTSIDE, Flags::SLEWED] {
        assert!(seen.contains(f), "{f:?} never seen");
    }
    assert_eq!(gst.axes[0], st, "same state");
}

/// An axis image with no table and no thermo term, loose limits.
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

const LIMITS: LimitSpec = LimitSpec {
    max_correction_um: 1.0e4,
    max_slew_um_per_cycle: 1.0e4,
    direction_hysteresis_counts: 0,
};

/// Counts per revolution of the test rotary axes (0.36 arc-seconds per count).
const CPR: u32 = 3_600_000;
const ARCSEC_PER_COUNT: f32 = 1_296_000.0 / CPR as f32;

/// A rotary axis image whose table spans one turn in `n` segments with a value that rises
/// linearly over the turn from 0 to `rise` arc-seconds (piecewise: segment k = rise·(k + t)/n).
fn rotary_table_image(n: usize, rise: f32, fwd: &mut Vec<[f32; 4]>) -> Vec<u8> {
    fwd.clear();
    for k in 0..n {
        fwd.push([rise * k as f32 / n as f32, rise / n as f32, 0.0, 0.0]);
    }
    image(&ImageSpec {
        axis_id: 4,
        um_per_count: ARCSEC_PER_COUNT,
        counter_bits: 32,
        table: Some(TableSpec {
            start_counts: 0,
            segment_counts: CPR / n as u32,
            forward: fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        }),
        thermo: None,
        limits: LIMITS,
    })
}

/// Reference: the table value at the position within the turn, computed from the known linear
/// rise (f64); tolerance 1e-3 arc-seconds (f32 evaluation of values ≤ 100″). The scale moves
/// through 360° forwards and back, crossing the wrap several times; also a jump of more than a
/// turn in one cycle (the slow modulo path).
#[test]
fn rotary_axis_wraps_through_360_degrees() {
    let mut fwd = Vec::new();
    let rot = rotary_table_image(64, 100.0, &mut fwd);
    let mut group = boxed_group();
    group
        .load(
            &[GroupAxisImage {
                name: AxisName::C,
                counts_per_rev: CPR,
                image: &rot,
            }],
            None,
        )
        .unwrap();
    let mut st = Box::new(GroupState::new());
    let mut input = GroupInput::ZERO;
    let mut out = GroupOutput::ZERO;
    let mut crossings = 0;
    let mut last_turn = 0u32;
    let mut pos: i64 = CPR as i64 - 50_000;
    let steps: Vec<i64> = (0..400)
        .map(|i| if i < 200 { 1_037 } else { -1_511 })
        .chain([5 * CPR as i64 + 12_345])
        .chain((0..50).map(|_| -777))
        .chain((0..150).map(|_| 36_001)) // one and a half turns forward
        .collect();
    for (i, step) in steps.iter().enumerate() {
        pos += step;
        input.axes[0].scale_raw = pos as u32;
        input.axes[0].command_counts = pos;
        group.cycle(&mut st, &input, &mut out);
        let turn = pos.rem_euclid(CPR as i64) as u32;
        assert_eq!(st.turn_position(0), Some(turn), "cycle {i}");
        if i > 0 && (turn as i64 - last_turn as i64).abs() > CPR as i64 / 2 {
            crossings += 1;
        }
        last_turn = turn;
        let want = 100.0 * turn as f64 / CPR as f64;
        let got = out.axes[0].correction_um as f64;
        assert!(
            (got - want).abs() < 1e-3,
            "cycle {i}: {got} vs {want} arcsec"
        );
        assert!(!out.axes[0].flags.contains(Flags::TABLE_OUTSIDE));
    }
    assert!(crossings >= 3, "crossed the wrap {crossings} times");
}

// ---- the rotary location-error stage against exact homogeneous transforms ----

type V3 = [f64; 3];
type M3 = [[f64; 3]; 3];

fn mv(m: &M3, v: V3) -> V3 {
    [0, 1, 2].map(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
}
fn mt(m: &M3) -> M3 {
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| m[j][i]))
}
fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn add(a: V3, b: V3) -> V3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
/// Rotation by `angle` about the unit vector `d` (Rodrigues).
fn rot(d: V3, angle: f64) -> M3 {
    let (s, c) = angle.sin_cos();
    let k = 1.0 - c;
    let [x, y, z] = d;
    [
        [c + x * x * k, x * y * k - z * s, x * z * k + y * s],
        [y * x * k + z * s, c + y * y * k, y * z * k - x * s],
        [z * x * k - y * s, z * y * k + x * s, c + z * z * k],
    ]
}
/// Rotation by the rotation vector `e`.
fn rotvec(e: V3) -> M3 {
    let n = (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt();
    if n == 0.0 {
        return rot([1.0, 0.0, 0.0], 0.0);
    }
    rot([e[0] / n, e[1] / n, e[2] / n], n)
}
/// Rotation by `angle` about the line through `o` with direction `d`, applied to `p` (the exact
/// homogeneous transform Trans(o)·Rot(d, angle)·Trans(−o)).
fn about_line(o: V3, d: V3, angle: f64, p: V3) -> V3 {
    add(o, mv(&rot(d, angle), sub(p, o)))
}

/// Exact deviation (reached − target, µm) of the AC trunnion with location errors `s` for the
/// tool tip `q` (µm from the pivot) and angles `a`, `c` (rad).
fn exact_deviation(s: &RotaryLocationSpec, q: V3, a: f64, c: f64) -> V3 {
    let u = 1e-6;
    let d_a = mv(
        &rotvec([0.0, s.eb0a_urad as f64 * u, s.ec0a_urad as f64 * u]),
        [1.0, 0.0, 0.0],
    );
    let o_a = [0.0, s.ey0a_um as f64, s.ez0a_um as f64];
    let d_c = mv(
        &rotvec([s.ea0c_urad as f64 * u, s.eb0c_urad as f64 * u, 0.0]),
        [0.0, 0.0, 1.0],
    );
    let o_c = [s.ex0c_um as f64, s.ey0c_um as f64, 0.0];
    // The workpiece point the CNC puts under the tool (nominal axes through the pivot).
    let p_w = mv(
        &mt(&rot([0.0, 0.0, 1.0], c)),
        mv(&mt(&rot([1.0, 0.0, 0.0], a)), q),
    );
    let actual = about_line(o_a, d_a, a, about_line(o_c, d_c, c, p_w));
    let e = sub(actual, q);
    [-e[0], -e[1], -e[2]]
}

/// A deterministic generator (xorshift) for the test's random poses and errors.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
}

/// Reference: the exact homogeneous transforms above (f64), same commanded counts. Tolerance:
/// 0.03 µm — the model is first order in the location errors; with each error ≤ 50 µm / 50 µrad
/// (|ε| ≤ 71 µrad, |o| ≤ 71 µm), |q| ≤ 840 mm and deviations ≤ 250 µm the neglected products
/// are bounded by |ε|·|δ| ≈ 0.018, |ε|²·|q| ≈ 0.004 and |ε|·|o| ≈ 0.005 µm (sum < 0.03 µm);
/// f32 rounding adds below 0.001 µm. The largest difference seen is printed (0.016 µm).
#[test]
fn rotary_stage_matches_exact_transforms() {
    let upc = [0.1f32, 0.1, 0.05];
    let images = [bare(upc[0]), bare(upc[1]), bare(upc[2])];
    let rot_a = bare(ARCSEC_PER_COUNT);
    let rot_c = bare(ARCSEC_PER_COUNT);
    let axes = [
        GroupAxisImage {
            name: AxisName::X,
            counts_per_rev: 0,
            image: &images[0],
        },
        GroupAxisImage {
            name: AxisName::Y,
            counts_per_rev: 0,
            image: &images[1],
        },
        GroupAxisImage {
            name: AxisName::Z,
            counts_per_rev: 0,
            image: &images[2],
        },
        GroupAxisImage {
            name: AxisName::A,
            counts_per_rev: CPR,
            image: &rot_a,
        },
        GroupAxisImage {
            name: AxisName::C,
            counts_per_rev: CPR,
            image: &rot_c,
        },
    ];
    let mut rng = Rng(0x9E37_79B9_7F4A_7C15);
    let mut worst = 0.0f64;
    let mut largest = 0.0f64;
    for case in 0..40 {
        let mut r = |m: f64| rng.range(-m, m) as f32;
        let spec = RotaryLocationSpec {
            ex0c_um: r(50.0),
            ey0c_um: r(50.0),
            ea0c_urad: r(50.0),
            eb0c_urad: r(50.0),
            ey0a_um: r(50.0),
            ez0a_um: r(50.0),
            eb0a_urad: r(50.0),
            ec0a_urad: r(50.0),
            pivot_counts: [1_000_000, -2_000_000, 4_000_000],
            tool_length_um: 120_000.0,
            ..RotaryLocationSpec::ZERO_AC
        };
        let mut group = boxed_group();
        group.load(&axes, Some(&spec)).unwrap();
        let mut st = Box::new(GroupState::new());
        let mut input = GroupInput::ZERO;
        let mut out = GroupOutput::ZERO;
        for _ in 0..25 {
            // Tool tip within ±400 mm of the pivot in X, Y and −500…+200 mm in Z.
            let cmd = [
                spec.pivot_counts[0] + rng.range(-4.0e6, 4.0e6) as i64,
                spec.pivot_counts[1] + rng.range(-4.0e6, 4.0e6) as i64,
                spec.pivot_counts[2] + rng.range(-8.0e6, 6.4e6) as i64,
                rng.range(-3.0 * CPR as f64, 3.0 * CPR as f64) as i64,
                rng.range(-3.0 * CPR as f64, 3.0 * CPR as f64) as i64,
            ];
            for k in 0..5 {
                input.axes[k].command_counts = cmd[k];
                input.axes[k].scale_raw = cmd[k] as u32;
            }
            // Fresh state each pose: no slew history.
            *st = GroupState::new();
            group.cycle(&mut st, &input, &mut out);
            let q = [
                (cmd[0] - spec.pivot_counts[0]) as f64 * upc[0] as f64,
                (cmd[1] - spec.pivot_counts[1]) as f64 * upc[1] as f64,
                (cmd[2] - spec.pivot_counts[2]) as f64 * upc[2] as f64 - spec.tool_length_um as f64,
            ];
            let angle =
                |c: i64| c.rem_euclid(CPR as i64) as f64 * std::f64::consts::TAU / CPR as f64;
            let want = exact_deviation(&spec, q, angle(cmd[3]), angle(cmd[4]));
            for k in 0..3 {
                let got = out.axes[k].correction_um as f64;
                worst = worst.max((got - want[k]).abs());
                largest = largest.max(want[k].abs());
                assert!(
                    (got - want[k]).abs() < 0.03,
                    "case {case}, axis {k}: stage {got} µm, exact {} µm",
                    want[k]
                );
            }
            // Rotary axes have no stage term (their own pipeline only: no table here).
            assert_eq!(out.axes[3].correction_um, 0.0);
        }
    }
    println!("largest |deviation| {largest:.3} µm, largest |stage − exact| {worst:.5} µm");
    assert!(
        largest > 20.0,
        "the cases exercise the errors ({largest} µm)"
    );
}

/// Reference: the count of commanded-angle changes (sin/cos are recomputed once per change and
/// never otherwise); exact.
#[test]
fn sin_cos_recomputed_only_when_an_angle_changes() {
    let lin = bare(0.1);
    let rot = bare(ARCSEC_PER_COUNT);
    let axes: Vec<GroupAxisImage> = [AxisName::X, AxisName::Y, AxisName::Z]
        .into_iter()
        .map(|name| GroupAxisImage {
            name,
            counts_per_rev: 0,
            image: &lin,
        })
        .chain(
            [AxisName::A, AxisName::C]
                .into_iter()
                .map(|name| GroupAxisImage {
                    name,
                    counts_per_rev: CPR,
                    image: &rot,
                }),
        )
        .collect();
    let spec = RotaryLocationSpec {
        ex0c_um: 10.0,
        ey0c_um: -5.0,
        ea0c_urad: 20.0,
        eb0c_urad: -8.0,
        ey0a_um: 3.0,
        ez0a_um: 7.0,
        eb0a_urad: 12.0,
        ec0a_urad: -4.0,
        pivot_counts: [0; 3],
        tool_length_um: 0.0,
        ..RotaryLocationSpec::ZERO_AC
    };
    let mut engine: Box<GroupEngine<POOL>> = Box::new(GroupEngine::new());
    engine.load(&axes, Some(&spec)).unwrap();
    let mut input = GroupInput::ZERO;
    let mut out = GroupOutput::ZERO;
    let mut changes = 0;
    let mut last = None;
    for i in 0..1000i64 {
        input.axes[0].command_counts = i * 13; // X moves every cycle
        // A changes every 10th cycle, C every 25th; a full turn of C lands on the same angle.
        let a = (i / 10) * 100;
        let c = (i / 25) * 7 + if i > 900 { CPR as i64 } else { 0 };
        input.axes[3].command_counts = a;
        input.axes[4].command_counts = c;
        let angles = (a, c.rem_euclid(CPR as i64));
        if last != Some(angles) {
            changes += 1;
            last = Some(angles);
        }
        engine.cycle(&input, &mut out);
    }
    assert_eq!(engine.state().angle_refreshes(), changes);
    assert!(changes < 200);
}

/// Reference: the outputs of each group alone; exact. A rejected group (one axis image corrupt)
/// leaves every axis on the old group; an accepted one switches every axis in the same cycle.
#[test]
fn group_swap_is_atomic() {
    let fwd_old = [[1.0f32, 0.0, 0.0, 0.0]; 4];
    let fwd_new = [[2.0f32, 0.0, 0.0, 0.0]; 4];
    let img = |fwd: &[[f32; 4]]| {
        image(&table_spec(
            TableSpec {
                start_counts: 0,
                segment_counts: 1000,
                forward: fwd,
                backward: &[],
                outside: OutsideStroke::Hold,
            },
            LOOSE,
        ))
    };
    let (old, new) = (img(&fwd_old), img(&fwd_new));
    let mut bad = new.clone();
    let k = bad.len() / 2;
    bad[k] ^= 0x10;
    let group = |x: &'static [u8], y: &'static [u8]| {
        [
            GroupAxisImage {
                name: AxisName::X,
                counts_per_rev: 0,
                image: x,
            },
            GroupAxisImage {
                name: AxisName::Y,
                counts_per_rev: 0,
                image: y,
            },
        ]
    };
    let (old, new, bad): (&'static [u8], &'static [u8], &'static [u8]) =
        (Vec::leak(old), Vec::leak(new), Vec::leak(bad));
    let mut engine: Box<GroupEngine<POOL>> = Box::new(GroupEngine::new());
    engine.load(&group(old, old), None).unwrap();
    let mut input = GroupInput::ZERO;
    let mut out = GroupOutput::ZERO;
    input.axes[0].scale_raw = 500;
    input.axes[1].scale_raw = 500;
    engine.cycle(&input, &mut out);
    assert_eq!(
        [out.axes[0].correction_um, out.axes[1].correction_um],
        [1.0, 1.0]
    );
    let err = engine.load(&group(new, bad), None).unwrap_err();
    assert_eq!(err.axis, Some(AxisName::Y));
    assert_eq!(err.error, ImageError::BadCrc);
    engine.cycle(&input, &mut out);
    assert_eq!(
        [out.axes[0].correction_um, out.axes[1].correction_um],
        [1.0, 1.0],
        "X must not be new while Y is old"
    );
    engine.load(&group(new, new), None).unwrap();
    engine.cycle(&input, &mut out);
    assert_eq!(
        [out.axes[0].correction_um, out.axes[1].correction_um],
        [2.0, 2.0]
    );
    assert_eq!(engine.stats().images_rejected, 1);
    assert_eq!(engine.stats().images_accepted, 2);
}

#[test]
fn typed_refusals_of_a_group() {
    let lin = bare(0.1);
    let rot = bare(ARCSEC_PER_COUNT);
    let mut fwd = Vec::new();
    let bad_grid = {
        let mut fwd2 = Vec::new();
        // 64 segments of CPR/64 counts, but starting at 10: not one turn from 0.
        let _ = rotary_table_image(64, 1.0, &mut fwd2);
        image(&ImageSpec {
            axis_id: 4,
            um_per_count: ARCSEC_PER_COUNT,
            counter_bits: 32,
            table: Some(TableSpec {
                start_counts: 10,
                segment_counts: CPR / 64,
                forward: &fwd2,
                backward: &[],
                outside: OutsideStroke::Hold,
            }),
            thermo: None,
            limits: LIMITS,
        })
    };
    let short_grid = rotary_table_image(60, 1.0, &mut fwd); // 60 · (CPR/60) = CPR: fine
    let ax = |name, counts_per_rev, image| GroupAxisImage {
        name,
        counts_per_rev,
        image,
    };
    let mut g = boxed_group();
    let spec = RotaryLocationSpec {
        ex0c_um: 0.0,
        ey0c_um: 0.0,
        ea0c_urad: 0.0,
        eb0c_urad: 0.0,
        ey0a_um: 0.0,
        ez0a_um: 0.0,
        eb0a_urad: 0.0,
        ec0a_urad: 0.0,
        pivot_counts: [0; 3],
        tool_length_um: 0.0,
        ..RotaryLocationSpec::ZERO_AC
    };
    let e = |r: Result<(), group::GroupError>| r.unwrap_err();
    assert_eq!(e(g.load(&[], None)).error, ImageError::AxisCount);
    let six = [ax(AxisName::X, 0, &lin[..]); 6];
    assert_eq!(e(g.load(&six, None)).error, ImageError::AxisCount);
    assert_eq!(
        e(g.load(&[ax(AxisName::X, 0, &lin), ax(AxisName::X, 0, &lin)], None)).error,
        ImageError::DuplicateAxis { axis: 0 }
    );
    // A rotary axis needs counts per revolution, a linear one must have none.
    assert!(matches!(
        e(g.load(&[ax(AxisName::A, 0, &rot)], None)).error,
        ImageError::OutOfRange {
            field: Field::CountsPerRev,
            ..
        }
    ));
    assert!(matches!(
        e(g.load(&[ax(AxisName::Y, CPR, &lin)], None)).error,
        ImageError::OutOfRange {
            field: Field::CountsPerRev,
            ..
        }
    ));
    // A rotary table must span exactly one turn from 0.
    let r = e(g.load(&[ax(AxisName::C, CPR, &bad_grid)], None));
    assert_eq!(
        (r.axis, r.error),
        (Some(AxisName::C), ImageError::GridMismatch { axis: 5 })
    );
    assert_eq!(
        e(g.load(&[ax(AxisName::C, CPR + 1, &short_grid)], None)).error,
        ImageError::GridMismatch { axis: 5 }
    );
    g.load(&[ax(AxisName::C, CPR, &short_grid)], None).unwrap();
    // The stage needs X, Y, Z, A and C.
    let xyz_a = [
        ax(AxisName::X, 0, &lin[..]),
        ax(AxisName::Y, 0, &lin),
        ax(AxisName::Z, 0, &lin),
        ax(AxisName::A, CPR, &rot),
    ];
    assert_eq!(
        e(g.load(&xyz_a, Some(&spec))).error,
        ImageError::AxisNotInGroup { axis: 5 }
    );
    let mut bad_spec = spec;
    bad_spec.eb0a_urad = f32::NAN;
    let five = [
        xyz_a[0],
        xyz_a[1],
        xyz_a[2],
        xyz_a[3],
        ax(AxisName::C, CPR, &rot),
    ];
    assert_eq!(
        e(g.load(&five, Some(&bad_spec))).error,
        ImageError::NonFinite {
            field: Field::RotaryLocation,
            index: 6
        }
    );
    g.load(&five, Some(&spec)).unwrap();
    assert!(g.has_rotary_stage());
    // Tables beyond the pool.
    let mut small: Box<Group<32>> = Box::new(Group::new());
    assert_eq!(
        e(small.load(&[ax(AxisName::C, CPR, &short_grid)], None)).error,
        ImageError::PoolTooSmall { needed: 60 },
    );
    assert!(!small.is_loaded());
    assert_eq!(MAX_AXES, 5);
}

mod counter_extension {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// Reference: the true position (i64 sum of the steps), exact. For any counter width
        /// 16..=32, any start and any sequence of steps below half the counter's range, the
        /// extended position equals the true one — single axis and group axis (linear and rotary:
        /// the turn position is the true position modulo the counts per revolution).
        #[test]
        fn extended_position_follows_the_true_position(
            bits in 16u8..=32,
            start in any::<i64>().prop_map(|v| v % (1i64 << 40)),
            steps in proptest::collection::vec(any::<i64>(), 1..300),
        ) {
            let half = 1i64 << (bits - 1);
            let mask = if bits == 32 { u32::MAX } else { (1u32 << bits) - 1 };
            let img = image(&ImageSpec {
                axis_id: 1,
                um_per_count: 0.1,
                counter_bits: bits,
                table: None,
                thermo: None,
                limits: LOOSE,
            });
            let (comp, group) = single_axis_and_x_c_group(&img, CPR);
            let mut st = State::new();
            let mut gst = Box::new(GroupState::new());
            let mut input = GroupInput::ZERO;
            let mut out = GroupOutput::ZERO;
            let mut truth = start;
            st.home(truth as u32 & mask, truth);
            gst.axes[0].home(truth as u32 & mask, truth);
            gst.axes[1].home(truth as u32 & mask, truth);
            for s in steps {
                let step = s % half; // |step| < half the counter's range
                truth += step;
                let raw = truth as u32 & mask;
                let o = comp.cycle(&mut st, &common::input(raw, 0));
                prop_assert_eq!(o.position_counts, truth);
                input.axes[0].scale_raw = raw;
                input.axes[1].scale_raw = raw;
                group.cycle(&mut gst, &input, &mut out);
                prop_assert_eq!(out.axes[0].position_counts, truth);
                prop_assert_eq!(out.axes[1].position_counts, truth);
                prop_assert_eq!(gst.turn_position(1), Some(truth.rem_euclid(CPR as i64) as u32));
            }
        }
    }
}

mod segment_cache {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        /// Reference: `Group::table_um` — the full table lookup (64-bit range test, segment
        /// division), no cache — at the extended position (linear X) and at the position within
        /// the turn (rotary C), in the axis's direction after the cycle; tolerance: none (bit for
        /// bit, and the same TABLE_OUTSIDE flag). The group's pipelines look the table up
        /// through the segment cache; the steps stay within segments, cross their boundaries,
        /// leave and re-enter the stroke, wrap the turn, jump by up to ±(2^31 − 1) counts, and
        /// the axes are homed now and then (which voids the cache). Loose limits: the applied
        /// correction is the table value itself.
        #[test]
        fn cached_lookup_equals_the_full_lookup(
            start in -(1i64 << 40)..(1i64 << 40),
            steps in proptest::collection::vec((0u8..8, any::<i32>()), 1..400),
        ) {
            let fwd: Vec<[f32; 4]> = (0..16)
                .map(|k| [k as f32 * 0.25, 0.5, -0.125 * (k % 3) as f32, 0.0625])
                .collect();
            let bwd: Vec<[f32; 4]> = fwd.iter().map(|c| [c[0] + 1.5, c[1], c[2], c[3]]).collect();
            let lin = image(&table_spec(
                TableSpec {
                    start_counts: -3_000,
                    segment_counts: 1_000,
                    forward: &fwd,
                    backward: &bwd,
                    outside: OutsideStroke::Taper { length_counts: 5_000 },
                },
                LOOSE,
            ));
            let mut rfwd = Vec::new();
            let rot = rotary_table_image(64, 100.0, &mut rfwd);
            let mut group = boxed_group();
            group
                .load(
                    &[
                        GroupAxisImage { name: AxisName::X, counts_per_rev: 0, image: &lin },
                        GroupAxisImage { name: AxisName::C, counts_per_rev: CPR, image: &rot },
                    ],
                    None,
                )
                .unwrap();
            let mut gst = Box::new(GroupState::new());
            let mut input = GroupInput::ZERO;
            let mut out = GroupOutput::ZERO;
            let mut truth = start % 20_000;
            for (i, (kind, s)) in steps.into_iter().enumerate() {
                let step = match kind {
                    0..=3 => (s % 700) as i64,   // within a segment, mostly
                    4 | 5 => (s % 40_000) as i64, // across segments, out of the stroke
                    6 => s as i64,                // anything an i32 holds
                    _ => 0,
                };
                truth += step;
                let raw = truth as u32;
                if kind == 7 && s % 3 == 0 {
                    for a in gst.axes.iter_mut().take(2) {
                        a.home(raw, truth);
                    }
                }
                input.axes[0].scale_raw = raw;
                input.axes[1].scale_raw = raw;
                group.cycle(&mut gst, &input, &mut out);
                let turn = truth.rem_euclid(CPR as i64);
                for (slot, table_pos) in [(0usize, truth), (1, turn)] {
                    let (want, outside) =
                        group.table_um(slot, gst.axes[slot].direction(), table_pos);
                    let o = out.axes[slot];
                    prop_assert_eq!(o.correction_um.to_bits(), want.to_bits(), "cycle {}, slot {}", i, slot);
                    prop_assert_eq!(o.flags.contains(Flags::TABLE_OUTSIDE), outside);
                }
                prop_assert_eq!(gst.turn_position(1), Some(turn as u32));
            }
        }
    }
}

mod priming {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        /// Reference: `Compensator::cycle` (which tests `primed` before extending the counter) on
        /// the same image and inputs; tolerance: none (every output bit for bit, and the same
        /// state). The group pipelines extend the counter without that test and redo the
        /// first cycle of a fresh or reset state in the segment cache's miss path: counter
        /// widths 16..=32, resets whose counter value has other high bits than the counter
        /// width keeps and differs from the next cycle's, steps large enough to reverse the
        /// direction (hysteresis 0..50) on that first cycle, a linear and a rotary slot.
        #[test]
        fn first_cycle_after_a_fresh_state_or_a_reset_equals_the_single_axis_call(
            bits in 16u8..=32,
            hysteresis in 0u32..50,
            start in any::<u32>(),
            steps in proptest::collection::vec((any::<i16>(), any::<u32>(), 0u8..6), 1..60),
        ) {
            let mask = if bits == 32 { u32::MAX } else { (1u32 << bits) - 1 };
            let fwd: Vec<[f32; 4]> = (0..64)
                .map(|k| [k as f32 * 0.25, 0.5, -0.125 * (k % 3) as f32, 0.0625])
                .collect();
            let bwd: Vec<[f32; 4]> = fwd.iter().map(|c| [c[0] + 1.5, c[1], c[2], c[3]]).collect();
            let mut spec = table_spec(
                TableSpec {
                    start_counts: 0,
                    segment_counts: CPR / 64,
                    forward: &fwd,
                    backward: &bwd,
                    outside: OutsideStroke::Hold,
                },
                LOOSE,
            );
            spec.counter_bits = bits;
            spec.limits.direction_hysteresis_counts = hysteresis;
            let img = image(&spec);
            let (comp, group) = single_axis_and_x_c_group(&img, CPR);
            let mut st = State::new();
            let mut gst = Box::new(GroupState::new());
            let mut input = GroupInput::ZERO;
            let mut out = GroupOutput::ZERO;
            let mut raw = start;
            for (i, (step, reset_raw, kind)) in steps.into_iter().enumerate() {
                if kind == 0 {
                    // A reset at a counter value with arbitrary high bits.
                    st.reset(reset_raw);
                    gst.reset(&[reset_raw; MAX_AXES]);
                } else if kind == 1 {
                    st = State::new();
                    *gst = GroupState::new();
                }
                raw = raw.wrapping_add(step as i32 as u32) & mask | (reset_raw & !mask);
                input.axes[0].scale_raw = raw;
                input.axes[1].scale_raw = raw;
                input.axes[0].command_counts = step as i64 * 1000;
                input.axes[1].command_counts = step as i64 * 1000;
                let want = comp.cycle(&mut st, &input.axes[0]);
                group.cycle(&mut gst, &input, &mut out);
                prop_assert_eq!(out.axes[0].position_counts, want.position_counts, "cycle {}", i);
                prop_assert_eq!(out.axes[1].position_counts, want.position_counts, "cycle {}", i);
                prop_assert_eq!(out.axes[0].corrected_command_counts, want.corrected_command_counts);
                prop_assert_eq!(out.axes[0].correction_um.to_bits(), want.correction_um.to_bits());
                prop_assert_eq!(out.axes[0].flags, want.flags, "cycle {}", i);
                prop_assert_eq!(out.axes[1].flags.contains(Flags::BACKWARD), want.flags.contains(Flags::BACKWARD));
                prop_assert_eq!(&gst.axes[0], &st, "cycle {}", i);
                let turn = want.position_counts.rem_euclid(CPR as i64) as u32;
                prop_assert_eq!(gst.turn_position(1), Some(turn));
            }
        }
    }
}
