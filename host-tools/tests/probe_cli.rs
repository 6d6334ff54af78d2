//! `axcomp fit probe` and `axcomp predict` on a probe calibration, end to end through the CLI binary, on the
//! twin's probe: calibration on a Ø25 mm sphere (582 touches at 100/300/600 mm/min, with bounce
//! and false triggers), a held-out Ø19.05 mm sphere at 450 mm/min; bad input; per-pose centres.

use std::path::Path;
use std::process::Command;

use axcomp_twin::probe::{
    ProbeModel, ProbePlan, SimTouch, TouchKind, simulate_touches, touches_csv,
};

mod common;
use common::{read_json as json, scratch as tmp_dir};

fn run(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(args)
        .output()
        .expect("run axcomp");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Calibration touches followed by the held-out sphere's touches (glitch-free), one CSV.
fn twin_file(dir: &Path) -> (std::path::PathBuf, Vec<SimTouch>) {
    let probe = ProbeModel::kinematic_demo();
    let mut t = simulate_touches(&probe, &ProbePlan::standard_calibration(), 3);
    let meas = simulate_touches(
        &probe.without_glitches(),
        &ProbePlan::measurement(450.0, 1),
        4,
    );
    t.extend(meas.into_iter().filter(|m| m.artefact == "sphere2"));
    let p = dir.join("touches.csv");
    std::fs::write(&p, touches_csv(&t)).unwrap();
    (p, t)
}

#[test]
fn twin_calibration_held_out_sphere_and_predict() {
    let dir = tmp_dir("twin");
    let (data, truth) = twin_file(&dir);
    let (cal, j, rep) = (dir.join("cal.json"), dir.join("fit.json"), dir.join("rep"));
    let (ok, out, err) = run(&[
        "fit",
        "probe",
        "--data",
        s(&data),
        "--sphere-diameter-mm",
        "25",
        "--holdout",
        "artefact=sphere2",
        "--holdout-diameter-mm",
        "19.05",
        "--stylus-diameter-mm",
        "3",
        "--out",
        s(&cal),
        "--json",
        s(&j),
        "--report",
        s(&rep),
    ]);
    assert!(ok, "{out}\n{err}");
    println!("{out}");
    let v = json(&j);
    for k in [
        "sphere_center_mm",
        "stylus_radius_mm",
        "pretravel",
        "repeatability_2sigma_um",
        "fit_rms_um",
        "holdout_rms_um",
        "diameter_error_um",
        "outliers",
    ] {
        assert!(v.get(k).is_some(), "missing {k}");
    }
    // Centre: the twin's (100, 50, 20) mm within 1 µm; stylus radius: the mean effective radius at zero
    // speed of the twin (1.5 mm − mean pretravel ≈ 4–6 µm) within 2 µm.
    let c = &v["sphere_center_mm"];
    for (k, want) in [100.0, 50.0, 20.0].iter().enumerate() {
        assert!((c[k].as_f64().unwrap() - want).abs() < 1e-3, "{c}");
    }
    let r = v["stylus_radius_mm"].as_f64().unwrap();
    assert!(r > 1.5 - 0.008 && r < 1.5 - 0.002, "{r}");
    // Held-out sphere at 450 mm/min (required: diameter error ≤ 0.5 µm, radial RMS ≤ 1.2σ = 0.6 µm, ≥ 90 %
    // better than uncorrected).
    let de = &v["diameter_error_um"];
    let (before, after) = (
        de["before"].as_f64().unwrap(),
        de["after"].as_f64().unwrap(),
    );
    let hr = v["holdout_rms_um"].as_f64().unwrap();
    let hb = v["holdout_rms_before_um"].as_f64().unwrap();
    println!(
        "diameter error before {before:+.3} after {after:+.3} reference {} µm; holdout RMS {hr:.3} (before {hb:.3}, reference {}) µm",
        de["reference_bilinear"], v["holdout_rms_reference_um"]
    );
    assert_eq!(de["on"], "holdout");
    assert!(after.abs() <= 0.5, "{after}");
    assert!(hr <= 1.2 * 0.5, "{hr}");
    assert!(1.0 - after.abs() / before.abs() >= 0.9);
    // Every glitch of the calibration rows is among the outliers (rows named by file:line; line = index + 2).
    let rows: Vec<String> = v["outliers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o["row"].as_str().unwrap().to_string())
        .collect();
    for (i, t) in truth.iter().enumerate() {
        if t.kind != TouchKind::Good {
            let line = format!("touches.csv:{} ", i + 2);
            assert!(
                rows.iter().any(|r| r.contains(&line)),
                "row {line} not flagged: {rows:?}"
            );
        }
    }
    for f in [
        "report.md",
        "residual_map.svg",
        "pretravel_speed.svg",
        "diameter_error.svg",
    ] {
        assert!(rep.join(f).exists(), "{f}");
    }

    // predict: the held-out touches corrected to contact points lie on the true sphere within 4σ.
    let meas = dir.join("meas.csv");
    let probe = ProbeModel::kinematic_demo().without_glitches();
    let m = simulate_touches(&probe, &ProbePlan::measurement(450.0, 1), 9);
    std::fs::write(&meas, touches_csv(&m)).unwrap();
    let pred = dir.join("pred.csv");
    let (ok, out, err) = run(&[
        "predict",
        "--model",
        s(&cal),
        "--data",
        s(&meas),
        "--out",
        s(&pred),
    ]);
    assert!(ok, "{out}\n{err}");
    let text = std::fs::read_to_string(&pred).unwrap();
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert!(
        header.ends_with(&["contact_x_mm", "contact_y_mm", "contact_z_mm"]),
        "{header:?}"
    );
    let mut worst: f64 = 0.0;
    for (l, t) in lines.zip(&m) {
        let f: Vec<f64> = l
            .split(',')
            .rev()
            .take(3)
            .map(|x| x.parse().unwrap())
            .collect();
        let contact = [f[2], f[1], f[0]];
        // Distance from the true surface point along the normal (the contact point's error), µm.
        let e: f64 = (0..3)
            .map(|k| (contact[k] - t.surface_mm[k]) * t.normal[k])
            .sum::<f64>()
            * 1000.0;
        worst = worst.max(e.abs());
    }
    // 4σ of the noise (2 µm) plus the calibration's own uncertainty (≈ 0.3 µm, `cargo run -p axcomp-probe
    // --example probe_seeds`).
    println!("worst contact error {worst:.3} µm over {} touches", m.len());
    assert!(worst < 2.5, "{worst}");
}

fn expect_error(dir: &Path, csv: &str, needle: &[&str]) {
    let data = dir.join("bad.csv");
    std::fs::write(&data, csv).unwrap();
    let out = dir.join("cal.json");
    let j = dir.join("fit.json");
    let (ok, o, err) = run(&[
        "fit",
        "probe",
        "--data",
        s(&data),
        "--sphere-diameter-mm",
        "25",
        "--out",
        s(&out),
        "--json",
        s(&j),
    ]);
    assert!(!ok, "{o}");
    for n in needle {
        assert!(err.contains(n), "`{n}` not in: {err}");
    }
    assert!(!out.exists() && !j.exists(), "something was written");
    let left: Vec<_> = std::fs::read_dir(dir).unwrap().collect();
    assert_eq!(left.len(), 1, "only the input remains: {left:?}");
}

fn good_rows(n_el: &[f64]) -> Vec<String> {
    let mut v = Vec::new();
    for &el in n_el {
        for k in 0..8 {
            let (a, e) = ((45.0 * k as f64).to_radians(), f64::to_radians(el));
            let n = [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()];
            let r = 12.5 + 1.5;
            v.push(format!(
                "{},{},{},{},{},{},100",
                r * n[0],
                r * n[1],
                r * n[2],
                -n[0],
                -n[1],
                -n[2]
            ));
        }
    }
    v
}

#[test]
fn bad_input_names_the_row_and_writes_nothing() {
    let header = "x_mm,y_mm,z_mm,approach_x,approach_y,approach_z,feed_mm_min\n";
    let body = |rows: &[String]| format!("{header}{}\n", rows.join("\n"));
    let dir = tmp_dir("bad");
    // Not unit length: row 5 (line 6).
    let mut r = good_rows(&[0.0, 45.0]);
    r[4] = "14,0,0,-0.8,0,0,100".into();
    expect_error(&dir, &body(&r), &["bad.csv:6", "not a unit vector"]);
    // Pointing away from the sphere: line 4.
    let mut r = good_rows(&[0.0, 45.0]);
    r[2] = "0,14,0,0,1,0,100".into();
    expect_error(&dir, &body(&r), &["bad.csv:4", "away from the sphere"]);
    // NaN: line 3, column x_mm.
    let mut r = good_rows(&[0.0, 45.0]);
    r[1] = "NaN,14,0,0,-1,0,100".into();
    expect_error(&dir, &body(&r), &["bad.csv:3", "x_mm"]);
    // Fewer touches than a sphere needs.
    let r = good_rows(&[0.0]);
    expect_error(&dir, &body(&r[..3]), &["3 touches", "at least 4"]);
    // All on one great circle (the equator).
    let r = good_rows(&[0.0]);
    expect_error(&dir, &body(&r), &["one plane", "great circle", "bad.csv:2"]);
    // A text cell: file, line and column.
    let mut r = good_rows(&[0.0, 45.0]);
    r[0] = "abc,0,0,-1,0,0,100".into();
    expect_error(&dir, &body(&r), &["bad.csv:2:1", "x_mm"]);
}

#[test]
fn per_pose_centres_as_rtest_rows() {
    // Three poses of a five-axis calibration: the sphere sits at the commanded tool point plus a known
    // offset (the location error to identify). Reference: those offsets; tolerance 1 µm: the centre's z
    // carries the calibration's z uncertainty, 0.25 µm 1σ (`cargo run -p axcomp-probe --example probe_seeds`), so 4σ.
    // The probe has bounce and false triggers: every pose's glitches are flagged and left out of its centre.
    let dir = tmp_dir("groups");
    let probe = ProbeModel::kinematic_demo();
    let poses = [
        ("0", "0", [100.0, 50.0, 20.0], [0.0, 0.0, 0.0]),
        ("30", "90", [80.0, 60.0, 30.0], [4.0, -3.0, 2.5]),
        ("-30", "180", [120.0, 40.0, 25.0], [-2.0, 6.0, -1.5]),
    ];
    let mut csv = String::new();
    let mut glitches = 0;
    for (k, (a, c, cmd, off)) in poses.iter().enumerate() {
        let centre = [
            cmd[0] + off[0] * 1e-3,
            cmd[1] + off[1] * 1e-3,
            cmd[2] + off[2] * 1e-3,
        ];
        let plan = ProbePlan::calibration(
            centre,
            25.0,
            &[0.0, 22.5, 45.0, 67.5, 90.0],
            24,
            &[100.0, 300.0, 600.0],
            1,
        );
        let t = simulate_touches(&probe, &plan, 20 + k as u64);
        glitches += t.iter().filter(|x| x.kind != TouchKind::Good).count();
        let text = touches_csv(&t);
        for (i, line) in text.lines().enumerate() {
            if i == 0 {
                if k == 0 {
                    csv.push_str(&format!("{line},a_deg,c_deg,cmd_x_mm,cmd_y_mm,cmd_z_mm\n"));
                }
                continue;
            }
            csv.push_str(&format!(
                "{line},{a},{c},{},{},{}\n",
                cmd[0], cmd[1], cmd[2]
            ));
        }
    }
    let data = dir.join("poses.csv");
    std::fs::write(&data, csv).unwrap();
    let (cen, j) = (dir.join("centres.csv"), dir.join("fit.json"));
    let (ok, out, err) = run(&[
        "fit",
        "probe",
        "--data",
        s(&data),
        "--sphere-diameter-mm",
        "25",
        "--group",
        "a_deg,c_deg",
        "--centres-out",
        s(&cen),
        "--json",
        s(&j),
    ]);
    assert!(ok, "{out}\n{err}");
    let v = json(&j);
    let flagged: usize = v["groups"]
        .as_array()
        .unwrap()
        .iter()
        .map(|g| g["outliers"].as_array().unwrap().len())
        .sum::<usize>()
        + v["outliers"].as_array().unwrap().len();
    println!("flagged {flagged} glitch rows over the poses ({glitches} simulated)");
    assert!(flagged >= glitches, "{flagged} < {glitches}");
    let text = std::fs::read_to_string(&cen).unwrap();
    println!("{text}");
    let mut lines = text.lines();
    // The contract's columns, then the calibration's error shared by every pose's centre (the rotary probe
    // route: whole triplets zero1_dx_um, zero1_dy_um, zero1_dz_um, zero2_…, read by `fit rtest`).
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(
        header[..8],
        [
            "x_mm", "y_mm", "z_mm", "a_deg", "c_deg", "dx_um", "dy_um", "dz_um"
        ]
    );
    assert!(
        header.len() > 8 && (header.len() - 8) % 3 == 0,
        "{header:?}"
    );
    for (i, h) in header[8..].iter().enumerate() {
        let want = format!("zero{}_{}", i / 3 + 1, ["dx_um", "dy_um", "dz_um"][i % 3]);
        assert_eq!(*h, want);
    }
    for (line, (a, c, cmd, off)) in lines.zip(&poses) {
        let f: Vec<&str> = line.split(',').collect();
        assert_eq!((f[3], f[4]), (*a, *c));
        assert_eq!(f[0].parse::<f64>().unwrap(), cmd[0]);
        for k in 0..3 {
            let d: f64 = f[5 + k].parse().unwrap();
            assert!((d - off[k]).abs() < 1.0, "{line}: {d} vs {}", off[k]);
        }
    }
}

#[test]
fn sim_probe_writes_touches_and_truth_that_fit_probe_reads() {
    let dir = tmp_dir("sim");
    let (cal_csv, m_csv, truth) = (
        dir.join("cal.csv"),
        dir.join("m.csv"),
        dir.join("truth.csv"),
    );
    let (ok, o, e) = run(&[
        "sim-probe",
        "--plan",
        "probe-cal",
        "--out",
        s(&cal_csv),
        "--seed",
        "5",
    ]);
    assert!(ok, "{o}\n{e}");
    let (ok, o, e) = run(&[
        "sim-probe",
        "--plan",
        "probe-measure",
        "--feed",
        "200",
        "--no-glitches",
        "--out",
        s(&m_csv),
        "--truth",
        s(&truth),
    ]);
    assert!(ok, "{o}\n{e}");
    let rows = |p: &Path| std::fs::read_to_string(p).unwrap().lines().count();
    assert_eq!(rows(&m_csv), rows(&truth));
    assert_eq!(rows(&m_csv), 1 + 64 + 36 + 25);
    let j = dir.join("fit.json");
    let (ok, o, e) = run(&[
        "fit",
        "probe",
        "--data",
        s(&cal_csv),
        "--sphere-diameter-mm",
        "25",
        "--json",
        s(&j),
    ]);
    assert!(ok, "{o}\n{e}");
    // Without --holdout the diameter error is judged on the calibration rows themselves.
    assert_eq!(json(&j)["diameter_error_um"]["on"], "calibration");
    // An unknown plan is refused and writes nothing.
    let bad = dir.join("bad.csv");
    let (ok, _, e) = run(&["sim-probe", "--plan", "helix", "--out", s(&bad)]);
    assert!(!ok && e.contains("helix") && !bad.exists(), "{e}");
}
