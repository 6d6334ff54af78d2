//! axcomp-numeric: the one host numeric layer shared by positioning, thermal, diagnose and the twin.
//!
//! | module | what |
//! |---|---|
//! | [`lsq`] | least squares by Householder QR (optional ridge), rank and condition report, VIF |
//! | [`stats`] | rms / mean / median / std, ln Γ, incomplete beta, Student t and F distributions |
//! | [`lag`] | the first-order lag (firmware form, and the diagnosis's time-ordered form) |
//! | [`bspline`] | the uniform cubic B-spline basis |
//! | [`hermite`] | the cubic Hermite segment through end values and slopes |
//! | [`minimize`] | golden-section minimisation in one dimension |
//! | [`noise`] | deterministic Gaussian test noise |

pub mod bspline;
pub mod hermite;
pub mod lag;
pub mod lsq;
pub mod minimize;
pub mod noise;
pub mod stats;
