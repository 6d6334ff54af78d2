//! Withheld-effect validation of the diagnosis (`axcomp validate-diagnosis`): many twin campaigns with
//! a known truth, each with one effect (or none) present in the twin but left out of the model told to
//! the diagnosis; the figures are top-1 accuracy, false alarms on null cases and the held-out shrink
//! compared with the oracle's.
//!
//! This crate joins the twin (`axcomp-twin`, which knows the truth) and the diagnosis
//! (`axcomp-diagnose`, which must not): the diagnosis depends on no simulator, so nothing of the truth
//! can leak into it.
//!
//! # Glossary
//! - **case**: one simulated campaign and the model told to the diagnosis.
//! - **withheld**: the effect present in the twin but not in the model (`None` = a null case).
//! - **oracle**: the base model plus the true withheld contribution as one column, refitted on the
//!   training rows — the best any diagnosis could do.
//! - **shrink**: held-out RMS reduction in % (`100·(1 − after/before)`).
//!
//! Modules: [`axis`] (single-axis campaigns: ISO 230-2 runs, scans, load steps, thermal rounds),
//! [`lines`] (laser lines of the three-axis twin), [`rtest`] (R-test campaigns of the five-axis twin),
//! [`probe`] (touch-probe campaigns: calibration sphere, plane, ring gauge, a held-out second sphere);
//! [`harness`] holds what they share (options checks, case schedule, validate loop, oracle RMS, rates,
//! per-SNR grouping, confusion matrix and its table).

pub mod axis;
pub mod harness;
pub mod lines;
pub mod probe;
pub mod rtest;
pub mod rtest_blind;
