//! `axcomp plan geometry` and `axcomp fit geometry` end to end on the three-axis twin: the contract's JSON,
//! model file, exports, report; bad input leaves nothing written.

mod common;
use common::scratch;
use std::path::Path;
use std::process::{Command, Output};

fn axcomp(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run axcomp")
}

fn ok(o: &Output) -> String {
    assert!(
        o.status.success(),
        "stdout {}\nstderr {}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// Twin truth unknown to the fit; reference σ = 0.5 µm. The seven lines are held out: their RMS after the
/// model must be within 1.1 σ (the required figure), and the JSON must carry the contract's fields.
#[test]
fn plan_simulate_fit_export_report() {
    let d = scratch("e2e");
    let out = ok(&axcomp(
        &[
            "plan",
            "geometry",
            "--stroke",
            "800,600,500",
            "--lines",
            "20",
            "--sigma-um",
            "0.5",
            "--twin-plan",
            "seven-line+plan",
            "--simulate",
            "lines.csv",
            "--json",
            "plan.json",
        ],
        &d,
    ));
    assert!(out.contains("all 21 identifiable: yes"), "{out}");
    assert!(out.contains("EA0Z"), "{out}");
    let out = ok(&axcomp(
        &[
            "fit",
            "geometry",
            "--data",
            "lines.csv",
            "--holdout",
            "line=L1,L2,L3,L4,L5,L6,L7",
            "--json",
            "fit.json",
            "--out",
            "model.json",
            "--report",
            "rep",
            "--export",
            "tables",
        ],
        &d,
    ));
    assert!(out.contains("held-out RMS"), "{out}");
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("fit.json")).unwrap()).unwrap();
    for k in ["raw_rms_um", "fit_rms_um", "holdout_rms_um"] {
        assert!(j[k].as_f64().unwrap().is_finite(), "{k}");
    }
    let h = j["holdout_rms_um"].as_f64().unwrap();
    assert!(h <= 1.1 * 0.5, "held-out RMS {h}");
    assert!(j["raw_rms_um"].as_f64().unwrap() > 5.0 * h);
    let errors = j["errors"].as_object().unwrap();
    assert_eq!(errors.len(), 21);
    for name in ["EXX", "EYX", "ECZ"] {
        let e = &errors[name];
        assert_eq!(e["unit"], if name == "ECZ" { "urad" } else { "um" });
        assert!(e["identified"].as_bool().unwrap(), "{name}: {e}");
        assert!(e["samples"].as_array().unwrap().len() > 2);
    }
    assert!(errors["EC0Y"]["value"].as_f64().unwrap().is_finite());
    let id = &j["identifiability"];
    assert!(id["rank"].as_u64().unwrap() > 100);
    assert!(id["condition_number"].as_f64().unwrap() >= 1.0);
    assert!(id["not_separable"].as_array().unwrap().is_empty());
    assert!(j["volumetric"]["max_um"].as_f64().unwrap() > 5.0);
    assert!(j["volumetric"]["rms_um"].as_f64().unwrap() > 1.0);
    let diag = j["iso230_6_body_diagonals"].as_array().unwrap();
    let l7 = diag.iter().find(|x| x["line"] == "L7").unwrap();
    assert_eq!(l7["basis"], "holdout");
    assert!(l7["after_um"].as_f64().unwrap() < l7["before_um"].as_f64().unwrap());
    // exports and report
    let exx = std::fs::read_to_string(d.join("tables/EXX.csv")).unwrap();
    assert!(
        exx.starts_with("component,position_mm,value,unit\nEXX,0.0000,"),
        "{exx}"
    );
    let ax = std::fs::read_to_string(d.join("tables/axis_X.csv")).unwrap();
    assert!(
        ax.starts_with("position_mm,EXX,EYX,EZX,EAX,EBX,ECX\n"),
        "{ax}"
    );
    assert!(d.join("tables/squareness.csv").exists());
    let md = std::fs::read_to_string(d.join("rep/report.md")).unwrap();
    assert!(
        md.contains("EXX.svg") && md.contains("volumetric_z1.svg") && md.contains("line_L4.svg")
    );
    // the model file is readable as a geometry model
    let m = std::fs::read_to_string(d.join("model.json")).unwrap();
    axcomp_geometry::GeometryModel::from_json(&m, "model.json").unwrap();
    // `axcomp predict` with the model file reproduces the fit's held-out RMS on the held-out lines
    // (reference: holdout_rms_um of fit.json; tolerance 1e-5 µm for the CSV's decimal rounding).
    ok(&axcomp(
        &[
            "predict",
            "--model",
            "model.json",
            "--data",
            "lines.csv",
            "--out",
            "pred.csv",
        ],
        &d,
    ));
    let out = std::fs::read_to_string(d.join("pred.csv")).unwrap();
    let header: Vec<&str> = out.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|x| *x == name).unwrap();
    for c in ["pred_ex_um", "pred_ey_um", "pred_ez_um"] {
        col(c);
    }
    let (line, dev, pred) = (col("line"), col("deviation_um"), col("pred_deviation_um"));
    let held = ["L1", "L2", "L3", "L4", "L5", "L6", "L7"];
    let (mut ss, mut n) = (0.0, 0usize);
    for l in out.lines().skip(1) {
        let c: Vec<&str> = l.split(',').collect();
        if held.contains(&c[line]) {
            let r: f64 = c[dev].parse::<f64>().unwrap() - c[pred].parse::<f64>().unwrap();
            ss += r * r;
            n += 1;
        }
    }
    let rms = (ss / n as f64).sqrt();
    assert!((rms - h).abs() < 1e-5, "predict {rms} vs fit {h}");
    let _ = std::fs::remove_dir_all(&d);
}

/// Seed 000's seven lines alone: ECY, EAZ, EBZ, ECZ reported not identified with a reason, the rest
/// identified; with --cv line a cross-validated RMS is given.
#[test]
fn seven_line_set_reports_the_four_it_cannot_identify() {
    let d = scratch("seven");
    ok(&axcomp(
        &[
            "plan",
            "geometry",
            "--stroke",
            "600,500,400",
            "--twin-plan",
            "seven-line",
            "--simulate",
            "seven.csv",
            "--targets",
            "15",
            "--sigma-um",
            "0.5",
        ],
        &d,
    ));
    for method in ["seven-line", "auto"] {
        ok(&axcomp(
            &[
                "fit",
                "geometry",
                "--data",
                "seven.csv",
                "--method",
                method,
                "--cv",
                "line",
                "--json",
                "fit.json",
            ],
            &d,
        ));
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("fit.json")).unwrap()).unwrap();
        assert!(j["cv_rms_um"].as_f64().unwrap().is_finite());
        for (name, e) in j["errors"].as_object().unwrap() {
            let fixed = ["ECY", "EAZ", "EBZ", "ECZ"].contains(&name.as_str());
            assert_eq!(
                e["identified"].as_bool().unwrap(),
                !fixed,
                "{method} {name}: {e}"
            );
            if fixed {
                assert!(e["reason"].as_str().unwrap().contains("lever arm"), "{e}");
            }
        }
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// `--prior evidence` on seed 000's seven lines: the JSON says which prior the evidence chose (its groups,
/// precisions, damping, the knot grids compared and the one kept), the fit still says what it cannot
/// determine (the four without lever arm), and the model predicts the held-out Y-axis-free lines as well as
/// a plausible fit should (held-out RMS finite and below the raw RMS). An unknown prior is refused.
#[test]
fn evidence_prior_is_reported_and_keeps_the_not_identified() {
    let d = scratch("evidence");
    ok(&axcomp(
        &[
            "plan",
            "geometry",
            "--stroke",
            "600,500,400",
            "--twin-plan",
            "seven-line",
            "--simulate",
            "seven.csv",
            "--targets",
            "15",
            "--sigma-um",
            "0.5",
        ],
        &d,
    ));
    ok(&axcomp(
        &[
            "fit",
            "geometry",
            "--data",
            "seven.csv",
            "--prior",
            "evidence",
            "--cv",
            "line",
            "--json",
            "fit.json",
        ],
        &d,
    ));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("fit.json")).unwrap()).unwrap();
    let m = &j["model"];
    assert!(m["method"].as_str().unwrap().contains("evidence"), "{m}");
    let prior = &m["prior"];
    let groups = prior["groups"].as_array().unwrap();
    assert_eq!(groups.len(), 4, "{prior}");
    assert!(
        groups[0][0].as_str().unwrap() == "positioning"
            && groups[0][1].as_array().unwrap().len() == 3
    );
    assert!(prior["log_evidence"].as_f64().unwrap().is_finite());
    assert!(prior["damping"].as_f64().unwrap() > 0.0);
    assert_eq!(prior["roughness_order"], 3, "the default roughness order");
    let grids = prior["knot_grids"].as_array().unwrap();
    assert!(grids.len() >= 2, "{prior}");
    let kept: Vec<u64> = m["knot_intervals"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    let best = grids
        .iter()
        .max_by(|a, b| {
            let ev = |g: &serde_json::Value| g["log_evidence"].as_f64().unwrap();
            ev(a).total_cmp(&ev(b))
        })
        .unwrap();
    assert_eq!(
        best["roughness_order"], prior["roughness_order"],
        "the roughness order kept is the one of highest evidence: {prior}"
    );
    let best_grid: Vec<u64> = best["intervals"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert_eq!(
        kept, best_grid,
        "the grid kept is the one of highest evidence: {prior}"
    );
    assert!(j["cv_rms_um"].as_f64().unwrap() < j["raw_rms_um"].as_f64().unwrap());
    for name in ["ECY", "EAZ", "EBZ", "ECZ"] {
        let e = &j["errors"][name];
        assert!(!e["identified"].as_bool().unwrap(), "{name}: {e}");
        assert!(e["reason"].as_str().unwrap().contains("lever arm"), "{e}");
    }
    let o = axcomp(
        &["fit", "geometry", "--data", "seven.csv", "--prior", "bayes"],
        &d,
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("--prior bayes"));
    let _ = std::fs::remove_dir_all(&d);
}

#[test]
fn bad_input_writes_nothing() {
    let d = scratch("bad");
    std::fs::write(
        d.join("bad.csv"),
        "x_mm,y_mm,z_mm,line,deviation_um,beam_x,beam_y,beam_z\n0,0,0,A,0,1,0,0\n100,0,0,A,1,1,0,0\n200,0,0,A,2,0.5,0,0\n",
    )
    .unwrap();
    let o = axcomp(
        &[
            "fit", "geometry", "--data", "bad.csv", "--json", "fit.json", "--out", "m.json",
            "--report", "rep",
        ],
        &d,
    );
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("line A") && err.contains("bad.csv:4"), "{err}");
    assert!(!d.join("fit.json").exists() && !d.join("m.json").exists() && !d.join("rep").exists());
    let o = axcomp(
        &[
            "fit",
            "geometry",
            "--data",
            "bad.csv",
            "--work-axes",
            "YX",
            "--tool-axes",
            "X",
        ],
        &d,
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("axis X appears 2 times"));
    let o = axcomp(&["plan", "geometry", "--stroke", "800,600"], &d);
    assert!(String::from_utf8_lossy(&o.stderr).contains("--stroke 800,600"));
    let _ = std::fs::remove_dir_all(&d);
}

/// RMS of `deviation_um − pred_deviation_um` and of `deviation_um` over a `predict` output.
fn predicted_rms(path: &Path) -> (f64, f64) {
    let text = std::fs::read_to_string(path).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|x| *x == name).unwrap();
    let (dev, pred) = (col("deviation_um"), col("pred_deviation_um"));
    let (mut ss, mut raw, mut n) = (0.0, 0.0, 0usize);
    for l in text.lines().skip(1) {
        let c: Vec<&str> = l.split(',').collect();
        let d: f64 = c[dev].parse().unwrap();
        let p: f64 = c[pred].parse().unwrap();
        (ss, raw, n) = (ss + (d - p) * (d - p), raw + d * d, n + 1);
    }
    ((ss / n as f64).sqrt(), (raw / n as f64).sqrt())
}

/// A tracking interferometer's campaign: points along lines through the volume, each read along its own
/// beam from one of four stations (`--twin-plan point-cloud`). Fitted as it comes (the beams as given), the
/// model predicts face diagonals read by a plain interferometer that the fit never saw. Reference: the
/// twin's reading noise σ = 0.5 µm; bound 1.6 σ (measured 0.47–0.62 µm over seeds 1–5), and below the
/// seven-line campaign of the same twin on the same diagonals (0.89–1.89 µm).
#[test]
fn point_cloud_read_along_station_beams_is_fitted_and_predicts_diagonals() {
    let d = scratch("point-cloud");
    for seed in ["1", "3"] {
        for plan in ["point-cloud", "seven-line", "face-diagonals"] {
            ok(&axcomp(
                &[
                    "plan",
                    "geometry",
                    "--stroke",
                    "800,600,500",
                    "--sigma-um",
                    "0.5",
                    "--runs",
                    "1",
                    "--seed",
                    seed,
                    "--twin-plan",
                    plan,
                    "--simulate",
                    &format!("{plan}.csv"),
                ],
                &d,
            ));
        }
        let mut held_out = Vec::new();
        for plan in ["point-cloud", "seven-line"] {
            ok(&axcomp(
                &[
                    "fit",
                    "geometry",
                    "--data",
                    &format!("{plan}.csv"),
                    "--out",
                    &format!("{plan}.model.json"),
                    "--json",
                    &format!("{plan}.fit.json"),
                ],
                &d,
            ));
            ok(&axcomp(
                &[
                    "predict",
                    "--model",
                    &format!("{plan}.model.json"),
                    "--data",
                    "face-diagonals.csv",
                    "--out",
                    &format!("{plan}.pred.csv"),
                ],
                &d,
            ));
            held_out.push(predicted_rms(&d.join(format!("{plan}.pred.csv"))));
        }
        let ((cloud, raw), (seven, _)) = (held_out[0], held_out[1]);
        println!(
            "seed {seed}: face diagonals raw {raw:.2} µm, point cloud {cloud:.3} µm, seven-line {seven:.3} µm"
        );
        assert!(
            cloud <= 1.6 * 0.5,
            "seed {seed}: point cloud held-out {cloud}"
        );
        assert!(cloud < seven, "seed {seed}: {cloud} vs seven-line {seven}");
        assert!(raw > 10.0 * cloud);
        // The station readings are not body diagonals, whatever their beams' directions.
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("point-cloud.fit.json")).unwrap())
                .unwrap();
        assert!(j["iso230_6_body_diagonals"].as_array().unwrap().is_empty());
        // `predict` on the campaign itself judges every row along its own beam: the fit's RMS again
        // (reference fit_rms_um; tolerance 1e-4 µm for the CSV's decimals).
        ok(&axcomp(
            &[
                "predict",
                "--model",
                "point-cloud.model.json",
                "--data",
                "point-cloud.csv",
                "--out",
                "self.csv",
            ],
            &d,
        ));
        let (own, _) = predicted_rms(&d.join("self.csv"));
        let fit = j["fit_rms_um"].as_f64().unwrap();
        assert!((own - fit).abs() < 1e-4, "predict {own} vs fit {fit}");
    }
    let _ = std::fs::remove_dir_all(&d);
}

/// The identifiable floor's computable parts next to the held-out figure, and `plan geometry --measured`
/// listing further lines. Reference: the fit's own σ̂ (`model.sigma_um`); the held-out RMS a model right in
/// the lines' span would score is at least σ̂ (noise plus estimation variance). The seven-line set cannot
/// separate ECY, EAZ, EBZ, ECZ; the first further line listed adds rank and reaches only those.
#[test]
fn floor_next_to_holdout_and_further_lines_after_measured_ones() {
    let d = scratch("floor");
    ok(&axcomp(
        &[
            "plan",
            "geometry",
            "--stroke",
            "800,600,500",
            "--lines",
            "1",
            "--sigma-um",
            "0.5",
            "--twin-plan",
            "seven-line",
            "--simulate",
            "seven.csv",
        ],
        &d,
    ));
    ok(&axcomp(
        &[
            "fit",
            "geometry",
            "--data",
            "seven.csv",
            "--holdout",
            "line=L2",
            "--json",
            "fit.json",
        ],
        &d,
    ));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("fit.json")).unwrap()).unwrap();
    let fl = &j["identifiable_floor"];
    let sigma = j["model"]["sigma_um"].as_f64().unwrap();
    assert_eq!(fl["noise_um"].as_f64().unwrap(), sigma, "{fl}");
    assert!(
        fl["expected_holdout_rms_um"].as_f64().unwrap() >= sigma,
        "{fl}"
    );
    assert!(fl["floor_um"].is_null(), "{fl}");
    let out = ok(&axcomp(
        &[
            "plan",
            "geometry",
            "--stroke",
            "800,600,500",
            "--measured",
            "seven.csv",
            "--json",
            "plan.json",
        ],
        &d,
    ));
    assert!(
        out.contains("further lines that would lower the identifiable floor"),
        "{out}"
    );
    let p: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("plan.json")).unwrap()).unwrap();
    let further = p["further_lines"].as_array().unwrap();
    assert!(!further.is_empty(), "{p}");
    // after the lines the plan adds, everything is separable: the list ranks by information gain
    assert!(p["complete"].as_bool().unwrap(), "{p}");
    assert!(
        further[0]["information_gain"].as_f64().unwrap() > 0.0,
        "{p}"
    );
}
