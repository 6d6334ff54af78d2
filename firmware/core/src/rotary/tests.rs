extern crate std;

use super::*;

/// Reference: f64 `sin`/`cos` of n·2π/cpr; tolerance 2e-7 (the module's bound: a few f32
/// roundings of values ≤ 1 plus the polynomials' truncation, below 1e-7 even at the largest
/// remainder |r| < 0.097 of a turn of 65 counts), over every 997th count of turns of
/// 3 600 000, 1000 (not a multiple of 64), 65 and 100 (the largest remainders) and 2^31
/// counts, every count of the small turns, and the last counts of each.
#[test]
fn sincos_from_table_and_polynomial() {
    for cpr in [3_600_000u32, 1000, 65, 100, 1 << 31] {
        let t = SinCosTable::new(cpr);
        let worst = largest_error(cpr, |n| t.sincos(n), |a| (a.sin(), a.cos()));
        assert!(worst < 2e-7, "cpr {cpr}: largest error {worst:e}");
    }
}

/// The same for C's table of (sin, 1 − cos) (reference: f64 `sin` and `1 − cos`; tolerance
/// 2.5e-7, the module's bound for C: roundings at the magnitude of 1 − cos θ ≤ 2).
#[test]
fn sin_versine_from_table_and_polynomial() {
    for cpr in [3_600_000u32, 1000, 65, 100, 1 << 31] {
        let t = SinCosTable::new_versine(cpr);
        let worst = largest_error(cpr, |n| t.sin_versine(n), |a| (a.sin(), 1.0 - a.cos()));
        assert!(worst < 2.5e-7, "cpr {cpr}: largest error {worst:e}");
    }
}

/// The largest difference of both values of `table(n)` from `exact(n·2π/cpr)` over every
/// 997th count of a turn of `cpr` counts (every count below 10 000 counts) and its last 5.
fn largest_error(
    cpr: u32,
    table: impl Fn(u32) -> (f32, f32),
    exact: impl Fn(f64) -> (f64, f64),
) -> f64 {
    let mut worst = 0.0f64;
    let stride = if cpr < 10_000 { 1 } else { 997 };
    for n in (0..cpr).step_by(stride).chain(cpr - 5..cpr) {
        let (v0, v1) = table(n);
        let (e0, e1) = exact(n as f64 * core::f64::consts::TAU / cpr as f64);
        worst = worst
            .max((v0 as f64 - e0).abs())
            .max((v1 as f64 - e1).abs());
    }
    worst
}

/// The first-order trunnion model of the module's docs in f64 with f64 sin/cos (the
/// reference for the table + polynomial sin/cos and the f32 folding): deviation
/// s(q) − e, e = R_T u + (I − R_T) o_T + ω × q, for an AC (`b` false) or BC trunnion.
fn reference_deviation(spec: &RotaryLocationSpec, upc: f64, cpr: u32, n: [i64; 5]) -> [f64; 3] {
    let b = spec.machine == RotaryMachine::BcTrunnion;
    let ang = |c: i64| c as f64 * core::f64::consts::TAU / cpr as f64;
    let (st, ct) = libm::sincos(ang(n[3]));
    let (sc, cc) = libm::sincos(ang(n[4]));
    let rc = |v: [f64; 3]| [cc * v[0] - sc * v[1], sc * v[0] + cc * v[1], v[2]];
    let rt = |v: [f64; 3]| {
        if b {
            [ct * v[0] + st * v[2], v[1], -st * v[0] + ct * v[2]]
        } else {
            [v[0], ct * v[1] - st * v[2], st * v[1] + ct * v[2]]
        }
    };
    let sub = |a: [f64; 3], c: [f64; 3]| [a[0] - c[0], a[1] - c[1], a[2] - c[2]];
    let add = |a: [f64; 3], c: [f64; 3]| [a[0] + c[0], a[1] + c[1], a[2] + c[2]];
    let cr = |a: [f64; 3], c: [f64; 3]| {
        [
            a[1] * c[2] - a[2] * c[1],
            a[2] * c[0] - a[0] * c[2],
            a[0] * c[1] - a[1] * c[0],
        ]
    };
    let f = |x: f32| x as f64;
    let urad = 1e-6;
    let o_c = [f(spec.ex0c_um), f(spec.ey0c_um), 0.0];
    let e_c = [f(spec.ea0c_urad) * urad, f(spec.eb0c_urad) * urad, 0.0];
    // A: (0, EY0A, EZ0A), (0, EB0A, EC0A); B: (EX0B, 0, EZ0B), (EA0B, 0, EC0B).
    let (o_t, e_t) = if b {
        (
            [f(spec.ey0a_um), 0.0, f(spec.ez0a_um)],
            [f(spec.eb0a_urad) * urad, 0.0, f(spec.ec0a_urad) * urad],
        )
    } else {
        (
            [0.0, f(spec.ey0a_um), f(spec.ez0a_um)],
            [0.0, f(spec.eb0a_urad) * urad, f(spec.ec0a_urad) * urad],
        )
    };
    let q = [
        (n[0] - spec.pivot_counts[0]) as f64 * upc,
        (n[1] - spec.pivot_counts[1]) as f64 * upc,
        (n[2] - spec.pivot_counts[2]) as f64 * upc - f(spec.tool_length_um),
    ];
    let u = sub(o_c, rc(o_c));
    let g = sub(e_c, rc(e_c));
    let h = sub(e_t, rt(e_t));
    let w = add(rt(g), h);
    let e = add(add(rt(u), sub(o_t, rt(o_t))), cr(w, q));
    let [ea0z, eb0z, ec0y] = spec.squareness_urad.map(|v| f(v) * urad);
    let s = [-ec0y * q[1] + eb0z * q[2], -ea0z * q[2], 0.0];
    sub(s, e)
}

/// A stage of `machine` with every location error and squareness at the large end of the
/// module's error analysis (offsets ≤ 50 µm, angles ≤ 100 µrad), the pivot off the origin and a
/// 200 mm tool.
fn large_errors(machine: RotaryMachine) -> RotaryLocationSpec {
    RotaryLocationSpec {
        machine,
        ex0c_um: 50.0,
        ey0c_um: -45.0,
        ea0c_urad: 100.0,
        eb0c_urad: -90.0,
        ey0a_um: 40.0,
        ez0a_um: -50.0,
        eb0a_urad: 80.0,
        ec0a_urad: -100.0,
        squareness_urad: [30.0, -20.0, 25.0],
        pivot_counts: [2_000_000, -1_000_000, 3_000_000],
        tool_length_um: 200_000.0,
        ..RotaryLocationSpec::ZERO_AC
    }
}

/// Reference: [`reference_deviation`] (the same first-order model in f64 with exact
/// sin/cos); tolerance 0.001 µm — the budget the module's error analysis leaves for the
/// table + polynomial sin/cos (about 1.2e-4 µm at these magnitudes) and the f32 arithmetic.
/// Offsets of 50 µm, angles of 100 µrad, squareness 30 µrad, a 200 mm tool, |q| up to about
/// 0.7 m, A and B trunnions, angles over whole turns (every 9 973rd count of each axis, the
/// two axes at unrelated angles); at 0.1 µm per count with a tool of whole counts, and at
/// 0.05 µm per count with a tool of 200 000.046875 µm (4 000 000.94 counts: the stage holds it
/// to the nearest count of Z, [`RotaryStage::tool_counts_z`], 0.003 µm long).
#[test]
fn stage_with_table_sincos_matches_the_f64_model() {
    let cpr = 3_600_000u32;
    let mut worst = 0.0f64;
    let cases = [
        (RotaryMachine::AcTrunnion, 0.1f32, 200_000.0f32),
        (RotaryMachine::BcTrunnion, 0.1, 200_000.0),
        (RotaryMachine::AcTrunnion, 0.05, 200_000.046875),
        (RotaryMachine::BcTrunnion, 0.05, 200_000.046875),
    ];
    for (machine, upc, tool) in cases {
        let spec = RotaryLocationSpec {
            tool_length_um: tool,
            ..large_errors(machine)
        };
        let stage = RotaryStage::new(&spec, [upc; 3], [cpr; 2], [0, 1, 2, 3, 4]);
        let mut i = 0i64;
        for a in (0..cpr).step_by(9973) {
            i += 1;
            let c = (a as u64 * 7 + 1_234_567) % cpr as u64;
            let n = [
                -3_000_000 + (i * 104_729) % 7_000_000,
                -6_000_000 + (i * 130_363) % 9_000_000,
                (i * 86_243) % 6_000_000,
                a as i64,
                c as i64,
            ];
            let mut cache = stage.cache_at([a, c as u32]);
            stage.refresh(&mut cache);
            let d = RotaryStage::deviation_um(&cache, stage.counts_from_pivot([n[0], n[1], n[2]]));
            let r = reference_deviation(&spec, upc as f64, cpr, n);
            for k in 0..3 {
                worst = worst.max((d[k] as f64 - r[k]).abs());
            }
        }
    }
    assert!(worst < 1e-3, "largest deviation error {worst:e} µm");
}

/// Reference: the deviation from the stored angle terms, [`RotaryStage::deviation_um`] after
/// [`RotaryStage::refresh`] (what a cycle without an angle change computes); exact (bit for
/// bit): the moving cycle's deviation is the same — from the terms in registers for the AC
/// trunnion ([`RotaryStage::refresh_deviation_ac`], the X, Y, Z, A, C cycle's), from the
/// stored terms for the BC kinds ([`RotaryStage::refresh_deviation`]) — and after it the
/// terms are stored (BC kinds) or computed from the cells ([`RotaryStage::fold_angles`], AC
/// trunnion) to the same bits, for all three kinds over whole turns of both angles.
#[test]
fn deviation_of_the_moving_cycle_equals_the_stored_terms() {
    let cpr = 3_600_000u32;
    for machine in [
        RotaryMachine::AcTrunnion,
        RotaryMachine::BcTrunnion,
        RotaryMachine::BcHead,
    ] {
        let spec = large_errors(machine);
        let stage = RotaryStage::new(&spec, [0.1, 0.2, 0.05], [cpr, cpr / 2], [0, 1, 2, 3, 4]);
        for (i, a) in (0..cpr).step_by(19_997).enumerate() {
            let c = (a as u64 * 7 + 1_234_567) % (cpr / 2) as u64;
            let n = [
                i as f32 * 1234.5 - 2.0e6,
                3.0e6 - i as f32 * 777.0,
                i as f32 * 99.0,
            ];
            let mut stored = stage.cache_at([a, c as u32]);
            stage.refresh(&mut stored);
            let want = RotaryStage::deviation_um(&stored, n);
            let mut moving = stage.cache_at([a, c as u32]);
            // The X, Y, Z, A, C cycle's refresh for the AC trunnion, the general one else.
            let d = if machine == RotaryMachine::AcTrunnion {
                stage.refresh_deviation_ac(&mut moving, n)
            } else {
                let d = stage.refresh_deviation(&mut moving, n[0], n[1], n[2]);
                [d.x, d.y, d.z]
            };
            assert_eq!(d.map(f32::to_bits), want.map(f32::to_bits));
            assert_eq!(moving.unfolded, machine == RotaryMachine::AcTrunnion);
            if moving.unfolded {
                stage.fold_angles(&mut moving);
            }
            assert!(!moving.unfolded);
            assert_eq!(moving.k.map(f32::to_bits), stored.k.map(f32::to_bits));
            assert_eq!(moving.m.map(f32::to_bits), stored.m.map(f32::to_bits));
        }
    }
}

/// Reference: `wrap` (the 64-bit modulo of the command, what the tracker replaces); exact. The
/// tracked positions within the turn of both axes equal it after every step — steps within
/// the turn, across 0 either way, of exactly ± one turn, beyond a turn, beyond i32 and
/// ±2^62 — for turns of 2 … 2^31 counts, a new turn length (a new image) after a reset of the
/// cache; and the tracker reports a change exactly when a position changed or it was not
/// primed. The coarse angle and the remainder it tracks for the sin/cos are those of the
/// division ([`SinCosTable::coarse`] of the position; exact).
#[test]
fn tracked_turn_positions_equal_the_modulo() {
    let mut next = crate::test_rng::xorshift(0x2545_F491_4F6C_DD1Du64);
    let mut checked = 0u32;
    let stage_for = |cprs: [u32; 2]| RotaryStage {
        counts_per_rev: cprs,
        sincos: [SinCosTable::new(cprs[0]), SinCosTable::new_versine(cprs[1])],
        ..RotaryStage::ZERO
    };
    for cpr in [2u32, 3, 1000, 3_600_000, (1 << 31) - 1, 1 << 31] {
        let mut cprs = [cpr, cpr / 2 + 1];
        let mut stage = stage_for(cprs);
        let mut cache = RotaryCache::NEW;
        let mut cmd = [next() as i64 >> 20, -(next() as i64 >> 30)];
        for i in 0..4000u32 {
            if i == 2000 {
                // A new image (other turn lengths) drops the cache.
                cache = RotaryCache::NEW;
                cprs = [cpr / 3 + 2, cpr];
                stage = stage_for(cprs);
            }
            let before = (cache.cpr, stage.turn(&cache));
            for (k, c) in cmd.iter_mut().enumerate() {
                let t = cprs[k] as i64;
                let r = next();
                let step = match r % 10 {
                    0 => 0,
                    1 => t,
                    2 => -t,
                    3 => (r >> 8) as i64 % (3 * t),
                    4 => (r >> 8) as i64 >> 3,
                    5 => -((r >> 8) as i64 >> 40),
                    6 => (r >> 8) as i64 % 1000 - 500,
                    _ => (r >> 8) as i64 % t - t / 2,
                };
                *c = c.wrapping_add(step).clamp(-(1 << 62), 1 << 62);
            }
            let moved = stage.track(&mut cache, cmd);
            let want = [wrap(cmd[0], cprs[0]), wrap(cmd[1], cprs[1])];
            assert_eq!(
                stage.turn(&cache),
                want,
                "turn {cpr}, cycle {i}, commands {cmd:?}"
            );
            assert_eq!(cache.cpr, cprs);
            for (k, &n) in want.iter().enumerate() {
                let coarse = stage.sincos[k].coarse(n);
                assert_eq!(
                    cache.cell[k].coarse(),
                    coarse,
                    "turn {cpr}, cycle {i}, axis {k}"
                );
            }
            assert_eq!(moved, before != (cprs, want), "turn {cpr}, cycle {i}");
            checked += 1;
        }
    }
    assert_eq!(checked, 6 * 4000);
}

/// Reference: the difference to the pivot in i64 saturated to i32, then converted (the rule
/// before the one shared fit test); exact, for each axis alone beyond i32 either way, at the
/// edges ±2^31, and all three within.
#[test]
fn counts_from_pivot_saturates_each_axis() {
    let p = [1i64 << 40, -(1 << 35), 7];
    let stage = RotaryStage {
        pivot_low_counts: p.map(|p| p - (1 << 31)),
        ..RotaryStage::ZERO
    };
    let want = |d: i64| d.clamp(i32::MIN as i64, i32::MAX as i64) as i32 as f32;
    let offsets = [
        0i64,
        12_345,
        -987_654,
        i32::MAX as i64,
        i32::MAX as i64 + 1,
        i32::MIN as i64,
        i32::MIN as i64 - 1,
        1 << 61,
        -(1 << 61),
    ];
    for (i, &a) in offsets.iter().enumerate() {
        for &b in &offsets {
            let c = offsets[(i * 5 + 3) % offsets.len()];
            let d = [a, b, c];
            let n = stage.counts_from_pivot([p[0] + a, p[1] + b, p[2] + c]);
            assert_eq!(n, d.map(want), "offsets {d:?}");
        }
    }
}

/// A wobble at the large end of a fit's (C 1…4 per turn, the tilt axis to t³; 5–20 µrad, 1–3 µm).
fn large_wobble() -> RotaryWobble {
    let mut w = RotaryWobble::NONE;
    for (k, row) in w.c.iter_mut().enumerate() {
        for (i, v) in row.iter_mut().enumerate() {
            let s = if (i + k) % 3 == 0 { -1.0 } else { 1.0 };
            *v = s * if i % 2 == 0 {
                20.0 - 3.0 * k as f32
            } else {
                3.0 - 0.5 * k as f32
            };
        }
    }
    for (d, row) in w.tilt.iter_mut().enumerate() {
        *row = [12.0, -2.0, -8.0, 1.5].map(|v| v / (d + 1) as f32);
    }
    w
}

/// The wobble's term of the deviation in f64 (the model of [`crate::rotary_wobble`] written with
/// rotation matrices): trunnion −T − W × q, head W × R_C R_B (0, 0, −L) + T, at the tilt angle `t`
/// (rad, signed) and C's angle `c`; q in µm.
fn reference_wobble(spec: &RotaryLocationSpec, t: f64, c: f64, q: [f64; 3]) -> [f64; 3] {
    let w = &spec.wobble;
    let rot = |axis: usize, a: f64, v: [f64; 3]| {
        let (s, co) = libm::sincos(a);
        let (i, j) = ((axis + 1) % 3, (axis + 2) % 3);
        let mut o = v;
        o[i] = co * v[i] - s * v[j];
        o[j] = s * v[i] + co * v[j];
        o
    };
    let add = |a: [f64; 3], b: [f64; 3]| [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
    let cr = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let (mut wc, mut rc) = ([0.0; 3], [0.0; 3]);
    for (k, h) in w.c.iter().enumerate() {
        let kc = (k + 1) as f64 * c;
        let (s, co) = (libm::sin(kc), libm::cos(kc));
        let v = |i: usize| h[i] as f64 * co + h[i + 4] as f64 * s;
        wc = add(wc, [v(0) * 1e-6, v(2) * 1e-6, 0.0]);
        rc = add(rc, [v(1), v(3), 0.0]);
    }
    let about_x = spec.machine == RotaryMachine::AcTrunnion;
    let p = if about_x { 1 } else { 0 };
    let (mut wt, mut rt) = ([0.0; 3], [0.0; 3]);
    for (d, row) in w.tilt.iter().enumerate() {
        let td = t.powi(d as i32 + 1);
        wt[p] += row[0] as f64 * 1e-6 * td;
        rt[p] += row[1] as f64 * td;
        wt[2] += row[2] as f64 * 1e-6 * td;
        rt[2] += row[3] as f64 * td;
    }
    let tilt_axis = if about_x { 0 } else { 1 };
    if spec.machine == RotaryMachine::BcHead {
        let v = rot(2, c, rot(1, t, [0.0, 0.0, -(spec.tool_length_um as f64)]));
        let big_w = add(wc, rot(2, c, wt));
        add(cr(big_w, v), add(rc, rot(2, c, rt)))
    } else {
        let big_w = add(rot(tilt_axis, t, wc), wt);
        let big_t = add(rot(tilt_axis, t, rc), rt);
        let m = cr(big_w, q);
        [-big_t[0] - m[0], -big_t[1] - m[1], -big_t[2] - m[2]]
    }
}

/// Reference: [`reference_wobble`] (f64, exact sin/cos and powers); tolerance 0.001 µm, the
/// module's budget for the stage's f32 arithmetic (the table + polynomial sin/cos and the
/// Chebyshev recurrence err by a few 1e-7 relative: 20 µrad at 0.7 m, 3 µm, 4 harmonics give a
/// few 1e-5 µm). The stage's deviation with the wobble minus the same stage's without, all three
/// kinds, the tilt over ±110° (negative angles above half a turn) and C over the turn, µm per
/// count 0.1, |q| up to about 0.7 m.
#[test]
fn wobble_adds_the_f64_model_to_the_deviation() {
    let cpr = 3_600_000u32;
    let upc = 0.1f32;
    let mut worst = 0.0f64;
    let mut largest = 0.0f64;
    for machine in [
        RotaryMachine::AcTrunnion,
        RotaryMachine::BcTrunnion,
        RotaryMachine::BcHead,
    ] {
        let plain = large_errors(machine);
        let spec = RotaryLocationSpec {
            wobble: large_wobble(),
            ..plain
        };
        let with = RotaryStage::new(&spec, [upc; 3], [cpr; 2], [0, 1, 2, 3, 4]);
        let without = RotaryStage::new(&plain, [upc; 3], [cpr; 2], [0, 1, 2, 3, 4]);
        assert!(with.has_wobble() && !without.has_wobble());
        for i in 0..400i64 {
            let t_counts = (i * 7_919) % 2_200_000 - 1_100_000;
            let a = t_counts.rem_euclid(cpr as i64) as u32;
            let c = ((i * 104_729 + 17) % cpr as i64) as u32;
            let n = [
                -3_000_000 + (i * 104_729) % 7_000_000,
                -6_000_000 + (i * 130_363) % 9_000_000,
                (i * 86_243) % 6_000_000,
            ];
            let dev = |stage: &RotaryStage| {
                let mut cache = stage.cache_at([a, c]);
                let q = stage.counts_from_pivot(n);
                let d = stage.refresh_deviation(&mut cache, q[0], q[1], q[2]);
                [d.x, d.y, d.z]
            };
            let (d1, d0) = (dev(&with), dev(&without));
            let ang = |n: i64| n as f64 * core::f64::consts::TAU / cpr as f64;
            let pivot = with.pivot_low_counts.map(|p| p + (1 << 31));
            let q = [0, 1, 2].map(|k| (n[k] - pivot[k]) as f64 * upc as f64);
            let r = reference_wobble(&spec, ang(t_counts), ang(c as i64), q);
            for k in 0..3 {
                worst = worst.max(((d1[k] - d0[k]) as f64 - r[k]).abs());
                largest = largest.max(r[k].abs());
            }
        }
    }
    std::eprintln!("wobble term up to {largest:.1} µm; largest error {worst:e} µm");
    assert!(largest > 20.0, "the wobble's term reaches {largest} µm");
    assert!(
        worst < 1e-3,
        "largest error of the wobble's term {worst:e} µm"
    );
}

/// The rotary section round-trips a wobble (version 3), and refuses a non-finite or too large
/// coefficient, naming it ([`Field::RotaryWobble`], index in the order of
/// [`RotaryWobble::coefficients`]).
#[test]
fn wobble_is_validated() {
    let mut spec = RotaryLocationSpec {
        wobble: large_wobble(),
        ..large_errors(RotaryMachine::BcHead)
    };
    assert_eq!(spec.validate(), Ok(()));
    spec.wobble.tilt[1][2] = f32::NAN;
    assert_eq!(
        spec.validate(),
        Err(crate::error::ImageError::NonFinite {
            field: crate::error::Field::RotaryWobble,
            index: 32 + 6
        })
    );
    spec.wobble.tilt[1][2] = 0.0;
    spec.wobble.c[0][1] = -2.0e4;
    assert_eq!(
        spec.validate(),
        Err(crate::error::ImageError::OutOfRange {
            field: crate::error::Field::RotaryWobble,
            index: 1
        })
    );
}
