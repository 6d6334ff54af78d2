//! The rotary probe route end to end: a touch probe (the twin's kinematic probe, with its lobing,
//! speed-dependent pretravel, bounces and false triggers) touches a Ø25 mm sphere on the table of a five-axis
//! twin at each pose of K4 and two C circles; `axcomp fit probe --group a_deg,c_deg --centres-out` turns each
//! pose's touches into a fitted sphere centre (an R-test row); `axcomp fit rtest --data centres.csv` identifies
//! the location errors. Reference: the twin's truth.

use std::path::Path;

use axcomp_kinematics::rotary::{
    FiveAxis, MachineKind, N_LOCATION, N_SETUP, Pose, c_circle, k4_path, pose_on_sphere,
};
use axcomp_twin::five_axis::FiveAxisTwin;
use axcomp_twin::probe::{ProbeModel, ProbePlan, simulate_touches, touches_csv};

mod common;
use common::{axcomp_in, read_json, scratch};

/// The sphere on the table (table frame), mm.
const SPHERE_MM: [f64; 3] = [150.0, 0.0, 100.0];

/// Poses: K4 (36 poses, tilt 0 → −60° → 0) and C circles at tilt 0° and −60° (18 poses each, C offset by 5°
/// so that no (a, c) pair repeats one of K4's).
fn poses(m: &FiveAxis) -> Vec<Pose> {
    let mut v = k4_path(m, SPHERE_MM, -60.0, 36);
    for tilt in [0.0, -60.0] {
        v.extend(
            c_circle(m, SPHERE_MM, tilt, 18)
                .into_iter()
                .map(|p| pose_on_sphere(m, SPHERE_MM, tilt, p.c_deg + 5.0)),
        );
    }
    v
}

/// The touch CSV of a probing campaign on the twin `twin` (seed `seed`): at each pose the machine is
/// commanded to put the stylus-tip centre at the nominal sphere centre; the sphere actually sits at the
/// commanded tool point plus the twin's displacement d = S − T there (its exact location-error model, the
/// sphere's set-up offset included, no reading noise: the probe brings its own).
fn probe_campaign(twin: &FiveAxisTwin, seed: u64) -> String {
    campaign(twin, seed, false)
}

/// Path of pose `k` of [`poses`]: `K4`, `C-circle@0`, `C-circle@-60`.
fn path_of(k: usize) -> &'static str {
    match k {
        0..36 => "K4",
        36..54 => "C-circle@0",
        _ => "C-circle@-60",
    }
}

/// [`probe_campaign`]; `with_path`: each touch also carries its pose's `path` and the twin's time (30 s per
/// pose: its drifts, when switched on, move on during the campaign).
fn campaign(twin: &FiveAxisTwin, seed: u64, with_path: bool) -> String {
    let probe = ProbeModel::kinematic_demo();
    let mut csv = String::new();
    for (k, pose) in poses(&twin.machine).iter().enumerate() {
        let time_s = if with_path { 30.0 * k as f64 } else { 0.0 };
        let d = twin.reading(pose, SPHERE_MM, 0, time_s);
        let centre = [0, 1, 2].map(|i| pose.p_mm[i] + d[i] * 1e-3);
        let plan = ProbePlan::calibration(
            centre,
            25.0,
            &[-30.0, 0.0, 30.0, 60.0, 90.0],
            12,
            &[100.0, 300.0],
            1,
        );
        let touches = simulate_touches(&probe, &plan, seed * 1000 + k as u64);
        for (i, line) in touches_csv(&touches).lines().enumerate() {
            if i == 0 {
                if k == 0 {
                    csv.push_str(&format!("{line},a_deg,c_deg,cmd_x_mm,cmd_y_mm,cmd_z_mm"));
                    csv.push_str(if with_path { ",path\n" } else { "\n" });
                }
                continue;
            }
            csv.push_str(&format!(
                "{line},{},{},{},{},{}",
                pose.tilt_deg, pose.c_deg, pose.p_mm[0], pose.p_mm[1], pose.p_mm[2]
            ));
            if with_path {
                csv.push_str(&format!(",{}", path_of(k)));
            }
            csv.push('\n');
        }
    }
    csv
}

fn run_ok(args: &[&str], dir: &Path) {
    let o = axcomp_in(args, dir);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `fit probe --group a_deg,c_deg --centres-out centres.csv` on `touches.csv` in `dir`.
fn fit_probe_centres(dir: &Path) {
    for f in ["centres.csv", "probe.json"] {
        let _ = std::fs::remove_file(dir.join(f));
    }
    run_ok(
        &[
            "fit",
            "probe",
            "--data",
            "touches.csv",
            "--sphere-diameter-mm",
            "25",
            "--group",
            "a_deg,c_deg",
            "--centres-out",
            "centres.csv",
            "--json",
            "probe.json",
        ],
        dir,
    );
}

/// The probe's zero uncertainty, measured as a shop would qualify it: the same touch plan on a machine
/// without location errors and a sphere exactly where commanded (seeds 1001–1020, never the route's), so every
/// probed centre should read d = 0; per seed the mean of the 72 centres' d is the zero error of that
/// calibration. Returns its RMS over the seeds per axis (µm): the standard uncertainty of the zero, bias
/// included.
fn probe_zero_std_um(dir: &Path) -> [f64; 3] {
    let mut sum2 = [0.0; 3];
    let seeds = 1001..=1020u64;
    let n = seeds.clone().count() as f64;
    for seed in seeds {
        let mut twin = FiveAxisTwin::random(FiveAxis::new(MachineKind::AcTrunnion, 0.0), seed);
        twin.location = [0.0; N_LOCATION];
        for s in twin.setup_offsets_um.iter_mut() {
            *s = [0.0; N_SETUP];
        }
        std::fs::write(dir.join("touches.csv"), probe_campaign(&twin, seed)).unwrap();
        fit_probe_centres(dir);
        let centres = std::fs::read_to_string(dir.join("centres.csv")).unwrap();
        let mut mean = [0.0; 3];
        let mut rows = 0.0;
        for line in centres.lines().skip(1) {
            let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
            for i in 0..3 {
                mean[i] += v[5 + i];
            }
            rows += 1.0;
        }
        for i in 0..3 {
            sum2[i] += (mean[i] / rows).powi(2);
        }
    }
    sum2.map(|v| (v / n).sqrt())
}

/// One `fit rtest` on `centres.csv`: per location error (name, value, std, identified).
fn fit_rtest(dir: &Path, extra: &[&str]) -> Vec<(String, f64, Option<f64>, bool)> {
    let _ = std::fs::remove_file(dir.join("fit.json"));
    let mut args = vec![
        "fit",
        "rtest",
        "--data",
        "centres.csv",
        "--json",
        "fit.json",
    ];
    args.extend_from_slice(extra);
    run_ok(&args, dir);
    let fit = read_json(&dir.join("fit.json"));
    // The JSON says which zero uncertainty the std include: the centres file's shared-error columns unless
    // --head-zero-std-um overrides them.
    let source = fit["zero_uncertainty"]["source"].as_str().unwrap();
    let expect = if extra.contains(&"--head-zero-std-um") {
        "--head-zero-std-um"
    } else {
        "data columns"
    };
    assert!(source.starts_with(expect), "{extra:?}: {source}");
    MachineKind::AcTrunnion
        .location_names()
        .iter()
        .map(|name| {
            let e = &fit["location_errors"][name];
            (
                name.to_string(),
                e["value"].as_f64().unwrap(),
                e["std"].as_f64(),
                e["identified"] == true,
            )
        })
        .collect()
}

/// Reference: the twin's truth (AC trunnion, seeds 1–20; offsets 5–50 µm, tilts and squareness 10–100 µrad).
/// The probe touches rings from 30° below the equator to the top (with touches from above only, the
/// probe's calibrated z zero is biased by up to 4 µm and lands in EZ0A, seen in a first version of this test).
///
/// The default `fit rtest` on the centres file includes the probe calibration's uncertainty that every
/// pose's centre shares: `fit probe --centres-out` writes it as the columns `zero1_dx_um …` (the calibration
/// fit's coefficient covariance propagated through each pose's centre fit), `fit rtest` propagates them into
/// the std (`axcomp_rtest::fit_shared`). A constant offset of all probed centres is exactly a change of EX0C,
/// EY0A, EZ0A with the sphere's set-up offset, so without it their std (≈ 0.05 µm) is too small.
///
/// Measured (this test prints it; seeds 1–20, and 1–200 in the ignored test below):
/// - default: 212 of 220 = 96.4 % (2108 of 2200 = 95.8 %) within 2 × the reported std, largest 2.8 (3.6)
///   std. Before the shared error was written (zero taken as exact) 92.3 % (91.8 %); before each pose's
///   outlier flags were iterated (`fit probe`: a 60 µm glitch stayed in beside a 400 µm false trigger at
///   seed 116's first pose) the largest was 4.8 std.
/// - `--head-zero-std-um SX,SY,SZ` with the zero's standard uncertainty measured by a separate qualification
///   ([`probe_zero_std_um`]: 0.010 / 0.012 / 0.087 µm): 212 of 220 (2107 of 2200 = 95.8 %), largest 2.6
///   (3.6) std — the propagated calibration uncertainty (z 0.114 µm) and the qualification agree.
/// - `--free-head-zero`: EX0C, EY0A, EZ0A reported not identified; 136 of 140 (1341 of 1400) of the rest
///   within 2 std.
///
/// Asserted: the default ≥ 95 % within 2 std (the required figure; 220 cases, binomial spread of a correct
/// 95.45 % coverage ±1.4 %, on 200 seeds ±0.45 %) and none beyond 6 std (probability 2e-9 per case for a
/// correct std); with the qualified zero ≥ 93 % (200 seeds ≥ 95 %) and none beyond 6 std; with
/// `--free-head-zero` ≥ 90 % of the rest.
#[test]
fn probed_sphere_centres_identify_the_location_errors() {
    route(20, "probe-route", 0.93);
}

/// The same over seeds 1–200 (2200 cases, binomial spread ±0.45 %): `cargo test -p axcomp --test
/// rotary_probe_route_cli -- --ignored --nocapture` (≈ 20 s).
#[test]
#[ignore]
fn probe_route_two_hundred_seeds() {
    route(200, "probe-route-200", 0.95);
}

/// Share of the default fit's estimates that must lie within 2 std of the truth: the required 95 %.
const DEFAULT_COVERAGE: f64 = 0.95;
/// Largest deviation (in reported std) tolerated for any estimate.
const WORST_STD: f64 = 6.0;

/// Seeds 1..=`n` of the probe route (see the test above), asserting its figures: the default fit at least
/// [`DEFAULT_COVERAGE`] within 2 std; with the qualified zero uncertainty at least `min_coverage_zero`.
fn route(n: u64, dir_name: &str, min_coverage_zero: f64) {
    let dir = scratch(dir_name);
    let (mut within, mut total, mut worst) = (0, 0, 0.0f64);
    let (mut within_free, mut total_free) = (0, 0);
    let (mut within_zero, mut total_zero, mut worst_zero) = (0, 0, 0.0f64);
    let zero_std = probe_zero_std_um(&dir);
    let zero_arg = format!("{},{},{}", zero_std[0], zero_std[1], zero_std[2]);
    println!(
        "probe zero uncertainty (qualification, seeds 1001–1020): {:.3} / {:.3} / {:.3} µm (X/Y/Z)",
        zero_std[0], zero_std[1], zero_std[2]
    );
    for seed in 1..=n {
        let machine = FiveAxis::new(MachineKind::AcTrunnion, 0.0);
        let twin = FiveAxisTwin::random(machine, seed);
        std::fs::write(dir.join("touches.csv"), probe_campaign(&twin, seed)).unwrap();
        fit_probe_centres(&dir);
        let centres = std::fs::read_to_string(dir.join("centres.csv")).unwrap();
        // The contract's columns first, then the calibration's shared error (zero1_dx_um, …).
        let header = centres.lines().next().unwrap();
        assert!(
            header.starts_with(
                "x_mm,y_mm,z_mm,a_deg,c_deg,dx_um,dy_um,dz_um,zero1_dx_um,zero1_dy_um,zero1_dz_um"
            ),
            "{header}"
        );
        assert_eq!(centres.lines().count(), 1 + poses(&machine).len());
        let mut line = format!("seed {seed}:");
        for (k, (name, v, s, identified)) in fit_rtest(&dir, &[]).into_iter().enumerate() {
            assert!(identified, "seed {seed} {name}: not identified");
            let s = s.unwrap();
            let z = (v - twin.location[k]).abs() / s;
            line += &format!(
                " {name} {v:.2}±{s:.2} (truth {:.2}, {z:.1}σ)",
                twin.location[k]
            );
            worst = worst.max(z);
            total += 1;
            within += (z <= 2.0) as usize;
        }
        println!("{line}");
        for (k, (name, v, s, identified)) in fit_rtest(&dir, &["--head-zero-std-um", &zero_arg])
            .into_iter()
            .enumerate()
        {
            assert!(identified, "seed {seed} {name}: not identified");
            let z = (v - twin.location[k]).abs() / s.unwrap();
            worst_zero = worst_zero.max(z);
            if z > 2.0 {
                println!("  with the zero's uncertainty: seed {seed} {name} {z:.2} std");
            }
            total_zero += 1;
            within_zero += (z <= 2.0) as usize;
        }
        for (k, (name, v, s, identified)) in fit_rtest(&dir, &["--free-head-zero"])
            .into_iter()
            .enumerate()
        {
            if ["EX0C", "EY0A", "EZ0A"].contains(&name.as_str()) {
                assert!(!identified, "seed {seed} {name}: needs the probe's zero");
                continue;
            }
            if identified {
                total_free += 1;
                within_free += ((v - twin.location[k]).abs() <= 2.0 * s.unwrap()) as usize;
            }
        }
    }
    println!(
        "default fit: {within} of {total} within 2 std, largest {worst:.2} std; \
         --free-head-zero: {within_free} of {total_free} identified ones within 2 std; \
         --head-zero-std-um {zero_arg}: {within_zero} of {total_zero} within 2 std, largest {worst_zero:.2} std"
    );
    assert!(
        within as f64 >= DEFAULT_COVERAGE * total as f64,
        "default: {within} of {total} within 2 std"
    );
    assert!(
        worst <= WORST_STD,
        "default: largest deviation {worst:.2} std"
    );
    assert!(
        within_zero as f64 >= min_coverage_zero * total_zero as f64,
        "with the zero's uncertainty: {within_zero} of {total_zero} within 2 std"
    );
    assert!(
        worst_zero <= WORST_STD,
        "with the zero's uncertainty: largest {worst_zero:.2} std"
    );
    assert!(
        total_free as u64 >= n * 6,
        "identified with --free-head-zero: {total_free}"
    );
    assert!(
        within_free as f64 >= 0.9 * total_free as f64,
        "{within_free} of {total_free}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--head-zero-std-um` bad input: a negative or non-numeric value, two values, or together with
/// `--free-head-zero` → a clear error naming the option, and no output written.
#[test]
fn head_zero_std_bad_input_is_refused() {
    let dir = scratch("probe-route-bad");
    let twin = FiveAxisTwin::random(FiveAxis::new(MachineKind::AcTrunnion, 0.0), 3);
    std::fs::write(dir.join("touches.csv"), probe_campaign(&twin, 3)).unwrap();
    fit_probe_centres(&dir);
    for (value, extra, expect) in [
        ("-0.1", None, "--head-zero-std-um"),
        ("abc", None, "--head-zero-std-um"),
        ("0.1,0.2", None, "one value or three"),
        ("0.1", Some("--free-head-zero"), "--free-head-zero"),
    ] {
        let mut args = vec![
            "fit",
            "rtest",
            "--data",
            "centres.csv",
            "--json",
            "bad.json",
            "--head-zero-std-um",
            value,
        ];
        args.extend(extra);
        let o = axcomp_in(&args, &dir);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!dir.join("bad.json").exists());
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The probe route on a machine whose location errors are zero but whose motion carries every effect beyond
/// the model (rotary positioning, wobble, run-out, linear geometry, thermal and set-up drift over a 36-minute
/// campaign): the touches carry their pose's `path`, `fit probe --centres-out` carries it into the R-test
/// rows, and `fit rtest --holdout path=C-circle@0` judges the circle at 0° never fitted against the plain
/// reference (the nominal kinematics with the sphere's set-up offsets only, fitted on the same rows), seeds
/// 1–20. Measured: the full model loses to the plain reference in 15 of 20 seeds, the default in 0 (3 with
/// the point comparison of leave-one-path-out RMS before the paired-gain rule: seeds 4, 9, 14, by 0.0–2.8
/// µm). Asserted (the measured figures, deterministic seeds):
/// the default loses to the plain reference in at most 3 of 20 seeds and never to the nominal kinematics
/// without correction; the JSON names what the default selection did.
#[test]
fn probe_route_with_effects_beyond_the_model_does_no_harm() {
    use axcomp_twin::five_axis::FiveAxisEffects;
    let dir = scratch("probe-route-effects");
    let (mut full_loses, mut default_loses, mut fixed) = (0, 0, 0);
    for seed in 1..=20u64 {
        let mut twin = FiveAxisTwin::random(FiveAxis::new(MachineKind::AcTrunnion, 0.0), seed);
        twin.location = [0.0; N_LOCATION];
        twin.effects = FiveAxisEffects::all_but_time_drift();
        std::fs::write(dir.join("touches.csv"), campaign(&twin, seed, true)).unwrap();
        fit_probe_centres(&dir);
        let centres = std::fs::read_to_string(dir.join("centres.csv")).unwrap();
        assert!(
            centres.starts_with("x_mm,y_mm,z_mm,a_deg,c_deg,path,dx_um"),
            "{}",
            centres.lines().next().unwrap()
        );
        let _ = std::fs::remove_file(dir.join("fit.json"));
        run_ok(
            &[
                "fit",
                "rtest",
                "--data",
                "centres.csv",
                "--holdout",
                "path=C-circle@0",
                "--json",
                "fit.json",
            ],
            &dir,
        );
        let j = read_json(&dir.join("fit.json"));
        let (model, full, nominal, setup) = common::rtest_comparison_rms_um(&j);
        let n_fixed = j["selection"]["fixed"].as_array().unwrap().len();
        println!(
            "seed {seed}: held-out RMS model {model:.3}, full {full:.3}, nominal {nominal:.3}, set-up only {setup:.3} µm; {n_fixed} fixed by the selection"
        );
        assert_eq!(j["selection"]["applied"], true);
        assert!(model < nominal, "seed {seed}");
        full_loses += (full > setup) as usize;
        default_loses += (model > setup) as usize;
        fixed += (n_fixed > 0) as usize;
    }
    println!(
        "probe route, effects beyond the model, location errors zero: held-out worse than the plain reference: full model {full_loses}, default {default_loses} of 20 (selection applied in {fixed})"
    );
    assert!(default_loses <= 3, "default loses in {default_loses} of 20");
    let _ = std::fs::remove_dir_all(&dir);
}
