//! `axcomp sim` end to end: the binary writes the contract's CSV and the truth JSON, rejects bad
//! options with a clear message, and writes nothing then.

use std::process::Command;

mod common;
use common::scratch;

fn axcomp(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(args)
        .output()
        .expect("run axcomp")
}

#[test]
fn writes_csv_and_truth_that_read_back() {
    let dir = scratch("ok");
    let out = dir.join("twin.csv");
    let truth = dir.join("truth.json");
    let o = axcomp(&[
        "sim",
        "--out",
        out.to_str().unwrap(),
        "--effects",
        "pitch_error,reversal,cogging",
        "--plan",
        "iso230",
        "--seed",
        "3",
        "--noise-um",
        "0.2",
        "--rows",
        "300",
        "--truth",
        truth.to_str().unwrap(),
    ]);
    assert!(
        o.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let ds =
        axcomp_data::Dataset::from_csv_str("twin.csv", &text, &axcomp_data::LoadOptions::default())
            .unwrap();
    // --rows 300 with 5 cycles × 2 directions → 30 targets → 300 rows exactly.
    assert_eq!(ds.n_rows(), 300);
    for col in [
        "target_mm",
        "deviation_um",
        "run",
        "direction",
        "time_s",
        "ambient_degC",
        "force_N",
        "velocity_mm_s",
        "accel_mm_s2",
        "offset_mm",
    ] {
        assert!(ds.has(col), "missing {col}");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&truth).unwrap()).unwrap();
    let kinds: Vec<&str> = json["axis"]["effects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|e| e["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, ["pitch_error", "reversal", "cogging"]);
    assert_eq!(json["seed"], 3);
    assert_eq!(json["axis"]["noise"]["deviation_um"], 0.2);

    // Same seed → same file; the truth's axis (with its noise σ) replays to the same file through --axis.
    let again = dir.join("again.csv");
    let o = axcomp(&[
        "sim",
        "--out",
        again.to_str().unwrap(),
        "--axis",
        truth.to_str().unwrap(),
        "--seed",
        "3",
        "--rows",
        "300",
    ]);
    assert!(
        o.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_eq!(std::fs::read_to_string(&again).unwrap(), text);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn every_plan_runs() {
    let dir = scratch("plans");
    for plan in ["iso230", "scan", "thermal", "load", "abbe"] {
        let out = dir.join(format!("{plan}.csv"));
        let o = axcomp(&[
            "sim",
            "--out",
            out.to_str().unwrap(),
            "--plan",
            plan,
            "--effects",
            "pitch_error,thermal_drift,following_error,force_deflection,abbe",
            "--random-params",
        ]);
        assert!(
            o.status.success(),
            "{plan}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        assert!(std::fs::metadata(&out).unwrap().len() > 100);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn large_thermal_and_survey_plans_run_with_progress() {
    // Long plans: `--plan thermal` must not fail from ~14,000 rows nor `--plan survey` from ~29,000 ("time
    // runs backwards"). 100,000 rows each (the plan-level test in axcomp-twin goes to 10⁶); progress on stderr.
    let dir = scratch("large");
    for plan in ["thermal", "survey"] {
        let out = dir.join(format!("{plan}.csv"));
        let o = axcomp(&[
            "sim",
            "--out",
            out.to_str().unwrap(),
            "--plan",
            plan,
            "--rows",
            "100000",
        ]);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{plan}: {stderr}");
        assert!(
            stderr.contains("simulating") && stderr.contains("writing"),
            "{stderr}"
        );
        let ds = axcomp_data::Dataset::load(&out, &axcomp_data::LoadOptions::default()).unwrap();
        let n = ds.n_rows() as f64;
        // Rounding to whole positions / rounds → within 15 % of the request.
        assert!((n / 100_000.0 - 1.0).abs() < 0.15, "{plan}: {n} rows");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_options_fail_clearly_and_write_nothing() {
    let dir = scratch("bad");
    let out = dir.join("x.csv");
    let cases: [(&[&str], &str); 4] = [
        (&["--effects", "pitch_error,bogus"], "bogus"),
        (&["--plan", "sideways"], "sideways"),
        (&["--noise-um", "-1"], "noise"),
        (&["--rows", "0"], "--rows"),
    ];
    for (extra, needle) in cases {
        let mut args = vec!["sim", "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let o = axcomp(&args);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{extra:?} succeeded");
        assert!(stderr.contains(needle), "{extra:?}: {stderr}");
        assert!(!out.exists(), "{extra:?} wrote a file");
    }
    let missing = dir.join("no/such/dir/x.csv");
    let o = axcomp(&["sim", "--out", missing.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("does not exist"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn image_runs_the_campaign_through_the_compensator() {
    let dir = scratch("image");
    let truth = dir.join("truth.json");
    let before = dir.join("before.csv");
    let o = axcomp(&[
        "sim",
        "--out",
        before.to_str().unwrap(),
        "--truth",
        truth.to_str().unwrap(),
        "--seed",
        "4",
    ]);
    assert!(
        o.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    // The ideal image of the default (demo) axis, written as a user's `axcomp image build` would be.
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&truth).unwrap()).unwrap();
    let axis: axcomp_twin::Axis = serde_json::from_value(json["axis"].clone()).unwrap();
    let image = dir.join("ideal.bin");
    std::fs::write(&image, axcomp_twin::ideal_image(&axis, 2.0).unwrap()).unwrap();
    let after = dir.join("after.csv");
    let o = axcomp(&[
        "sim",
        "--out",
        after.to_str().unwrap(),
        "--image",
        image.to_str().unwrap(),
        "--seed",
        "4",
    ]);
    assert!(
        o.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(String::from_utf8_lossy(&o.stdout).contains("compensated"));
    let rms = |p: &std::path::Path| {
        let text = std::fs::read_to_string(p).unwrap();
        let ds = axcomp_data::Dataset::from_csv_str(
            "x.csv",
            &text,
            &axcomp_data::LoadOptions::default(),
        )
        .unwrap();
        let d = ds.numeric("deviation_um").unwrap();
        (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt()
    };
    let (b, a) = (rms(&before), rms(&after));
    // Reference: the demo axis' ~6 µm RMS falls to the 0.5 µm noise floor (tolerance: below 0.7 µm).
    assert!(b > 4.0 && a < 0.7, "before {b} after {a}");
    // A file that is not an image is refused, naming it.
    let o = axcomp(&[
        "sim",
        "--out",
        dir.join("x.csv").to_str().unwrap(),
        "--image",
        truth.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("truth.json"));
    assert!(!dir.join("x.csv").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn spindle_plan_writes_process_columns_and_the_generators_truth() {
    let dir = scratch("spindle");
    let out = dir.join("spindle.csv");
    let truth = dir.join("truth.json");
    let o = axcomp(&[
        "sim",
        "--out",
        out.to_str().unwrap(),
        "--plan",
        "spindle",
        "--rows",
        "1000",
        "--truth",
        truth.to_str().unwrap(),
    ]);
    assert!(
        o.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let ds = axcomp_data::Dataset::from_csv_str(
        "spindle.csv",
        &text,
        &axcomp_data::LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(ds.n_rows(), 1000);
    assert_eq!(ds.sensors().len(), 16);
    for col in ["spindle_rpm", "ap_mm", "fz_mm", "force_N", "deviation_um"] {
        assert!(ds.numeric(col).is_ok(), "{col}");
    }
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&truth).unwrap()).unwrap();
    assert!(
        json["synth_truth"]["terms"]
            .as_array()
            .is_some_and(|t| !t.is_empty())
    );
    let _ = std::fs::remove_dir_all(&dir);
}
