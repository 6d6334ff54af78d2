//! Tests of the splines: interpolation end conditions, B-spline basis, penalised fits and evaluation.

use super::*;

fn cubic(x: f64) -> f64 {
    1.5 - 2.0 * x + 0.3 * x * x - 0.05 * x * x * x
}

#[test]
fn not_a_knot_reproduces_a_cubic() {
    // Reference: the cubic itself; not-a-knot splines reproduce cubics exactly. Tolerance 1e-9.
    let x = [-20.0, -13.0, -5.0, 0.0, 2.5, 9.0, 20.0];
    let y: Vec<f64> = x.iter().map(|&v| cubic(v)).collect();
    let s = interpolate(&x, &y, EndCondition::NotAKnot).unwrap();
    for k in 0..=400 {
        let v = -20.0 + 0.1 * k as f64;
        assert!(
            (s.eval(v) - cubic(v)).abs() < 1e-9,
            "x={v}: {} vs {}",
            s.eval(v),
            cubic(v)
        );
    }
}

#[test]
fn clamped_reproduces_a_cubic() {
    let x = [0.0, 1.0, 3.0, 4.5];
    let y: Vec<f64> = x.iter().map(|&v| cubic(v)).collect();
    let d = |v: f64| -2.0 + 0.6 * v - 0.15 * v * v;
    let s = interpolate(
        &x,
        &y,
        EndCondition::Clamped {
            start_slope: d(0.0),
            end_slope: d(4.5),
        },
    )
    .unwrap();
    for k in 0..=45 {
        let v = 0.1 * k as f64;
        assert!((s.eval(v) - cubic(v)).abs() < 1e-9);
    }
}

#[test]
fn natural_spline_matches_hand_computed_values() {
    // Reference (by hand): through (0,0),(1,1),(2,0) the natural spline has M1 = 6(δ1−δ0)/(2(h0+h1)) = −3,
    // so S(x) = −x³/2 + 3x/2 on [0,1]: S(0.5) = 11/16, S'(0) = 1.5, and by symmetry S(1.5) = 11/16.
    let s = interpolate(&[0.0, 1.0, 2.0], &[0.0, 1.0, 0.0], EndCondition::Natural).unwrap();
    assert!((s.eval(0.5) - 0.6875).abs() < 1e-12);
    assert!((s.eval(1.5) - 0.6875).abs() < 1e-12);
    assert!((s.slope(0.0) - 1.5).abs() < 1e-12);
    assert!(s.curvature(0.0).abs() < 1e-12 && s.curvature(2.0).abs() < 1e-12);
    // Five points, non-uniform: natural conditions and interpolation hold; C2 at the interior knots.
    let x = [0.0, 0.7, 2.0, 2.4, 5.0];
    let y = [1.0, -1.0, 0.5, 2.0, 0.0];
    let s = interpolate(&x, &y, EndCondition::Natural).unwrap();
    for i in 0..5 {
        assert!((s.eval(x[i]) - y[i]).abs() < 1e-12);
    }
    for &k in &x[1..4] {
        let e = 1e-9;
        assert!((s.curvature(k - e) - s.curvature(k + e)).abs() < 1e-6);
        assert!((s.slope(k - e) - s.slope(k + e)).abs() < 1e-6);
    }
}

#[test]
fn least_squares_bspline_reproduces_a_cubic() {
    // Reference: the cubic; it lies in the spline space, and its roughness term vanishes only for
    // λ = 0 — with λ = 0 the fit must be exact (1e-9 µm on values of tens of µm).
    let cubic = |x: f64| cubic(x / 4.0);
    let basis = BSplineBasis::new(vec![-20.0, -11.0, -4.0, 3.0, 20.0]).unwrap();
    let mut st = NormalStats::zeros(basis.len(), 3);
    for k in 0..200 {
        let x = -20.0 + 40.0 * k as f64 / 199.0;
        let (j, v) = basis.values(x);
        st.add_row(j, &v, cubic(x));
    }
    let c = st.solve(&[]).unwrap();
    let pc = basis.to_piecewise(&c);
    for k in 0..=80 {
        let x = -20.0 + 0.5 * k as f64;
        assert!(
            (pc.eval(x) - cubic(x)).abs() < 1e-9,
            "{x}: {} vs {}",
            pc.eval(x),
            cubic(x)
        );
    }
    assert!(st.sse(&c) < 1e-12);
}

#[test]
fn basis_values_match_the_division_form_and_sum_to_one() {
    // Reference: the textbook Cox–de Boor recursion with divisions (values_in); partition of unity.
    for basis in [
        BSplineBasis::new(vec![-20.0, -11.0, -4.0, 3.0, 3.5, 20.0]).unwrap(),
        BSplineBasis::uniform(0.0, 7.0, 7).unwrap(),
    ] {
        for k in 0..=500 {
            let a = basis.breaks()[0];
            let b = *basis.breaks().last().unwrap();
            let x = a + (b - a) * k as f64 / 500.0;
            let (j, v) = basis.values(x);
            let w = basis.values_in(j, x);
            for r in 0..4 {
                assert!((v[r] - w[r]).abs() < 1e-14, "x={x} r={r}");
            }
            assert!((v.iter().sum::<f64>() - 1.0).abs() < 1e-14);
        }
    }
}

#[test]
fn roughness_matches_integral_of_squared_curvature() {
    // Reference: ∫ f''² for f = cubic on [-20, 20], f'' = 0.6 − 0.3x: ∫(0.6−0.3x)² dx = 0.36·40 + 0.09·(2·20³/3).
    let basis = BSplineBasis::new(vec![-20.0, -11.0, -4.0, 3.0, 20.0]).unwrap();
    let mut st = NormalStats::zeros(basis.len(), 3);
    for k in 0..100 {
        let x = -20.0 + 40.0 * k as f64 / 99.0;
        let (j, v) = basis.values(x);
        st.add_row(j, &v, cubic(x));
    }
    let c = st.solve(&[]).unwrap();
    let want = 0.36 * 40.0 + 0.09 * (2.0 * 8000.0 / 3.0);
    let got = basis.roughness().quad(&c);
    assert!((got - want).abs() < 1e-8 * want, "{got} vs {want}");
}

#[test]
fn horner_resampling_matches_the_spline() {
    // Knots on the uniform grid → the table reproduces the spline (tolerance 1e-6 µm).
    let x = [-20.0, -15.0, -10.0, -5.0, 0.0, 5.0, 10.0, 15.0, 20.0];
    let y = [-49.0, -30.0, 2.0, 40.0, 45.0, 10.0, -20.0, -5.0, 12.0];
    for end in [EndCondition::Natural, EndCondition::NotAKnot] {
        let s = interpolate(&x, &y, end).unwrap();
        let t = resample_uniform(&s, -20.0, 1.25, 32).unwrap();
        for k in 0..=4000 {
            let v = -20.0 + 0.01 * k as f64;
            assert!((t.eval(v) - s.eval(v)).abs() < 1e-6, "{end:?} x={v}");
        }
    }
    // Knots off the grid: C2 approximation, close but not exact.
    let s = interpolate(
        &[0.0, 1.3, 2.9, 4.0],
        &[0.0, 1.0, -1.0, 0.5],
        EndCondition::Natural,
    )
    .unwrap();
    let t = resample_uniform(&s, 0.0, 0.04, 100).unwrap();
    let worst = (0..=400)
        .map(|k| (t.eval(k as f64 * 0.01) - s.eval(k as f64 * 0.01)).abs())
        .fold(0.0, f64::max);
    assert!(worst < 1e-3, "{worst}");
}

#[test]
fn banded_solver_matches_dense_solution() {
    // Reference: a 6×6 SPD band system with known solution x = [1..6].
    let mut a = Band::zeros(6, 2);
    for i in 0..6 {
        a.add(i, i, 6.0 + i as f64);
        if i + 1 < 6 {
            a.add(i, i + 1, 1.0);
        }
        if i + 2 < 6 {
            a.add(i, i + 2, -0.5);
        }
    }
    let x: Vec<f64> = (1..=6).map(|v| v as f64).collect();
    let b: Vec<f64> = (0..6)
        .map(|i| (0..6).map(|j| a.get(i, j) * x[j]).sum())
        .collect();
    let got = a.solve(&b).unwrap();
    for i in 0..6 {
        assert!((got[i] - x[i]).abs() < 1e-12);
    }
}

#[test]
fn combine_adds_curves() {
    let a = interpolate(&[0.0, 1.0, 2.0], &[0.0, 1.0, 0.0], EndCondition::Natural).unwrap();
    let b = PiecewiseCubic::line(0.0, 2.0, 1.0, 0.5);
    let c = a.combine(1.0, &b, -0.5);
    for k in 0..=20 {
        let x = 0.1 * k as f64;
        assert!((c.eval(x) - (a.eval(x) - 0.5 * b.eval(x))).abs() < 1e-12);
    }
}
