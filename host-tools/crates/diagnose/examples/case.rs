//! Prints the diagnosis JSON of one validation case: `cargo run --release -p axcomp-diagnose --example
//! case -- <index> [seed] [rows]`.

use axcomp_diagnose::validate::{self, ValidateOptions};
use axcomp_diagnose::{diagnose, DiagnoseOptions};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let index = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(0);
    let seed = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let rows = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(5000);
    let opts = ValidateOptions { seed, rows, ..ValidateOptions::default() }.build().unwrap();
    let c = validate::make_case(&opts, index).unwrap();
    println!("plan {} withheld {:?} snr {:?} model {:?}", c.plan, c.withheld, c.snr, c.model);
    println!("axis effects: {}", serde_json::to_string(&c.axis.effects).unwrap());
    let d = diagnose(&c.obs, &c.model, &DiagnoseOptions::default()).unwrap();
    println!("{}", serde_json::to_string_pretty(&d).unwrap());
}
