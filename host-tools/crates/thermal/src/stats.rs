//! Descriptive statistics and the Student-t distribution: the host numeric layer's
//! ([`axcomp_numeric::stats`]).
pub use axcomp_numeric::stats::*;
