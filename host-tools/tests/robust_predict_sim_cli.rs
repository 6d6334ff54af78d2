//! Robustness of `axcomp predict`, `axcomp sim`, `axcomp sim-probe` and `axcomp plan geometry` on inputs an
//! outside evaluation may send (contract: `shared/spec/interfaces.md`, "Any fitted model: `axcomp
//! predict`": a row the model cannot predict — outside its stroke, a missing input — is an error naming the
//! row, not a silent prediction). Each test failed before its fix. The data are the twin's (`axcomp sim
//! --machine`, `axcomp sim-probe`), rewritten the way another tool could write them.

use std::path::Path;

mod common;
use common::{axcomp_in, fails_untouched_naming, ok_in, scratch, table, write_table};

fn stdout_of(args: &[&str], dir: &Path) -> String {
    let o = axcomp_in(args, dir);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn col(header: &[String], name: &str) -> usize {
    header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"))
}

/// An R-test model fitted on two set-ups (`sim --machine ac-trunnion --plan rtest-h2`: the C circles again
/// with the sphere 50 mm higher, set-up 2) has one pair of sphere offsets per set-up, 10–20 µm apart. Rows
/// without a `setup` column must not be predicted with set-up 1's offsets, silently: the set-up-2 circles
/// would come out at 10.3 µm RMS in dx instead of 0.30 µm. A missing input naming the file and the column; with the
/// column the same rows are predicted.
#[test]
fn rtest_model_of_several_setups_needs_the_setup_column() {
    let dir = scratch("rtest-setup");
    ok_in(
        &[
            "sim",
            "--machine",
            "ac-trunnion",
            "--plan",
            "rtest-h2",
            "--out",
            "rt.csv",
        ],
        &dir,
    );
    ok_in(
        &["fit", "rtest", "--data", "rt.csv", "--out", "model.json"],
        &dir,
    );
    let (header, rows) = table(&dir.join("rt.csv"));
    let s = col(&header, "setup");
    let second: Vec<Vec<String>> = rows.iter().filter(|r| r[s] == "2").cloned().collect();
    assert!(!second.is_empty(), "the plan has a second set-up");
    write_table(&dir.join("setup2.csv"), &header, &second);
    let drop = |r: &[String]| -> Vec<String> {
        r.iter()
            .enumerate()
            .filter(|(k, _)| *k != s)
            .map(|(_, c)| c.clone())
            .collect()
    };
    let bare: Vec<Vec<String>> = second.iter().map(|r| drop(r)).collect();
    write_table(&dir.join("bare.csv"), &drop(&header), &bare);
    fails_untouched_naming(
        &[
            "predict",
            "--model",
            "model.json",
            "--data",
            "bare.csv",
            "--out",
            "p.csv",
        ],
        &dir,
        &["bare.csv", "missing column `setup`"],
    );
    ok_in(
        &[
            "predict",
            "--model",
            "model.json",
            "--data",
            "setup2.csv",
            "--out",
            "p.csv",
        ],
        &dir,
    );
}

/// A force law with x_ap = 1 (fixed, as in Kienzle's law F = kc1.1·b·h^(1−mc): the README's example) must not give
/// a negative force for a negative depth of cut, silently (`fit force` refuses such a value, a power law
/// needs > 0): an error naming file, line and column, nothing written. Zero (no cut) is 0 N.
#[test]
fn force_law_refuses_a_negative_process_parameter() {
    let dir = scratch("law-negative");
    std::fs::write(
        dir.join("law.json"),
        r#"{ "k": 1572.35, "x_ap": 1.0, "y_fz": 0.8464, "z_n": 0.0 }"#,
    )
    .unwrap();
    std::fs::write(dir.join("rows.csv"), "ap_mm,fz_mm\n1,0.1\n-1,0.1\n").unwrap();
    fails_untouched_naming(
        &[
            "predict", "--model", "law.json", "--data", "rows.csv", "--out", "p.csv",
        ],
        &dir,
        &["rows.csv:3:1", "ap_mm", "-1"],
    );
    std::fs::write(dir.join("rows.csv"), "ap_mm,fz_mm\n1,-0.1\n").unwrap();
    fails_untouched_naming(
        &[
            "predict", "--model", "law.json", "--data", "rows.csv", "--out", "p.csv",
        ],
        &dir,
        &["rows.csv:2:2", "fz_mm"],
    );
    std::fs::write(dir.join("rows.csv"), "ap_mm,fz_mm\n0,0.1\n2,0.1\n").unwrap();
    ok_in(
        &[
            "predict", "--model", "law.json", "--data", "rows.csv", "--out", "p.csv",
        ],
        &dir,
    );
    let (header, rows) = table(&dir.join("p.csv"));
    let p = col(&header, "pred_force_N");
    // Reference: the law by hand, 1572.35·2·0.1^0.8464 N; tolerance 1e-9 relative (same arithmetic).
    let want = 1572.35 * 2.0 * 0.1f64.powf(0.8464);
    let got: f64 = rows[1][p].parse().unwrap();
    assert!((got - want).abs() <= 1e-9 * want, "{got} vs {want}");
    assert_eq!(rows[0][p].parse::<f64>().unwrap(), 0.0);
}

/// A probe calibrated on one side of the sphere only (the twin's calibration touches whose normal points to
/// +x: azimuths −90° … 90°) may choose a harmonic model that, applied by `predict` to the other side, puts
/// the contact points up to 25 µm off the true surface (13.8 µm RMS on the ring gauge), silently. The README
/// says a direction the calibration cannot tell is an error naming the row: the calibration records the
/// arc without touches (90° … 270°) and `predict` refuses a touch more than 10° inside it, naming the row;
/// touches on the calibrated side are still corrected, and a calibration that goes round records no arc.
#[test]
fn probe_calibration_refuses_azimuths_it_has_no_touches_in() {
    let dir = scratch("probe-half");
    ok_in(
        &[
            "sim-probe",
            "--plan",
            "probe-cal",
            "--no-glitches",
            "--out",
            "cal.csv",
        ],
        &dir,
    );
    let (header, rows) = table(&dir.join("cal.csv"));
    let ax = col(&header, "approach_x");
    let half: Vec<Vec<String>> = rows
        .iter()
        .filter(|r| r[ax].parse::<f64>().unwrap() <= 0.0)
        .cloned()
        .collect();
    write_table(&dir.join("half.csv"), &header, &half);
    let fit = |data: &str, out: &str| {
        ok_in(
            &[
                "fit",
                "probe",
                "--data",
                data,
                "--sphere-diameter-mm",
                "25",
                "--out",
                out,
            ],
            &dir,
        )
    };
    fit("half.csv", "half.json");
    fit("cal.csv", "full.json");
    let cal = common::read_json(&dir.join("half.json"));
    let gap = &cal["azimuth_gap_deg"];
    // Reference: the kept normals' azimuths are −90° … 90° (every 15°), so the empty arc is 90° … 270°;
    // tolerance 1e-6° (atan2 of the twin's 9-decimal vectors).
    let (from, to) = (gap[0].as_f64().unwrap(), gap[1].as_f64().unwrap());
    assert!(
        (from - 90.0).abs() < 1e-6 && (to - 270.0).abs() < 1e-6,
        "{gap}"
    );
    assert!(
        common::read_json(&dir.join("full.json"))
            .get("azimuth_gap_deg")
            .is_none()
    );
    // The other side: the first row whose normal lies more than 10° inside the arc (approach_x > sin 10°).
    let other = rows
        .iter()
        .position(|r| r[ax].parse::<f64>().unwrap() > 0.2)
        .unwrap();
    let needle = format!("cal.csv:{} (row {})", other + 2, other + 1);
    fails_untouched_naming(
        &[
            "predict",
            "--model",
            "half.json",
            "--data",
            "cal.csv",
            "--out",
            "p.csv",
        ],
        &dir,
        &[&needle, "azimuth"],
    );
    ok_in(
        &[
            "predict",
            "--model",
            "half.json",
            "--data",
            "half.csv",
            "--out",
            "p.csv",
        ],
        &dir,
    );
    ok_in(
        &[
            "predict",
            "--model",
            "full.json",
            "--data",
            "cal.csv",
            "--out",
            "p.csv",
        ],
        &dir,
    );
}

/// `plan geometry --lines 0` (unchecked: a plan of no lines with NaN uncertainties and, with `--simulate`,
/// a header-only CSV, exit 0), `--runs 0` (one run measured silently), `--targets 1000` (6 minutes; 100000
/// killed for memory), `--seed`/`--twin-plan` without `--simulate` (silently ignored) and `--sigma-um -1`
/// (not a parser error about an unexpected argument): each is refused naming the option,
/// nothing written; a plan that leaves components unidentifiable says so instead of printing NaN.
#[test]
fn plan_geometry_refuses_counts_it_cannot_plan_with() {
    let dir = scratch("plan-counts");
    let base = ["plan", "geometry", "--stroke", "400,300,200"];
    let with = |extra: &[&'static str]| -> Vec<&'static str> {
        let mut v = base.to_vec();
        v.extend_from_slice(extra);
        v
    };
    for (extra, needle) in [
        (
            &["--lines", "0", "--simulate", "l.csv", "--json", "p.json"][..],
            "--lines 0",
        ),
        (&["--runs", "0", "--simulate", "l.csv"][..], "--runs 0"),
        (
            &["--targets", "201", "--json", "p.json"][..],
            "--targets 201",
        ),
        (&["--seed", "3", "--json", "p.json"][..], "--simulate"),
        (&["--twin-plan", "seven-line"][..], "--simulate"),
        (&["--sigma-um", "-1"][..], "--sigma-um -1"),
    ] {
        fails_untouched_naming(&with(extra), &dir, &[needle]);
    }
    let text = stdout_of(&with(&["--lines", "3"]), &dir);
    assert!(text.contains("all 21 identifiable: no"), "{text}");
    assert!(!text.contains("NaN"), "{text}");
    assert!(text.contains("EXX   not identifiable"), "{text}");
}

/// `sim --rows 1000000000` aborted the process (a 72 GB allocation failed, exit 134 with a backtrace) and
/// `sim-probe --repeats 1000000` likewise; now both are refused naming the option and its bound, nothing
/// written.
#[test]
fn sim_counts_beyond_memory_are_refused() {
    let dir = scratch("sim-counts");
    fails_untouched_naming(
        &["sim", "--rows", "1000000000", "--out", "a.csv"],
        &dir,
        &["--rows 1000000000", "at most"],
    );
    fails_untouched_naming(
        &[
            "sim-probe",
            "--plan",
            "probe-cal",
            "--repeats",
            "1000000",
            "--out",
            "a.csv",
        ],
        &dir,
        &["--repeats 1000000", "at most"],
    );
}

/// `sim --plan spindle` writes a thermo-force campaign with idle periods (ap_mm, fz_mm, spindle_rpm and
/// force_N all 0; 1800 of 5400 rows). `fit force` must read the file back without editing (not refuse it:
/// "0 is not a positive finite number"), and `predict` must take the idle rows of a law with z_n < 0 (0^z
/// infinite): the fit leaves the rows without a cut out with a note, and `predict`
/// gives them 0 N (what the firmware outputs) and reproduces the fit's residual RMS on the cutting rows.
#[test]
fn spindle_campaign_is_read_back_by_fit_force_and_predicted() {
    let dir = scratch("spindle-force");
    ok_in(&["sim", "--plan", "spindle", "--out", "s.csv"], &dir);
    ok_in(
        &[
            "fit", "force", "--data", "s.csv", "--out", "law.json", "--json", "fit.json",
        ],
        &dir,
    );
    let fit = common::read_json(&dir.join("fit.json"));
    let notes = fit["notes"].to_string();
    assert!(notes.contains("1800 rows without a cut"), "{notes}");
    ok_in(
        &[
            "predict", "--model", "law.json", "--data", "s.csv", "--out", "p.csv",
        ],
        &dir,
    );
    let (header, rows) = table(&dir.join("p.csv"));
    let (ap, f, p) = (
        col(&header, "ap_mm"),
        col(&header, "force_N"),
        col(&header, "pred_force_N"),
    );
    let num = |r: &[String], k: usize| -> f64 { r[k].parse().unwrap() };
    let (mut sum, mut cut) = (0.0, 0usize);
    for r in &rows {
        if num(r, ap) == 0.0 {
            assert_eq!(num(r, p), 0.0, "an idle row predicts 0 N");
        } else {
            sum += (num(r, f) - num(r, p)).powi(2);
            cut += 1;
        }
    }
    let rms = (sum / cut as f64).sqrt();
    // Reference: the fit's own residual RMS on the same rows (law.rms_n); tolerance 1e-6 relative (the
    // CSV's printed force values).
    let want = fit["law"]["rms_n"].as_f64().unwrap();
    assert_eq!(cut, 3600);
    assert!(
        (rms - want).abs() <= 1e-6 * want,
        "predict {rms} vs fit {want}"
    );
}

/// A geometry model predicted on a row whose Y is outside the model's grid must not name column `x_mm` whatever
/// the axis ("c.csv:3:1 (column `x_mm`): axis position [100, -1, 100] …"), but the column of the axis that
/// is outside, and its range.
#[test]
fn geometry_predict_names_the_axis_outside_the_model() {
    let dir = scratch("geometry-axis");
    ok_in(
        &[
            "plan",
            "geometry",
            "--stroke",
            "400,300,200",
            "--simulate",
            "lines.csv",
        ],
        &dir,
    );
    ok_in(
        &[
            "fit",
            "geometry",
            "--data",
            "lines.csv",
            "--out",
            "model.json",
        ],
        &dir,
    );
    std::fs::write(
        dir.join("rows.csv"),
        "x_mm,y_mm,z_mm\n100,100,100\n100,-1,100\n",
    )
    .unwrap();
    fails_untouched_naming(
        &[
            "predict",
            "--model",
            "model.json",
            "--data",
            "rows.csv",
            "--out",
            "p.csv",
        ],
        &dir,
        &["rows.csv:3:2 (column `y_mm`)", "Y 0 … 300 mm"],
    );
}

/// A thermal model with sensor lags restarts its lags (in equilibrium with the row) where time does not
/// increase, as the fit does; rows sent in another order (reversed here, or shuffled) must not lose their
/// lags silently: `predict` says how many rows restart and where the first is (the predictions stay those of
/// the fit's rule); rows in time order get no note.
#[test]
fn thermal_lags_say_where_time_does_not_increase() {
    let dir = scratch("thermal-order");
    ok_in(&["sim", "--plan", "thermal", "--out", "t.csv"], &dir);
    ok_in(
        &[
            "fit", "thermal", "--data", "t.csv", "--select", "all", "--lags", "--out", "m.json",
        ],
        &dir,
    );
    let m = common::read_json(&dir.join("m.json"));
    assert!(
        m["sensors"]
            .as_array()
            .unwrap()
            .iter()
            .any(|s| s["tau_s"].as_f64().unwrap() > 0.0),
        "the model has a lag: {m}"
    );
    let (header, mut rows) = table(&dir.join("t.csv"));
    rows.reverse();
    write_table(&dir.join("rev.csv"), &header, &rows);
    let o = axcomp_in(
        &[
            "predict", "--model", "m.json", "--data", "t.csv", "--out", "p.csv",
        ],
        &dir,
    );
    assert!(o.status.success());
    assert!(!String::from_utf8_lossy(&o.stderr).contains("does not increase"));
    let o = axcomp_in(
        &[
            "predict", "--model", "m.json", "--data", "rev.csv", "--out", "p.csv",
        ],
        &dir,
    );
    assert!(o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    let want = format!(
        "time_s does not increase at {} row(s) (first rev.csv:3:",
        rows.len() - 1
    );
    assert!(err.contains(&want), "{err}");
}
