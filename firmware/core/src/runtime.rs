//! The runtime types of one axis: the validated object [`AxisCompensator`] (its coefficients, read
//! through `&self`, loaded once from an image) and its [`State`] (everything that changes per cycle
//! or per sensor reading, through `&mut`), with where the table segments are kept ([`TableStore`]).
//!
//! Only data and its small accessors live here; the stages that read them are
//! [`crate::counter`], [`crate::table`], [`crate::thermo`] and [`crate::limits`], composed by
//! [`crate::compensator`]; the loader ([`crate::image`]) fills them. Both layouts are `#[repr(C)]`
//! in an order chosen for the per-cycle path's loads: keep it.

use crate::MAX_FORCES;
use crate::counts::CounterShift;
use crate::sensor::{MeasuredSet, ZERO_LAW};
use crate::spec::ForceLaw;

pub use crate::state::State;
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
    pub(crate) counter_bits: u8,
    // ---- the per-cycle fields of the counter and the limits, in pairs that one paired load
    // reads (the shift and the hysteresis; the two magnitude keys) ----
    /// 32 − counter_bits (0 for the identity: a 32-bit counter).
    pub(crate) sext_shift: CounterShift,
    pub(crate) hysteresis_counts: u32,
    /// [`crate::limits::magnitude_key`] of `max_correction_um` if every applied correction, in counts, is below
    /// 2^29 in magnitude (`MAX_LIMIT_UM` / `um_per_count` < 2^29), else 0: the cycle's fast path
    /// (within the clamp, rounded with `round_half_away_bounded`) is never taken for an
    /// unbounded image (no magnitude's key is below 0).
    pub(crate) fast_max_key: u32,
    /// `max_slew_um_per_cycle` as the cycle's fast path tests it: see [`crate::limits::magnitude_key`].
    pub(crate) slew_key: u32,
    /// `um_per_count / 2` (exact), so that the cycle's quotient is already doubled for the
    /// bounded rounding.
    pub(crate) half_um_per_count: f32,
    // ---- read off the per-cycle path ----
    pub(crate) um_per_count: f32,
    pub(crate) max_correction_um: f32,
    /// Counts per revolution of a rotary group axis (its table is indexed by the position within
    /// the turn); 0 for a linear axis and always for [`OwnTable`] storage.
    pub(crate) counts_per_rev: u32,
    // ---- positioning table ----
    pub(crate) bidirectional: bool,
    pub(crate) taper: bool,
    pub(crate) n_segments: u32,
    pub(crate) start_counts: i64,
    /// Knot spacing; `None` = no table (so the division needs no zero check).
    pub(crate) segment: Option<core::num::NonZeroU32>,
    /// n·segment_counts ≤ u32::MAX (validated).
    pub(crate) span_counts: u32,
    pub(crate) taper_counts: u32,
    pub(crate) inv_taper: f32,
    /// `[direction][0 = low end, 1 = high end]` table value at the stroke ends.
    pub(crate) edge: [[f32; 2]; 2],
    // ---- thermo-force term ----
    pub(crate) has_thermo: bool,
    pub(crate) sensor_period_ms: u32,
    pub(crate) n_sensors: u8,
    /// The sensors' settings where the storage keeps them with the axis ([`OwnTable`]: all
    /// [`MAX_SENSORS`]); a group keeps its axes' in an array of their own (`()` here), so that
    /// the per-cycle fields of all five axes are within short load offsets of the group.
    pub(crate) sensors: S::Sensors,
    pub(crate) b0_um: f32,
    pub(crate) has_expansion: bool,
    /// ΔT against each sensor's first accepted reading (thermo flag REFERENCE_AT_SWITCH_ON).
    pub(crate) reference_at_switch_on: bool,
    /// The range guard is on (thermo flag RISE_GUARD; bounds in the sensors' settings).
    pub(crate) rise_guard: bool,
    pub(crate) expansion_sensor: u8,
    pub(crate) x_ref_counts: i64,
    pub(crate) c_um_per_mm_k: f32,
    /// c · um_per_count / 1000: µm per count per kelvin.
    pub(crate) expansion_um_per_count_k: f32,
    pub(crate) n_forces: u8,
    pub(crate) chi_um_per_n: [f32; MAX_FORCES],
    pub(crate) force_predicted: [bool; MAX_FORCES],
    /// Bit j set: force j is measured (χ_j in `chi_measured[j]`).
    pub(crate) measured_mask: u8,
    pub(crate) chi_measured: [f32; MAX_FORCES],
    /// `measured_mask` as an enum, so the cycle's dispatch needs no range check.
    pub(crate) measured: MeasuredSet,
    /// THERMAL_FROZEN if the image has sensors: `State::thermo_bits` holds the thermo flags
    /// XOR this, so that a fresh (all-zero) State reads as frozen until its sensors report.
    pub(crate) thermo_flags_xor: u16,
    pub(crate) laws: [ForceLaw; MAX_FORCES],
    /// The table segments (or where to find them). Last, so that every other field is within a
    /// load's immediate offset of `self`.
    pub(crate) table: S,
}

impl<S: TableStore> AxisCompensator<S> {
    /// The identity (zero correction, valid) with table storage `table`.
    pub const fn identity_with(table: S) -> AxisCompensator<S> {
        AxisCompensator {
            loaded: false,
            axis_id: 0,
            counter_bits: 0,
            sext_shift: CounterShift::S0,
            um_per_count: 0.0,
            counts_per_rev: 0,
            bidirectional: false,
            taper: false,
            n_segments: 0,
            start_counts: 0,
            segment: None,
            span_counts: 0,
            taper_counts: 0,
            inv_taper: 0.0,
            edge: [[0.0; 2]; 2],
            has_thermo: false,
            sensor_period_ms: 0,
            n_sensors: 0,
            sensors: S::NO_SENSORS,
            b0_um: 0.0,
            has_expansion: false,
            reference_at_switch_on: false,
            rise_guard: false,
            expansion_sensor: 0,
            x_ref_counts: 0,
            c_um_per_mm_k: 0.0,
            expansion_um_per_count_k: 0.0,
            n_forces: 0,
            chi_um_per_n: [0.0; MAX_FORCES],
            force_predicted: [false; MAX_FORCES],
            measured_mask: 0,
            chi_measured: [0.0; MAX_FORCES],
            measured: MeasuredSet::None,
            thermo_flags_xor: 0,
            laws: [ZERO_LAW; MAX_FORCES],
            max_correction_um: 0.0,
            slew_key: 0,
            hysteresis_counts: 0,
            half_um_per_count: 0.0,
            fast_max_key: 0,
            table,
        }
    }
}
