//! Monte Carlo check of the standard uncertainties themselves, free of the seed-to-seed luck of the truth:
//! one machine (truth of seed `S`), `N` noise draws of the same campaign (K4 run 1 + C circles at 0° and
//! −60°, σ = 0.3 µm); per parameter the empirical standard deviation of the estimates over the draws
//! against the root mean square of the reported std (ratio 1 when the std is right; its own sampling spread
//! is ±1/√(2N)), and the share of draws within 2 reported std of the truth.
//! Run: `cargo run --release -p axcomp-rtest --example rtest_noise_mc -- 400 1` (N, S).
use axcomp_kinematics::rotary::N_LOCATION;
use axcomp_twin::five_axis::FiveAxisTwin;

#[path = "common/mod.rs"]
mod common;

fn main() {
    let n: u64 = common::arg(1, 400);
    let seed: u64 = common::arg(2, 1);
    for kind in common::KINDS {
        let (m, paths) = common::machine_and_paths(kind);
        let fitted = &paths[..paths.len() - 1];
        let twin = FiveAxisTwin::random(m, seed);
        let mut est: Vec<Vec<f64>> = vec![Vec::new(); N_LOCATION];
        let mut var: Vec<f64> = vec![0.0; N_LOCATION];
        let mut within = [0usize; N_LOCATION];
        for draw in 0..n {
            let f = common::measure_and_fit(&twin, fitted, 100_000 + draw);
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
