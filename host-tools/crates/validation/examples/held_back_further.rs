//! What `plan geometry`'s further lines buy on held-back twin lines: the default fit's median held-out
//! RMS (lines at other offsets and diagonals) on the training lines alone, with the first K further lines
//! the plan lists after them, and with K lines drawn at random among its other candidates:
//! `cargo run --release -p axcomp-validation --example held_back_further -- [SEEDS [FIRST_SEED [K]]]`.
use axcomp_geometry::FitOptions;
use axcomp_validation::held_back::{HeldBackOptions, further_gain};

fn main() {
    let arg = |i: usize, default: u64| {
        std::env::args()
            .nth(i)
            .map_or(default, |s| s.parse().expect("a number"))
    };
    let (seeds, first, k) = (arg(1, 10), arg(2, 0), arg(3, 2) as usize);
    let opts = HeldBackOptions::default();
    let results: Vec<_> = (first..first + seeds)
        .map(|s| {
            let g = further_gain(&opts, s, &FitOptions::default(), k);
            println!(
                "seed {s}: before {:.3} | planned {:.3} ({}) | random {:.3} µm",
                g.before,
                g.planned,
                g.lines.join(", "),
                g.random
            );
            g
        })
        .collect();
    let med = |f: &dyn Fn(&axcomp_validation::held_back::FurtherGain) -> f64| {
        let mut v: Vec<f64> = results.iter().map(f).collect();
        axcomp_numeric::stats::median(&mut v)
    };
    println!(
        "median held-out RMS: training lines {:.3}, + {k} planned further lines {:.3}, + {k} random candidate lines {:.3} µm (σ {})",
        med(&|g| g.before),
        med(&|g| g.planned),
        med(&|g| g.random),
        opts.noise_um
    );
}
