//! Runs a range of line-harness cases and prints each: `cargo run --release -p axcomp-validation
//! --example lines_case -- FIRST COUNT`.
use axcomp_validation::lines::{LineValidateOptions, run_case};

fn main() {
    let a: Vec<usize> = std::env::args()
        .skip(1)
        .map(|s| s.parse().unwrap())
        .collect();
    let opts = LineValidateOptions::default();
    for i in a[0]..a[0] + a[1] {
        match run_case(&opts, i) {
            Ok(c) => println!(
                "{i}: {} ({}) snr {:?} ho {:?} → {} ({}) gap {:.2} shrink {:.1} oracle {:?} {:.2}s",
                c.withheld,
                c.detail,
                c.snr,
                c.holdout_lines,
                c.verdict,
                c.correct,
                c.gap_um,
                c.shrink_pct,
                c.oracle_shrink_pct,
                c.seconds
            ),
            Err(e) => println!("{i}: error {e}"),
        }
    }
}
