//! Prints the diagnosis JSON of one validation case: `cargo run --release -p axcomp-validation --example
//! case -- <index> [seed] [rows]`.

use axcomp_diagnose::{DiagnoseOptions, diagnose};
use axcomp_validation::axis::{self as validate, ValidateOptions};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let index = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(0);
    let seed = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let rows = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(5000);
    let opts = ValidateOptions {
        seed,
        rows,
        ..ValidateOptions::default()
    }
    .build()
    .unwrap();
    let c = validate::make_case(&opts, index).unwrap();
    println!(
        "plan {} withheld {:?} snr {:?} model {:?}",
        c.plan, c.withheld, c.snr, c.model
    );
    println!(
        "axis effects: {}",
        serde_json::to_string(&c.axis.effects).unwrap()
    );
    let d = diagnose(&c.obs, &c.model, &DiagnoseOptions::default()).unwrap();
    println!("{}", serde_json::to_string_pretty(&d).unwrap());
    // Oracle: base model + the true withheld contribution, refitted on the training rows.
    let train = c.obs.train_rows();
    let hold = c.obs.holdout_rows();
    let mut cols = vec![vec![1.0; c.obs.n_rows()]];
    cols.extend(d.model_columns.iter().cloned());
    cols.push(c.truth_um.clone());
    let fit = axcomp_diagnose::lsq::fit(&cols, &c.obs.target, &train);
    let after = axcomp_numeric::stats::rms(
        hold.iter()
            .map(|&i| c.obs.target[i] - fit.predict(&cols, i)),
    );
    let peak = hold
        .iter()
        .map(|&i| c.truth_um[i].abs())
        .fold(0.0, f64::max);
    println!(
        "oracle: rank {} of {}, last coef {:.4}, held-out RMS after {after:.4} (before {:.4}), truth peak on held-out {peak:.3}",
        fit.rank,
        cols.len(),
        fit.coef.last().unwrap(),
        d.gap.holdout_rms_um
    );
}
