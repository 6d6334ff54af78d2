//! `axcomp fit rtest` and `axcomp plan rtest` end to end on five-axis twin data: the contract's JSON, the
//! report, the model file read back through `axcomp_rtest::predict_rows`, and bad input (clear error, nothing
//! written).

use std::path::Path;
use std::process::{Command, Output};

use axcomp_kinematics::rotary::{FiveAxis, MachineKind};
use axcomp_twin::five_axis::{FiveAxisTwin, standard_paths};

mod common;
use common::scratch;

fn axcomp(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("running axcomp")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// K4 run 1, C circles at 0° and −60°, K4 run 2 on an AC trunnion twin (seed 3, σ = 0.3 µm).
fn twin_csv() -> String {
    let m = FiveAxis::new(MachineKind::AcTrunnion, 0.0);
    let twin = FiveAxisTwin::random(m, 3);
    let paths = standard_paths(&m, [150.0, 0.0, 100.0], -60.0, 72, &[0.0, -60.0], 36, None);
    twin.measure(&paths, 3).to_csv_string()
}

fn fails(dir: &Path, csv: &str, extra: &[&str], want: &str) {
    std::fs::write(dir.join("bad.csv"), csv).unwrap();
    let mut args = vec![
        "fit",
        "rtest",
        "--data",
        "bad.csv",
        "--json",
        "out.json",
        "--out",
        "model.json",
    ];
    args.extend_from_slice(extra);
    let o = axcomp(&args, dir);
    let err = stderr(&o);
    assert!(!o.status.success(), "{extra:?} succeeded");
    assert!(err.contains(want), "stderr lacks `{want}`:\n{err}");
    assert!(
        !dir.join("out.json").exists() && !dir.join("model.json").exists(),
        "wrote output on error"
    );
}

/// Reference: the twin's known truth, σ = 0.3 µm. The held-out K4 run is predicted at the noise level
/// (≤ 1.1 σ = 0.33 µm), its ISO 10791-6 K4 ranges shrink ≥ 90 %, and the model file read back through
/// `predict_rows` reproduces the held-out RMS (tolerance 1e-9 µm: same arithmetic).
#[test]
fn fit_rtest_json_report_and_model() {
    let dir = scratch("fit");
    std::fs::write(dir.join("rtest.csv"), twin_csv()).unwrap();
    let o = axcomp(
        &[
            "fit",
            "rtest",
            "--data",
            "rtest.csv",
            "--holdout",
            "run=2",
            "--json",
            "fit.json",
            "--report",
            "rep",
            "--out",
            "model.json",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("fit.json")).unwrap()).unwrap();
    let le = j["location_errors"].as_object().unwrap();
    for n in [
        "EX0C", "EY0C", "EA0C", "EB0C", "EY0A", "EZ0A", "EB0A", "EC0A", "EA0Z", "EB0Z", "EC0Y",
    ] {
        let e = &le[n];
        assert_eq!(e["identified"], true, "{n}");
        assert!(e["value"].is_f64() && e["std"].as_f64().unwrap() > 0.0);
        assert!(e["unit"] == "um" || e["unit"] == "urad");
    }
    assert_eq!(le.len(), 11);
    assert!(j["condition_number"].as_f64().unwrap() < 100.0);
    let hold = j["holdout_rms_um"].as_f64().unwrap();
    assert!(hold <= 0.33, "held-out RMS {hold}");
    assert!(j["raw_rms_um"].as_f64().unwrap() > 10.0);
    assert!(j["fit_rms_um"].as_f64().unwrap() <= 0.33);
    for c in ["dx_um", "dy_um", "dz_um"] {
        let before = j["k4"]["before"][c].as_f64().unwrap();
        let after = j["k4"]["after"][c].as_f64().unwrap();
        assert!(after <= 0.1 * before, "K4 {c}: {before} → {after}");
    }
    assert!(j["setup_offsets"]["1"]["sphere"]["dx_um"].is_f64());
    let md = std::fs::read_to_string(dir.join("rep/report.md")).unwrap();
    assert!(md.contains("Sign convention"));
    for f in [
        "path_dx.svg",
        "path_dy.svg",
        "path_dz.svg",
        "rotary_range.svg",
    ] {
        assert!(
            std::fs::read_to_string(dir.join("rep").join(f))
                .unwrap()
                .starts_with("<svg")
        );
    }
    // The model file, read back and predicted on the held-out rows without their readings.
    let model: axcomp_rtest::RtestModel =
        serde_json::from_str(&std::fs::read_to_string(dir.join("model.json")).unwrap()).unwrap();
    let ds =
        axcomp_data::Dataset::load(&dir.join("rtest.csv"), &axcomp_data::LoadOptions::default())
            .unwrap();
    let pred = axcomp_rtest::predict_rows(&model, &ds).unwrap();
    let run = ds.run().unwrap();
    let (dx, dy, dz) = (
        ds.numeric("dx_um").unwrap(),
        ds.numeric("dy_um").unwrap(),
        ds.numeric("dz_um").unwrap(),
    );
    let mut ss = 0.0;
    let mut n = 0;
    for i in 0..pred.len() {
        if run[i] == "2" {
            ss += (dx[i] - pred[i][0]).powi(2)
                + (dy[i] - pred[i][1]).powi(2)
                + (dz[i] - pred[i][2]).powi(2);
            n += 3;
        }
    }
    assert!(((ss / n as f64).sqrt() - hold).abs() < 1e-9);
    // The same through `axcomp predict` (contract: pred_dx_um, pred_dy_um, pred_dz_um), on rows without
    // their readings; tolerance 1e-6 µm (the CSV writes the predictions in decimal).
    let text = std::fs::read_to_string(dir.join("rtest.csv")).unwrap();
    let header: Vec<&str> = text
        .lines()
        .find(|l| !l.starts_with('#'))
        .unwrap()
        .split(',')
        .collect();
    let keep: Vec<bool> = header
        .iter()
        .map(|h| !matches!(*h, "dx_um" | "dy_um" | "dz_um"))
        .collect();
    let inputs: String = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| {
            let cells: Vec<&str> = l
                .split(',')
                .zip(&keep)
                .filter(|(_, k)| **k)
                .map(|(c, _)| c)
                .collect();
            cells.join(",") + "\n"
        })
        .collect();
    std::fs::write(dir.join("poses.csv"), inputs).unwrap();
    let o = axcomp(
        &[
            "predict",
            "--model",
            "model.json",
            "--data",
            "poses.csv",
            "--out",
            "pred.csv",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let out = std::fs::read_to_string(dir.join("pred.csv")).unwrap();
    let header: Vec<&str> = out.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (px, py, pz) = (col("pred_dx_um"), col("pred_dy_um"), col("pred_dz_um"));
    for (i, line) in out.lines().skip(1).enumerate() {
        let c: Vec<f64> = line
            .split(',')
            .map(|v| v.parse().unwrap_or(f64::NAN))
            .collect();
        for (k, j) in [px, py, pz].into_iter().enumerate() {
            assert!(
                (c[j] - pred[i][k]).abs() < 1e-6,
                "row {i}: {} vs {}",
                c[j],
                pred[i][k]
            );
        }
    }
}

#[test]
fn fit_rtest_cross_validation_by_path() {
    let dir = scratch("cv");
    std::fs::write(dir.join("rtest.csv"), twin_csv()).unwrap();
    let o = axcomp(
        &[
            "fit",
            "rtest",
            "--data",
            "rtest.csv",
            "--cv",
            "path",
            "--json",
            "cv.json",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("cv.json")).unwrap()).unwrap();
    // Reference: σ = 0.3 µm. Leaving out one path (K4 both runs, or one circle) still leaves all 11
    // determined, so every path is predicted at the noise level: ≤ 1.1 σ.
    assert!(
        j["cv_rms_um"].as_f64().unwrap() <= 0.33,
        "{}",
        j["cv_rms_um"]
    );
    assert_eq!(j["k4"]["from"], "cross-validated prediction");
}

/// A rank-deficient set (one C circle at tilt 0) is fitted, and the parameters it cannot determine are
/// flagged with reasons, not invented.
#[test]
fn rank_deficient_set_flags_parameters() {
    let dir = scratch("deficient");
    let csv = twin_csv();
    let mut keep: Vec<&str> = csv.lines().take(2).collect();
    keep.extend(csv.lines().filter(|l| l.contains(",C-circle@0,")));
    std::fs::write(dir.join("circle.csv"), keep.join("\n")).unwrap();
    let o = axcomp(
        &["fit", "rtest", "--data", "circle.csv", "--json", "c.json"],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("c.json")).unwrap()).unwrap();
    let flagged: Vec<&str> = j["location_errors"]
        .as_object()
        .unwrap()
        .iter()
        .filter(|(_, v)| v["identified"] == false)
        .map(|(k, _)| k.as_str())
        .collect();
    // A circle at tilt 0 never moves the tilt axis: its offsets and tilts cannot show.
    for n in ["EY0A", "EZ0A", "EB0A", "EC0A"] {
        assert!(flagged.contains(&n), "{n} not flagged: {flagged:?}");
        assert!(j["location_errors"][n]["reason"].as_str().unwrap().len() > 10);
        assert!(j["location_errors"][n]["std"].is_null());
    }
}

#[test]
fn plan_rtest_recommends_circles() {
    let dir = scratch("plan");
    let o = axcomp(
        &["plan", "rtest", "--sigma-um", "0.3", "--json", "plan.json"],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("plan.json")).unwrap()).unwrap();
    let cands = j["candidates"].as_array().unwrap();
    assert_eq!(cands[0]["paths"], serde_json::json!(["K4"]));
    assert_eq!(cands[0]["all_identified"], false);
    let rec = &cands[j["recommended"].as_u64().unwrap() as usize];
    assert_eq!(rec["all_identified"], true);
    assert!(
        rec["paths"]
            .as_array()
            .unwrap()
            .iter()
            .any(|p| p.as_str().unwrap().starts_with("C@"))
    );
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("recommended:"), "{out}");
}

#[test]
fn bad_input_is_a_clear_error_and_writes_nothing() {
    let dir = scratch("bad");
    let csv = twin_csv();
    let lines: Vec<&str> = csv.lines().collect();
    // lines[0] comment, [1] header, [2..] rows; row at index 3 is file line 4.
    let edit = |i: usize, f: &dyn Fn(&str) -> String| -> String {
        let mut v: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
        v[i] = f(&v[i]);
        v.join("\n")
    };
    let set_field = |line: &str, k: usize, val: &str| -> String {
        let mut f: Vec<String> = line.split(',').map(|s| s.to_string()).collect();
        f[k] = val.to_string();
        f.join(",")
    };
    // Angle out of range (a_deg is field 3).
    fails(
        &dir,
        &edit(3, &|l| set_field(l, 3, "200")),
        &[],
        "out of range",
    );
    // NaN reading (dx_um is field 5).
    fails(&dir, &edit(3, &|l| set_field(l, 5, "NaN")), &[], "dx_um");
    // A pose repeated with a conflicting reading in the same path and run.
    let mut v: Vec<String> = lines.iter().map(|s| s.to_string()).collect();
    v.insert(4, set_field(lines[3], 5, "999"));
    fails(&dir, &v.join("\n"), &[], "conflicting readings");
    // A path with a single pose.
    fails(
        &dir,
        &edit(5, &|l| set_field(l, 8, "lonely")),
        &[],
        "single pose",
    );
    // Machine kind that does not match the columns.
    fails(&dir, &csv, &["--machine", "bc-trunnion"], "b_deg");
    fails(&dir, &csv, &["--machine", "bc-head"], "--pivot-mm");
    fails(&dir, &csv, &["--machine", "xyz"], "ac-trunnion");
}

/// The probe route: sphere centres in the R-test form, without the optional `path`, `run`, `setup` and
/// `time_s` columns (each pose's fitted centre minus the commanded tool point). Reference: σ = 0.3 µm, the
/// in-sample fit at the noise level (≤ 1.1 σ), all 11 identified, and better than the nominal kinematics.
#[test]
fn probe_route_centres_csv_is_accepted() {
    let dir = scratch("centres");
    let csv = twin_csv();
    let mut out = vec!["x_mm,y_mm,z_mm,a_deg,c_deg,dx_um,dy_um,dz_um".to_string()];
    // K4 run 1 and the C circle at 0° (no pose measured twice: a repeat needs a `run` column).
    for l in csv
        .lines()
        .skip(2)
        .filter(|l| l.contains(",K4,1,") || l.contains(",C-circle@0,"))
    {
        out.push(l.split(',').take(8).collect::<Vec<_>>().join(","));
    }
    std::fs::write(dir.join("centres.csv"), out.join("\n")).unwrap();
    let o = axcomp(
        &["fit", "rtest", "--data", "centres.csv", "--json", "c.json"],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("c.json")).unwrap()).unwrap();
    assert!(j["fit_rms_um"].as_f64().unwrap() <= 0.33);
    assert_eq!(j["beats_nominal"], true);
    assert!(
        j["location_errors"]
            .as_object()
            .unwrap()
            .values()
            .all(|v| v["identified"] == true)
    );
}

/// `fit rtest` on a twin whose location errors are zero and whose readings carry every effect beyond the
/// model (`axcomp sim --machine ac-trunnion --effects …`, seed 2): with a C circle held out and with `--cv
/// path`, the JSON compares the reported model with the full model, the nominal kinematics without
/// correction and with the set-up offsets only, on the same judged rows; the default's selection says what
/// it did; `--full-model` reports the full model. Reference: the plain reference (`nominal_setup_rms_um`);
/// the default must not lose to it here (on seeds 1–20 it loses in 2, the full model in 13: the library test
/// `default_selection_does_no_harm_with_effects_beyond_the_model`), and with location errors of the
/// specified size the selection keeps every one (`fit_rtest_json_report_and_model`'s twin, below).
#[test]
fn held_out_comparison_with_the_nominal_kinematics() {
    use axcomp_twin::five_axis::FiveAxisEffects;
    let dir = scratch("rtest-nominal");
    let m = FiveAxis::new(MachineKind::AcTrunnion, 0.0);
    let mut twin = FiveAxisTwin::random(m, 2);
    twin.location = [0.0; 11];
    twin.effects = FiveAxisEffects::all_but_time_drift();
    let paths = standard_paths(&m, [150.0, 0.0, 100.0], -60.0, 72, &[0.0, -60.0], 36, None);
    std::fs::write(dir.join("fx.csv"), twin.measure(&paths, 2).to_csv_string()).unwrap();
    std::fs::write(dir.join("clean.csv"), twin_csv()).unwrap();
    let run = |data: &str, extra: &[&str]| -> serde_json::Value {
        let _ = std::fs::remove_file(dir.join("n.json"));
        let mut args = vec!["fit", "rtest", "--data", data, "--json", "n.json"];
        args.extend_from_slice(extra);
        let o = axcomp(&args, &dir);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        serde_json::from_str(&std::fs::read_to_string(dir.join("n.json")).unwrap()).unwrap()
    };
    for split in [["--holdout", "path=C-circle@0"], ["--cv", "path"]] {
        let j = run("fx.csv", &split);
        let (model, full, nominal, setup) = common::rtest_comparison_rms_um(&j);
        println!(
            "{split:?}: model {model:.3}, full {full:.3}, nominal {nominal:.3}, set-up only {setup:.3} µm; selection {}",
            j["selection"]
        );
        assert_eq!(j["nominal_setup_rms_um"].as_f64().unwrap(), setup);
        assert_eq!(j["selection"]["applied"], true);
        assert!(model <= setup, "{split:?}: {model} > {setup}");
        assert!(model < nominal);
        if !j["selection"]["fixed"].as_array().unwrap().is_empty() {
            for (name, v) in j["location_errors"].as_object().unwrap() {
                assert_eq!(v["value"], 0.0, "{name}");
                assert_eq!(v["identified"], false, "{name}");
                assert!(v["reason"].as_str().unwrap().contains("default selection"));
            }
        }
        let f = run("fx.csv", &[split[0], split[1], "--full-model"]);
        assert!(
            f["selection"]["rule"]
                .as_str()
                .unwrap()
                .starts_with("--full-model")
        );
        assert_eq!(
            f["comparison"]["model_rms_um"],
            f["comparison"]["full_model_rms_um"]
        );
        assert!((f["comparison"]["full_model_rms_um"].as_f64().unwrap() - full).abs() < 1e-9);
    }
    // A twin of the specified magnitudes (location errors 5–50 µm, 10–100 µrad, no effects beyond): nothing fixed.
    let j = run("clean.csv", &["--holdout", "run=2"]);
    assert!(j["selection"]["fixed"].as_array().unwrap().is_empty());
    assert_eq!(
        j["comparison"]["model_rms_um"],
        j["comparison"]["full_model_rms_um"]
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// A head-head B/C campaign (bc-head, pivot 250 mm, seed 7, σ = 0.1 µm, 6 s per pose) that probes
/// B = C = 0 again at the start and at the end as single-pose runs of K4 (runs 0 and 9), with the tool
/// point creeping (`time_drift`, set to −6, 4, −8 µm/h along X, Y, Z) during the campaign.
/// Reference: the injected drift over the time between the first and the last visit, `−rate·Δt` (the
/// twin's `time_drift`: `d −= rate·t`); tolerance per component 4·√2·σ = 0.57 µm (the difference of two
/// readings of noise σ). The file is fitted (no "single pose" / "conflicting" refusal), the K4 run 2 held
/// out is predicted better than the nominal kinematics, and `predict` reads the model back on every row.
#[test]
fn revisited_pose_as_single_pose_runs_fits_predicts_and_reports_the_closure_drift() {
    use axcomp_kinematics::rotary::pose_on_sphere;
    use axcomp_twin::five_axis::RtestPathSpec;
    let dir = scratch("revisit");
    let m = FiveAxis::new(MachineKind::BcHead, 250.0);
    let mut twin = FiveAxisTwin::random(m, 7);
    twin.noise_um = 0.1;
    twin.dwell_s = 6.0;
    twin.effects.time_drift = true;
    let rate = [-6.0, 4.0, -8.0];
    twin.effect_params.time_um_h = rate;
    let sphere = [0.0; 3];
    let closure = |run| RtestPathSpec {
        path: "K4".into(),
        run,
        setup: "1".into(),
        sphere_mm: sphere,
        poses: vec![pose_on_sphere(&m, sphere, 0.0, 0.0)],
    };
    let mut paths = vec![closure(0)];
    paths.extend(standard_paths(
        &m,
        sphere,
        -60.0,
        72,
        &[0.0, -60.0],
        36,
        None,
    ));
    paths.push(closure(9));
    let campaign = twin.measure(&paths, 7);
    let elapsed = campaign.rows.last().unwrap().time_s - campaign.rows[0].time_s;
    std::fs::write(dir.join("rtest.csv"), campaign.to_csv_string()).unwrap();
    let o = axcomp(
        &[
            "fit",
            "rtest",
            "--data",
            "rtest.csv",
            "--machine",
            "bc-head",
            "--pivot-mm",
            "250",
            "--holdout",
            "run=2",
            "--json",
            "fit.json",
            "--report",
            "rep",
            "--out",
            "model.json",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("fit.json")).unwrap()).unwrap();
    let hold = j["holdout_rms_um"].as_f64().unwrap();
    let raw = j["raw_rms_um"].as_f64().unwrap();
    assert!(hold < raw, "held-out {hold} µm vs nominal {raw} µm");
    // Every K4 pose is revisited by K4 run 2; the closure pose is the one at B = C = 0.
    let poses = j["closure"]["poses"].as_array().unwrap();
    assert_eq!(poses.len(), 72, "K4 runs 1 and 2 share their 72 poses");
    let p = poses
        .iter()
        .find(|p| p["pose"]["b_deg"] == 0.0 && p["pose"]["c_deg"] == 0.0)
        .expect("the B = C = 0 pose is in the closure");
    assert_eq!(p["first"]["run"], "0");
    assert_eq!(p["last"]["run"], "9");
    // Visits: the two closure runs, K4 runs 1 and 2 start there, and the C circle at B = 0 passes C = 0.
    assert_eq!(p["visits"], 5);
    assert!((p["elapsed_s"].as_f64().unwrap() - elapsed).abs() < 1e-9);
    let tol = 4.0 * std::f64::consts::SQRT_2 * twin.noise_um;
    let mut mag2 = 0.0;
    for (c, key) in ["dx_um", "dy_um", "dz_um"].iter().enumerate() {
        let want = -rate[c] * elapsed / 3600.0;
        let got = p[key].as_f64().unwrap();
        assert!(
            (got - want).abs() <= tol,
            "closure {key}: {got:.3} µm vs injected {want:.3} µm (tolerance {tol:.2})"
        );
        mag2 += got * got;
    }
    assert!((p["magnitude_um"].as_f64().unwrap() - mag2.sqrt()).abs() < 1e-9);
    let md = std::fs::read_to_string(dir.join("rep/report.md")).unwrap();
    assert!(md.contains("Closure"), "{md}");
    let o = axcomp(
        &[
            "predict",
            "--model",
            "model.json",
            "--data",
            "rtest.csv",
            "--out",
            "pred.csv",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let pred = std::fs::read_to_string(dir.join("pred.csv")).unwrap();
    let header = pred.lines().find(|l| !l.starts_with('#')).unwrap();
    assert!(header.contains("pred_dx_um"), "{header}");
    assert_eq!(
        pred.lines().filter(|l| !l.starts_with('#')).count(),
        1 + campaign.rows.len()
    );
}

/// A pose repeated within one path and run is an error naming both lines, whether its readings conflict or
/// are identical (a duplicated row); the same pose as a further run is accepted (test above).
#[test]
fn duplicate_row_within_a_run_names_both_lines() {
    let dir = scratch("dup");
    let csv = twin_csv();
    let mut v: Vec<String> = csv.lines().map(|s| s.to_string()).collect();
    v.insert(5, v[4].clone());
    fails(&dir, &v.join("\n"), &[], "identical readings");
    // Line 1 is the twin's `#` comment, line 2 the header: the copied row is at lines 5 and 6.
    fails(&dir, &v.join("\n"), &[], "lines 5 and 6");
}
