//! `axcomp predict` for each model kind through the CLI binary: positioning table, thermal model, probe
//! calibration; rows the model cannot predict are errors naming the row, and nothing is half-written.

use std::path::Path;
use std::process::Command;

use axcomp_positioning::TableFile;
use axcomp_thermal::model_file::{ModelForce, ModelSensor, ThermalModelFile};

mod common;
use common::scratch as tmp_dir;

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

/// Column `name` of a CSV text as numbers.
fn column(text: &str, name: &str) -> Vec<f64> {
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let k = header
        .iter()
        .position(|h| *h == name)
        .unwrap_or_else(|| panic!("no {name}: {header:?}"));
    lines
        .map(|l| l.split(',').nth(k).unwrap().parse().unwrap())
        .collect()
}

fn table() -> TableFile {
    TableFile {
        format: axcomp_positioning::table_file::FORMAT.into(),
        axis: "X".into(),
        start_mm: 0.0,
        segment_mm: 50.0,
        // Forward: 2 + x/50 µm (linear); backward: forward + 3 µm.
        forward: vec![[2.0, 1.0, 0.0, 0.0], [3.0, 1.0, 0.0, 0.0]],
        backward: vec![[5.0, 1.0, 0.0, 0.0], [6.0, 1.0, 0.0, 0.0]],
        model: "test".into(),
        cv_rms_um: 0.0,
        raw_rms_um: 0.0,
        cv_method: String::new(),
        provenance: None,
    }
}

#[test]
fn positioning_table_adds_pred_deviation_and_refuses_outside_the_stroke() {
    let dir = tmp_dir("positioning");
    let model = dir.join("table.json");
    table().save(&model).unwrap();
    let data = dir.join("rows.csv");
    // The measured column may be absent; extra columns are carried along.
    std::fs::write(
        &data,
        "# note\ntarget_mm,direction,run\n0,+,1\n25,+,1\n75,-,2\n100,-,2\n",
    )
    .unwrap();
    let out = dir.join("pred.csv");
    let (ok, o, e) = run(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--out",
        s(&out),
    ]);
    assert!(ok, "{o}\n{e}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(
        text.starts_with("target_mm,direction,run,pred_deviation_um\n"),
        "{text}"
    );
    // Reference: the table's polynomials by hand (2 + x/50 forward, 5 + x/50 backward); tolerance 1e-12.
    let p = column(&text, "pred_deviation_um");
    for (got, want) in p.iter().zip([2.0, 2.5, 6.5, 7.0]) {
        assert!((got - want).abs() < 1e-12, "{p:?}");
    }
    // Outside the stroke [0, 100]: line 5 named, nothing written.
    std::fs::write(&data, "target_mm,direction\n10,+\n50,-\n99,+\n100.5,+\n").unwrap();
    let out2 = dir.join("pred2.csv");
    let (ok, _, e) = run(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--out",
        s(&out2),
    ]);
    assert!(!ok);
    assert!(
        e.contains("rows.csv:5") && e.contains("outside the table's stroke"),
        "{e}"
    );
    assert!(!out2.exists());
    // A bidirectional table needs the direction.
    std::fs::write(&data, "target_mm\n10\n").unwrap();
    let (ok, _, e) = run(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--out",
        s(&out2),
    ]);
    assert!(!ok && e.contains("direction"), "{e}");
    assert!(!out2.exists());
}

fn thermal_model() -> ThermalModelFile {
    ThermalModelFile {
        format: axcomp_thermal::model_file::FORMAT.into(),
        target: "ch3_um".into(),
        sensor_period_ms: 1000,
        b0_um: 1.0,
        sensors: vec![
            ModelSensor {
                name: "motor".into(),
                reference_degc: 20.0,
                tau_s: 10.0,
                coef_um_per_k: 2.0,
                min_degc: 0.0,
                max_degc: 60.0,
                max_rate_degc_per_s: 1.0,
                stale_timeout_ms: 10_000,
                rise_min_k: None,
                rise_max_k: None,
            },
            ModelSensor {
                name: "ambient".into(),
                reference_degc: 20.0,
                tau_s: 0.0,
                coef_um_per_k: -1.0,
                min_degc: 0.0,
                max_degc: 50.0,
                max_rate_degc_per_s: 1.0,
                stale_timeout_ms: 10_000,
                rise_min_k: None,
                rise_max_k: None,
            },
        ],
        forces: vec![ModelForce {
            column: "load_N".into(),
            chi_um_per_n: 0.01,
            law: None,
        }],
        raw_rms_um: 0.0,
        holdout_rms_um: None,
        target_offset_um: None,
        runs_column: None,
    }
}

#[test]
fn thermal_model_adds_pred_target_with_lags_and_refuses_implausible_rows() {
    let dir = tmp_dir("thermal");
    let model = dir.join("model.json");
    thermal_model().save(&model).unwrap();
    let data = dir.join("rows.csv");
    // Motor steps 20 → 30 °C at t = 10 s, sampled every 10 s (= τ); ambient 21 °C; load 100 N.
    std::fs::write(
        &data,
        "time_s,motor_degC,ambient_degC,load_N\n0,20,21,100\n10,30,21,100\n20,30,21,100\n",
    )
    .unwrap();
    let out = dir.join("pred.csv");
    let (ok, o, e) = run(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--out",
        s(&out),
    ]);
    assert!(ok, "{o}\n{e}");
    let p = column(&std::fs::read_to_string(&out).unwrap(), "pred_ch3_um");
    // Reference: e = 1 + 2·(lag − 20) − 1·(21 − 20) + 0.01·100 with the exact first-order lag
    // y_k = y_{k−1} + (1 − e^{−1})(u_k − y_{k−1}): y = 20, 20 + 10(1 − e^{−1}), 20 + 10(1 − e^{−2}).
    // Tolerance 1e-9 µm (rounding).
    let a = 1.0 - (-1.0f64).exp();
    let lagged = [0.0, 10.0 * a, 10.0 * (1.0 - (1.0 - a) * (1.0 - a))];
    for (got, l) in p.iter().zip(lagged) {
        let want = 1.0 + 2.0 * l - 1.0 + 1.0;
        assert!((got - want).abs() < 1e-9, "{got} vs {want}");
    }
    // The lag needs time_s.
    std::fs::write(&data, "motor_degC,ambient_degC,load_N\n20,21,100\n").unwrap();
    let out2 = dir.join("pred2.csv");
    let (ok, _, e) = run(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--out",
        s(&out2),
    ]);
    assert!(!ok && e.contains("time_s"), "{e}");
    // A temperature outside the plausible range: line 3, column motor_degC.
    std::fs::write(
        &data,
        "time_s,motor_degC,ambient_degC,load_N\n0,20,21,100\n1,75,21,100\n",
    )
    .unwrap();
    let (ok, _, e) = run(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--out",
        s(&out2),
    ]);
    assert!(
        !ok && e.contains("rows.csv:3") && e.contains("motor_degC"),
        "{e}"
    );
    // A missing force column.
    std::fs::write(&data, "time_s,motor_degC,ambient_degC\n0,20,21\n").unwrap();
    let (ok, _, e) = run(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--out",
        s(&out2),
    ]);
    assert!(!ok && e.contains("load_N"), "{e}");
    assert!(!out2.exists());
}

#[test]
fn probe_calibration_refuses_speeds_and_directions_it_cannot_tell() {
    let dir = tmp_dir("probe");
    // A hand-made calibration: constant model, Ø3 mm ball, one speed (100 mm/min), elevations 0…90°.
    let cal = axcomp_probe::Calibration {
        format: axcomp_probe::FORMAT.into(),
        sphere_center_mm: [0.0; 3],
        sphere_diameter_mm: 25.0,
        stylus_radius_mm: 1.5,
        structure: axcomp_probe::Structure::Constant,
        coef_mm: vec![1.496],
        feed_range_mm_min: [100.0, 100.0],
        elevation_range_deg: [0.0, 90.0],
        azimuth_gap_deg: None,
        fit_rms_um: 0.5,
    };
    let model = dir.join("cal.json");
    std::fs::write(&model, cal.to_json()).unwrap();
    let data = dir.join("t.csv");
    std::fs::write(
        &data,
        "x_mm,y_mm,z_mm,approach_x,approach_y,approach_z,feed_mm_min\n10,0,0,1,0,0,100\n0,0,5,0,0,-1,100\n",
    )
    .unwrap();
    let out = dir.join("pred.csv");
    let (ok, o, e) = run(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--out",
        s(&out),
    ]);
    assert!(ok, "{o}\n{e}");
    let text = std::fs::read_to_string(&out).unwrap();
    // Reference: p + r_eff·u = (10 + 1.496, 0, 0) and (0, 0, 5 − 1.496); tolerance 1e-12 mm.
    assert!((column(&text, "contact_x_mm")[0] - 11.496).abs() < 1e-12);
    assert!((column(&text, "contact_z_mm")[1] - 3.504).abs() < 1e-12);
    // Another speed than the only calibrated one: line 3 named.
    std::fs::write(
        &data,
        "x_mm,y_mm,z_mm,approach_x,approach_y,approach_z,feed_mm_min\n10,0,0,1,0,0,100\n0,0,5,0,0,-1,400\n",
    )
    .unwrap();
    let out2 = dir.join("pred2.csv");
    let (ok, _, e) = run(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--out",
        s(&out2),
    ]);
    assert!(!ok && e.contains("t.csv:3") && e.contains("400"), "{e}");
    // Approaching from below (normal elevation −90°, far below the calibrated 0°): line 2.
    std::fs::write(
        &data,
        "x_mm,y_mm,z_mm,approach_x,approach_y,approach_z,feed_mm_min\n0,0,-5,0,0,1,100\n",
    )
    .unwrap();
    let (ok, _, e) = run(&[
        "predict",
        "--model",
        s(&model),
        "--data",
        s(&data),
        "--out",
        s(&out2),
    ]);
    assert!(
        !ok && e.contains("t.csv:2") && e.contains("elevation"),
        "{e}"
    );
    assert!(!out2.exists());
    // An unknown model file.
    let other = dir.join("other.json");
    std::fs::write(&other, "{\"format\": \"something/1\"}").unwrap();
    let (ok, _, e) = run(&[
        "predict",
        "--model",
        s(&other),
        "--data",
        s(&data),
        "--out",
        s(&out2),
    ]);
    assert!(!ok && e.contains("unknown model format"), "{e}");
}
