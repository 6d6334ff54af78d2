//! The fitted model, converted to the core's spec and loaded by the firmware's `Compensator`, gives the same
//! correction as the host's `ThermalModel::predict` (same lag discretisation, same terms). Reference: the
//! host prediction in f64; tolerance 0.01 µm + 1e-5 relative (the firmware computes in f32).

use axcomp_thermal::model_file::ThermalModelFile;
use axcomp_thermal::{ThermalInput, ThermalOptions, fit_thermal};
use axcomp_twin::synth::{SynthConfig, generate};

#[test]
#[allow(clippy::needless_range_loop)] // rows index several parallel columns
fn firmware_replays_the_host_prediction() {
    let d = generate(&SynthConfig {
        seed: 9,
        ..SynthConfig::default()
    });
    let input = ThermalInput {
        time_s: d.time_s.clone(),
        sensors: d.sensor_series(),
        forces: d.force_series(),
        target: d.error_um.clone(),
        conditions: Some(d.condition.iter().map(|c| c.to_string()).collect()),
        holdout: None,
        runs: None,
    };
    let fit = fit_thermal(
        &input,
        &ThermalOptions {
            lags: true,
            ..ThermalOptions::default()
        },
    )
    .unwrap();
    assert!(
        fit.model.terms.iter().any(|t| t.tau_s > 0.0),
        "want at least one lagged term to compare lags"
    );
    let period_ms = (d.time_s[1] - d.time_s[0]) as u32 * 1000;
    let file = ThermalModelFile::from_fit(&fit, &input, "error_um", period_ms);
    file.validate().unwrap();
    let owned = file.to_core();
    let spec = axcomp_core::ImageSpec {
        axis_id: 1,
        um_per_count: 0.001,
        counter_bits: 32,
        table: None,
        thermo: Some(owned.spec()),
        limits: axcomp_core::LimitSpec {
            max_correction_um: 1.0e4,
            max_slew_um_per_cycle: 1.0e4,
            direction_hysteresis_counts: 0,
        },
    };
    let mut buf = vec![0u8; axcomp_core::image_len(&spec)];
    axcomp_core::write_image(&spec, &mut buf).unwrap();
    let mut comp = axcomp_core::Compensator::IDENTITY;
    comp.load(&buf).unwrap();
    let mut st = axcomp_core::State::new();
    let host = &fit.prediction;
    let mut worst: f64 = 0.0;
    for k in 0..d.time_s.len() {
        let readings: Vec<f32> = file
            .sensors
            .iter()
            .map(|s| {
                input
                    .sensors
                    .iter()
                    .find(|x| x.name == s.name)
                    .unwrap()
                    .values[k] as f32
            })
            .collect();
        comp.update_temperatures(&mut st, (d.time_s[k] * 1000.0) as u32, &readings);
        let mut forces = [0.0f32; axcomp_core::MAX_FORCES];
        for (j, f) in file.forces.iter().enumerate() {
            forces[j] = input
                .forces
                .iter()
                .find(|x| x.name == f.column)
                .unwrap()
                .values[k] as f32;
        }
        let out = comp.cycle(
            &mut st,
            &axcomp_core::CycleInput {
                scale_raw: 0,
                command_counts: 0,
                forces_n: forces,
            },
        );
        let diff = (f64::from(out.correction_um) - host[k]).abs();
        worst = worst.max(diff);
        assert!(
            diff <= 0.01 + 1e-5 * host[k].abs(),
            "row {k}: firmware {} vs host {}",
            out.correction_um,
            host[k]
        );
    }
    println!(
        "worst |firmware − host| = {worst:.5} µm over {} rows",
        d.time_s.len()
    );
}
