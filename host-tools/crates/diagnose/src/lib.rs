//! Sim-to-real gap diagnosis: which unmodelled effect explains what a model misses, and where.
//!
//! Glossary:
//! - **observations**: one campaign as plain columns (target error, position, direction, time, sensors, ...)
//!   plus the held-out mask ([`Observations`]).
//! - **effect kind**: a named error source of the contract vocabulary ([`EffectKind`]); each kind is a
//!   *family* of regressors (basis functions) built from the columns, some with a searched nonlinear
//!   parameter (a period, a time constant, a decay length) — see [`basis`].
//! - **model**: the effects the user says are modelled; fitted by least squares on the training rows.
//! - **gap**: the residual of that model; on the held-out rows it is what the model fails to predict.
//! - **candidate**: an effect kind not in the model; it is judged by refitting the *whole* model with the
//!   candidate's family added on the training rows and predicting the held-out rows.
//! - **shrink**: `100·(1 − rms_after/rms_before)` of the held-out gap.
//! - **verdict**: the candidate judged responsible, or `none` when no candidate explains the gap beyond
//!   noise: training F-test with Bonferroni over all searched variants, and a *material* held-out gain
//!   (≥ 5 % of the gap and ≥ 0.05 σ, independent of the number of held-out rows); ties between nested
//!   effects by held-out evidence ([`engine::VERDICT_RULE`]).
//! - **where**: contiguous regions of a variable (`target_mm`, `time_s`, `velocity_mm_s`, `direction`)
//!   holding most of the held-out gap.
//!
//! Modules: [`obs`] (plain columns), [`dataset`] (from an `axcomp-data` CSV), [`basis`] (regressor
//! families), [`lsq`] (rank-robust least squares and exact refit RSS drops), [`judge`] (the verdict rule
//! on columns, shared by every data kind), [`engine`] (the single-axis diagnosis), [`lines`] (laser-line data of a three-axis machine),
//! [`locate`] (where the gap lies), [`report`] (Markdown + SVG), [`stats`] (F / t tails). The
//! withheld-effect validation harness lives in `axcomp-validation`, so that this crate depends on no
//! simulator.
//!
//! ```no_run
//! use axcomp_diagnose::{diagnose, DiagnoseOptions, EffectKind, Observations};
//! # fn obs() -> Observations { unimplemented!() }
//! let d = diagnose(&obs(), &[EffectKind::PitchError], &DiagnoseOptions::default()).unwrap();
//! println!("{} ({})", d.verdict, d.note);
//! ```

pub mod basis;
pub mod dataset;
pub mod engine;
pub mod error;
pub mod judge;
pub mod lines;
pub mod locate;
pub mod lsq;
pub mod obs;
pub mod probe;
pub mod report;
pub mod rtest;
pub mod stats;

/// The effect vocabulary is the twin's (one definition for the twin and the diagnosis).
pub use axcomp_effects::EffectKind;
pub use engine::{Candidate, DiagnoseOptions, Diagnosis, Gap, diagnose};
pub use error::DiagnoseError;
pub use locate::Region;
pub use obs::Observations;
