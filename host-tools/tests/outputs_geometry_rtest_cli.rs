//! All-or-nothing outputs, following `outputs_more_cli.rs`: for `plan geometry`,
//! `fit geometry`, `fit rtest`, `plan rtest` and `replay`, the last output path that cannot be written (its
//! directory is missing) fails with exit code 2 before anything is written: existing outputs keep their old
//! bytes, no new file appears, no temporary is left, and the message names the user's path. A control run
//! with writable paths succeeds (so the failure is the path's, not the input's).

use axcomp_kinematics::rotary::{FiveAxis, MachineKind};
use axcomp_twin::five_axis::{FiveAxisTwin, standard_paths};

mod common;
use common::{fails_untouched, ok_in as ok, scratch};

/// K4 run 1, C circles at 0° and −60°, K4 run 2 on an AC trunnion twin (seed 3, σ = 0.3 µm), as in
/// `rtest_cli.rs`.
fn rtest_csv() -> String {
    let m = FiveAxis::new(MachineKind::AcTrunnion, 0.0);
    let twin = FiveAxisTwin::random(m, 3);
    let paths = standard_paths(&m, [150.0, 0.0, 100.0], -60.0, 72, &[0.0, -60.0], 36, None);
    twin.measure(&paths, 3).to_csv_string()
}

#[test]
fn plan_and_fit_geometry_bad_last_output_touch_nothing() {
    let dir = scratch("out-geometry");
    std::fs::write(dir.join("plan.json"), "old plan").unwrap();
    let plan = |json: &'static str, csv: &'static str| {
        [
            "plan",
            "geometry",
            "--stroke",
            "800,600,500",
            "--lines",
            "20",
            "--sigma-um",
            "0.5",
            "--json",
            json,
            "--simulate",
            csv,
        ]
    };
    // --simulate (the last output) cannot be written: the plan JSON is not written either.
    fails_untouched(
        &plan("plan.json", "missing-dir/lines.csv"),
        &dir,
        "missing-dir/lines.csv",
    );
    // Control: writable paths succeed and replace the old JSON.
    ok(&plan("plan.json", "lines.csv"), &dir);
    assert_ne!(std::fs::read(dir.join("plan.json")).unwrap(), b"old plan");
    assert!(dir.join("lines.csv").is_file());

    std::fs::write(dir.join("fit.json"), "old fit").unwrap();
    std::fs::write(dir.join("model.json"), "old model").unwrap();
    let fit = |report: &'static str, export: &'static str| {
        [
            "fit",
            "geometry",
            "--data",
            "lines.csv",
            "--json",
            "fit.json",
            "--out",
            "model.json",
            "--report",
            report,
            "--export",
            export,
        ]
    };
    // The export folder's parent is missing.
    fails_untouched(
        &fit("rep", "missing-dir/tables"),
        &dir,
        "missing-dir/tables",
    );
    // The report folder's parent is missing.
    fails_untouched(&fit("missing-dir/rep", "tables"), &dir, "missing-dir/rep");
    // Control: every output written.
    ok(&fit("rep", "tables"), &dir);
    assert_ne!(std::fs::read(dir.join("fit.json")).unwrap(), b"old fit");
    assert_ne!(std::fs::read(dir.join("model.json")).unwrap(), b"old model");
    assert!(dir.join("rep/report.md").is_file());
    assert!(std::fs::read_dir(dir.join("tables")).unwrap().count() > 0);
}

#[test]
fn fit_and_plan_rtest_bad_last_output_touch_nothing() {
    let dir = scratch("out-rtest");
    std::fs::write(dir.join("rtest.csv"), rtest_csv()).unwrap();
    std::fs::write(dir.join("fit.json"), "old fit").unwrap();
    std::fs::write(dir.join("model.json"), "old model").unwrap();
    let fit = |report: &'static str, out: &'static str| {
        [
            "fit",
            "rtest",
            "--data",
            "rtest.csv",
            "--holdout",
            "run=2",
            "--report",
            report,
            "--json",
            "fit.json",
            "--out",
            out,
        ]
    };
    // --out (the last output) cannot be written: neither the report nor the JSON is written.
    fails_untouched(
        &fit("rep", "missing-dir/model.json"),
        &dir,
        "missing-dir/model.json",
    );
    // The report folder's parent is missing.
    fails_untouched(
        &fit("missing-dir/rep", "model.json"),
        &dir,
        "missing-dir/rep",
    );
    // Control: every output written.
    ok(&fit("rep", "model.json"), &dir);
    assert_ne!(std::fs::read(dir.join("fit.json")).unwrap(), b"old fit");
    assert_ne!(std::fs::read(dir.join("model.json")).unwrap(), b"old model");
    assert!(dir.join("rep/report.md").is_file());

    let plan = |json: &'static str| ["plan", "rtest", "--sigma-um", "0.3", "--json", json];
    fails_untouched(
        &plan("missing-dir/plan.json"),
        &dir,
        "missing-dir/plan.json",
    );
    ok(&plan("plan.json"), &dir);
    assert!(dir.join("plan.json").is_file());
}

#[test]
fn replay_bad_csv_touches_nothing() {
    let dir = scratch("out-replay");
    ok(
        &[
            "trace",
            "--scenario",
            "equivalence",
            "--cycles",
            "10000",
            "--out",
            "e.trace",
        ],
        &dir,
    );
    std::fs::write(dir.join("out.bin"), "old records").unwrap();
    let replay = |csv: &'static str| {
        [
            "replay", "--trace", "e.trace", "--out", "out.bin", "--csv", csv,
        ]
    };
    // --csv (the last output) cannot be written: the records file keeps its old bytes.
    fails_untouched(&replay("missing-dir/out.csv"), &dir, "missing-dir/out.csv");
    // --csv names an existing folder, not a file (its parent exists): still nothing written.
    std::fs::create_dir(dir.join("csv-folder")).unwrap();
    fails_untouched(&replay("csv-folder"), &dir, "csv-folder");
    // Control: both written.
    ok(&replay("out.csv"), &dir);
    assert_ne!(std::fs::read(dir.join("out.bin")).unwrap(), b"old records");
    assert!(dir.join("out.csv").is_file());
}
