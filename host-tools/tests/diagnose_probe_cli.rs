//! `axcomp diagnose` on probe touches, end to end through the CLI binary: twin campaigns
//! of the withheld-effect validation (`axcomp_validation::probe`) written as touch CSVs, diagnosed with
//! `--model probe_radius --holdout artefact=sphere2`; the contract's JSON fields; bad input.

use std::path::{Path, PathBuf};

use axcomp_validation::probe::{ProbeValidateOptions, make_case};

mod common;
use common::{axcomp_in, fails_untouched, read_json, scratch};

/// Case `index` of the probe validation at `snr` as a touch CSV in `dir`.
fn case_csv(dir: &Path, index: usize, snr: f64) -> (PathBuf, String) {
    let opts = ProbeValidateOptions {
        snrs: vec![snr],
        ..ProbeValidateOptions::default()
    };
    let c = make_case(&opts, index).unwrap();
    let d = &c.data;
    let mut s = String::from(
        "x_mm,y_mm,z_mm,approach_x,approach_y,approach_z,feed_mm_min,artefact,run,time_s,frame_degC\n",
    );
    for i in 0..d.touches.len() {
        let t = &d.touches[i];
        s.push_str(&format!(
            "{:.7},{:.7},{:.7},{:.9},{:.9},{:.9},{},{},{},{:.3},{:.4}\n",
            t.position_mm[0],
            t.position_mm[1],
            t.position_mm[2],
            t.approach[0],
            t.approach[1],
            t.approach[2],
            t.feed_mm_min,
            d.artefact[i],
            d.run.as_ref().unwrap()[i],
            d.time_s.as_ref().unwrap()[i],
            d.temperatures[0].1[i]
        ));
    }
    let p = dir.join(format!("touches{index}.csv"));
    std::fs::write(&p, s).unwrap();
    (
        p,
        c.withheld
            .map_or("none".to_string(), |k| k.name().to_string()),
    )
}

#[test]
fn withheld_bending_is_named_with_the_contract_fields_and_a_report() {
    let dir = scratch("bending");
    // Case 2 withholds stylus_bending (the order of `WITHHELD`); SNR 8.
    let (csv, withheld) = case_csv(&dir, 2, 8.0);
    assert_eq!(withheld, "stylus_bending");
    let o = axcomp_in(
        &[
            "diagnose",
            "--data",
            csv.to_str().unwrap(),
            "--model",
            "probe_radius",
            "--holdout",
            "artefact=sphere2",
            "--json",
            "d.json",
            "--report",
            "rep",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j = read_json(&dir.join("d.json"));
    assert_eq!(j["verdict"], "stylus_bending", "{j}");
    assert_eq!(j["data_kind"], "probe_touches");
    for k in ["train_rms_um", "holdout_rms_um", "holdout_max_um"] {
        assert!(j["gap"][k].as_f64().unwrap() > 0.0, "{k}");
    }
    let effects = j["effects"].as_array().unwrap();
    assert!(effects.len() >= 5, "{effects:?}");
    for e in effects {
        for k in [
            "kind",
            "score",
            "params",
            "holdout_rms_after_um",
            "shrink_pct",
        ] {
            assert!(!e[k].is_null(), "{k} in {e}");
        }
    }
    assert!(j["where"].is_array());
    // The held-out sphere's placement is projected out, the training artefacts' is in the model.
    let arts = j["artefacts"].as_array().unwrap();
    assert!(
        arts.iter()
            .any(|a| a["name"] == "sphere2" && a["placement"] == "projected")
    );
    assert!(dir.join("rep/diagnosis.md").exists());
    assert!(dir.join("rep/holdout_vs_elevation_deg.svg").exists());
}

#[test]
fn a_null_case_gives_none() {
    let dir = scratch("null");
    // Case 3 is a null case (every 4th).
    let (csv, withheld) = case_csv(&dir, 3, 8.0);
    assert_eq!(withheld, "none");
    let o = axcomp_in(
        &[
            "diagnose",
            "--data",
            csv.to_str().unwrap(),
            "--model",
            "probe_radius",
            "--holdout",
            "artefact=sphere2",
            "--json",
            "d.json",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(read_json(&dir.join("d.json"))["verdict"], "none");
}

#[test]
fn bad_probe_input_names_what_and_writes_nothing() {
    let dir = scratch("bad");
    let (csv, _) = case_csv(&dir, 0, 4.0);
    let text = std::fs::read_to_string(&csv).unwrap();
    std::fs::write(dir.join("old.json"), "keep").unwrap();
    let base = |data: &str, model: &str, holdout: &str| -> Vec<String> {
        [
            "diagnose",
            "--data",
            data,
            "--model",
            model,
            "--holdout",
            holdout,
            "--json",
            "old.json",
            "--report",
            "rep",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect()
    };
    let run = |args: Vec<String>, needle: &str| {
        let a: Vec<&str> = args.iter().map(String::as_str).collect();
        fails_untouched(&a, &dir, needle);
    };
    let c = csv.to_str().unwrap();
    run(base(c, "lobing", "artefact=sphere2"), "base model");
    run(base(c, "probe_radius,wobble", "artefact=sphere2"), "wobble");
    run(base(c, "probe_radius", "artefact=nowhere"), "holdout");
    // A non-unit approach vector on data line 6 (row 5 of the touches).
    let mut lines: Vec<String> = text.lines().map(String::from).collect();
    let mut cells: Vec<String> = lines[5].split(',').map(String::from).collect();
    cells[3] = "0.9".into();
    lines[5] = cells.join(",");
    let badf = dir.join("bad.csv");
    std::fs::write(&badf, lines.join("\n") + "\n").unwrap();
    run(
        base(badf.to_str().unwrap(), "probe_radius", "artefact=sphere2"),
        "bad.csv:6",
    );
}

#[test]
fn probe_pretravel_holds_the_calibrated_pretravel_and_names_a_thermal_drift() {
    let dir = scratch("pretravel");
    // Case 6 withholds thermal_drift (the order of `WITHHELD`, every 4th case null); SNR 8.
    let (csv, withheld) = case_csv(&dir, 6, 8.0);
    assert_eq!(withheld, "thermal_drift");
    let o = axcomp_in(
        &[
            "diagnose",
            "--data",
            csv.to_str().unwrap(),
            "--model",
            "probe_pretravel",
            "--holdout",
            "artefact=sphere2",
            "--json",
            "d.json",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j = read_json(&dir.join("d.json"));
    assert_eq!(j["verdict"], "thermal_drift", "{j}");
    // The pretravel model (axcomp-probe's harmonic structure chosen by cross-validation) is a base term;
    // the kinds it holds are no candidates.
    assert!(
        j["model"]
            .as_array()
            .unwrap()
            .iter()
            .any(|t| t["kind"] == "probe_pretravel")
    );
    let holds: Vec<&str> = j["model_holds"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_str().unwrap())
        .collect();
    for e in j["effects"].as_array().unwrap() {
        assert!(!holds.contains(&e["kind"].as_str().unwrap()), "{e}");
    }
}
