//! Model file: save/load round trip, validation messages, ridge options.

use axcomp_thermal::model_file::ThermalModelFile;
use axcomp_thermal::{Ridge, ThermalInput, ThermalOptions, fit_thermal};
use axcomp_twin::synth::{SynthConfig, generate};

fn input() -> ThermalInput {
    let d = generate(&SynthConfig {
        seed: 3,
        ..SynthConfig::default()
    });
    ThermalInput {
        time_s: d.time_s.clone(),
        sensors: d.sensor_series(),
        forces: d.force_series(),
        target: d.error_um.clone(),
        conditions: Some(d.condition.iter().map(|c| c.to_string()).collect()),
        holdout: Some(d.condition.iter().map(|&c| c == 1).collect()),
        runs: None,
    }
}

#[test]
fn round_trip_and_validation() {
    let inp = input();
    let fit = fit_thermal(&inp, &ThermalOptions::default()).unwrap();
    let file = ThermalModelFile::from_fit(&fit, &inp, "error_um", 1000);
    let dir = std::env::temp_dir().join(format!("axcomp-thermal-mf-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("m.json");
    file.save(&p).unwrap();
    // serde_json's default float parsing may differ in the last bit (no `float_roundtrip`): compare the f32
    // spec the firmware gets, which must be identical.
    let back = ThermalModelFile::load(&p).unwrap();
    assert_eq!(back.to_core(), file.to_core());
    assert_eq!(
        back.sensors.iter().map(|s| &s.name).collect::<Vec<_>>(),
        file.sensors.iter().map(|s| &s.name).collect::<Vec<_>>()
    );
    // Sensor order and coefficients carry over to the core spec (f32).
    let core = file.to_core();
    assert_eq!(core.sensors.len(), file.sensors.len());
    assert_eq!(core.b_um_per_k[0], file.sensors[0].coef_um_per_k as f32);
    // A broken file names what is wrong.
    let mut bad = file.clone();
    bad.sensors[0].min_degc = bad.sensors[0].max_degc;
    bad.save(&p).unwrap();
    let e = ThermalModelFile::load(&p).unwrap_err().to_string();
    assert!(e.contains("m.json") && e.contains("sensors[0]"), "{e}");
    std::fs::write(&p, "{").unwrap();
    assert!(
        ThermalModelFile::load(&p)
            .unwrap_err()
            .to_string()
            .contains("not a thermal model file")
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn ridge_options() {
    let inp = input();
    let off = fit_thermal(&inp, &ThermalOptions::default()).unwrap();
    let auto = fit_thermal(
        &inp,
        &ThermalOptions {
            ridge: Ridge::Auto,
            ..ThermalOptions::default()
        },
    )
    .unwrap();
    let big = fit_thermal(
        &inp,
        &ThermalOptions {
            ridge: Ridge::Fixed(100.0),
            ..ThermalOptions::default()
        },
    )
    .unwrap();
    assert_eq!(off.ridge_lambda, 0.0);
    // Auto picks λ from its grid {0, 1e-6 … 10}.
    assert!(auto.ridge_lambda == 0.0 || (1e-6..=10.0).contains(&auto.ridge_lambda));
    // A huge ridge shrinks the thermal coefficients toward 0 (sum of |b| smaller than without ridge).
    let sum = |f: &axcomp_thermal::ThermalFit| {
        f.model
            .terms
            .iter()
            .map(|t| t.coef_um_per_k.abs())
            .sum::<f64>()
    };
    assert!(sum(&big) < sum(&off), "{} vs {}", sum(&big), sum(&off));
    assert!(
        ThermalOptions {
            ridge: Ridge::Fixed(-1.0),
            ..ThermalOptions::default()
        }
        .build()
        .is_err()
    );
}
