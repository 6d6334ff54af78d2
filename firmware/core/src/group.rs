//! An axis group: 1–5 axes corrected together, each with today's single-axis pipeline, plus a
//! cross-axis stage that corrects the linear axes from the whole group's commanded positions.
//!
//! # Glossary
//! - **group**: up to [`MAX_AXES`] axes, each named once: linear X, Y, Z (µm per count, as a
//!   single axis) and rotary A, B, C (counts per revolution; their "µm" are arc-seconds, i.e.
//!   `um_per_count` = 1 296 000 / counts per revolution by convention of the host tools).
//! - **slot**: an axis's index in the group (the order of [`Group::load`]'s list).
//! - **turn position**: a rotary axis's position modulo its counts per revolution, in
//!   `[0, counts_per_rev)`; kept incrementally (one add and one compare per cycle), the full
//!   modulo only when an axis moves a whole turn or more in one cycle.
//! - **pool**: the coefficient storage shared by the group's tables (`POOL` segments); an axis's
//!   forward and backward halves are two ranges of it.
//! - **cross-axis stage**: a deviation vector for X, Y, Z computed from all axes' commanded
//!   positions, added to those axes' errors before their limits: the volumetric geometric stage
//!   ([`crate::geometric`]) and the rotary location-error stage ([`crate::rotary`]); with both,
//!   the deviation is the geometric one plus the rotary one (in that order of the f32 sum).
//!
//! # Order of the stages in one group cycle
//! 1. the cross-axis stages (if the image has them; they read only the commanded positions):
//!    a. geometric: one segment search per axis on the commanded X, Y, Z, the model's functions
//!    and lever arms → the model error e for X, Y, Z;
//!    b. rotary: commanded angles of the tilt axis (A or B) and C within the turn, sin/cos and
//!    the angle terms recomputed only when one of them changed, the tool tip from the commanded
//!    X, Y, Z → a deviation for X, Y, Z, added to a's;
//! 2. per axis, its whole pipeline in one call (in slot order; with the rotary stage alone, in
//!    the order X, Y, Z, A (or B), C — each pipeline reads and writes only its own slot, so the
//!    order changes nothing): counter extension → direction (hysteresis) → segment index of the
//!    table grid (once per axis and cycle: the table position is the extended position, or the
//!    turn position for a rotary axis; every error function of that axis uses this index) →
//!    table value → thermo-force term → + the stages' deviation (X, Y, Z) → clamp → slew →
//!    rounding to counts → corrected command.
//!
//! The stage's deviation is added to the same error, in the same order, as when it ran between
//! the error and the limits (one pass over the axes instead of two; the outputs are the same).
//!
//! A single-axis group with no stage therefore computes exactly what [`crate::Compensator::cycle`]
//! computes (the same functions; tested bit for bit).

pub use crate::axis::{AxisName, GroupAxisImage, MAX_AXES};
pub use crate::error::GroupError;
pub use crate::group_cycle::Group;
pub use crate::group_engine::GroupEngine;
pub use crate::group_state::{GroupState, GroupStats};
pub use crate::io::{GroupInput, GroupOutput};
pub use crate::runtime::PoolTable;
