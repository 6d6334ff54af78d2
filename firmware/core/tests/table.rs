//! Positioning table: exact cubic, spline through points, directions, outside the stroke.

mod common;
use axcomp_core::*;
use common::*;

#[test]
fn one_segment_reproduces_a_cubic() {
    // Reference: the cubic 3 − 2t + 0.5t² + 1.25t³ (µm) evaluated in f64 at t = rem/segment.
    // Tolerance 2e-6 µm: f32 rounding of t and of four Horner steps on values ≤ 3 µm.
    let c = [[3.0f32, -2.0, 0.5, 1.25]];
    let seg = 4096u32;
    let spec = table_spec(
        TableSpec {
            start_counts: -1000,
            segment_counts: seg,
            forward: &c,
            backward: &[],
            outside: OutsideStroke::Hold,
        },
        LOOSE,
    );
    let comp = load(&spec);
    let c64 = [3.0, -2.0, 0.5, 1.25];
    for rem in (0..seg).step_by(7) {
        let (v, outside) = comp.table_um(Direction::Forward, -1000 + rem as i64);
        assert!(!outside);
        let want = horner(&c64, rem as f64 / seg as f64);
        assert!(
            (v as f64 - want).abs() < 2e-6,
            "rem {rem}: {v} vs {want} (tol 2e-6 µm)"
        );
    }
    // Backward direction on a unidirectional table uses the forward one.
    assert_eq!(
        comp.table_um(Direction::Backward, 100).0,
        comp.table_um(Direction::Forward, 100).0
    );
}

#[test]
fn spline_through_known_points() {
    // Reference: a natural cubic spline computed in f64 (common::natural_spline) through
    // y_k = 5 sin(0.37 k) + 0.2 k (µm) at 64 uniform knots, 2500 counts apart. The f32 table
    // must hit every knot to 1e-4 µm, agree with the f64 spline between knots to 1e-4 µm, and be
    // continuous across knots (C0 to 1e-4 µm; C1, C2 of the f64 coefficients to 1e-9).
    let y: Vec<f64> = (0..=64)
        .map(|k| 5.0 * (0.37 * k as f64).sin() + 0.2 * k as f64)
        .collect();
    let segs = natural_spline(&y);
    for w in segs.windows(2) {
        let (a, b) = (&w[0], &w[1]);
        assert!((a.iter().sum::<f64>() - b[0]).abs() < 1e-9, "C0");
        assert!((a[1] + 2.0 * a[2] + 3.0 * a[3] - b[1]).abs() < 1e-9, "C1");
        assert!((2.0 * a[2] + 6.0 * a[3] - 2.0 * b[2]).abs() < 1e-9, "C2");
    }
    let fwd = to_f32(&segs);
    let seg = 2500u32;
    let start = 123_456i64;
    let comp = load(&table_spec(
        TableSpec {
            start_counts: start,
            segment_counts: seg,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        },
        LOOSE,
    ));
    for (k, &yk) in y.iter().enumerate() {
        let (v, _) = comp.table_um(Direction::Forward, start + k as i64 * seg as i64);
        assert!((v as f64 - yk).abs() < 1e-4, "knot {k}: {v} vs {yk}");
    }
    for p in (0..64 * seg as i64).step_by(613) {
        let s = (p / seg as i64) as usize;
        let t = (p % seg as i64) as f64 / seg as f64;
        let want = horner(&segs[s], t);
        let (v, outside) = comp.table_um(Direction::Forward, start + p);
        assert!(!outside);
        assert!((v as f64 - want).abs() < 1e-4, "pos {p}: {v} vs {want}");
    }
}

#[test]
fn bidirectional_tables_follow_the_direction() {
    // Forward table constant 1 µm, backward constant −2 µm: the value is exact.
    let fwd = [[1.0f32, 0.0, 0.0, 0.0]; 8];
    let bwd = [[-2.0f32, 0.0, 0.0, 0.0]; 8];
    let comp = load(&table_spec(
        TableSpec {
            start_counts: 0,
            segment_counts: 100,
            forward: &fwd,
            backward: &bwd,
            outside: OutsideStroke::Hold,
        },
        LimitSpec {
            direction_hysteresis_counts: 5,
            ..LOOSE
        },
    ));
    assert_eq!(comp.table_um(Direction::Forward, 50).0, 1.0);
    assert_eq!(comp.table_um(Direction::Backward, 50).0, -2.0);
    let mut st = State::new();
    // Moving up: forward table (1 µm = 10 counts).
    for p in 0..50u32 {
        let o = comp.cycle(&mut st, &input(p, p as i64));
        assert_eq!(o.correction_um, 1.0);
        assert!(!o.flags.contains(Flags::BACKWARD));
    }
    // Moving down by more than the hysteresis: backward table.
    let mut last = None;
    for p in (30..50u32).rev() {
        last = Some(comp.cycle(&mut st, &input(p, p as i64)));
    }
    let o = last.unwrap();
    assert_eq!(o.correction_um, -2.0);
    assert_eq!(o.correction_counts, -20);
    assert_eq!(o.corrected_command_counts, 30 + 20);
    assert!(o.flags.contains(Flags::BACKWARD));
}

#[test]
fn outside_the_stroke_hold_and_taper() {
    // Segment 0: 2 + t µm (2 at the low end), last segment ends at 2 + 1 = 3 µm.
    let fwd = [[2.0f32, 1.0, 0.0, 0.0], [3.0, 0.0, 0.0, 0.0]];
    let hold = load(&table_spec(
        TableSpec {
            start_counts: 1000,
            segment_counts: 100,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        },
        LOOSE,
    ));
    assert_eq!(hold.table_um(Direction::Forward, 999), (2.0, true));
    assert_eq!(hold.table_um(Direction::Forward, i64::MIN), (2.0, true));
    assert_eq!(hold.table_um(Direction::Forward, 1000), (2.0, false));
    assert_eq!(hold.table_um(Direction::Forward, 1199), (3.0, false));
    assert_eq!(hold.table_um(Direction::Forward, 1200), (3.0, true));
    assert_eq!(hold.table_um(Direction::Forward, i64::MAX), (3.0, true));

    let taper = load(&table_spec(
        TableSpec {
            start_counts: 1000,
            segment_counts: 100,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Taper { length_counts: 400 },
        },
        LOOSE,
    ));
    // Linear to 0 over 400 counts: reference 2·(1 − d/400) below, 3·(1 − d/400) above, to 1e-6.
    for d in [0i64, 1, 100, 200, 399] {
        let (lo, o1) = taper.table_um(Direction::Forward, 1000 - d);
        let (hi, o2) = taper.table_um(Direction::Forward, 1200 + d);
        assert!((d == 0 || o1) && o2);
        let f = 1.0 - d as f32 / 400.0;
        if d > 0 {
            assert!((lo - 2.0 * f).abs() < 1e-6, "low d={d}: {lo}");
        }
        assert!((hi - 3.0 * f).abs() < 1e-6, "high d={d}: {hi}");
    }
    assert_eq!(taper.table_um(Direction::Forward, 1000 - 400), (0.0, true));
    assert_eq!(
        taper.table_um(Direction::Forward, 1200 + 10_000),
        (0.0, true)
    );
    assert_eq!(taper.table_um(Direction::Forward, i64::MIN), (0.0, true));
    // The cycle flags it.
    let mut st = State::new();
    let o = taper.cycle(&mut st, &input(500, 0));
    assert!(o.flags.contains(Flags::TABLE_OUTSIDE));
}
