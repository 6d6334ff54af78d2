//! `fit geometry`'s default on held-back twin lines (see `axcomp_validation::held_back`): ten seeds of the
//! seven-line set plus the Y and Z axis lines, predicting axis lines at other offsets, face diagonals and a
//! tool-offset diagonal never fitted.
use axcomp_geometry::FitOptions;
use axcomp_geometry::fit::{Prior, PriorGroups};
use axcomp_validation::held_back::{HeldBackOptions, HeldBackResult, run_case};

fn median(mut v: Vec<f64>) -> f64 {
    axcomp_numeric::stats::median(&mut v)
}

/// The default (the evidence prior: roughness and size precisions per component kind, damping and knot
/// grid by the training readings' marginal likelihood, third-difference roughness) on ten cases.
/// Reference: computed in the same run, the plain reference (`--method plain`), the minimum-norm
/// reference, the identifiable floor (minimum-norm fit of the noise-free training readings, judged on the
/// same noisy held-back readings) and the Gaussian oracle (the posterior mean under the twin generator's
/// own prior and noise). Tolerance: the median over the 10 seeds of the held-out RMS on lines at other
/// offsets and diagonals ≤ the plain and minimum-norm references' medians, ≤ 1.2 × the floor's and
/// ≤ 1.05 × the oracle's (with 15 targets and 20 seeds per range it is 1.13–1.30 × the floor and
/// 0.99–1.03 × the oracle: the example `held_back`).
#[test]
fn default_fit_on_held_back_lines() {
    assert_eq!(
        FitOptions::default().prior,
        Prior::Evidence(PriorGroups::Kind)
    );
    let opts = HeldBackOptions {
        targets: 11,
        ..HeldBackOptions::default()
    };
    let results: Vec<_> = (0..10)
        .map(|s| run_case(&opts, s, &FitOptions::default()))
        .collect();
    let med = |f: &dyn Fn(&HeldBackResult) -> f64| median(results.iter().map(f).collect());
    let (default, plain, min_norm, floor, oracle) = (
        med(&|r| r.default.lines),
        med(&|r| r.plain.lines),
        med(&|r| r.min_norm.lines),
        med(&|r| r.floor.lines),
        med(&|r| r.oracle.lines),
    );
    println!(
        "median held-out RMS, lines at other offsets and diagonals: default {default:.3}, plain {plain:.3}, minimum-norm {min_norm:.3}, identifiable floor {floor:.3}, Gaussian oracle {oracle:.3} µm (σ {})",
        opts.noise_um
    );
    assert!(default <= plain, "default {default} vs plain {plain}");
    assert!(
        default <= min_norm,
        "default {default} vs minimum-norm {min_norm}"
    );
    assert!(default <= 1.2 * floor, "default {default} vs floor {floor}");
    assert!(
        default <= 1.05 * oracle,
        "default {default} vs oracle {oracle}"
    );
}
