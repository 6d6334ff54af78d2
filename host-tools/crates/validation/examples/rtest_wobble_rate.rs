//! Verdict rate of the R-test diagnosis on the five-axis twin over seeds: for each seed and machine
//! (`ac-trunnion`, `bc-trunnion`), the validation plan (`axcomp_validation::rtest::plan`: K4 + C circles
//! on two set-ups fitted, a C circle at −30° and a second K4 held out), σ = 0.3 µm, with nothing beyond
//! the location errors, a C-axis positioning error (`rotary_positioning`), a wobble of the tilt axis A/B
//! varying with its angle (`tilt_wobble`, a `rotary_wobble`), a C wobble (`rotary_wobble`) or the linear
//! axes' errors (`linear_geometry`), at the twin's own magnitudes. Prints each case's verdict (with the
//! oracle's held-out shrink for the tilt-axis wobble) and the count of right verdicts per case kind; for
//! the tilt-axis wobble also per machine and over the identifiable cases (oracle shrink ≥ 5 %, the
//! verdict rule's materiality floor: below it the location errors absorb almost all of the wobble).
//!
//! `cargo run --release -p axcomp-validation --example rtest_wobble_rate -- [SEEDS]` (default 10).

use axcomp_diagnose::judge::{DiagnoseOptions, MIN_SHRINK_PCT};
use axcomp_kinematics::rotary::{FiveAxis, MachineKind};
use axcomp_twin::five_axis::FiveAxisTwin;
use axcomp_validation::harness;
use axcomp_validation::rtest::{observations, plan};

/// The oracle's held-out shrink (%): the base columns plus the true contribution as one column.
fn oracle_shrink(camp: &axcomp_diagnose::rtest::RtestCampaign, contribution: &[f64]) -> f64 {
    let mut cols: Vec<&[f64]> = camp.base_columns.iter().map(|c| c.as_slice()).collect();
    let ones = vec![1.0; camp.y.len()];
    cols.push(&ones);
    let b = harness::holdout_rms_after_fit(&cols, &camp.y, &camp.train, &camp.holdout);
    cols.push(contribution);
    let a = harness::holdout_rms_after_fit(&cols, &camp.y, &camp.train, &camp.holdout);
    harness::shrink_pct(b, a)
}

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(10);
    let cases: [(&str, &str); 5] = [
        ("none", "none"),
        ("rotary_positioning", "rotary_positioning"),
        ("tilt_wobble", "rotary_wobble"),
        ("rotary_wobble", "rotary_wobble"),
        ("linear_geometry", "linear_geometry"),
    ];
    let mut right = vec![0usize; cases.len()];
    let mut total = vec![0usize; cases.len()];
    // Tilt-axis wobble per machine: (right, cases, right identifiable, identifiable).
    let mut tilt = [[0usize; 4]; 2];
    for seed in 1..=seeds {
        for (mi, kind) in [MachineKind::AcTrunnion, MachineKind::BcTrunnion]
            .into_iter()
            .enumerate()
        {
            let m = FiveAxis::new(kind, 0.0);
            for (ci, (effect, want)) in cases.iter().enumerate() {
                let mut twin = FiveAxisTwin::random(m, 1000 + seed);
                twin.dwell_s = 6.0;
                let mut contribution = Vec::new();
                if *effect != "none" {
                    let mut clean = twin.clone();
                    clean.noise_um = 0.0;
                    let without = clean.measure(&plan(&m), 0);
                    clean.effects.enable(effect);
                    let with = clean.measure(&plan(&m), 0);
                    contribution = with
                        .rows
                        .iter()
                        .zip(&without.rows)
                        .flat_map(|(a, b)| [0, 1, 2].map(|i| a.d_um[i] - b.d_um[i]))
                        .collect();
                    assert!(twin.effects.enable(effect));
                }
                let c = twin.measure(&plan(&m), 1000 + seed);
                let obs = observations(&c);
                let (d, camp) =
                    axcomp_diagnose::rtest::diagnose(&obs, &[], &DiagnoseOptions::default())
                        .expect("diagnosis");
                let v = d.diagnosis.verdict.clone();
                total[ci] += 1;
                let ok = v == *want;
                if ok {
                    right[ci] += 1;
                }
                let mut oracle = String::new();
                if *effect == "tilt_wobble" {
                    let o = oracle_shrink(&camp, &contribution);
                    let identifiable = o >= MIN_SHRINK_PCT;
                    let t = &mut tilt[mi];
                    t[0] += usize::from(ok);
                    t[1] += 1;
                    t[2] += usize::from(ok && identifiable);
                    t[3] += usize::from(identifiable);
                    oracle = format!(" (oracle shrink {o:.1} %)");
                }
                println!("seed {seed} {} {effect}: verdict {v}{oracle}", kind.name());
            }
        }
    }
    for (ci, (effect, want)) in cases.iter().enumerate() {
        println!("{effect:20} → {want:20}: {}/{} right", right[ci], total[ci]);
    }
    for (mi, name) in ["ac-trunnion", "bc-trunnion"].iter().enumerate() {
        let t = tilt[mi];
        println!(
            "tilt_wobble on {name}: {}/{} right; identifiable (oracle shrink ≥ {MIN_SHRINK_PCT} %): {}/{}",
            t[0], t[1], t[2], t[3]
        );
    }
}
