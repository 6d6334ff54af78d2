//! How far any choice of the default fit's settings could go on the held-back twin lines: per case, the
//! best held-out RMS of the lines at other offsets and diagonals over a grid of knot intervals (4, 8, the
//! default), damping and smoothing λ, picked by the held-out lines themselves. Not a method (a user has no
//! held-out truth to pick by): a bound on what selecting these settings per campaign can reach, shown next
//! to the identifiable floor (medians, µm):
//! `cargo run --release -p axcomp-validation --example held_back_bound -- [SEEDS [FIRST_SEED]]`.
use axcomp_geometry::{FitOptions, Judge, analyse};
use axcomp_validation::held_back::{HeldBackOptions, make_case, min_norm_predictions, score};

fn median(mut v: Vec<f64>) -> f64 {
    axcomp_numeric::stats::median(&mut v)
}

fn main() {
    let arg = |i: usize, d: u64| {
        std::env::args()
            .nth(i)
            .map_or(d, |s| s.parse().expect("a number"))
    };
    let (seeds, first) = (arg(1, 20), arg(2, 0));
    let opts = HeldBackOptions::default();
    let (mut best, mut floor, mut default) = (Vec::new(), Vec::new(), Vec::new());
    for s in first..first + seeds {
        let case = make_case(&opts, s);
        let judge = Judge::Holdout(case.held.clone());
        let train: Vec<usize> = (0..case.held.len()).filter(|&i| !case.held[i]).collect();
        let fl = min_norm_predictions(&case.data, &train, &case.truth_um, None, 0.0, 0.0);
        floor.push(score(&case, &fl).lines);
        let held_rms = |fo: &FitOptions| {
            let an = analyse(&case.data, &judge, fo).expect("held-back case fits");
            let p = axcomp_geometry::analysis::predict_readings(&an.fit.model, &case.data);
            score(&case, &p).lines
        };
        default.push(held_rms(&FitOptions::default()));
        let mut b = (f64::INFINITY, String::new());
        for iv in [Some(4), Some(8), None] {
            for d in [1e-5, 3e-5, 1e-4, 3e-4, 1e-3] {
                for l in [0.0, 1e-3, 1e-2, 1e-1, 1.0] {
                    let fo = FitOptions {
                        intervals: iv,
                        damping: d,
                        lambdas: vec![l],
                        ..FitOptions::default()
                    };
                    let sc = held_rms(&fo);
                    if sc < b.0 {
                        b = (sc, format!("intervals {iv:?}, damping {d}, λ {l}"));
                    }
                }
            }
        }
        println!(
            "seed {s}: default {:.3}, best {:.3} ({}), floor {:.3}",
            default.last().unwrap(),
            b.0,
            b.1,
            floor.last().unwrap()
        );
        best.push(b.0);
    }
    let (d, b, f) = (median(default), median(best), median(floor));
    println!(
        "median lines: default {d:.3} ({:.2}× floor), best per case {b:.3} ({:.2}× floor), floor {f:.3} µm",
        d / f,
        b / f
    );
}
