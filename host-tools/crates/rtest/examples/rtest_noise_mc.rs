//! Monte Carlo check of the standard uncertainties themselves, free of the seed-to-seed luck of the truth:
//! one machine (truth of seed `S`), `N` noise draws of the same campaign (K4 run 1 + C circles at 0° and
//! −60°, σ = 0.3 µm); per parameter the empirical standard deviation of the estimates over the draws
//! against the root mean square of the reported std (ratio 1 when the std is right; its own sampling spread
//! is ±1/√(2N)), and the share of draws within 2 reported std of the truth.
//! Run: `cargo run --release -p axcomp-rtest --example rtest_noise_mc -- 400 1` (N, S).
use axcomp_data::{Dataset, LoadOptions};
use axcomp_kinematics::rotary::{FiveAxis, MachineKind, N_LOCATION};
use axcomp_rtest::{RtestData, fit};
use axcomp_twin::five_axis::{FiveAxisTwin, standard_paths};

fn main() {
    let n: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(400);
    let seed: u64 = std::env::args()
        .nth(2)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
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
        let twin = FiveAxisTwin::random(m, seed);
        let mut est: Vec<Vec<f64>> = vec![Vec::new(); N_LOCATION];
        let mut var: Vec<f64> = vec![0.0; N_LOCATION];
        let mut within = vec![0usize; N_LOCATION];
        for draw in 0..n {
            let csv = twin.measure(fitted, 100_000 + draw).to_csv_string();
            let ds = Dataset::from_csv_str("twin", &csv, &LoadOptions::default()).unwrap();
            let data = RtestData::from_dataset(&ds, m, true).unwrap();
            let rows: Vec<usize> = (0..data.poses.len()).collect();
            let f = fit(&data, &rows).unwrap();
            for k in 0..N_LOCATION {
                let s = f.std[k].unwrap();
                est[k].push(f.theta[k]);
                var[k] += s * s / n as f64;
                within[k] += ((f.theta[k] - twin.location[k]).abs() <= 2.0 * s) as usize;
            }
        }
        let names = kind.location_names();
        let mut line = format!("{} (seed {seed}, {n} draws): sd/std", kind.name());
        let mut all_within = 0;
        for k in 0..N_LOCATION {
            let mean = est[k].iter().sum::<f64>() / n as f64;
            let sd =
                (est[k].iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
            line += &format!(
                " {} {:.3} (bias {:+.2})",
                names[k],
                sd / var[k].sqrt(),
                (mean - twin.location[k]) / var[k].sqrt()
            );
            all_within += within[k];
        }
        println!(
            "{line}; within 2 std {:.1} %",
            100.0 * all_within as f64 / (n as f64 * N_LOCATION as f64)
        );
    }
}
