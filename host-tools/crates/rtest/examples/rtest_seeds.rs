//! Coverage of the standard uncertainties on the five-axis twin (known truth): for each machine kind, seeds
//! 1..=N, K4 run 1 + C circles at 0° and −60° fitted (σ = 0.3 µm), prints per parameter the mean and standard
//! deviation of the z-score (estimate − truth)/std and the share within 2 std, then the pooled coverage; and a
//! noise-free fit's largest |estimate − truth| (the model's own consistency with the twin).
//! Run: `cargo run --release -p axcomp-rtest --example rtest_seeds -- 200`.
use axcomp_data::{Dataset, LoadOptions};
use axcomp_kinematics::rotary::{FiveAxis, MachineKind, N_LOCATION};
use axcomp_rtest::{RtestData, fit};
use axcomp_twin::five_axis::{FiveAxisTwin, standard_paths};

fn main() {
    let n: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let first: u64 = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let sigma: f64 = std::env::args()
        .nth(3)
        .and_then(|s| s.parse().ok())
        .unwrap_or(0.3);
    for kind in [
        MachineKind::AcTrunnion,
        MachineKind::BcTrunnion,
        MachineKind::BcHead,
    ] {
        let m = FiveAxis::new(kind, 250.0);
        let sphere = if kind == MachineKind::BcHead {
            [0.0; 3]
        } else {
            [150.0, 0.0, 100.0]
        };
        let paths = standard_paths(&m, sphere, -60.0, 72, &[0.0, -60.0], 36, None);
        let fitted = &paths[..paths.len() - 1];
        let mut z: Vec<Vec<f64>> = vec![Vec::new(); N_LOCATION];
        let mut noise_free_max = 0.0f64;
        for seed in first..first + n {
            for noise in [sigma, 0.0] {
                let mut twin = FiveAxisTwin::random(m, seed);
                twin.noise_um = noise;
                let csv = twin.measure(fitted, seed).to_csv_string();
                let ds = Dataset::from_csv_str("twin", &csv, &LoadOptions::default()).unwrap();
                let data = RtestData::from_dataset(&ds, m, true).unwrap();
                let rows: Vec<usize> = (0..data.poses.len()).collect();
                let f = fit(&data, &rows).unwrap();
                for k in 0..N_LOCATION {
                    let e = f.theta[k] - twin.location[k];
                    if noise > 0.0 {
                        z[k].push(e / f.std[k].unwrap());
                    } else {
                        noise_free_max = noise_free_max.max(e.abs());
                    }
                }
            }
        }
        let names = kind.location_names();
        let mut within = 0;
        let mut total = 0;
        for k in 0..N_LOCATION {
            let w = z[k].iter().filter(|v| v.abs() <= 2.0).count();
            within += w;
            total += z[k].len();
            let mean = z[k].iter().sum::<f64>() / z[k].len() as f64;
            let sd = (z[k].iter().map(|v| (v - mean).powi(2)).sum::<f64>()
                / (z[k].len() - 1).max(1) as f64)
                .sqrt();
            println!(
                "  {} {:5}: z mean {:+.3} sd {:.3}, within 2 std {}/{}",
                kind.name(),
                names[k],
                mean,
                sd,
                w,
                z[k].len()
            );
        }
        println!(
            "{} ({n} seeds): within 2 std {within}/{total} = {:.1} %; noise-free fit: largest |error| {:.2e} µm|µrad",
            kind.name(),
            100.0 * within as f64 / total as f64,
            noise_free_max
        );
    }
}
