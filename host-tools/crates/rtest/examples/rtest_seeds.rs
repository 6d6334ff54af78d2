//! Coverage of the standard uncertainties on the five-axis twin (known truth): for each machine kind, seeds
//! 1..=N, K4 run 1 + C circles at 0° and −60° fitted (σ = 0.3 µm), prints per parameter the mean and standard
//! deviation of the z-score (estimate − truth)/std and the share within 2 std, then the pooled coverage; and a
//! noise-free fit's largest |estimate − truth| (the model's own consistency with the twin).
//! Run: `cargo run --release -p axcomp-rtest --example rtest_seeds -- 200`.
use axcomp_kinematics::rotary::N_LOCATION;
use axcomp_twin::five_axis::FiveAxisTwin;

#[path = "common/mod.rs"]
mod common;

fn main() {
    let n: u64 = common::arg(1, 20);
    let first: u64 = common::arg(2, 1);
    let sigma: f64 = common::arg(3, 0.3);
    for kind in common::KINDS {
        let (m, paths) = common::machine_and_paths(kind);
        let fitted = &paths[..paths.len() - 1];
        let mut z: Vec<Vec<f64>> = vec![Vec::new(); N_LOCATION];
        let mut noise_free_max = 0.0f64;
        for seed in first..first + n {
            for noise in [sigma, 0.0] {
                let mut twin = FiveAxisTwin::random(m, seed);
                twin.noise_um = noise;
                let f = common::measure_and_fit(&twin, fitted, seed);
                #[allow(clippy::needless_range_loop)] // parallel arrays indexed together
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
