//! The runtime object of one axis, [`AxisCompensator`]: the settings of its stages as values (read
//! through `&self`, loaded once from an image) and its table segments (kept where its
//! [`TableStore`] keeps them). What changes per cycle or per sensor reading is the axis's
//! [`crate::State`] (`state`, through `&mut`).
//!
//! # Glossary
//! - **stage**: one step of an axis's correction, a settings type with methods that take its own
//!   part of the [`crate::State`]: [`crate::counter::CounterStage`] (counter extension, direction),
//!   [`crate::table::TableStage`] (positioning table), [`crate::thermo::ThermoForceStage`]
//!   (thermo-force term), [`crate::limits::LimitStage`] (clamp, slew, rounding to counts). No stage
//!   names the compensator; [`crate::compensator`] composes them, the loader ([`crate::image`])
//!   fills them.
//!
//! The layout is `#[repr(C)]` in an order chosen for the per-cycle path's loads (the stages'
//! fields nest in the order the flat struct had them): keep it.

use crate::counter::CounterStage;
use crate::limits::LimitStage;
use crate::table::TableStage;
use crate::thermo::ThermoForceStage;

pub(crate) use crate::store::PoolSource;
pub use crate::store::{OwnTable, PoolTable, TableStore};

/// The validated runtime compensation object of one axis: owned, fixed capacity, no borrow of
/// the image.
///
/// [`Compensator::IDENTITY`] is all zero bytes, so a `static` holding it (or an [`crate::Engine`])
/// lands in `.bss` (checked on thumbv7em: a `static` Engine adds 67 400 bytes of `.bss`, no `.data`).
pub type Compensator = AxisCompensator<OwnTable>;

/// One axis's pipeline (counter, direction, table, thermo-force, limits) with its table segments
/// kept by `S`: in the object itself ([`OwnTable`], the single-axis [`Compensator`]) or in the
/// coefficient pool of an axis group ([`crate::group`]).
#[derive(Debug, Clone)]
#[repr(C)]
pub struct AxisCompensator<S: TableStore> {
    pub(crate) loaded: bool,
    pub(crate) axis_id: u16,
    // ---- the per-cycle fields of the counter and the limits, in pairs that one paired load
    // reads (the shift and the hysteresis; the two magnitude keys) ----
    /// The counter stage (extension, direction hysteresis).
    pub(crate) counter: CounterStage,
    /// The limits stage (clamp, slew, rounding to counts).
    pub(crate) limits: LimitStage,
    // ---- read off the per-cycle path ----
    /// Counts per revolution of a rotary group axis (its table is indexed by the position within
    /// the turn); 0 for a linear axis and always for [`OwnTable`] storage.
    pub(crate) counts_per_rev: u32,
    /// The positioning table's settings (its segments in `segments`).
    pub(crate) table: TableStage,
    /// The thermo-force term's settings (with the sensors' where the storage keeps them).
    pub(crate) thermo: ThermoForceStage<S::Sensors>,
    /// The table segments (or where to find them). Last, so that every other field is within a
    /// load's immediate offset of `self`.
    pub(crate) segments: S,
}

impl<S: TableStore> AxisCompensator<S> {
    /// The identity (zero correction, valid) with table storage `table`.
    pub const fn identity_with(table: S) -> AxisCompensator<S> {
        AxisCompensator {
            loaded: false,
            axis_id: 0,
            counter: CounterStage::IDENTITY,
            limits: LimitStage::IDENTITY,
            counts_per_rev: 0,
            table: TableStage::NONE,
            thermo: ThermoForceStage::none(S::NO_SENSORS),
            segments: table,
        }
    }
}
