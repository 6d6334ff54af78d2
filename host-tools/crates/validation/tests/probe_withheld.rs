//! Withheld-effect validation on touch-probe twin campaigns, a CI-sized run:
//! 32 cases (24 with one of the six probe effects withheld at SNR 4 or 8, 8 null
//! cases), held out: the second sphere (`artefact=sphere2`, fixed before any case is drawn). The full
//! figure (200 cases, SNR 3–8) comes from `axcomp validate-diagnosis --harness probe` (docs/figures.md).

use axcomp_validation::probe::{ProbeValidateOptions, validate};

#[test]
fn probe_top1_and_false_alarms_on_32_cases() {
    let opts = ProbeValidateOptions {
        cases: 32,
        seed: 7,
        snrs: vec![4.0, 8.0],
        ..ProbeValidateOptions::default()
    }
    .build()
    .unwrap();
    let s = validate(&opts, |_| {}).unwrap();
    println!("{}", s.to_markdown());
    // Targets: top-1 ≥ 90 % at SNR ≥ 4, false alarms ≤ 5 %. With 24 non-null cases one miss
    // is 4.2 %, with 8 null cases one false alarm is 12.5 %: the test allows 2 misses and no false alarm.
    assert_eq!(s.top1_snr_ge4_cases, 24);
    assert!(
        s.top1_snr_ge4_pct >= 100.0 * 22.0 / 24.0 - 1e-9,
        "{}",
        s.to_markdown()
    );
    assert_eq!(s.null_cases, 8);
    assert!(s.false_alarm_pct <= 0.0, "{}", s.to_markdown());
    // The verdict's held-out shrink is close to the oracle's when right (median ratio ≥ 0.8).
    assert!(
        s.median_shrink_over_oracle.unwrap() >= 0.8,
        "{}",
        s.to_markdown()
    );
}
