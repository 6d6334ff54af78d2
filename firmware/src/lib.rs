//! axcomp-firmware: the compensation firmware's portable application code.
//!
//! Glossary:
//! - **Cycle**: one pass of the fixed-rate control loop: read the scale and the command, run the core's
//!   correction pipeline, write the corrected command.
//! - **Scale**: the linear encoder; read as a raw, wrapping hardware counter (`u32`), extended by the core.
//! - **Command**: the position setpoint from the motion controller, in scale counts.
//! - **Board**: one concrete chip and its wiring (QEMU netduinoplus2, STM32G474RE). Only `board::*` names a
//!   chip; the loop and the drivers are generic over the traits in [`control`] and embedded-hal 1.0.
//! - **Trace**: a binary recording of inputs (cycles, temperatures, process parameters, table images) that the
//!   QEMU firmware and the host replay through the same `axcomp_core::Engine`.
//! - **Overrun**: a cycle whose compute time exceeded the cycle period ([`control::CycleStats`]); the drive
//!   also counts cycles whose output came after the next cycle's deadline ([`drive::LatenessMeter`]).
//! - **Drive**: the board's loop around the group engine (`axcomp_core::group::GroupEngine`, one to five
//!   axes; a single-axis machine is a group of one): setpoint link ([`setpoint`]) and its supervisors,
//!   board capabilities and the image check, lateness, watchdog, status word ([`status`]); see
//!   [`drive::group::GroupDrive`].
//!
//! Host builds (`cargo test`) compile the portable modules only; the board modules need `target_os = "none"`.
#![cfg_attr(not(any(test, feature = "std")), no_std)]

#[macro_use]
mod fmt;

pub mod board_caps;
pub mod control;
pub mod drive;
pub mod max31865;
pub mod probe_capture;
pub mod replay;
pub mod setpoint;
pub mod status;

#[cfg(target_os = "none")]
pub mod board;

#[cfg(feature = "std")]
mod drive_scenario;
#[cfg(feature = "std")]
mod probe_scenario;

/// The trace scenario generator: the host crate `axcomp-scenario` plus the drive-trace scenarios that need
/// the firmware's link and drive types (re-exported for tests/).
#[cfg(feature = "std")]
pub mod scenario {
    pub use crate::drive_scenario::*;
    pub use crate::probe_scenario::*;
    pub use axcomp_scenario::*;
}
