//! Least squares and collinearity diagnostics: the host numeric layer's ([`axcomp_numeric::lsq`]).
pub use axcomp_numeric::lsq::*;
