//! Verdict rate of the R-test diagnosis on the five-axis twin over seeds: for each seed and machine
//! (`ac-trunnion`, `bc-trunnion`), the validation plan (`axcomp_validation::rtest::plan`: K4 + C circles
//! on two set-ups fitted, a C circle at −30° and a second K4 held out), σ = 0.3 µm, with nothing beyond
//! the location errors, a C-axis positioning error (`rotary_positioning`), a wobble of the tilt axis A/B
//! varying with its angle (`tilt_wobble`, a `rotary_wobble`), a C wobble (`rotary_wobble`) or the linear
//! axes' errors (`linear_geometry`), at the twin's own magnitudes. Prints each case's verdict and the
//! count of right verdicts per case kind.
//!
//! `cargo run --release -p axcomp-validation --example rtest_wobble_rate -- [SEEDS]` (default 10).

use axcomp_diagnose::judge::DiagnoseOptions;
use axcomp_kinematics::rotary::{FiveAxis, MachineKind};
use axcomp_twin::five_axis::FiveAxisTwin;
use axcomp_validation::rtest::{observations, plan};

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
    for seed in 1..=seeds {
        for kind in [MachineKind::AcTrunnion, MachineKind::BcTrunnion] {
            let m = FiveAxis::new(kind, 0.0);
            for (ci, (effect, want)) in cases.iter().enumerate() {
                let mut twin = FiveAxisTwin::random(m, 1000 + seed);
                twin.dwell_s = 6.0;
                if *effect != "none" {
                    assert!(twin.effects.enable(effect));
                }
                let c = twin.measure(&plan(&m), 1000 + seed);
                let obs = observations(&c);
                let (d, _) =
                    axcomp_diagnose::rtest::diagnose(&obs, &[], &DiagnoseOptions::default())
                        .expect("diagnosis");
                let v = d.diagnosis.verdict.clone();
                total[ci] += 1;
                if v == *want {
                    right[ci] += 1;
                }
                println!("seed {seed} {} {effect}: verdict {v}", kind.name());
            }
        }
    }
    for (ci, (effect, want)) in cases.iter().enumerate() {
        println!("{effect:20} → {want:20}: {}/{} right", right[ci], total[ci]);
    }
}
