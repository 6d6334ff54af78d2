//! The CLI against the user contract (`../shared/spec/interfaces.md`), through the binary: items an audit of
//! the contract found the CLI doing differently (one test per item).

use std::path::Path;

mod common;
use common::{axcomp_in, read_json, scratch};

/// Runs `args` in `dir`: (success, stdout, stderr).
fn run(args: &[&str], dir: &Path) -> (bool, String, String) {
    let o = axcomp_in(args, dir);
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn run_ok(args: &[&str], dir: &Path) -> String {
    let (ok, out, err) = run(args, dir);
    assert!(ok, "{args:?}:\n{out}\n{err}");
    out
}

/// Column `name` of a CSV file (no quoted fields) as numbers.
fn column(path: &Path, name: &str) -> Vec<f64> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let k = header
        .iter()
        .position(|h| *h == name)
        .unwrap_or_else(|| panic!("no column {name} in {}: {header:?}", path.display()));
    lines
        .map(|l| l.split(',').nth(k).unwrap().parse().unwrap())
        .collect()
}

fn header(path: &Path) -> Vec<String> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .find(|l| !l.starts_with('#'))
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect()
}

/// A thermal campaign in the form of the Voron files: a raw position column `pos_steps` (microsteps of
/// 2.5 µm, far from zero: a homing position), two temperatures `frame_t`, `bed_t` that rise along different
/// curves, `time_s`, and `phase` (`heat` for the first 150 rows, `cool` after). The position follows
/// z = 2.5·pos_steps = 50 000 + 3·ΔT_frame − 1.5·ΔT_bed µm exactly (plus a ±0.05 µm deterministic ripple), so
/// an every-sensor least-squares fit is near exact.
fn thermal_csv(with_measured: bool) -> String {
    let mut s = String::from("time_s,frame_t,bed_t,phase");
    s.push_str(if with_measured { ",pos_steps\n" } else { "\n" });
    for i in 0..200 {
        let t = 10.0 * i as f64;
        let (frame, bed) = if i < 150 {
            (20.0 + 8.0 * (1.0 - (-t / 600.0).exp()), 20.0 + 0.01 * t)
        } else {
            let t0 = 1490.0;
            let f0 = 20.0 + 8.0 * (1.0 - (-t0 / 600.0f64).exp());
            (f0 - 0.002 * (t - t0), 20.0 + 0.01 * t0 - 0.008 * (t - t0))
        };
        let z =
            50_000.0 + 3.0 * (frame - 20.0) - 1.5 * (bed - 20.0) + 0.05 * (i as f64 * 1.7).sin();
        let phase = if i < 150 { "heat" } else { "cool" };
        s.push_str(&format!("{t},{frame},{bed},{phase}"));
        if with_measured {
            s.push_str(&format!(",{}", z / 2.5));
        }
        s.push('\n');
    }
    s
}

const THERMAL_RENAMES: [&str; 10] = [
    "--rename",
    "pos_steps=z_um",
    "--scale",
    "z_um=2.5",
    "--rename",
    "frame_t=frame_degC",
    "--rename",
    "bed_t=bed_degC",
    "--target",
    "z_um",
];

/// Contract, "Any fitted model": `predict --model MODEL --data F [--where ..] [--rename ..] [--scale ..]`
/// needs only the model's inputs; the measured columns may be absent. A user (or an outside evaluation)
/// passes the fit's `--rename`/`--scale` to `predict` on rows without the measured column: the options that
/// name the absent measured column are skipped (with a note), not an error. A model input that is still
/// missing (here: a typo in a sensor's rename) stays an error naming the column.
#[test]
fn predict_takes_the_fits_rename_and_scale_without_the_measured_column() {
    let dir = scratch("rename");
    std::fs::write(dir.join("fit.csv"), thermal_csv(true)).unwrap();
    std::fs::write(dir.join("rows.csv"), thermal_csv(false)).unwrap();
    let mut fit = vec![
        "fit",
        "thermal",
        "--data",
        "fit.csv",
        "--select",
        "all",
        "--holdout",
        "phase=cool",
        "--out",
        "model.json",
    ];
    fit.extend(THERMAL_RENAMES);
    run_ok(&fit, &dir);
    let mut predict = vec![
        "predict",
        "--model",
        "model.json",
        "--data",
        "rows.csv",
        "--out",
        "pred.csv",
    ];
    predict.extend(&THERMAL_RENAMES[..8]);
    let (ok, out, err) = run(&predict, &dir);
    assert!(ok, "{out}\n{err}");
    assert!(
        err.contains("pos_steps") && err.contains("--rename"),
        "the skipped option is named: {err}"
    );
    assert_eq!(column(&dir.join("pred.csv"), "pred_z_um").len(), 200);
    // Same rows with the measured column: the predictions are the same (reference: the run above;
    // tolerance: none, the same arithmetic).
    let mut with = predict.clone();
    with[4] = "fit.csv";
    with[6] = "pred_with.csv";
    run_ok(&with, &dir);
    assert_eq!(
        column(&dir.join("pred.csv"), "pred_z_um"),
        column(&dir.join("pred_with.csv"), "pred_z_um")
    );
    // A model input missing because of a typo is still an error naming it, and nothing is written.
    let mut typo = predict.clone();
    typo[5] = "--out";
    typo[6] = "pred_typo.csv";
    let k = typo
        .iter()
        .position(|a| *a == "frame_t=frame_degC")
        .unwrap();
    typo[k] = "frame_t=frme_degC";
    let (ok, _, err) = run(&typo, &dir);
    assert!(!ok && err.contains("frame_degC"), "{err}");
    assert!(!dir.join("pred_typo.csv").exists());
}

/// Contract, "Any fitted model": predictions are `pred_<column>`, so that an outside tool can judge the model
/// on rows it never saw. A thermal model fitted with `--zero-at-start N` models the change since the start;
/// `pred_z_um` must still be a prediction of `z_um` (the start offset added back), so that the RMS of
/// `z_um − pred_z_um` on the held-out rows equals the fit's `holdout_rms_um`.
#[test]
fn predict_thermal_zero_at_start_predicts_the_target_itself() {
    let dir = scratch("zero");
    std::fs::write(dir.join("fit.csv"), thermal_csv(true)).unwrap();
    let mut fit = vec![
        "fit",
        "thermal",
        "--data",
        "fit.csv",
        "--select",
        "all",
        "--zero-at-start",
        "5",
        "--holdout",
        "phase=cool",
        "--out",
        "model.json",
        "--json",
        "fit.json",
    ];
    fit.extend(THERMAL_RENAMES);
    run_ok(&fit, &dir);
    let mut predict = vec![
        "predict",
        "--model",
        "model.json",
        "--data",
        "fit.csv",
        "--out",
        "pred.csv",
    ];
    predict.extend(&THERMAL_RENAMES[..8]);
    run_ok(&predict, &dir);
    let pred = dir.join("pred.csv");
    let (z, p) = (column(&pred, "z_um"), column(&pred, "pred_z_um"));
    // Held-out rows: the last 50 (phase=cool).
    let held: Vec<f64> = (150..200).map(|i| z[i] - p[i]).collect();
    let rms = (held.iter().map(|r| r * r).sum::<f64>() / held.len() as f64).sqrt();
    let want = read_json(&dir.join("fit.json"))["holdout_rms_um"]
        .as_f64()
        .unwrap();
    // Reference: the fit's own held-out RMS; tolerance 1e-6 µm (CSV round trip of the values).
    assert!(
        (rms - want).abs() < 1e-6,
        "RMS of z_um − pred_z_um on the held-out rows {rms} µm vs holdout_rms_um {want} µm"
    );
}

/// Contract, "Any fitted model": prediction columns are `pred_<column>`. A positioning table fitted with
/// `--target dev_x_um` predicts `dev_x_um`: `predict` adds `pred_dev_x_um` (not `pred_deviation_um`).
#[test]
fn predict_positioning_names_the_column_after_the_fits_target() {
    let dir = scratch("target");
    let mut csv = String::from("target_mm,run,direction,dev_x_um\n");
    for run in 1..=4 {
        for k in 0..=10 {
            let x = 10.0 * k as f64;
            for (d, b) in [("+", 1.0), ("-", -1.0)] {
                let e = 5.0 * (x / 30.0).sin() + 0.02 * x + b + 0.01 * ((run * 7 + k) as f64).sin();
                csv.push_str(&format!("{x},{run},{d},{e}\n"));
            }
        }
    }
    std::fs::write(dir.join("pos.csv"), csv).unwrap();
    run_ok(
        &[
            "fit",
            "positioning",
            "--data",
            "pos.csv",
            "--target",
            "dev_x_um",
            "--out",
            "table.json",
        ],
        &dir,
    );
    run_ok(
        &[
            "predict",
            "--model",
            "table.json",
            "--data",
            "pos.csv",
            "--out",
            "pred.csv",
        ],
        &dir,
    );
    let h = header(&dir.join("pred.csv"));
    assert!(h.contains(&"pred_dev_x_um".to_string()), "{h:?}");
    assert!(!h.contains(&"pred_deviation_um".to_string()), "{h:?}");
    // The predictions follow the measured column (reference: the data; tolerance 0.5 µm, the fitted
    // table's CV RMS is ~0.01 µm on this smooth campaign).
    let (m, p) = (
        column(&dir.join("pred.csv"), "dev_x_um"),
        column(&dir.join("pred.csv"), "pred_dev_x_um"),
    );
    for (a, b) in m.iter().zip(&p) {
        assert!((a - b).abs() < 0.5, "{a} vs {b}");
    }
}

/// Contract, "Any fitted model": `predict` reads any model file that a `fit` command writes; `fit force --out`
/// writes a force law F = K·ap^x·fz^y·n^z, which `predict` applies to rows without the measured force:
/// `pred_<force column>`. Reference: the law the noise-free rows were made with, F = 2000·ap·fz^0.75·n^−0.1
/// (the fit recovers it); tolerance 1e-6 relative.
#[test]
fn predict_applies_a_force_law_of_fit_force() {
    let dir = scratch("force");
    let law = |ap: f64, fz: f64, n: f64| 2000.0 * ap * fz.powf(0.75) * n.powf(-0.1);
    let mut fit = String::from("ap_mm,fz_mm,n_rpm,Fc_N\n");
    let mut rows = String::from("ap_mm,fz_mm,n_rpm\n");
    for (i, ap) in [0.5, 1.0, 2.0, 3.0].iter().enumerate() {
        for (j, fz) in [0.05, 0.1, 0.2].iter().enumerate() {
            let n = 2000.0 + 1000.0 * ((i + 2 * j) % 4) as f64;
            fit.push_str(&format!("{ap},{fz},{n},{}\n", law(*ap, *fz, n)));
            let (ap2, fz2) = (ap * 1.1, fz * 0.9);
            rows.push_str(&format!("{ap2},{fz2},{n}\n"));
        }
    }
    std::fs::write(dir.join("fit.csv"), fit).unwrap();
    std::fs::write(dir.join("rows.csv"), rows).unwrap();
    run_ok(
        &["fit", "force", "--data", "fit.csv", "--out", "law.json"],
        &dir,
    );
    run_ok(
        &[
            "predict", "--model", "law.json", "--data", "rows.csv", "--out", "pred.csv",
        ],
        &dir,
    );
    let pred = dir.join("pred.csv");
    let (ap, fz, n, f) = (
        column(&pred, "ap_mm"),
        column(&pred, "fz_mm"),
        column(&pred, "n_rpm"),
        column(&pred, "pred_Fc_N"),
    );
    for i in 0..f.len() {
        let want = law(ap[i], fz[i], n[i]);
        assert!(
            ((f[i] - want) / want).abs() < 1e-6,
            "row {i}: {} N vs {want} N",
            f[i]
        );
    }
}

/// A campaign whose error follows a lagged temperature: z = 5·lag(ΔT_frame, τ = 300 s) − 1.5·ΔT_bed µm, rows
/// every 10 s, heating then cooling (`phase`). The time is in a column `time` holding seconds (numbers, not
/// timestamps): the contract reads only a `time` column of timestamps as `time_s`.
fn lagged_csv() -> String {
    let mut s = String::from("time,frame_degC,bed_degC,phase,z_um\n");
    let (mut y, mut prev_t) = (0.0f64, 0.0f64);
    for i in 0..300 {
        let t = 10.0 * i as f64;
        let frame = if i < 200 {
            8.0 * (1.0 - (-t / 900.0).exp())
        } else {
            8.0 * (1.0 - (-1990.0f64 / 900.0).exp()) * (-(t - 1990.0) / 600.0).exp()
        };
        let bed = 3.0 * (0.01 * t).sin();
        let a = 1.0 - (-(t - prev_t) / 300.0).exp();
        y += a * (frame - y);
        prev_t = t;
        let z = 5.0 * y - 1.5 * bed + 0.02 * (i as f64 * 1.3).sin();
        let phase = if i < 200 { "heat" } else { "cool" };
        s.push_str(&format!(
            "{t},{},{},{phase},{z}\n",
            20.0 + frame,
            20.0 + bed
        ));
    }
    s
}

/// Contract, "Measurement CSV": `time_s` is the time since the start, and only a `time` column of timestamps
/// stands in for it. Without either, `fit thermal` must not fit its lags over the row index and write the time
/// constants, in rows, as `tau_s` (seconds: `predict` and the firmware read them so, and `predict` would
/// refuse the same file for want of `time_s`). The default choice leaves lagged candidates out and says
/// why (stderr and `lags_note`), and `--lags` without a time names the `time` column that is not read.
#[test]
fn fit_thermal_without_time_has_no_lags_in_rows() {
    let dir = scratch("notime");
    std::fs::write(dir.join("c.csv"), lagged_csv()).unwrap();
    let (ok, out, err) = run(
        &[
            "fit",
            "thermal",
            "--data",
            "c.csv",
            "--target",
            "z_um",
            "--holdout",
            "phase=cool",
            "--out",
            "model.json",
            "--json",
            "fit.json",
        ],
        &dir,
    );
    assert!(ok, "{out}\n{err}");
    let model = read_json(&dir.join("model.json"));
    for s in model["sensors"].as_array().unwrap() {
        assert_eq!(s["tau_s"].as_f64(), Some(0.0), "a lag without time: {s}");
    }
    let note = read_json(&dir.join("fit.json"))["lags_note"]
        .as_str()
        .unwrap_or_default()
        .to_string();
    assert!(
        note.contains("time_s") && note.contains("--rename time=time_s"),
        "{note}"
    );
    assert!(err.contains("lagged candidates left out"), "{err}");
    // The model applies to the same rows.
    run_ok(
        &[
            "predict",
            "--model",
            "model.json",
            "--data",
            "c.csv",
            "--out",
            "p.csv",
        ],
        &dir,
    );
    // With the seconds given as `time_s`, the lag is found (reference: τ = 300 s of the data; tolerance
    // 30 %, the grid and golden-section search of the fit over a 3000 s campaign).
    run_ok(
        &[
            "fit",
            "thermal",
            "--data",
            "c.csv",
            "--rename",
            "time=time_s",
            "--target",
            "z_um",
            "--holdout",
            "phase=cool",
            "--out",
            "model_s.json",
        ],
        &dir,
    );
    let m = read_json(&dir.join("model_s.json"));
    let frame = m["sensors"]
        .as_array()
        .unwrap()
        .iter()
        .find(|s| s["name"] == "frame")
        .unwrap()
        .clone();
    let tau = frame["tau_s"].as_f64().unwrap();
    assert!((tau - 300.0).abs() < 90.0, "frame τ {tau} s");
    // --lags without a time column names the `time` column that is not read.
    let (ok, _, err) = run(
        &[
            "fit", "thermal", "--data", "c.csv", "--target", "z_um", "--select", "all", "--lags",
        ],
        &dir,
    );
    assert!(!ok && err.contains("--rename time=time_s"), "{err}");
}

/// Contract, "Touch probe": `fit probe --json` has `repeatability_2sigma_um`. When the calibration rows
/// hold no repeated touches (here the twin's run 2 is held out, leaving one run) the figure is `null`, and the
/// JSON says why instead of leaving a bare null; with both runs it is a number and the note says how it was
/// measured.
#[test]
fn fit_probe_says_why_repeatability_is_null() {
    let dir = scratch("repeat");
    run_ok(
        &[
            "sim-probe",
            "--plan",
            "probe-cal",
            "--out",
            "t.csv",
            "--seed",
            "3",
        ],
        &dir,
    );
    run_ok(
        &[
            "fit",
            "probe",
            "--data",
            "t.csv",
            "--sphere-diameter-mm",
            "25",
            "--holdout",
            "run=2",
            "--json",
            "h.json",
        ],
        &dir,
    );
    let j = read_json(&dir.join("h.json"));
    assert!(
        j["repeatability_2sigma_um"].is_null(),
        "{}",
        j["repeatability_2sigma_um"]
    );
    let note = j["repeatability_note"].as_str().unwrap_or_default();
    assert!(note.contains("no repeated touches"), "{note:?}");
    run_ok(
        &[
            "fit",
            "probe",
            "--data",
            "t.csv",
            "--sphere-diameter-mm",
            "25",
            "--json",
            "a.json",
        ],
        &dir,
    );
    let j = read_json(&dir.join("a.json"));
    // Reference: the twin probe's repeatability 2σ of about 1 µm (README); tolerance: 0.3 … 3 µm.
    let r = j["repeatability_2sigma_um"].as_f64().unwrap();
    assert!((0.3..3.0).contains(&r), "{r}");
    assert!(
        j["repeatability_note"]
            .as_str()
            .unwrap_or_default()
            .contains("pooled")
    );
}

/// The help texts say what the CLI does: `predict` takes every model kind the contract lists (its help named
/// only three), `fit probe --group` reads each group's commanded tool point from `cmd_x_mm, cmd_y_mm,
/// cmd_z_mm` (its error message sends the user to `--help`, which did not name them), and `diagnose`'s JSON
/// `where` shares are fractions 0..1 (the help said 0..100 %).
#[test]
fn help_texts_agree_with_the_behaviour() {
    let dir = scratch("help");
    for args in [&["predict", "--help"][..], &["--help"][..]] {
        let out = run_ok(args, &dir);
        for kind in [
            "positioning table",
            "thermal model",
            "geometry model",
            "rotary-axis model",
            "probe calibration",
        ] {
            assert!(
                out.contains(kind),
                "{args:?} does not name `{kind}`:\n{out}"
            );
        }
    }
    let out = run_ok(&["fit", "probe", "--help"], &dir);
    for c in ["cmd_x_mm", "cmd_y_mm", "cmd_z_mm"] {
        assert!(
            out.contains(c),
            "fit probe --help does not name {c}:\n{out}"
        );
    }
    let out = run_ok(&["diagnose", "--help"], &dir);
    assert!(
        !out.contains("shares are in 0..100 %") && out.contains("0..1"),
        "diagnose --help on the `where` shares:\n{out}"
    );
}
