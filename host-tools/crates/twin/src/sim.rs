//! Running a plan on an axis: time, temperatures, the drive (with or without the core's compensator),
//! noise.
//!
//! Glossary:
//! - *scale position*: where the drive puts the carriage according to its own scale; without
//!   compensation it is the target (in whole counts), with compensation it is the target minus the
//!   core's correction.
//! - *reached position*: scale position + true deviation there; *deviation* = reached − target.
//! - *feed*: the periodic temperature readings handed to the compensator (every
//!   [`SENSOR_PERIOD_MS`]).

use rand::SeedableRng;
use rand::rngs::StdRng;

use crate::axis::{Axis, AxisError};
use crate::campaign::{Campaign, Row, Truth};
use crate::effects::Conditions;
use crate::plan::{Plan, Sample};
use crate::thermal::ThermalState;

/// Period at which the simulated drive hands temperature readings to a compensator: images built for
/// the twin use `sensor_period_ms = SENSOR_PERIOD_MS`.
pub const SENSOR_PERIOD_MS: u32 = 1000;

/// What can go wrong before a simulation starts.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    #[error("invalid axis: {0}")]
    Axis(#[from] AxisError),
    #[error("the plan has no samples")]
    EmptyPlan,
    #[error("plan sample {index} is not usable: {why}")]
    Sample { index: usize, why: &'static str },
}

/// How the drive turns a commanded target into a scale position.
pub(crate) trait Drive {
    /// Called at every integration step of the temperatures (≤ 1 s apart).
    fn on_thermal_step(
        &mut self,
        _st: &ThermalState,
        _readings: &mut dyn FnMut(&ThermalState) -> [f64; 3],
    ) {
    }
    /// Moves to the sample's target and returns (scale position in counts, applied correction in µm).
    fn position(&mut self, axis: &Axis, sample: &Sample, measured_force_n: f64) -> (i64, f64);
}

/// No compensation: the scale settles on the target (rounded to counts).
pub(crate) struct OpenLoop;

impl Drive for OpenLoop {
    fn position(&mut self, axis: &Axis, sample: &Sample, _force: f64) -> (i64, f64) {
        (axis.counts(sample.target_mm), 0.0)
    }
}

use axcomp_numeric::noise::gauss;

/// Runs `plan` on `axis` with `drive`. The measurement noise is drawn from a generator seeded by
/// `seed` in row order (so the same seed gives the same noise whatever the effects' amplitudes);
/// the compensator's sensor feed uses a second, independent stream.
pub(crate) fn run(
    axis: &Axis,
    plan: &Plan,
    drive: &mut dyn Drive,
    seed: u64,
    compensated: bool,
) -> Result<Campaign, SimError> {
    axis.validate()?;
    let samples = plan.samples();
    if samples.is_empty() {
        return Err(SimError::EmptyPlan);
    }
    let mut last_t = f64::NEG_INFINITY;
    for (index, s) in samples.iter().enumerate() {
        let finite = [
            s.target_mm,
            s.time_s,
            s.velocity_mm_s,
            s.accel_mm_s2,
            s.force_n,
            s.offset_mm,
        ]
        .iter()
        .all(|v| v.is_finite());
        if !finite {
            return Err(SimError::Sample {
                index,
                why: "a value is not finite",
            });
        }
        if s.time_s < last_t || s.time_s < 0.0 {
            return Err(SimError::Sample {
                index,
                why: "time runs backwards or is negative",
            });
        }
        last_t = s.time_s;
    }

    let env = plan.environment();
    let reference: [f64; 3] = [0, 1, 2].map(|i| axis.sensors[i].reference_degc);
    let lag = [0, 1, 2].map(|i| axis.lag_tau_s(i));
    let mut thermal = ThermalState::new(reference, lag, env);
    let mut rng = StdRng::seed_from_u64(seed);
    let mut feed_rng = StdRng::seed_from_u64(seed ^ 0x5eed_feed_0f7e_a5e5);
    let sigma_t = axis.noise.temperature_degc;
    let mut readings = |st: &ThermalState| st.temps_degc.map(|t| t + gauss(&mut feed_rng, sigma_t));

    let mut rows = Vec::with_capacity(samples.len());
    let mut truth = Vec::with_capacity(samples.len());
    for s in &samples {
        thermal.advance_to(s.time_s, &axis.thermal, env, |st| {
            drive.on_thermal_step(st, &mut readings)
        });
        let cond = Conditions {
            time_s: s.time_s,
            temps_degc: thermal.temps_degc.to_vec(),
            lagged_degc: thermal.lagged_degc.to_vec(),
            force_n: s.force_n,
            velocity_mm_s: s.velocity_mm_s,
            accel_mm_s2: s.accel_mm_s2,
            offset_mm: s.offset_mm,
        };
        // Readings first (fixed order of draws per row: deviation, temperatures, force).
        let deviation_noise = gauss(&mut rng, axis.noise.deviation_um);
        let temps: Vec<f64> = cond
            .temps_degc
            .iter()
            .map(|t| t + gauss(&mut rng, sigma_t))
            .collect();
        let force_n = if s.force_n != 0.0 {
            s.force_n + gauss(&mut rng, axis.noise.force_n)
        } else {
            0.0
        };

        let (scale_counts, correction_um) = drive.position(axis, s, force_n);
        let scale_mm = axis.mm(scale_counts);
        let contributions_um = axis.contributions_um(scale_mm, s.direction, &cond);
        let true_dev = (scale_mm - s.target_mm) * 1e3 + contributions_um.iter().sum::<f64>();
        rows.push(Row {
            target_mm: s.target_mm,
            deviation_um: true_dev + deviation_noise,
            run: s.run,
            direction: s.direction,
            time_s: s.time_s,
            temps_degc: temps,
            force_n,
            velocity_mm_s: s.velocity_mm_s,
            accel_mm_s2: s.accel_mm_s2,
            offset_mm: s.offset_mm,
        });
        truth.push(Truth {
            deviation_um: true_dev,
            scale_mm,
            correction_um,
            contributions_um,
            conditions: cond,
        });
    }
    Ok(Campaign {
        axis_name: axis.name.clone(),
        plan: plan.name().to_owned(),
        seed,
        compensated,
        sensor_names: axis.sensors.iter().map(|s| s.name.clone()).collect(),
        rows,
        truth,
        extra_columns: Vec::new(),
    })
}
