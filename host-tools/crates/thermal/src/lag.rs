//! First-order lag as the firmware runs it: the host numeric layer's ([`axcomp_numeric::lag`]).
pub use axcomp_numeric::lag::{alpha, lag, lag_into};
