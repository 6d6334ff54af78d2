//! `axcomp fit thermal` end to end through the CLI binary: the synthetic twin (known truth) and the real
//! Voron frame-growth data from `../shared` (skipped when absent, unless `CI` is set).

use std::path::Path;
use std::process::Command;

use axcomp_thermal::model_file::ThermalModelFile;
use axcomp_thermal::synth::{SynthConfig, generate};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_axcomp"))
}

mod common;
use common::{read_json as json, scratch as tmp_dir, shared};

fn run(args: &[&str]) -> (bool, String, String) {
    let out = bin().args(args).output().expect("run axcomp");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn twin_unseen_condition_within_1p2_of_oracle_and_model_file_builds_an_image() {
    let dir = tmp_dir("twin");
    let d = generate(&SynthConfig {
        seed: 5,
        ..SynthConfig::default()
    });
    let csv = dir.join("twin.csv");
    d.write_csv(&csv).unwrap();
    let (j, m, r) = (
        dir.join("fit.json"),
        dir.join("model.json"),
        dir.join("report"),
    );
    let (ok, out, err) = run(&[
        "fit",
        "thermal",
        "--data",
        csv.to_str().unwrap(),
        "--target",
        "error_um",
        "--holdout",
        "condition=2",
        "--cv",
        "condition",
        "--lags",
        "--json",
        j.to_str().unwrap(),
        "--out",
        m.to_str().unwrap(),
        "--report",
        r.to_str().unwrap(),
    ]);
    assert!(ok, "{out}\n{err}");
    let v = json(&j);
    // Reference: the oracle (true sensors, coefficients, lags, χ on the measured columns) on the same rows.
    let oracle = d.oracle_prediction();
    let mask: Vec<bool> = d.condition.iter().map(|&c| c == 2).collect();
    let res: Vec<f64> = d.error_um.iter().zip(&oracle).map(|(a, b)| a - b).collect();
    let oracle_rms = axcomp_thermal::stats::rms_masked(&res, &mask);
    let got = v["holdout_rms_um"].as_f64().unwrap();
    let raw = v["raw_rms_um"].as_f64().unwrap();
    println!(
        "twin: raw {raw:.3} µm, fitted {got:.3} µm, oracle {oracle_rms:.3} µm, sensors {}",
        v["sensors"]
    );
    assert!(
        got <= 1.2 * oracle_rms,
        "held-out {got} µm > 1.2 × oracle {oracle_rms} µm"
    );
    // Contract fields.
    assert!(v["sensors"].as_array().is_some_and(|s| !s.is_empty()));
    assert!(
        v["model"]["terms"]
            .as_array()
            .is_some_and(|t| !t.is_empty())
    );
    assert!(v["cv_rms_um"].as_f64().is_some());
    assert_eq!(v["fcm_gra"]["method"], "fcm_gra");
    assert_eq!(v["forward"]["method"], "forward_cv");
    assert!(v["vif"].as_array().is_some() && v["condition_number"].as_f64().is_some());
    // The force column was fitted jointly: χ within 20 % of the truth 0.01 µm/N.
    let chi = v["model"]["forces"][0]["chi_um_per_n"].as_f64().unwrap();
    assert!((chi - 0.01).abs() < 0.002, "χ = {chi}");
    for f in [
        "report.md",
        "prediction.svg",
        "residual_per_condition.svg",
        "sensors.svg",
    ] {
        assert!(r.join(f).is_file(), "{f} missing");
    }
    // The model file converts to the core spec and builds a valid image.
    let mf = ThermalModelFile::load(&m).unwrap();
    let owned = mf.to_core();
    let spec = axcomp_core::ImageSpec {
        axis_id: 1,
        um_per_count: 0.1,
        counter_bits: 32,
        table: None,
        thermo: Some(owned.spec()),
        limits: axcomp_core::LimitSpec {
            max_correction_um: 500.0,
            max_slew_um_per_cycle: 1.0,
            direction_hysteresis_counts: 0,
        },
    };
    let mut buf = vec![0u8; axcomp_core::image_len(&spec)];
    axcomp_core::write_image(&spec, &mut buf).expect("image from the thermal model file");
    let mut comp = axcomp_core::Compensator::IDENTITY;
    comp.load(&buf).expect("compensator loads the image");
}

#[test]
fn bad_csv_cell_is_named_and_nothing_is_written() {
    let dir = tmp_dir("bad");
    let csv = dir.join("bad.csv");
    std::fs::write(&csv, "time_s,a_degC,error_um\n0,20,1\n1,20.5,x\n2,21,3\n").unwrap();
    let (j, m) = (dir.join("fit.json"), dir.join("model.json"));
    let (ok, _, err) = run(&[
        "fit",
        "thermal",
        "--data",
        csv.to_str().unwrap(),
        "--target",
        "error_um",
        "--json",
        j.to_str().unwrap(),
        "--out",
        m.to_str().unwrap(),
    ]);
    assert!(!ok);
    assert!(
        err.contains("bad.csv:3:3"),
        "error does not name file:line:column: {err}"
    );
    assert!(!j.exists() && !m.exists());
    let (ok, _, err) = run(&[
        "fit",
        "thermal",
        "--data",
        csv.to_str().unwrap(),
        "--ridge=-1",
    ]);
    assert!(!ok && err.contains("--ridge"), "{err}");
}

#[test]
fn guard_refuses_a_model_worse_than_raw() {
    // Training rows: error follows the sensor (1 µm/K); held-out rows: the sensor keeps rising but the error
    // is 0, so the model (≈ 1 µm/K · ΔT) is far worse than no compensation there.
    let dir = tmp_dir("guard");
    let csv = dir.join("g.csv");
    let mut text = String::from("time_s,part,a_degC,error_um\n");
    for k in 0..60 {
        let t = 20.0 + 0.1 * k as f64 + if k % 2 == 0 { 0.01 } else { -0.01 };
        let (part, e) = if k < 40 {
            ("train", t - 20.0)
        } else {
            ("late", 0.0)
        };
        text += &format!("{k},{part},{t},{e}\n");
    }
    std::fs::write(&csv, text).unwrap();
    let (j, m) = (dir.join("g.json"), dir.join("g-model.json"));
    let args = [
        "fit",
        "thermal",
        "--data",
        csv.to_str().unwrap(),
        "--target",
        "error_um",
        "--holdout",
        "part=late",
        "--json",
        j.to_str().unwrap(),
        "--out",
        m.to_str().unwrap(),
    ];
    let (ok, _, err) = run(&args);
    assert!(
        !ok && err.contains("do-no-harm guard") && err.contains("--force"),
        "{err}"
    );
    assert!(!m.exists(), "model written despite the guard");
    let v = json(&j);
    assert_eq!(v["guard"]["passed"], false);
    assert_eq!(v["model_written"], false);
    // --force writes it anyway.
    let mut forced = args.to_vec();
    forced.push("--force");
    let (ok, _, err) = run(&forced);
    assert!(ok && m.exists(), "{err}");
}

const VORON: &str = "data/real/thermal-voron-frame-z";

fn voron_args(file: &Path, um_per_step: Option<&str>) -> Vec<String> {
    let mut a: Vec<String> = ["fit", "thermal", "--data"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    a.push(file.display().to_string());
    for r in [
        "frame_t=frame_degC",
        "chamber_t=chamber_degC",
        "bed_t=bed_degC",
        "he_t=he_degC",
    ] {
        a.extend(["--rename".to_string(), r.to_string()]);
    }
    match um_per_step {
        Some(f) => a.extend(
            [
                "--rename",
                "mcu_pos_z=z_um",
                "--scale",
                &format!("z_um={f}"),
                "--target",
                "z_um",
            ]
            .map(String::from),
        ),
        // step_dist not stated in the file: fit in microsteps, no unit guessed.
        None => {
            a.extend(["--rename", "mcu_pos_z=z_steps", "--target", "z_steps"].map(String::from))
        }
    }
    a.extend(["--zero-at-start", "1"].map(String::from));
    a
}

#[test]
fn voron_frame_growth_beats_plain_least_squares_on_the_cooling_phase() {
    let Some(shared) = shared() else { return };
    let dir = tmp_dir("voron");
    let file = shared
        .join(VORON)
        .join("frame_exp_quant_v3_2021-06-13_05-41-53.csv");
    // step_dist = 0.0025 mm (header) → 2.5 µm per microstep; hold out the cooling phase.
    let base = voron_args(&file, Some("2.5"));
    let fit = |extra: &[&str], name: &str| {
        let j = dir.join(name);
        let mut a = base.clone();
        a.extend(["--holdout", "bed_target=0", "--json", j.to_str().unwrap()].map(String::from));
        a.extend(extra.iter().map(|s| s.to_string()));
        let out = bin().args(&a).output().unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        json(&j)
    };
    // Reference: plain least squares on all four sensors without lags (measured here, not hard-coded).
    let plain = fit(&["--select", "all"], "plain.json");
    let ours = fit(&["--lags"], "lags.json");
    let (raw, p, h) = (
        ours["raw_rms_um"].as_f64().unwrap(),
        plain["holdout_rms_um"].as_f64().unwrap(),
        ours["holdout_rms_um"].as_f64().unwrap(),
    );
    println!(
        "voron 05-41-53: raw {raw:.2} µm, plain LS (4 sensors, no lags) {p:.2} µm, ours {h:.2} µm ({}: {})",
        ours["chosen_method"], ours["formula"]
    );
    assert!(h < p, "ours {h} µm not below plain least squares {p} µm");
    assert!(h <= raw, "ours {h} µm worse than raw {raw} µm");
}

#[test]
fn voron_other_files_never_worse_than_raw() {
    let Some(shared) = shared() else { return };
    let dir = tmp_dir("voron-guard");
    // (file, µm per microstep or None when step_dist is not stated, holdout)
    let runs: [(&str, Option<&str>, &str); 4] = [
        (
            "frame_exp_quant_v3_2021-06-13_05-41-53.csv",
            Some("2.5"),
            "bed_target=0",
        ),
        // Header says step_dist=0.0125 mm → 12.5 µm per microstep, taken as written.
        (
            "expansion_quant_whoppingpochard_2514_2021-06-13_20-04-43.csv",
            Some("12.5"),
            "bed_target=0",
        ),
        (
            "frame_exp_quant_v3_2021-06-12_12-54-36-mvieleers_V2.1253.csv",
            None,
            "bed_target=0",
        ),
        // Heating only: hold out the last part in time.
        (
            "frame_temp_v_pos_2021-06-05_13-24-32.csv",
            None,
            "time_s>=8000",
        ),
    ];
    for (i, (f, scale, holdout)) in runs.iter().enumerate() {
        for lags in [false, true] {
            let (j, m) = (
                dir.join(format!("{i}-{lags}.json")),
                dir.join(format!("{i}-{lags}-model.json")),
            );
            let mut a = voron_args(&shared.join(VORON).join(f), *scale);
            a.extend(
                [
                    "--holdout",
                    holdout,
                    "--json",
                    j.to_str().unwrap(),
                    "--out",
                    m.to_str().unwrap(),
                ]
                .map(String::from),
            );
            if lags {
                a.push("--lags".into());
            }
            let out = bin().args(&a).output().unwrap();
            let v = json(&j);
            let (raw, h) = (
                v["raw_rms_um"].as_f64().unwrap(),
                v["holdout_rms_um"].as_f64().unwrap(),
            );
            println!(
                "{f} lags={lags}: raw {raw:.2}, model {h:.2}, written {}",
                m.exists()
            );
            // The guard: a model is written only if it is not worse than raw on the held-out rows; otherwise
            // the command fails saying why and writes no model.
            if h <= raw {
                assert!(
                    out.status.success() && m.exists(),
                    "{}",
                    String::from_utf8_lossy(&out.stderr)
                );
            } else {
                assert!(!out.status.success() && !m.exists());
                assert!(String::from_utf8_lossy(&out.stderr).contains("do-no-harm guard"));
            }
        }
    }
}

#[test]
fn force_law_from_fit_force_goes_into_the_model_file() {
    // Coupled thermo-force chain: fit the twin's cutting-force law on the cutting rows (`fit force`), attach it
    // to the force term of the thermal model (`fit thermal --force-law`), build an image with it.
    let dir = tmp_dir("law");
    let d = generate(&SynthConfig {
        seed: 4,
        ..SynthConfig::default()
    });
    let twin = dir.join("twin.csv");
    d.write_csv(&twin).unwrap();
    let cut = dir.join("cut.csv");
    let mut text = String::from("ap_mm,fz_mm,spindle_rpm,force_N\n");
    for k in (0..d.time_s.len()).filter(|&k| d.force_n[k] > 0.0) {
        text += &format!(
            "{},{},{},{}\n",
            d.ap_mm[k], d.fz_mm[k], d.spindle_rpm[k], d.force_n[k]
        );
    }
    std::fs::write(&cut, text).unwrap();
    let (fj, law) = (dir.join("force.json"), dir.join("law.json"));
    let (ok, out, err) = run(&[
        "fit",
        "force",
        "--data",
        cut.to_str().unwrap(),
        "--json",
        fj.to_str().unwrap(),
        "--out",
        law.to_str().unwrap(),
    ]);
    assert!(ok, "{out}{err}");
    // The twin's law is F = 1800·ap^0.9·fz^0.75·n^-0.1 with 2 % noise: exponents within 0.05 (reference: the
    // generator's settings).
    let v = json(&fj);
    for (k, want) in [("x_ap", 0.9), ("y_fz", 0.75), ("z_n", -0.1)] {
        let got = v["law"][k]["value"].as_f64().unwrap();
        assert!((got - want).abs() < 0.05, "{k} = {got}, truth {want}");
    }
    let m = dir.join("model.json");
    let (ok, out, err) = run(&[
        "fit",
        "thermal",
        "--data",
        twin.to_str().unwrap(),
        "--target",
        "error_um",
        "--holdout",
        "condition=2",
        "--cv",
        "condition",
        "--force-law",
        &format!("force_N={}", law.display()),
        "--out",
        m.to_str().unwrap(),
    ]);
    assert!(ok, "{out}{err}");
    let mf = ThermalModelFile::load(&m).unwrap();
    let l = mf.forces[0].law.expect("law attached");
    assert!((l.x_ap - 0.9).abs() < 0.05);
    let owned = mf.to_core();
    assert!(owned.forces[0].law.is_some());
    let (ok, _, err) = run(&[
        "fit",
        "thermal",
        "--data",
        twin.to_str().unwrap(),
        "--target",
        "error_um",
        "--force-law",
        "spindle_N=x.json",
    ]);
    assert!(!ok && err.contains("x.json"), "{err}");
}
