//! axcomp-core: the portable `no_std` compensation engine shared by the firmware and the host tools.
//!
//! One library computes the correction on the target and in every host simulation, bit for bit:
//! `f32` arithmetic with only `+ - * /`, comparisons and `libm` functions, integer scale counts for
//! positions, no allocation, no panics on the per-cycle path.
//!
//! # Glossary
//! - **positioning table**: the predicted deviation (reached − target, µm) along the stroke, as a C2
//!   cubic spline over uniform segments, one table per approach direction (or one for both).
//! - **knot**: a segment boundary; knot k sits at `start_counts + k·segment_counts`.
//! - **segment**: the interval between two knots; its polynomial is stored in the image in Horner
//!   form `[c0, c1, c2, c3]` in t = (position − knot) / segment_counts in [0, 1), and held by the
//!   loaded axis converted to the remainder r = position − knot in counts
//!   ([`segment_per_count`]: evaluated as c0 + r·(c1' + r·(c2' + r·c3'))).
//! - **reversal**: a change of the approach direction; detected with a hysteresis so that scale
//!   noise at standstill does not toggle between the forward and backward tables.
//! - **thermo-force term**: E = b0 + Σ b_i·ΔT_i + c·(x − x_ref)·ΔT_s + Σ χ_j·F_j (µm).
//! - **ΔT**: a (lagged) sensor temperature minus its reference temperature (the image's, or the
//!   sensor's first accepted reading with [`ThermoReference::SwitchOn`]), kelvin.
//! - **range guard**: per-sensor rise bounds; a sensor's term b_i·ΔT_i is left out while its
//!   unlagged rise is outside them ([`Flags::THERMAL_GUARDED`]).
//! - **force source**: a force term is *predicted* (from the cutting-force law and the process
//!   parameters given to [`AxisCompensator::set_process`]) if its [`ForceSpec`] has a `law`, else
//!   *measured* (from [`CycleInput::forces_n`] at the same index).
//! - **sensor rate / cycle rate**: lags, sensor health, b0 + Σ b_i·ΔT_i, c·ΔT_s and predicted
//!   forces are computed at the sensor rate ([`AxisCompensator::update_temperatures`]) and cached in
//!   the [`State`]; [`Compensator::cycle`] only adds them up.
//! - **lag**: first-order filter y += α(u − y), α = 1 − exp(−period/τ), modelling the delay
//!   between a sensor and the structure it stands for.
//! - **slew**: the change of the applied correction from one cycle to the next; limited to
//!   `max_slew_um_per_cycle` so that a new table or a temperature step never makes the axis jump.
//! - **clamp**: the limit `max_correction_um` on the magnitude of the total correction.
//! - **stale**: a sensor that has had no accepted reading for `stale_timeout_ms`; the thermal
//!   contribution is then frozen at its last good value for [`STALE_HOLD_MS`], then ramps out
//!   over [`STALE_RAMP_MS`] to b0 + predicted forces (flag [`Flags::THERMAL_RAMP_OUT`]).
//! - **image**: the versioned, CRC-protected binary form of an [`ImageSpec`] that the host writes
//!   and the firmware loads ([`write_image`], [`Compensator::load`]); see [`image`] for the layout.
//! - **slot**: one of the two [`Compensator`]s of the [`Engine`] (A/B); a new image is loaded into
//!   the spare slot and becomes active only if it is valid.
//!
//! # Use
//! ```
//! use axcomp_core::*;
//! let fwd = [[1.0f32, 0.5, 0.0, 0.0]; 4];
//! let spec = ImageSpec {
//!     axis_id: 1, um_per_count: 0.1, counter_bits: 32,
//!     table: Some(TableSpec { start_counts: 0, segment_counts: 1000, forward: &fwd,
//!                             backward: &[], outside: OutsideStroke::Hold }),
//!     thermo: None,
//!     limits: LimitSpec { max_correction_um: 100.0, max_slew_um_per_cycle: 10.0,
//!                         direction_hysteresis_counts: 5 },
//! };
//! let mut buf = [0u8; 512];
//! let n = write_image(&spec, &mut buf).unwrap();
//! let mut comp = Compensator::IDENTITY;
//! comp.load(&buf[..n]).unwrap();
//! let mut st = State::new();
//! // t = 200/1000 = 0.2 in segment 0: 1.0 + 0.2·0.5 = 1.1 µm = 11 counts, subtracted.
//! let out = comp.cycle(&mut st, &CycleInput { scale_raw: 200, command_counts: 200, forces_n: [0.0; 3] });
//! assert_eq!(out.correction_counts, 11);
//! assert_eq!(out.corrected_command_counts, 189);
//! ```
#![no_std]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

#[cfg(feature = "std")]
extern crate std;

mod axis;
pub mod bench;
mod compensator;
mod counter;
mod counts;
mod engine;
mod error;
mod format;
pub mod geometric;
pub mod group;
mod group_check;
mod group_cycle;
mod group_engine;
pub mod group_image;
mod group_image_parse;
mod group_image_write;
mod group_state;
mod hint;
pub mod image;
mod io;
mod le;
mod limits;
pub mod probe;
mod probe_settings;
pub mod provenance;
mod provenance_block;
pub mod rotary;
mod rotary_spec;
mod rotary_wobble;
mod runtime;
mod sensor;
mod spec;
mod state;
mod store;
mod table;
mod thermo;
pub mod trace;
pub mod wiring;

pub use counts::Direction;
pub use engine::{Engine, EngineStats};
pub use error::{Field, ImageError};
pub use format::crc32;
pub use image::{ImageInfo, declared_image_len, image_len, inspect_image, write_image};
pub use io::{CycleInput, CycleOutput, Flags};
pub use limits::round_to_counts;
pub use runtime::{AxisCompensator, Compensator, OwnTable, TableStore};
pub use sensor::{ForceSource, ProcessParams};
pub use spec::{
    ExpansionSpec, ForceLaw, ForceSpec, ImageSpec, LimitSpec, OutsideStroke, SensorSpec, TableSpec,
    ThermoForceSpec, ThermoReference,
};
pub use state::State;
pub use table::per_count as segment_per_count;

/// Segments per direction of the positioning table.
pub const MAX_SEGMENTS: usize = 1024;
/// Temperature sensors of the thermo-force term.
pub const MAX_SENSORS: usize = 16;
/// Force terms of the thermo-force term.
pub const MAX_FORCES: usize = 3;
/// Consecutive accepted readings a stale sensor needs before it counts as healthy again.
pub const RECOVERY_READINGS: u8 = 3;
/// Predicted forces with a larger magnitude (or NaN/inf) are replaced by 0 N and flagged.
pub const MAX_FORCE_N: f32 = 1.0e7;
/// A sum of measured force terms Σ χ_j·F_j beyond this (or NaN/inf) is dropped and flagged, µm.
pub const MAX_FORCE_TERM_UM: f32 = 1.0e4;
/// How long a frozen thermal term is held after a sensor went stale, ms (then it ramps out).
pub const STALE_HOLD_MS: u32 = 60_000;
/// How long the ramp-out of a frozen thermal term takes, ms: Σ b_i·ΔT_i and c·ΔT_s go linearly to
/// 0, leaving b0 + predicted forces (the value that needs no sensor), flagged
/// [`Flags::THERMAL_RAMP_OUT`].
pub const STALE_RAMP_MS: u32 = 60_000;
/// Size of one table-image flash slot (A or B), bytes: `memory.x` reserves two of them (the
/// STM32G474RE's 512 KiB flash: 256 KiB of code, then slots A and B of 128 KiB each).
pub const IMAGE_SLOT_LEN: usize = 128 * 1024;
/// Largest image this build accepts (one flash slot).
pub const MAX_IMAGE_LEN: usize = IMAGE_SLOT_LEN;

/// Deterministic random numbers for the unit tests of this crate (the host crates use
/// `axcomp_numeric`'s test noise).
#[cfg(test)]
pub(crate) mod test_rng {
    /// A xorshift64 generator started at `seed` (non-zero): each call returns the next value.
    pub(crate) fn xorshift(seed: u64) -> impl FnMut() -> u64 {
        let mut x = seed;
        move || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        }
    }
}
