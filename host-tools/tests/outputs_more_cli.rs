//! All-or-nothing outputs, following `outputs_cli.rs`: for `sim`, `sim-probe`,
//! `fit probe`, `predict`, `trace`, `image build` and `validate-diagnosis`, the last output path that
//! cannot be written (its directory is missing) fails with exit code 2 and nothing — old or new — is
//! touched: existing outputs keep their old bytes, no new file appears, no temporary is left, and the
//! message names the user's path.

use std::path::Path;

mod common;
use common::{fails_untouched, ok_in as ok, scratch};

/// 21 targets × 6 bidirectional runs of a smooth error with a little noise.
fn positioning_csv(path: &Path) {
    let mut s = String::from("target_mm,run,direction,deviation_um\n");
    for run in 1..=6 {
        for (d, sign) in [("+", 1.0), ("-", -1.0)] {
            for k in 0..21 {
                let x = 10.0 * k as f64;
                let noise = ((run * 31 + k * 17) % 13) as f64 / 13.0 - 0.5;
                let y = 12.0 * (x / 40.0).sin() + 2.0 * sign + noise;
                s.push_str(&format!("{x},{run},{d},{y:.4}\n"));
            }
        }
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn sim_bad_truth_touches_nothing() {
    let dir = scratch("sim");
    std::fs::write(dir.join("s.csv"), "old campaign").unwrap();
    let args = [
        "sim",
        "--plan",
        "survey",
        "--rows",
        "200",
        "--out",
        "s.csv",
        "--truth",
        "missing-dir/t.json",
    ];
    fails_untouched(&args, &dir, "missing-dir/t.json");
    // Control: with a writable truth path both files are written.
    ok(&[&args[..7], &["--truth", "t.json"]].concat(), &dir);
    assert_ne!(std::fs::read(dir.join("s.csv")).unwrap(), b"old campaign");
    assert!(dir.join("t.json").is_file());
}

#[test]
fn sim_probe_and_fit_probe_bad_last_output_touch_nothing() {
    let dir = scratch("probe");
    std::fs::write(dir.join("touches.csv"), "old touches").unwrap();
    let sim = [
        "sim-probe",
        "--plan",
        "probe-cal",
        "--truth",
        "truth.csv",
        "--out",
        "missing-dir/touches.csv",
    ];
    fails_untouched(&sim, &dir, "missing-dir/touches.csv");
    ok(&[&sim[..5], &["--out", "touches.csv"]].concat(), &dir);
    std::fs::write(dir.join("cal.json"), "old calibration").unwrap();
    std::fs::create_dir(dir.join("rep")).unwrap();
    std::fs::write(dir.join("rep/report.md"), "old report").unwrap();
    fails_untouched(
        &[
            "fit",
            "probe",
            "--data",
            "touches.csv",
            "--sphere-diameter-mm",
            "25",
            "--report",
            "rep",
            "--out",
            "cal.json",
            "--json",
            "missing-dir/fit.json",
        ],
        &dir,
        "missing-dir/fit.json",
    );
}

#[test]
fn predict_trace_and_image_build_bad_output_touch_nothing() {
    let dir = scratch("predict");
    positioning_csv(&dir.join("d.csv"));
    ok(
        &["fit", "positioning", "--data", "d.csv", "--out", "t.json"],
        &dir,
    );
    fails_untouched(
        &[
            "predict",
            "--model",
            "t.json",
            "--data",
            "d.csv",
            "--out",
            "missing-dir/p.csv",
        ],
        &dir,
        "missing-dir/p.csv",
    );
    fails_untouched(
        &[
            "image",
            "build",
            "--table",
            "t.json",
            "--axis-id",
            "1",
            "--um-per-count",
            "0.1",
            "--out",
            "missing-dir/t.img",
        ],
        &dir,
        "missing-dir/t.img",
    );
    // Control: the same inputs with a writable path succeed (the failure above is the path's).
    ok(
        &[
            "image",
            "build",
            "--table",
            "t.json",
            "--axis-id",
            "1",
            "--um-per-count",
            "0.1",
            "--out",
            "t.img",
        ],
        &dir,
    );
    fails_untouched(
        &[
            "trace",
            "--scenario",
            "equivalence",
            "--cycles",
            "100",
            "--out",
            "missing-dir/e.trace",
        ],
        &dir,
        "missing-dir/e.trace",
    );
}

#[test]
fn validate_diagnosis_report_and_json_together_or_not_at_all() {
    let dir = scratch("validate");
    std::fs::write(dir.join("v.md"), "old summary").unwrap();
    fails_untouched(
        &[
            "validate-diagnosis",
            "--cases",
            "1",
            "--markdown",
            "v.md",
            "--json",
            "missing-dir/v.json",
        ],
        &dir,
        "missing-dir/v.json",
    );
}

#[test]
fn fit_thermal_bad_last_output_touches_nothing() {
    let dir = scratch("thermal");
    let d = axcomp_twin::synth::generate(&axcomp_twin::synth::SynthConfig {
        seed: 5,
        ..Default::default()
    });
    d.write_csv(&dir.join("twin.csv")).unwrap();
    std::fs::write(dir.join("model.json"), "old model").unwrap();
    std::fs::create_dir(dir.join("rep")).unwrap();
    std::fs::write(dir.join("rep/report.md"), "old report").unwrap();
    let base = [
        "fit",
        "thermal",
        "--data",
        "twin.csv",
        "--target",
        "error_um",
        "--report",
        "rep",
        "--out",
        "model.json",
    ];
    fails_untouched(
        &[&base[..], &["--json", "missing-dir/fit.json"]].concat(),
        &dir,
        "missing-dir/fit.json",
    );
    // Control: with a writable JSON path every output is written.
    ok(&[&base[..], &["--json", "fit.json"]].concat(), &dir);
    assert_ne!(std::fs::read(dir.join("model.json")).unwrap(), b"old model");
    assert_ne!(
        std::fs::read(dir.join("rep/report.md")).unwrap(),
        b"old report"
    );
    assert!(dir.join("fit.json").is_file() && dir.join("rep/prediction.svg").is_file());
}

#[test]
fn diagnose_bad_last_output_touches_nothing() {
    let dir = scratch("diagnose");
    ok(
        &[
            "sim",
            "--plan",
            "survey",
            "--rows",
            "400",
            "--effects",
            "pitch_error,reversal",
            "--out",
            "s.csv",
        ],
        &dir,
    );
    std::fs::create_dir(dir.join("rep")).unwrap();
    std::fs::write(dir.join("rep/diagnosis.md"), "old report").unwrap();
    let base = [
        "diagnose",
        "--data",
        "s.csv",
        "--model",
        "pitch_error",
        "--holdout",
        "offset_mm=100",
        "--report",
        "rep",
    ];
    fails_untouched(
        &[&base[..], &["--json", "missing-dir/d.json"]].concat(),
        &dir,
        "missing-dir/d.json",
    );
    ok(&[&base[..], &["--json", "d.json"]].concat(), &dir);
    assert_ne!(
        std::fs::read(dir.join("rep/diagnosis.md")).unwrap(),
        b"old report"
    );
    assert!(dir.join("d.json").is_file());
}
