//! The laser-line withheld-effect harness on a reduced run (the full figure: `axcomp validate-diagnosis
//! --data-kind lines --cases 200`, docs/figures.md). Deterministic: the cases are seeded.

use axcomp_validation::lines::{LineValidateOptions, case_kind, make_case, run_case, summarise};

#[test]
fn reduced_line_harness_meets_the_issue_targets() {
    // 32 cases (8 null, 24 withheld: each kind at SNR 3, 4, 6 and 8), seed 1. Targets: top-1 ≥
    // 90 % at SNR ≥ 4, false alarms ≤ 5 % (here: none of the 8 null cases), median shrink ≥ 0.8 × oracle.
    // Measured on this subset (the first 32 cases of the 200-case run in docs/figures.md): top-1 at SNR ≥ 4 17/18
    // (94.4 %; one `time_drift` called `thermal_drift`), false alarms 0/8, median shrink / oracle 1.00.
    let opts = LineValidateOptions {
        cases: 32,
        ..LineValidateOptions::default()
    }
    .build()
    .unwrap();
    let results: Vec<_> = (0..opts.cases)
        .map(|i| run_case(&opts, i).unwrap())
        .collect();
    let s = summarise(results);
    let md = s.to_markdown();
    assert_eq!(s.null_cases, 8, "{md}");
    assert_eq!(s.cases_at_snr_ge4, 18, "{md}");
    assert!(s.top1_at_snr_ge4 >= 0.9, "{md}");
    assert!(s.false_alarm_rate <= 0.05, "{md}");
    assert!(s.median_shrink_ratio_to_oracle >= 0.8, "{md}");
    // Every kind of the vocabulary was withheld at least once and named at least once.
    for (row, counts) in &s.confusion {
        let k = s.confusion.iter().position(|(r, _)| r == row).unwrap();
        assert!(counts.iter().sum::<usize>() >= 4, "{row}: {md}");
        assert!(counts[k] >= 1, "{row} never named: {md}");
    }
}

#[test]
fn cases_are_sized_by_the_part_the_model_cannot_absorb_and_nulls_add_nothing() {
    let opts = LineValidateOptions::default();
    for i in 0..8 {
        let c = make_case(&opts, i).unwrap();
        let hold: Vec<usize> = (0..c.obs.n_rows()).filter(|&r| c.obs.held_out[r]).collect();
        let peak = hold
            .iter()
            .map(|&r| c.contribution_um[r].abs())
            .fold(0.0, f64::max);
        match case_kind(&opts, i) {
            (None, None) => {
                assert!(c.contribution_um.iter().all(|v| *v == 0.0));
                assert_eq!(c.model.len(), 21);
            }
            (Some(_), Some(snr)) => {
                // The held-out peak is at least SNR·σ (it equals SNR·σ when nothing is absorbed; reference:
                // the scaling in make_case; tolerance 1e-9 relative).
                assert!(
                    peak >= snr * opts.noise_um * (1.0 - 1e-9),
                    "case {i}: {peak} < {}",
                    snr * opts.noise_um
                );
                // The withheld components are not in the model told to the diagnosis.
                if c.detail.starts_with("twin components") {
                    assert!(c.model.len() < 21, "{}", c.detail);
                }
            }
            _ => unreachable!(),
        }
    }
}
