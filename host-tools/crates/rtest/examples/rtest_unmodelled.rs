//! Held-out prediction on twins with effects beyond the 11-parameter model: for each machine kind, seeds
//! 1..=N, the location errors scaled by F (1: the specified 5–50 µm / 10–100 µrad; 0.1 or 0: a well-built or
//! already compensated machine, where the unmodelled effects dominate), all effects on, K4 run 2 held out:
//! the held-out RMS of the full model, of the default (`fit rtest` as shipped), of the nominal kinematics
//! without correction and of the nominal kinematics with only the sphere's set-up offsets fitted.
//! Run: `cargo run --release -p axcomp-rtest --example rtest_unmodelled -- 20 0.1 [run=2|path=C-circle@0|cv:path|cv:run] [FIRST]`
//! (N seeds from FIRST, default 1).
use axcomp_data::Split;
use axcomp_rtest::analysis::analyse_selected;
use axcomp_twin::five_axis::{FiveAxisEffects, FiveAxisTwin};

#[path = "common/mod.rs"]
mod common;

fn main() {
    let n: u64 = common::arg(1, 20);
    let scale: f64 = common::arg(2, 1.0);
    let holdout = std::env::args().nth(3).unwrap_or_else(|| "run=2".into());
    let first: u64 = common::arg(4, 1);
    for kind in common::KINDS {
        let (m, paths) = common::machine_and_paths(kind);
        let (mut worse_full, mut worse_default) = (0, 0);
        let mut sums = [0.0; 4];
        for seed in first..first + n {
            let mut twin = FiveAxisTwin::random(m, seed);
            for v in twin.location.iter_mut() {
                *v *= scale;
            }
            twin.effects = FiveAxisEffects::all_but_time_drift();
            let (ds, data) = common::measure(&twin, &paths, seed);
            let split = match holdout.strip_prefix("cv:") {
                Some(col) => Split::from_args(None, Some(col)).unwrap(),
                None => Split::from_args(Some(&holdout), None).unwrap(),
            };
            let a = analyse_selected(&ds, &data, split.as_ref(), &Default::default(), None, true)
                .unwrap();
            let nominal_setup = a.nominal_setup_rms_um;
            let full = a.full_rms_um;
            let def = a.judged_rms_um;
            println!(
                "{} seed {seed}: full {full:.3} default {def:.3} nominal {:.3} nominal+set-up {nominal_setup:.3} µm; fixed by selection: {:?}",
                kind.name(),
                a.raw_rms_um,
                a.selection
                    .as_ref()
                    .map(|s| s
                        .fixed
                        .iter()
                        .map(|(k, _)| kind.location_names()[*k])
                        .collect::<Vec<_>>())
                    .unwrap_or_default()
            );
            worse_full += (full > nominal_setup) as usize;
            worse_default += (def > nominal_setup) as usize;
            for (s, v) in sums
                .iter_mut()
                .zip([full, def, a.raw_rms_um, nominal_setup])
            {
                *s += v / n as f64;
            }
        }
        println!(
            "{} (scale {scale}, {holdout}, {n} seeds from {first}): mean held-out RMS full {:.3} default {:.3} nominal {:.3} nominal+set-up {:.3} µm; worse than nominal+set-up: full {worse_full}, default {worse_default}",
            kind.name(),
            sums[0],
            sums[1],
            sums[2],
            sums[3]
        );
    }
}
