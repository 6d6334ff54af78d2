//! Held-back lines of the three-axis twin over many seeds: `fit geometry`'s default next to the plain
//! and minimum-norm references, the identifiable floor and the Gaussian oracle (medians of the held-out RMS, µm):
//! `cargo run --release -p axcomp-validation --example held_back -- [SEEDS [FIRST_SEED]]` (seeds
//! FIRST_SEED.., default 20 seeds from 0).
use axcomp_geometry::FitOptions;
use axcomp_geometry::fit::{Prior, PriorGroups};
use axcomp_validation::held_back::{HeldBackOptions, HeldScore, run_case};

fn median(mut v: Vec<f64>) -> f64 {
    axcomp_numeric::stats::median(&mut v)
}

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .map_or(20, |s| s.parse().expect("SEEDS: a number"));
    let first: u64 = std::env::args()
        .nth(2)
        .map_or(0, |s| s.parse().expect("FIRST_SEED: a number"));
    // AXCOMP_NOISE overrides the reading noise σ (µm; 0 shows each method's bias alone)
    let opts = HeldBackOptions {
        noise_um: std::env::var("AXCOMP_NOISE")
            .ok()
            .map_or(HeldBackOptions::default().noise_um, |s| {
                s.parse().expect("a number")
            }),
        ..HeldBackOptions::default()
    };
    // the default fit's options; AXCOMP_DAMPING, AXCOMP_INTERVALS and AXCOMP_LAMBDAS (comma-separated
    // smoothing candidates) override its damping, knot intervals and λ set (to compare values);
    // AXCOMP_PRIOR=kind|component|global the evidence prior with those groups (kind: the default), line-cv
    // one λ by leave-one-line-out cross-validation
    let fit = FitOptions {
        damping: std::env::var("AXCOMP_DAMPING")
            .ok()
            .map_or(FitOptions::default().damping, |s| {
                s.parse().expect("a number")
            }),
        intervals: std::env::var("AXCOMP_INTERVALS")
            .ok()
            .map(|s| s.parse().expect("a number")),
        lambdas: std::env::var("AXCOMP_LAMBDAS")
            .ok()
            .map_or(FitOptions::default().lambdas, |s| {
                s.split(',').map(|x| x.parse().expect("a number")).collect()
            }),
        prior: match std::env::var("AXCOMP_PRIOR").as_deref() {
            Ok("component") => Prior::Evidence(PriorGroups::Component),
            Ok("kind") => Prior::Evidence(PriorGroups::Kind),
            Ok("global") => Prior::Evidence(PriorGroups::Global),
            Ok("line-cv") => Prior::LineCv,
            Err(_) => FitOptions::default().prior,
            Ok(other) => panic!("AXCOMP_PRIOR: {other} (component, kind, global or line-cv)"),
        },
        // AXCOMP_ORDER: the roughness order (2, 3, 4), or `chosen` for the evidence's choice among them
        roughness_order: match std::env::var("AXCOMP_ORDER").as_deref() {
            Err(_) => FitOptions::default().roughness_order,
            Ok("chosen") => None,
            Ok(o) => Some(o.parse().expect("a roughness order")),
        },
        ..FitOptions::default()
    };
    let results: Vec<_> = (first..first + seeds)
        .map(|s| {
            let r = run_case(&opts, s, &fit);
            let f = |h: &HeldScore| {
                format!(
                    "lines {:.3} (axis {:.3} diag {:.3}) beam {:.3}",
                    h.lines, h.axis, h.diagonal, h.beam
                )
            };
            println!(
                "seed {s}: default {} | plain {} | min-norm {} | floor {} | oracle {}",
                f(&r.default),
                f(&r.plain),
                f(&r.min_norm),
                f(&r.floor),
                f(&r.oracle)
            );
            r
        })
        .collect();
    let med =
        |get: &dyn Fn(&HeldScore) -> f64,
         pick: &dyn Fn(&axcomp_validation::held_back::HeldBackResult) -> HeldScore| {
            median(results.iter().map(|r| get(&pick(r))).collect())
        };
    for (name, get) in [
        (
            "lines",
            &(|h: &HeldScore| h.lines) as &dyn Fn(&HeldScore) -> f64,
        ),
        ("axis", &|h: &HeldScore| h.axis),
        ("diagonal", &|h: &HeldScore| h.diagonal),
        ("beam", &|h: &HeldScore| h.beam),
    ] {
        println!(
            "median {name}: default {:.3}, plain {:.3}, min-norm {:.3}, floor {:.3}, Gaussian oracle {:.3} µm (σ {})",
            med(get, &|r| r.default),
            med(get, &|r| r.plain),
            med(get, &|r| r.min_norm),
            med(get, &|r| r.floor),
            med(get, &|r| r.oracle),
            opts.noise_um
        );
    }
}
