//! Every report's plots read: each system's chain runs on small twin data (positioning,
//! thermal, force, geometry, R-test, probe, diagnose on survey, R-test and touch data; the Kistler milling
//! files when `../shared` is there) and every SVG it writes is checked through the plot description each
//! SVG carries (`axcomp_plot::descriptions`), not by matching its drawing:
//! - it is not empty: some series drew markers, line pieces or bars;
//! - no series is lost: a series with values drew something, one with fewer than two values drew each as a
//!   marker, a line with fewer than `style::FEW_POINTS` values shows a marker at each;
//! - a magnitude axis (declared, or a label that says |…| or RMS) starts at 0, none goes below it;
//! - axis labels are written in the one style (`quantity (unit)`, units spelled as in `style::UNITS`);
//! - titles say something (not empty).

use std::path::Path;

use axcomp_plot::style::{FEW_POINTS, check_label};

mod common;
use common::{ok_in as ok, scratch, shared};

/// Checks every SVG in `dir`; returns their names.
fn check_svgs(dir: &Path) -> Vec<String> {
    let mut names = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_none_or(|x| x != "svg") {
            continue;
        }
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        let svg = std::fs::read_to_string(&p).unwrap();
        let descs = axcomp_plot::descriptions(&svg);
        assert!(!descs.is_empty(), "{name}: no plot description");
        for d in &descs {
            let d: serde_json::Value =
                serde_json::from_str(d).unwrap_or_else(|e| panic!("{name}: {e}: {d}"));
            check_chart(&name, &d);
        }
        names.push(name);
    }
    names.sort();
    names
}

fn check_chart(name: &str, d: &serde_json::Value) {
    let title = d["title"].as_str().unwrap();
    assert!(!title.trim().is_empty(), "{name}: no title");
    let y_label = d["y_label"].as_str().unwrap();
    check_label(y_label).unwrap_or_else(|e| panic!("{name}: y label: {e}"));
    if d["chart"] == "figure" {
        check_label(d["x_label"].as_str().unwrap())
            .unwrap_or_else(|e| panic!("{name}: x label: {e}"));
    }
    let series = d["series"].as_array().unwrap();
    let drawn =
        |s: &serde_json::Value| s["markers"].as_u64().unwrap() + s["segments"].as_u64().unwrap();
    assert!(
        series.iter().any(|s| drawn(s) > 0),
        "{name} ({title}): nothing drawn: {d}"
    );
    for s in series {
        let n = s["points"].as_u64().unwrap();
        let label = format!("{name}: series {}", s["name"]);
        if n > 0 {
            assert!(drawn(s) > 0, "{label}: {n} values, nothing drawn");
        }
        if (1..2).contains(&n) && s["kind"] != "bars" && s["kind"] != "band" {
            assert_eq!(
                s["markers"].as_u64(),
                Some(n),
                "{label}: lone value not a marker"
            );
        }
        if ["line", "dashed"].contains(&s["kind"].as_str().unwrap()) && n < FEW_POINTS as u64 {
            assert_eq!(
                s["markers"].as_u64(),
                Some(n),
                "{label}: few values without markers"
            );
        }
    }
    let says_magnitude = y_label.starts_with('|') || y_label.contains("RMS");
    if says_magnitude {
        assert_eq!(
            d["magnitude"], true,
            "{name}: {y_label:?} not declared a magnitude"
        );
    }
    if d["magnitude"] == true {
        let lo = d["y_axis"][0].as_f64().unwrap();
        assert!(lo >= 0.0, "{name}: magnitude axis from {lo}");
    }
}

/// Asserts that `dir` holds (at least) the `expected` SVGs, all passing [`check_svgs`].
fn expect(dir: &Path, expected: &[&str]) {
    let names = check_svgs(dir);
    for e in expected {
        assert!(
            names.iter().any(|n| n == e),
            "{}: no {e} in {names:?}",
            dir.display()
        );
    }
}

/// 21 targets × 6 bidirectional runs of a smooth error with a little noise (as in `outputs_more_cli.rs`).
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
fn positioning_and_demo_plots_read() {
    let dir = scratch("positioning");
    positioning_csv(&dir.join("d.csv"));
    ok(
        &[
            "fit",
            "positioning",
            "--data",
            "d.csv",
            "--out",
            "t.json",
            "--report",
            "rep",
        ],
        &dir,
    );
    expect(&dir.join("rep"), &["positioning.svg", "residual.svg"]);
    ok(&["demo", "--out", "demo"], &dir);
    expect(
        &dir.join("demo"),
        &[
            "deviation_before.svg",
            "deviation_after.svg",
            "iso230_before_after.svg",
        ],
    );
}

#[test]
fn thermal_plots_read() {
    let dir = scratch("thermal");
    let d = axcomp_twin::synth::generate(&axcomp_twin::synth::SynthConfig {
        seed: 5,
        ..Default::default()
    });
    d.write_csv(&dir.join("twin.csv")).unwrap();
    ok(
        &[
            "fit", "thermal", "--data", "twin.csv", "--target", "error_um", "--report", "rep",
            "--out", "m.json",
        ],
        &dir,
    );
    expect(
        &dir.join("rep"),
        &[
            "prediction.svg",
            "residual_per_condition.svg",
            "sensors.svg",
        ],
    );
}

/// Eight rows of a power law F = 1500·ap·fz^0.8 (reference values, no noise but a ±1 % ripple) and four
/// validation rows: the force plot shows eight fitted and four validation samples.
#[test]
fn force_plots_read() {
    let dir = scratch("force");
    let rows = |fzs: &[f64], aps: &[f64]| {
        let mut s = String::from("ap_mm,fz_mm,n_rpm,Fc_N\n");
        for (k, (&fz, &ap)) in fzs.iter().zip(aps).enumerate() {
            let f = 1500.0 * ap * f64::powf(fz, 0.8) * (1.0 + 0.01 * (k as f64 * 1.7).sin());
            s.push_str(&format!("{ap},{fz},1000,{f:.3}\n"));
        }
        s
    };
    std::fs::write(
        dir.join("f.csv"),
        rows(
            &[0.05, 0.1, 0.15, 0.2, 0.25, 0.3, 0.35, 0.4],
            &[1.0, 2.0, 1.0, 2.0, 1.0, 2.0, 1.0, 2.0],
        ),
    )
    .unwrap();
    std::fs::write(
        dir.join("v.csv"),
        rows(&[0.12, 0.22, 0.32, 0.18], &[1.5, 1.5, 0.5, 3.0]),
    )
    .unwrap();
    ok(
        &[
            "fit",
            "force",
            "--data",
            "f.csv",
            "--fix",
            "z_n=0",
            "--validate",
            "v.csv",
            "--report",
            "rep",
        ],
        &dir,
    );
    expect(&dir.join("rep"), &["force_fit.svg"]);
    let svg = std::fs::read_to_string(dir.join("rep/force_fit.svg")).unwrap();
    let d: serde_json::Value = serde_json::from_str(&axcomp_plot::descriptions(&svg)[0]).unwrap();
    assert_eq!(
        d["series"][0]["markers"],
        8 + 4,
        "fitted + validation samples"
    );

    let Some(shared) = shared() else { return };
    let m = shared.join("data/real/force-milling-slot-kistler");
    let mut args: Vec<String> = ["fit", "force", "--kind", "milling", "--dynoware"]
        .map(String::from)
        .to_vec();
    for f in [300, 600, 900, 1200, 1500] {
        args.push(
            m.join(format!("6-n6000f{f}ap3ae25.csv"))
                .display()
                .to_string(),
        );
    }
    args.extend(
        [
            "--n-rpm", "6000", "--flutes", "2", "--ap-mm", "3", "--report", "mill",
        ]
        .map(String::from),
    );
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    ok(&args, &dir);
    expect(&dir.join("mill"), &["mean_forces.svg"]);
    // Each force's fitted line has the colour of its measured points.
    let svg = std::fs::read_to_string(dir.join("mill/mean_forces.svg")).unwrap();
    let d: serde_json::Value = serde_json::from_str(&axcomp_plot::descriptions(&svg)[0]).unwrap();
    let s = d["series"].as_array().unwrap();
    for pair in s.chunks(2) {
        assert_eq!(pair[0]["colour"], pair[1]["colour"], "{pair:?}");
    }
}

#[test]
fn geometry_plots_read() {
    use axcomp_kinematics::Topology;
    use axcomp_twin::geometry::{GeometryTwin, plan_by_name};
    let dir = scratch("geometry");
    let stroke = [800.0, 600.0, 500.0];
    let mut lines = plan_by_name("seven-line", stroke, 11).unwrap();
    lines.extend(plan_by_name("step-diagonal", stroke, 11).unwrap());
    lines.extend(plan_by_name("tool-offsets", stroke, 11).unwrap());
    let twin = GeometryTwin::random(stroke, Topology::default(), 1);
    std::fs::write(
        dir.join("lines.csv"),
        twin.measure(&lines, 2, 101).to_csv_string(),
    )
    .unwrap();
    ok(
        &[
            "fit",
            "geometry",
            "--data",
            "lines.csv",
            "--holdout",
            "line=L4",
            "--report",
            "rep",
        ],
        &dir,
    );
    expect(
        &dir.join("rep"),
        &["EXX.svg", "volumetric_z1.svg", "line_L4.svg"],
    );
    // The held-out line is drawn per pass in position order: every predicted piece is sorted, so no line
    // runs back to the start (the file order's false line back to 0).
    let svg = std::fs::read_to_string(dir.join("rep/line_L4.svg")).unwrap();
    let d: serde_json::Value = serde_json::from_str(&axcomp_plot::descriptions(&svg)[0]).unwrap();
    let predicted: u64 = d["series"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|s| s["kind"] == "dashed")
        .map(|s| s["segments"].as_u64().unwrap())
        .sum();
    assert!(predicted >= 2, "one piece per pass (2 runs): {d}");
}

#[test]
fn rtest_plots_read() {
    use axcomp_kinematics::rotary::{FiveAxis, MachineKind};
    use axcomp_twin::five_axis::{FiveAxisTwin, standard_paths};
    let dir = scratch("rtest");
    let m = FiveAxis::new(MachineKind::AcTrunnion, 0.0);
    let twin = FiveAxisTwin::random(m, 3);
    let paths = standard_paths(&m, [150.0, 0.0, 100.0], -60.0, 72, &[0.0, -60.0], 36, None);
    std::fs::write(dir.join("r.csv"), twin.measure(&paths, 3).to_csv_string()).unwrap();
    ok(
        &[
            "fit",
            "rtest",
            "--data",
            "r.csv",
            "--holdout",
            "run=2",
            "--report",
            "rep",
        ],
        &dir,
    );
    expect(
        &dir.join("rep"),
        &[
            "path_dx.svg",
            "path_dy.svg",
            "path_dz.svg",
            "rotary_range.svg",
        ],
    );
    let svg = std::fs::read_to_string(dir.join("rep/rotary_range.svg")).unwrap();
    assert!(!svg.contains("-0.0°"), "a tilt written −0");
    let d: serde_json::Value = serde_json::from_str(&axcomp_plot::descriptions(&svg)[0]).unwrap();
    assert_eq!(d["x_axis"][1].as_f64(), Some(360.0), "C over one turn");
    ok(
        &[
            "diagnose",
            "--data",
            "r.csv",
            "--model",
            "location_errors",
            "--holdout",
            "run=2",
            "--report",
            "diag",
        ],
        &dir,
    );
    expect(&dir.join("diag"), &["heldout_components.svg"]);
}

#[test]
fn probe_plots_read() {
    let dir = scratch("probe");
    ok(
        &[
            "sim-probe",
            "--plan",
            "probe-cal",
            "--out",
            "cal.csv",
            "--seed",
            "5",
        ],
        &dir,
    );
    ok(
        &[
            "sim-probe",
            "--plan",
            "probe-measure",
            "--feed",
            "200",
            "--out",
            "m.csv",
        ],
        &dir,
    );
    // The calibration touches and the second sphere's (held out) in one file.
    let cal = std::fs::read_to_string(dir.join("cal.csv")).unwrap();
    let m = std::fs::read_to_string(dir.join("m.csv")).unwrap();
    let mut all = cal.clone();
    for l in m.lines().skip(1).filter(|l| l.contains("sphere2")) {
        all.push_str(l);
        all.push('\n');
    }
    std::fs::write(dir.join("t.csv"), all).unwrap();
    ok(
        &[
            "fit",
            "probe",
            "--data",
            "t.csv",
            "--sphere-diameter-mm",
            "25",
            "--holdout",
            "artefact=sphere2",
            "--holdout-diameter-mm",
            "19.05",
            "--stylus-diameter-mm",
            "3",
            "--report",
            "rep",
        ],
        &dir,
    );
    expect(
        &dir.join("rep"),
        &[
            "diameter_error.svg",
            "pretravel_speed.svg",
            "residual_map.svg",
            "residual_map_plain.svg",
        ],
    );
    // The held-out sphere is probed at one feed: each series is one value, drawn as a marker.
    let svg = std::fs::read_to_string(dir.join("rep/diameter_error.svg")).unwrap();
    let d: serde_json::Value = serde_json::from_str(&axcomp_plot::descriptions(&svg)[0]).unwrap();
    for s in d["series"].as_array().unwrap() {
        assert_eq!(
            (s["points"].as_u64(), s["markers"].as_u64()),
            (Some(1), Some(1)),
            "{s}"
        );
    }
    // Touches coloured by approach: more than one class, each class's model line in its colour.
    let svg = std::fs::read_to_string(dir.join("rep/pretravel_speed.svg")).unwrap();
    let d: serde_json::Value = serde_json::from_str(&axcomp_plot::descriptions(&svg)[0]).unwrap();
    let s = d["series"].as_array().unwrap();
    assert!(s.len() >= 4, "{d}");
    for pair in s.chunks(2) {
        assert_eq!(pair[0]["colour"], pair[1]["colour"], "{pair:?}");
    }
    ok(
        &[
            "diagnose",
            "--data",
            "t.csv",
            "--model",
            "probe_radius",
            "--holdout",
            "artefact=sphere2",
            "--report",
            "diag",
        ],
        &dir,
    );
    check_svgs(&dir.join("diag"));
}

#[test]
fn diagnose_plots_read() {
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
    ok(
        &[
            "diagnose",
            "--data",
            "s.csv",
            "--model",
            "pitch_error",
            "--holdout",
            "offset_mm=100",
            "--report",
            "rep",
        ],
        &dir,
    );
    expect(&dir.join("rep"), &["gap_target_mm.svg"]);
}
