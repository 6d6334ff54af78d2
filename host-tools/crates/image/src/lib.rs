//! Fitted models into the firmware's image, and images described: what `axcomp image build|group|inspect`,
//! `axcomp demo` and `axcomp replay` share.
//!
//! Glossary:
//! - *image*: the versioned, CRC-protected binary the firmware loads (`axcomp_core::write_image`).
//! - *group image*: schema 2, one section per axis (each holding that axis's schema-1 image), an
//!   optional rotary location-error model, geometric model, probe settings and sensor names
//!   (`axcomp_core::group_image`).
//! - *geometric section*: a `fit geometry` model converted for the core's volumetric stage
//!   (`axcomp_core::geometric`): each of the 18 component functions, a cubic B-spline on its axis's
//!   knot grid in mm, becomes per-segment Horner polynomials over the same knots in counts; the
//!   squareness constants, the stacking and the tool offset are copied. Every component goes in
//!   with the values the model holds (what `axcomp predict` uses): a *not-separable* one
//!   (`identified: false`, only its combination with others is measured) at its minimum-norm share,
//!   one not identified for another reason (no data) as the zero the model holds; the identified
//!   mask keeps the model's flags and `image inspect` says which is which ([`geometric`]). A `fit
//!   rtest` model's `linear_geometry` goes into its translational components, alone or added to a
//!   `fit geometry` model's ([`linear_geometry`]).
//! - *rotary section*: a `fit rtest` model's 11 location errors for the core's rotary stage
//!   ([`rotary`]).
//! - *double correction*: two sources of one group image correcting the same error: an axis's
//!   positioning table and the geometric model's positioning component of that axis (EXX, EYY,
//!   EZZ), or the rotary model's squareness and the geometric model's (EC0Y, EB0Z, EA0Z), both
//!   non-zero ([`group::refuse_double_correction`]).
//! - *board refusal*: what the STM32G474 board's own checks refuse of an image ([`board`]).
//! - *replay*: a binary trace run through the core's engine, as the QEMU firmware runs it ([`replay`]).

/// `Err(Error::Invalid(..))` unless `cond`.
macro_rules! ensure {
    ($cond:expr, $($fmt:tt)+) => {
        if !$cond {
            return Err($crate::Error::Invalid(format!($($fmt)+)));
        }
    };
}
/// `return Err(Error::Invalid(..))`.
macro_rules! bail {
    ($($fmt:tt)+) => {
        return Err($crate::Error::Invalid(format!($($fmt)+)))
    };
}

pub mod angle_table;
pub mod args;
pub mod axis;
pub mod board;
pub mod describe;
pub mod extension;
pub mod geometric;
pub mod group;
pub mod linear_geometry;
pub mod replay;
pub mod rotary;

pub use describe::{describe, describe_any, describe_geometric, describe_trust, to_hex};
pub use extension::{provenance_block, with_extension, with_provenance_section};
pub use geometric::{
    GeometricSection, bspline_segment_to_horner, exclude_geometric_components, geometric_from_model,
};
pub use rotary::rotary_from_rtest_model;

/// Why a model, an image or a trace cannot be turned into (or read as) what was asked.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The input cannot be carried by the image as given; the message names what and where.
    #[error("{0}")]
    Invalid(String),
    /// The firmware core's image writer or parser refuses it, with what was being done.
    #[error("{what}: {err}")]
    Core {
        what: String,
        err: axcomp_core::ImageError,
    },
    /// The firmware core's image check, as it words it.
    #[error(transparent)]
    Image(#[from] axcomp_core::ImageError),
    /// The group would correct one error twice (every pair named, with the way out).
    #[error("{0}")]
    DoubleCorrection(String),
    /// Formatting a description failed.
    #[error(transparent)]
    Fmt(#[from] std::fmt::Error),
}

impl Error {
    /// The core's refusal `err` of what was being done (`what`).
    pub fn core(what: impl Into<String>, err: axcomp_core::ImageError) -> Self {
        Error::Core {
            what: what.into(),
            err,
        }
    }
}

/// Result of this crate.
pub type Result<T> = std::result::Result<T, Error>;

/// A message for a missing value or a failed step, as [`Error::Invalid`]: an `Option`'s `None` is the
/// message alone, a `Result`'s error follows the message after ": ".
pub(crate) trait Context<T> {
    fn with_context(self, message: impl FnOnce() -> String) -> Result<T>;
}

impl<T> Context<T> for Option<T> {
    fn with_context(self, message: impl FnOnce() -> String) -> Result<T> {
        self.ok_or_else(|| Error::Invalid(message()))
    }
}

impl<T, E: std::fmt::Display> Context<T> for std::result::Result<T, E> {
    fn with_context(self, message: impl FnOnce() -> String) -> Result<T> {
        self.map_err(|e| Error::Invalid(format!("{}: {e}", message())))
    }
}
