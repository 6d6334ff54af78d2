//! Thermal fit on the synthetic twin: 16 collinear sensors, lagged response, one unseen operating condition
//! held out. Reference: the oracle (true sensors, coefficients, lags and χ on the measured columns).

use axcomp_numeric::stats;
use axcomp_thermal::{Ridge, ThermalInput, ThermalOptions, fit_thermal};
use axcomp_twin::synth::{SynthConfig, generate};

fn input(d: &axcomp_twin::synth::SynthData, held_condition: usize) -> ThermalInput {
    ThermalInput {
        time_s: d.time_s.clone(),
        sensors: d.sensor_series(),
        forces: d.force_series(),
        target: d.error_um.clone(),
        conditions: Some(d.condition.iter().map(|c| c.to_string()).collect()),
        holdout: Some(d.condition.iter().map(|&c| c == held_condition).collect()),
        runs: None,
    }
}

#[test]
fn twin_holdout_within_1p2_of_oracle() {
    for seed in 1u64..=5 {
        let cfg = SynthConfig {
            seed,
            ..SynthConfig::default()
        };
        let d = generate(&cfg);
        let held = 2;
        let inp = input(&d, held);
        let opts = ThermalOptions {
            lags: true,
            ridge: Ridge::Off,
            ..ThermalOptions::default()
        };
        let t0 = std::time::Instant::now();
        let fit = fit_thermal(&inp, &opts).unwrap();
        let el = t0.elapsed();
        let mask: Vec<bool> = d.condition.iter().map(|&c| c == held).collect();
        let oracle = d.oracle_prediction();
        let oracle_res: Vec<f64> = d.error_um.iter().zip(&oracle).map(|(a, b)| a - b).collect();
        let oracle_rms = stats::rms_masked(&oracle_res, &mask);
        let got = fit.holdout_rms_um.unwrap();
        println!(
            "seed {seed}: raw {:.3} µm, fitted {got:.3} µm, oracle {oracle_rms:.3} µm, ratio {:.3}, method {} ({}), \
             sensors {:?} τ {:?}, fit took {el:?}",
            fit.raw_rms_um,
            got / oracle_rms,
            fit.chosen_method,
            fit.why,
            fit.sensors,
            fit.model
                .terms
                .iter()
                .map(|t| t.tau_s.round())
                .collect::<Vec<_>>()
        );
        println!(
            "  fcm_gra {:?} nested {:.3}; forward {:?} nested {:.3}",
            fit.fcm_gra.sensors,
            fit.fcm_gra.nested_cv_rms_um,
            fit.forward.sensors,
            fit.forward.nested_cv_rms_um
        );
        // Done-when: held-out RMS within 1.2× of the oracle's.
        assert!(
            got <= 1.2 * oracle_rms,
            "seed {seed}: fitted {got} > 1.2 × oracle {oracle_rms}"
        );
        assert!(fit.guard.passed);
    }
}

#[test]
fn fcm_gra_groups_sensors_by_their_main_heat_source() {
    // The twin's sensor i is driven mainly by latent source i % 3: 0 spindle and 1 drive (both follow the
    // heating/cooling phases, similar shapes), 2 ambient (slow daily swing). The reference method's clustering
    // must not mix ambient-driven sensors with heat-driven ones.
    let d = generate(&SynthConfig::default());
    let r = axcomp_thermal::select::fcm_gra(&d.sensors_degc, &d.error_um, 6);
    println!(
        "clusters {}, XB {:?}, assignment {:?}, selected {:?}",
        r.clusters, r.xie_beni, r.cluster_of, r.selected
    );
    assert!(r.converged && r.clusters >= 2);
    for i in 0..16 {
        for j in 0..16 {
            if (i % 3 == 2) != (j % 3 == 2) {
                assert_ne!(
                    r.cluster_of[i], r.cluster_of[j],
                    "sensors {i} and {j} mixed: {:?}",
                    r.cluster_of
                );
            }
        }
    }
    // Memberships sum to 1 per sensor (tolerance 1e-9) and one sensor is kept per cluster.
    for u in &r.memberships {
        assert!((u.iter().sum::<f64>() - 1.0).abs() < 1e-9);
    }
    assert_eq!(r.selected.len(), r.clusters);
    // The kept sensor has the highest grey relational grade within its cluster.
    for &s in &r.selected {
        let k = r.cluster_of[s];
        assert!(
            (0..16)
                .filter(|&i| r.cluster_of[i] == k)
                .all(|i| r.grades[i] <= r.grades[s])
        );
    }
}
