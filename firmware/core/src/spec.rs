//! What the host writes into a table image: borrowed slices in physical units.
//!
//! These structs are the input of [`crate::write_image`]; [`crate::Compensator::load`] parses the
//! image bytes back into the validated runtime object. Nothing here is used per cycle.

/// Behaviour of the positioning table beyond the measured stroke.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutsideStroke {
    /// Hold the value at the nearest stroke end.
    Hold,
    /// Taper linearly from the end value to 0 over `length_counts` (> 0) beyond the end.
    Taper {
        /// Length of the taper in scale counts.
        length_counts: u32,
    },
}

/// Positioning table: uniform cubic segments in Horner form.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableSpec<'a> {
    /// Scale position of knot 0.
    pub start_counts: i64,
    /// Uniform knot spacing in counts, > 0.
    pub segment_counts: u32,
    /// Per segment `[c0, c1, c2, c3]`: deviation_um = c0 + t(c1 + t(c2 + t c3)), t in [0, 1).
    pub forward: &'a [[f32; 4]],
    /// Same length as `forward`; empty = unidirectional (forward used both ways).
    pub backward: &'a [[f32; 4]],
    /// Beyond the stroke.
    pub outside: OutsideStroke,
}

/// One temperature sensor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorSpec {
    /// ΔT = T_filtered − reference.
    pub reference_degc: f32,
    /// Plausible range: readings outside `[min, max]` are rejected.
    pub min_degc: f32,
    /// Upper end of the plausible range.
    pub max_degc: f32,
    /// Plausibility of the change between two accepted readings (> 0).
    pub max_rate_degc_per_s: f32,
    /// First-order lag time constant, 0 = no lag.
    pub lag_tau_s: f32,
    /// No accepted reading for this long → thermal term frozen + fault (> 0).
    pub stale_timeout_ms: u32,
}

/// Cutting-force power law F = k·ap^x·fz^y·n^z (N).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceLaw {
    /// Coefficient K.
    pub k: f32,
    /// Exponent of the depth of cut ap (mm).
    pub x_ap: f32,
    /// Exponent of the feed per tooth fz (mm).
    pub y_fz: f32,
    /// Exponent of the spindle speed n (rpm).
    pub z_n: f32,
}

/// One force term χ·F.
///
/// The force source is chosen by the image: `law: Some(..)` → [`crate::ForceSource::Predicted`]
/// (from [`crate::Compensator::set_process`]); `law: None` → [`crate::ForceSource::Measured`]
/// (from [`crate::CycleInput::forces_n`] at the same index).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ForceSpec {
    /// Compliance: deviation per newton.
    pub chi_um_per_n: f32,
    /// Force law used when the force is predicted.
    pub law: Option<ForceLaw>,
}

/// Scale/structure expansion term c·(x − x_ref)·ΔT_s.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExpansionSpec {
    /// Index of the sensor s giving ΔT_s.
    pub sensor: u8,
    /// Reference position where expansion is zero.
    pub x_ref_counts: i64,
    /// Expansion coefficient, µm per mm per kelvin.
    pub c_um_per_mm_k: f32,
}

/// What a sensor's ΔT is taken against.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ThermoReference {
    /// Each sensor's `reference_degc` of the image.
    Fixed,
    /// Each sensor's first accepted reading after the image was loaded or the [`crate::State`]
    /// reset (a model fitted on runs that each start at switch-on, `fit thermal --runs`); the
    /// lag then starts at ΔT = 0 and `reference_degc` is only the nominal temperature the model
    /// was fitted around (not used by the firmware).
    SwitchOn,
}

/// Thermo-force term E = b0 + Σ b_i·ΔT_i + c·(x − x_ref)·ΔT_s + Σ χ_j·F_j (µm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThermoForceSpec<'a> {
    /// Rate at which `update_temperatures` is called (> 0); sets the lag coefficients.
    pub sensor_period_ms: u32,
    /// At most [`crate::MAX_SENSORS`].
    pub sensors: &'a [SensorSpec],
    /// Constant term.
    pub b0_um: f32,
    /// One per sensor (0 for a sensor used only by the expansion term).
    pub b_um_per_k: &'a [f32],
    /// Optional expansion term.
    pub expansion: Option<ExpansionSpec>,
    /// At most [`crate::MAX_FORCES`].
    pub forces: &'a [ForceSpec],
    /// What each ΔT_i is taken against.
    pub reference: ThermoReference,
    /// Range guard: empty = none, else one `(rise_min_k, rise_max_k)` per sensor (lo < hi). While
    /// sensor i's unlagged rise (last accepted reading − its reference) is outside its bounds, its
    /// term b_i·ΔT_i is left out of the sum (the sensor stays healthy, the other terms stay).
    pub rise_bounds_k: &'a [(f32, f32)],
}

/// Safety limits of the applied correction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LimitSpec {
    /// |total correction| clamp (> 0).
    pub max_correction_um: f32,
    /// Change of the applied correction per cycle (> 0).
    pub max_slew_um_per_cycle: f32,
    /// Direction flips only after moving more than this against the current direction.
    pub direction_hysteresis_counts: u32,
}

/// Everything a table image holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageSpec<'a> {
    /// Axis the image belongs to.
    pub axis_id: u16,
    /// Scale resolution (> 0).
    pub um_per_count: f32,
    /// 16..=32, width of the hardware counter that wraps.
    pub counter_bits: u8,
    /// Positioning table, if any.
    pub table: Option<TableSpec<'a>>,
    /// Thermo-force term, if any.
    pub thermo: Option<ThermoForceSpec<'a>>,
    /// Limits (always present).
    pub limits: LimitSpec,
}
