//! Runs the withheld-effect validation without the CLI: `cargo run --release -p axcomp-validation --example
//! validate -- [cases] [seed] [rows]`.

use axcomp_validation::axis::{self as validate, ValidateOptions};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let cases = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(48);
    let seed = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let rows = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(5000);
    let opts = ValidateOptions {
        cases,
        seed,
        rows,
        ..ValidateOptions::default()
    }
    .build()
    .unwrap();
    let summary = validate::validate(&opts, |c| {
        eprintln!(
            "case {:3} {:8} withheld {:20} snr {:?} verdict {:20} {} shrink {:6.1} oracle {:?} ties {:?} model {:?} {:.2}s",
            c.index,
            c.plan,
            c.withheld,
            c.snr,
            c.verdict,
            if c.correct { "ok " } else { "BAD" },
            c.shrink_pct,
            c.oracle_shrink_pct.map(|v| (v * 10.0).round() / 10.0),
            c.ties,
            c.model,
            c.seconds
        )
    })
    .unwrap();
    println!("{}", summary.to_markdown());
}
