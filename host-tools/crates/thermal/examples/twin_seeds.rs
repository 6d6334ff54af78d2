//! Held-out RMS vs the oracle on the twin over many seeds (prints figures):
//! `cargo run --release -p axcomp-thermal --example twin_seeds [N]`
//! (`SEL=all` forces every sensor, `RIDGE=auto` a CV-chosen ridge, `NOLAGS=1` no lags, `HELD=k` holds out
//! condition k instead of 2).

use axcomp_numeric::stats;
use axcomp_thermal::{ThermalInput, ThermalOptions, fit_thermal};
use axcomp_twin::synth::{SynthConfig, generate};

fn main() {
    let n: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let mut ratios = vec![];
    for seed in 1..=n {
        let d = generate(&SynthConfig {
            seed,
            ..SynthConfig::default()
        });
        let held: usize = std::env::var("HELD")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(2);
        let input = ThermalInput {
            time_s: d.time_s.clone(),
            sensors: d.sensor_series(),
            forces: d.force_series(),
            target: d.error_um.clone(),
            conditions: Some(d.condition.iter().map(|c| c.to_string()).collect()),
            holdout: Some(d.condition.iter().map(|&c| c == held).collect()),
            runs: None,
        };
        let mut opts = ThermalOptions {
            lags: true,
            ..ThermalOptions::default()
        };
        if std::env::var("SEL").is_ok_and(|s| s == "all") {
            opts.selection = axcomp_thermal::Selection::All;
            opts.max_sensors = 16;
        }
        if std::env::var("RIDGE").is_ok_and(|s| s == "auto") {
            opts.ridge = axcomp_thermal::Ridge::Auto;
        }
        let fit = fit_thermal(&input, &opts).unwrap();
        let mask: Vec<bool> = d.condition.iter().map(|&c| c == held).collect();
        let oracle = d.oracle_prediction();
        let res: Vec<f64> = d.error_um.iter().zip(&oracle).map(|(a, b)| a - b).collect();
        let o = stats::rms_masked(&res, &mask);
        let h = fit.holdout_rms_um.unwrap();
        ratios.push(h / o);
        println!(
            "seed {seed:3}: raw {:7.3} µm, fitted {h:.3} µm, oracle {o:.3} µm, ratio {:.3} ({}, {:?})",
            fit.raw_rms_um,
            h / o,
            fit.chosen_method,
            fit.sensors
        );
        for c in &fit.candidates {
            println!(
                "      {:<13} validation {:.3} held-out {:.3}",
                c.name,
                c.validation_rms_um,
                c.holdout_rms_um.unwrap_or(f64::NAN)
            );
        }
    }
    ratios.sort_by(|a, b| a.total_cmp(b));
    println!(
        "ratio fitted/oracle over {n} seeds: median {:.3}, worst {:.3}, seeds above 1.2: {}",
        ratios[ratios.len() / 2],
        ratios[ratios.len() - 1],
        ratios.iter().filter(|r| **r > 1.2).count()
    );
}
