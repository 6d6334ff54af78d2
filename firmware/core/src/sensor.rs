//! The thermo-force stage's values: each sensor's settings ([`SensorRt`], loaded from the image) and
//! its health and lag ([`SensorState`], per reading), the force terms' sources and laws, and the
//! process parameters of the predicted forces. A leaf below [`crate::runtime`]; the stage that
//! updates and adds them is [`crate::thermo`].

use crate::spec::{ForceLaw, SensorSpec};
use crate::{MAX_SENSORS, RECOVERY_READINGS};

/// Where the force F_j of a force term comes from.
///
/// Chosen by the image: a [`ForceSpec`] with a `law` is `Predicted` (from the process parameters
/// given to [`crate::AxisCompensator::set_process`]; 0 N until the first call), one without is `Measured`
/// (from [`crate::CycleInput::forces_n`] at the same index).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ForceSource {
    /// From the force sensor values in each [`crate::CycleInput`].
    Measured,
    /// From the force law and the current process parameters.
    Predicted,
}

/// Process parameters for predicted forces.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ProcessParams {
    /// Depth of cut, mm.
    pub ap_mm: f32,
    /// Feed per tooth, mm.
    pub fz_mm: f32,
    /// Spindle speed, rpm.
    pub n_rpm: f32,
}

/// Which force terms are measured (bit j of the discriminant = term j), for the cycle's dispatch.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub(crate) enum MeasuredSet {
    None = 0,
    F0 = 0b001,
    F1 = 0b010,
    F01 = 0b011,
    F2 = 0b100,
    F02 = 0b101,
    F12 = 0b110,
    F012 = 0b111,
}

impl MeasuredSet {
    /// From the bit mask (bits above 2 are ignored).
    pub(crate) const fn from_mask(mask: u8) -> MeasuredSet {
        match mask & 0b111 {
            0b001 => MeasuredSet::F0,
            0b010 => MeasuredSet::F1,
            0b011 => MeasuredSet::F01,
            0b100 => MeasuredSet::F2,
            0b101 => MeasuredSet::F02,
            0b110 => MeasuredSet::F12,
            0b111 => MeasuredSet::F012,
            _ => MeasuredSet::None,
        }
    }
}

/// Validated sensor settings with the derived lag coefficient.
#[derive(Debug, Clone, Copy)]
pub struct SensorRt {
    pub(crate) reference_degc: f32,
    pub(crate) min_degc: f32,
    pub(crate) max_degc: f32,
    pub(crate) max_rate_degc_per_s: f32,
    pub(crate) lag_tau_s: f32,
    pub(crate) stale_timeout_ms: u32,
    pub(crate) b_um_per_k: f32,
    /// α = 1 − exp(−period/τ), 1 without lag.
    pub(crate) alpha: f32,
    /// Range guard: the term b_i·ΔT_i counts while the unlagged rise is within these bounds
    /// (K; −∞, +∞ without the guard).
    pub(crate) rise_min_k: f32,
    pub(crate) rise_max_k: f32,
}

impl SensorRt {
    pub(crate) const ZERO: SensorRt = SensorRt {
        reference_degc: 0.0,
        min_degc: 0.0,
        max_degc: 0.0,
        max_rate_degc_per_s: 0.0,
        lag_tau_s: 0.0,
        stale_timeout_ms: 0,
        b_um_per_k: 0.0,
        alpha: 0.0,
        rise_min_k: 0.0,
        rise_max_k: 0.0,
    };
}

pub(crate) const ZERO_LAW: ForceLaw = ForceLaw {
    k: 0.0,
    x_ap: 0.0,
    y_fz: 0.0,
    z_n: 0.0,
};

/// [`SensorState::health`]: rejected readings (bits 0..24, saturating), seen (bit 24), stale
/// (bit 25) and the consecutive accepted readings (bits 26..32, saturating at 63; a stale sensor
/// recovers at [`RECOVERY_READINGS`]). One word, so that a sensor's state stays 20 bytes and an
/// axis's [`crate::State`] (five of them in a group's state) keeps its size.
pub(crate) const REJECTED_MASK: u32 = (1 << 24) - 1;
pub(crate) const SEEN: u32 = 1 << 24;
pub(crate) const STALE: u32 = 1 << 25;
pub(crate) const STREAK_ONE: u32 = 1 << 26;
pub(crate) const STREAK_MASK: u32 = 63 * STREAK_ONE;
/// A streak of 63 (with any other bits below it): no further increment.
pub(crate) const STREAK_MAX: u32 = STREAK_MASK;
const _: () = assert!((RECOVERY_READINGS as u32) < 63);

/// Per-sensor health and lag state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SensorState {
    /// Rejected-reading count, seen, stale and streak (see [`REJECTED_MASK`] and the bits after it).
    pub(crate) health: u32,
    pub(crate) last_good_degc: f32,
    pub(crate) last_good_ms: u32,
    /// Lagged ΔT, kelvin.
    pub(crate) filtered_dt: f32,
    /// What ΔT is taken against, °C: the image's `reference_degc`, or with the reference at
    /// switch-on the first accepted reading (set at that reading).
    pub(crate) reference_degc: f32,
}

impl SensorState {
    pub(crate) const NEW: SensorState = SensorState {
        health: 0,
        last_good_degc: 0.0,
        last_good_ms: 0,
        filtered_dt: 0.0,
        reference_degc: 0.0,
    };
    /// An accepted reading has been seen.
    pub(crate) fn seen(&self) -> bool {
        self.health & SEEN != 0
    }
    /// Stale (or recovering).
    pub(crate) fn stale(&self) -> bool {
        self.health & STALE != 0
    }
    /// Rejected readings (saturating at 2^24 − 1).
    pub(crate) fn rejected(&self) -> u32 {
        self.health & REJECTED_MASK
    }
}

/// Sensor settings of one axis: `cfgs` (its own or its group's array) for its `n_sensors`.
pub(crate) fn sensor_spec(cfgs: &[SensorRt; MAX_SENSORS], n: u8, i: usize) -> Option<SensorSpec> {
    if i >= n as usize {
        return None;
    }
    cfgs.get(i).map(|s| SensorSpec {
        reference_degc: s.reference_degc,
        min_degc: s.min_degc,
        max_degc: s.max_degc,
        max_rate_degc_per_s: s.max_rate_degc_per_s,
        lag_tau_s: s.lag_tau_s,
        stale_timeout_ms: s.stale_timeout_ms,
    })
}

/// b_i (µm/K) and the lag coefficient α of sensor `i` (see [`sensor_spec`]).
pub(crate) fn sensor_b_alpha(
    cfgs: &[SensorRt; MAX_SENSORS],
    n: u8,
    i: usize,
) -> Option<(f32, f32)> {
    if i >= n as usize {
        return None;
    }
    cfgs.get(i).map(|s| (s.b_um_per_k, s.alpha))
}
