//! `axcomp-twin`: a digital twin of a precision linear axis. It simulates measurement campaigns whose
//! truth is known, writes them as the contract's measurement CSV, and can run them *compensated*
//! through `axcomp_core::Compensator` — the firmware's own code — to show what a table does.
//!
//! # Glossary
//! - **axis** ([`Axis`]): stroke, scale resolution, temperature sensors, thermal behaviour, noise and a
//!   set of **effects** ([`Effect`], kinds [`EffectKind`] named as in the contract: `pitch_error`,
//!   `reversal`, `scale_expansion`, `thermal_drift`, `thermal_lag`, `force_deflection`, `cogging`,
//!   `interpolation_error`, `end_effect`, `following_error`, `abbe`, `time_drift`).
//! - **deviation**: position reached minus target, µm (ISO 230-2). The **truth** is the noise-free
//!   deviation, the sum of the effects' **contributions** at the scale position.
//! - **plan** ([`Plan`]): what is measured when — ISO 230-2 runs ([`Iso230Plan`]), scans at several
//!   speeds ([`ScanPlan`]), warm-up/cool-down ([`ThermalPlan`]), load steps ([`LoadPlan`]), Abbe offsets
//!   (`Plan::by_name("abbe", ..)`), and all of them on one time line ([`SurveyPlan`]); thermo-force campaigns under cutting load come from
//!   `axcomp-thermal`'s generator through [`simulate_spindle`] (see [`spindle`]).
//! - **campaign** ([`Campaign`]): the measured **rows** (CSV) plus the per-row [`Truth`].
//! - **scale counts**: `round(x_mm·1000 / axis.scale_um_per_count)`, zero at 0 mm — the count space of
//!   the core's tables.
//!
//! # Use
//! ```
//! use axcomp_twin::{Axis, Iso230Plan, Plan, simulate};
//! let axis = Axis::linear_motor_demo();
//! let plan = Plan::from(Iso230Plan::standard(axis.start_mm, axis.end_mm));
//! let campaign = simulate(&axis, &plan, None, 42).unwrap();
//! assert_eq!(campaign.rows.len(), 21 * 5 * 2);
//! let csv = campaign.to_csv_string();
//! assert!(csv.contains("target_mm,deviation_um,run,direction,time_s,ambient_degC"));
//! ```
//!
//! Compensated runs: build an image with `axcomp_core::write_image` (table in the twin's scale counts,
//! `um_per_count = axis.scale_um_per_count`, thermo sensors in the twin's order ambient, motor, scale,
//! `sensor_period_ms = SENSOR_PERIOD_MS`), load it into a `Compensator` and pass it to [`simulate`]. The
//! drive then commands every move through `Compensator::cycle` and settles where the corrected command
//! puts it (see [`drive`]); the measured deviation is what remains.
//!
//! [`IdealTable`] / [`ideal_image`] build the best compensation the core can hold for a twin axis
//! straight from its truth (no fit): the floor a fitted table or thermo model can be compared with.
//!
//! Performance (`cargo bench -p axcomp-twin --bench simulate`): a 5,000-row campaign takes a few ms
//! open loop and a few tens of ms compensated.
//!
//! For the validation harness: [`Axis::random`] draws plausible parameters, [`Campaign::contribution_um`]
//! gives each effect's contribution per row, and [`Axis::scale_effect`] scales one effect exactly; the
//! noise depends only on the seed, so re-simulating after scaling changes nothing else.

pub mod axis;
pub mod campaign;
pub mod drive;
pub mod effects;
pub mod ideal;
pub mod plan;
pub mod probe;
pub mod sim;
pub mod spindle;
pub mod synth;
pub mod thermal;

pub use axis::{Axis, AxisError, Noise, Sensor};
pub use campaign::{Campaign, ExtraColumn, Row, Truth};
pub use effects::{
    Abbe, Cogging, Conditions, DriftTerm, Effect, EffectKind, EndEffect, FollowingError,
    ForceDeflection, InterpolationError, LagTerm, Layout, PitchError, Reversal, ScaleExpansion,
    ThermalDrift, ThermalLag, TimeDrift, UnknownEffect, Wave,
};
pub use ideal::{IdealTable, IdealThermo, ideal_image};
pub use plan::{
    Iso230Plan, LoadPlan, Plan, Sample, ScanPlan, SurveyPlan, ThermalPlan, UnknownPlan,
};
pub use sim::{SENSOR_PERIOD_MS, SimError};
pub use spindle::{SpindleCampaign, simulate_spindle, spindle_config};
pub use thermal::{DutyStep, Environment, ThermalModel};

use serde::Serialize;

/// Simulates `plan` on `axis`. Without `compensation` the drive settles on each target (in whole
/// scale counts); with it, every move is commanded through `Compensator::cycle` (see [`drive`]).
/// The noise is a function of `seed` only (same seed → same campaign, bit for bit).
pub fn simulate(
    axis: &Axis,
    plan: &Plan,
    compensation: Option<&axcomp_core::Compensator>,
    seed: u64,
) -> Result<Campaign, SimError> {
    match compensation {
        None => sim::run(axis, plan, &mut sim::OpenLoop, seed, false),
        Some(comp) => sim::run(axis, plan, &mut drive::Compensated::new(comp), seed, true),
    }
}

/// What `axcomp sim --truth` writes: the axis (effect kinds and parameters), the plan and the seed.
#[derive(Debug, Clone, Serialize)]
pub struct TruthReport<'a> {
    pub axis: &'a Axis,
    pub plan: &'a Plan,
    pub seed: u64,
    pub rows: usize,
    pub compensated: bool,
    /// Kinds present, by contract name.
    pub effects: Vec<&'static str>,
    /// RMS over the rows of each present kind's contribution, µm.
    pub contribution_rms_um: std::collections::BTreeMap<&'static str, f64>,
}

impl<'a> TruthReport<'a> {
    pub fn new(axis: &'a Axis, plan: &'a Plan, campaign: &Campaign) -> TruthReport<'a> {
        let kinds = axis.kinds();
        TruthReport {
            axis,
            plan,
            seed: campaign.seed,
            rows: campaign.rows.len(),
            compensated: campaign.compensated,
            effects: kinds.iter().map(|k| k.name()).collect(),
            contribution_rms_um: kinds
                .iter()
                .map(|&k| {
                    // No rows, no error: 0 for an empty campaign.
                    let r = if campaign.rows.is_empty() {
                        0.0
                    } else {
                        axcomp_numeric::stats::rms(
                            (0..campaign.rows.len()).map(|i| campaign.contribution_um(k, i)),
                        )
                    };
                    (k.name(), r)
                })
                .collect(),
        }
    }

    /// Pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("truth report serialises")
    }
}
pub mod five_axis;
pub mod five_axis_probe;
pub mod geometry;
