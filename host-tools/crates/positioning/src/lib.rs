//! axcomp-positioning: models of the positioning deviation of a linear axis along its stroke, chosen by
//! cross-validation, guarded against doing harm, and resampled to the firmware's uniform table.
//!
//! Glossary:
//! - *deviation*: position reached minus target position (ISO 230-2), µm; the table holds the predicted
//!   deviation and the firmware subtracts it.
//! - *target*: a commanded measuring position (mm); *run* (ISO: cycle): one pass over all targets.
//! - *direction*: approach direction, +1 positive (forward) / −1 negative (backward); *reversal*: forward −
//!   backward deviation at the same target (backlash, lost motion).
//! - *knot*: a breakpoint of a spline; *segment*: one uniform interval of the firmware table.
//! - *CV*: cross-validation; leave-one-run-out predicts each run from a model fitted on the other runs.
//! - *guard*: the do-no-harm rule that refuses a table not clearly better than no compensation.
//!
//! Entry points: [`campaign::fit_campaign`] (a measurement file's campaign → judged table, JSON, report:
//! [`report`]); [`fit::fit`] (points → chosen model, CV figures, table); [`table_file::TableFile`] (the table
//! file and its conversion to [`axcomp_core::TableSpec`]); [`guard::judge`].

// `!(a > b)` is used on purpose: it is also true when a value is NaN, which must be rejected too.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod campaign;
pub mod campaign_figures;
pub mod campaign_types;
pub mod export;
pub mod fit;
pub mod guard;
pub mod iso230;
pub mod predict;
pub mod report;
pub mod spline;
pub mod table_file;
pub mod warmup;

pub use fit::{Candidate, Curves, FitError, FitOptions, FitResult, Observation, fit};
pub use guard::GuardVerdict;
pub use table_file::{OwnedTableSpec, TableError, TableFile};
