//! End-to-end tests of `axcomp diagnose` and `axcomp validate-diagnosis` (real data from `../shared`,
//! overridable with `AXCOMP_SHARED`; skipped when absent unless `CI` is set).

mod common;
use common::scratch;
use std::path::{Path, PathBuf};
use std::process::Command;

fn shared() -> Option<PathBuf> {
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/.."));
    match axcomp_data::shared_dir(root) {
        Some(d) => Some(d),
        None if std::env::var_os("CI").is_some() => panic!("../shared not found (CI is set)"),
        None => {
            println!("skipped: ../shared not found");
            None
        }
    }
}

fn axcomp(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(args)
        .output()
        .expect("run axcomp");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

fn read_json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn ess_b02_x_pitch_only_model_misses_the_reversal() {
    let Some(sh) = shared() else { return };
    let data = sh.join("data/real/ess-linear-axes-iso230/tidy/iso230_2_runs_long.csv");
    let dir = scratch("ess");
    let json = dir.join("d.json");
    let report = dir.join("report");
    let (ok, stdout, stderr) = axcomp(&[
        "diagnose",
        "--data",
        data.to_str().unwrap(),
        "--where",
        "test_id=ESS_TDU_B02_X_2022-04-06",
        "--model",
        "pitch_error",
        "--holdout",
        "cycle=5",
        "--json",
        json.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    let d = read_json(&json);
    // Contract fields.
    for k in ["train_rms_um", "holdout_rms_um", "holdout_max_um"] {
        assert!(d["gap"][k].as_f64().unwrap() > 0.0, "gap.{k}");
    }
    assert!(d["where"].as_array().is_some_and(|w| !w.is_empty()));
    for k in ["variable", "from", "to", "share"] {
        assert!(!d["where"][0][k].is_null(), "where[0].{k}");
    }
    // Acceptance: the verdict is `reversal` and the held-out gap shrinks by more than half
    // (shrink_pct = 100·(1 − after/before) on the 18 held-out rows of cycle 5).
    assert_eq!(d["verdict"], "reversal", "{stdout}");
    let top = &d["effects"][0];
    assert_eq!(top["kind"], "reversal");
    let shrink = top["shrink_pct"].as_f64().unwrap();
    assert!(shrink > 50.0, "held-out shrink {shrink} %");
    let before = d["gap"]["holdout_rms_um"].as_f64().unwrap();
    let after = top["holdout_rms_after_um"].as_f64().unwrap();
    assert!((shrink - 100.0 * (1.0 - after / before)).abs() < 1e-9);
    for k in [
        "kind",
        "score",
        "params",
        "holdout_rms_after_um",
        "shrink_pct",
    ] {
        assert!(!top[k].is_null(), "effects[0].{k}");
    }
    assert!(report.join("diagnosis.md").is_file());
    assert!(report.join("gap_target_mm.svg").is_file());
    // The rule is stated in the JSON, each candidate says whether its held-out gain is material,
    // and the verdict's gain is material by that rule (≥ 5 % of the gap and ≥ 0.05 σ).
    assert!(
        d["verdict_rule"]
            .as_str()
            .is_some_and(|r| r.contains("material"))
    );
    assert_eq!(top["material"], true);
    let gain = top["holdout_gain_um"].as_f64().unwrap();
    assert!((gain - (before - after)).abs() < 1e-9, "gain {gain}");
    assert!(gain >= 0.05 * before && gain >= 0.05 * top["noise_um"].as_f64().unwrap());
    for r in d["where"]
        .as_array()
        .unwrap()
        .iter()
        .chain(d["verdict_where"].as_array().unwrap())
    {
        let share = r["share"].as_f64().unwrap();
        assert!((0.0..=1.0).contains(&share), "share {share}");
    }
    // The reversal verdict colours the points by direction, in the before and the after panel.
    let after_svg = std::fs::read_to_string(report.join("gap_target_mm_after.svg")).unwrap();
    assert!(
        after_svg.contains("forward (+) approach") && after_svg.contains("reverse (−) approach")
    );
    let md = std::fs::read_to_string(report.join("diagnosis.md")).unwrap();
    assert!(md.contains("Verdict: `reversal`"), "{md}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn voron_frame_growth_is_attributed_to_a_thermal_lag() {
    let Some(sh) = shared() else { return };
    let data =
        sh.join("data/real/thermal-voron-frame-z/frame_exp_quant_v3_2021-06-13_05-41-53.csv");
    let dir = scratch("voron");
    let json = dir.join("d.json");
    // Z trigger position in microsteps × 2.5 µm (step_dist 0.0025 mm in the file header); frame and
    // chamber thermistors as sensors; trained on heating, judged on the cool-down (bed_target = 0).
    let (ok, stdout, stderr) = axcomp(&[
        "diagnose",
        "--data",
        data.to_str().unwrap(),
        "--rename",
        "mcu_pos_z=z_um",
        "--scale",
        "z_um=2.5",
        "--rename",
        "frame_t=frame_degC",
        "--rename",
        "chamber_t=chamber_degC",
        "--target",
        "z_um",
        "--model",
        "thermal_drift",
        "--holdout",
        "bed_target=0",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    println!("{stdout}");
    let d = read_json(&json);
    // Time-series only: no positional candidates apply.
    let na: Vec<&str> = d["not_applicable"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    for k in ["cogging", "reversal", "pitch_error", "end_effect"] {
        assert!(na.contains(&k), "{k} should not apply: {na:?}");
    }
    // What it finds (measured 2026-11-21): the instantaneous drift model extrapolates badly into the
    // cool-down (held-out RMS ≈ 123 µm); the gap lies in the cool-down time range, and a first-order lag of
    // the frame and chamber temperatures (τ ≈ 18 min) is the verdict, shrinking the held-out gap by ≈ 39 %
    // (123 → 75 µm RMS).
    assert_eq!(d["verdict"], "thermal_lag", "{stdout}");
    let shrink = d["effects"][0]["shrink_pct"].as_f64().unwrap();
    assert!(shrink > 20.0, "held-out shrink {shrink} %");
    assert_eq!(d["where"][0]["variable"], "time_s");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_input_is_named() {
    let Some(sh) = shared() else { return };
    let data = sh.join("data/real/ess-linear-axes-iso230/tidy/iso230_2_runs_long.csv");
    let d = data.to_str().unwrap();
    let w = "test_id=ESS_TDU_B02_X_2022-04-06";
    let (ok, _, err) = axcomp(&[
        "diagnose",
        "--data",
        d,
        "--where",
        w,
        "--model",
        "pitch,reversal",
        "--holdout",
        "cycle=5",
    ]);
    assert!(!ok && err.contains("unknown effect kind `pitch`"), "{err}");
    let (ok, _, err) = axcomp(&[
        "diagnose",
        "--data",
        d,
        "--where",
        w,
        "--model",
        "thermal_drift",
        "--holdout",
        "cycle=5",
    ]);
    assert!(
        !ok && err.contains("thermal_drift") && err.contains("_degC"),
        "{err}"
    );
    let (ok, _, err) = axcomp(&[
        "diagnose",
        "--data",
        d,
        "--where",
        w,
        "--model",
        "pitch_error",
        "--holdout",
        "cycle=9",
    ]);
    assert!(
        !ok && err.contains("cycle=9") && err.contains("no row"),
        "{err}"
    );
    let (ok, _, err) = axcomp(&[
        "diagnose",
        "--data",
        d,
        "--where",
        w,
        "--model",
        "pitch_error",
        "--holdout",
        "cycle=5",
        "--target",
        "nope_um",
    ]);
    assert!(!ok && err.contains("nope_um"), "{err}");
}

#[test]
fn validate_diagnosis_reduced_run_meets_sane_minima() {
    // 24 cases (18 with one effect withheld at SNR 4 or 6, 6 nulls), 3000 rows each, deterministic in the
    // seed. The targets at SNR ≥ 4 as far as 24 cases can show them: top-1 ≥ 90 % (at most 1 of 18
    // missed; measured 18 of 18), no false alarm on the 6 nulls (the target ≤ 5 % needs more nulls; the full
    // run in the README has 120), no share outside 0..1.
    let dir = scratch("validate");
    let json = dir.join("v.json");
    let (ok, stdout, stderr) = axcomp(&[
        "validate-diagnosis",
        "--cases",
        "24",
        "--seed",
        "7",
        "--snr",
        "4,6",
        "--rows",
        "3000",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    let v = read_json(&json);
    assert_eq!(v["cases"], 24);
    let fa = v["false_alarm_rate"].as_f64().unwrap();
    let top1 = v["top1_attribution"].as_f64().unwrap();
    let ratio = v["median_shrink_ratio_to_oracle"].as_f64().unwrap();
    println!("{stdout}");
    assert_eq!(v["shares_out_of_range"], 0);
    assert_eq!(fa, 0.0, "false alarms {fa}");
    assert!(top1 >= 0.9, "top-1 attribution {top1}");
    assert!(ratio >= 0.8, "median shrink / oracle {ratio}");
    assert!(stderr.contains("[24/24]"), "progress on stderr");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn validate_diagnosis_hard_harness_reduced_run() {
    // The hard harness (1,500 rows, 3 ISO cycles, held out outside the training regime) on 24 cases: 18
    // withheld at SNR 4 or 6, 6 nulls, deterministic in the seed. The full run (README: `--harness hard
    // --cases 480 --seed 1`) is the acceptance figure; here the targets as far as 24 cases show
    // them: top-1 ≥ 90 % (at most 1 of 18 missed; measured 17 of 18), no false alarm on the 6 nulls, no
    // share outside 0..1.
    let dir = scratch("validate-hard");
    let json = dir.join("v.json");
    let (ok, stdout, stderr) = axcomp(&[
        "validate-diagnosis",
        "--harness",
        "hard",
        "--cases",
        "24",
        "--seed",
        "3",
        "--snr",
        "4,6",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    let v = read_json(&json);
    assert_eq!(v["harness"], "hard");
    assert_eq!(v["rows_per_case"], 1500);
    let fa = v["false_alarm_rate"].as_f64().unwrap();
    let top1 = v["top1_attribution"].as_f64().unwrap();
    println!("{stdout}");
    assert_eq!(fa, 0.0, "false alarms {fa}");
    assert!(top1 >= 0.9, "top-1 attribution {top1}");
    assert_eq!(v["shares_out_of_range"], 0);
    let (ok, _, err) = axcomp(&["validate-diagnosis", "--harness", "nope", "--cases", "1"]);
    assert!(
        !ok && err.contains("--harness") && err.contains("nope"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn large_campaign_report_stays_small_with_one_time_unit() {
    // 60,000 simulated survey rows (20 % held out at offset 100 mm): progress on stderr, and every SVG
    // thinned to ≤ 4,000 points per series (well below 1 MB), time in one unit chosen by the span.
    let dir = scratch("large");
    let csv = dir.join("s.csv");
    let (ok, _, err) = axcomp(&[
        "sim",
        "--plan",
        "survey",
        "--rows",
        "60000",
        "--effects",
        "pitch_error,reversal,thermal_drift",
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
    let report = dir.join("report");
    let (ok, stdout, stderr) = axcomp(&[
        "diagnose",
        "--data",
        csv.to_str().unwrap(),
        "--model",
        "pitch_error,reversal",
        "--holdout",
        "offset_mm=100",
        "--report",
        report.to_str().unwrap(),
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    assert!(stderr.contains("diagnose: searching"), "progress: {stderr}");
    let mut n_svg = 0;
    for e in std::fs::read_dir(&report).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "svg") {
            n_svg += 1;
            let len = std::fs::metadata(&p).unwrap().len();
            assert!(len < 1_000_000, "{}: {len} bytes", p.display());
            let svg = std::fs::read_to_string(&p).unwrap();
            if p.to_string_lossy().contains("time_s") {
                let units = ["time (s)", "time (min)", "time (h)"];
                assert_eq!(
                    units.iter().filter(|u| svg.contains(*u)).count(),
                    1,
                    "{}",
                    p.display()
                );
            }
        }
    }
    assert!(n_svg >= 2);
    let _ = std::fs::remove_dir_all(&dir);
}
