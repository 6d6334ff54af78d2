//! Verdict rates of the R-test diagnosis on blind-set-like `ac-trunnion` campaigns (none / rotary
//! positioning / A-axis wobble) with amplitudes, noise and K4-like path sets varied per seed
//! (`axcomp_validation::rtest_blind`). Prints each case and, per kind, the right verdicts over all cases
//! and over the identifiable ones (oracle shrink ≥ 5 %).
//!
//! `cargo run --release -p axcomp-validation --example rtest_blind_rate -- [SEEDS]` (default 20).

use axcomp_twin::five_axis::TiltWobbleShape;
use axcomp_validation::rtest_blind::{BlindKind, run_blind_case, tally, tally_shape};

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(20);
    let mut cases = Vec::new();
    for seed in 1..=seeds {
        for kind in BlindKind::ALL {
            let c = run_blind_case(kind, seed).expect("diagnosis");
            println!(
                "seed {seed:3} {:18} {:16} σ {:.2} µm scale {:.2} poses {:3}: verdict {:18} oracle shrink {}",
                kind.want(),
                c.shape.unwrap_or("-"),
                c.noise_um,
                c.scale,
                c.poses,
                c.verdict,
                c.oracle_shrink_pct
                    .map_or("-".to_string(), |o| format!("{o:.1} %"))
            );
            cases.push(c);
        }
    }
    for kind in BlindKind::ALL {
        let (right, n, right_id, n_id) = tally(&cases, kind);
        println!(
            "{:18}: {right}/{n} right; identifiable (oracle shrink ≥ 5 %): {right_id}/{n_id}",
            kind.want()
        );
    }
    for shape in TiltWobbleShape::ALL {
        let (right, n, right_id, n_id) = tally_shape(&cases, shape);
        println!(
            "  wobble {:16}: {right}/{n} right; identifiable: {right_id}/{n_id}",
            shape.name()
        );
    }
    let right = cases.iter().filter(|c| c.correct).count();
    let ident: Vec<_> = cases.iter().filter(|c| c.identifiable()).collect();
    let right_id = ident.iter().filter(|c| c.correct).count();
    println!(
        "all: {right}/{} right; identifiable: {right_id}/{}",
        cases.len(),
        ident.len()
    );
}
