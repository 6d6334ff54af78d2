//! Thermo-force campaigns under machining load, from `axcomp-thermal`'s synthetic generator
//! (`crate::synth`): the twin holds the axis at one target while a spindle runs through
//! heating/cooling phases at several speeds, cuts with a force from the power law
//! `F = K·ap^x·fz^y·n^z`, and 16 strongly collinear temperature sensors (`s01` … `s16`) follow hidden
//! heat sources.
//!
//! Glossary:
//! - *condition*: one spindle speed with its depth of cut `ap` and feed per tooth `fz`; each runs a
//!   heating phase (cutting) then a cooling phase. The CSV's `run` is the condition number (from 1).
//! - *synth truth*: the generator's error model `b0 + Σ b_k·(lag(T_k, τ_k) − T_k(0)) + χ·F` over a few
//!   true sensors ([`axcomp_effects::thermal_model::ThermalModel`]).
//! - *positional part*: the axis' `pitch_error`, `reversal`, `cogging`, `interpolation_error` and
//!   `end_effect` at the held target (constant over the campaign).
//!
//! The axis' own thermal, force, time, speed and Abbe effects are *not* applied here: the generator's
//! truth takes their place. In the [`Truth`] rows the generator's terms are booked as `thermal_lag`
//! (terms with τ > 0), `thermal_drift` (b0 and terms with τ = 0) and `force_deflection` (χ·F), and
//! `conditions.temps_degc` holds the 16 noise-free sensor temperatures (not the axis' three).

use crate::synth::{SynthConfig, generate};
use axcomp_effects::thermal_model::ThermalModel;
use axcomp_numeric::lag::lag;

use crate::axis::Axis;
use crate::campaign::{Campaign, ExtraColumn, Row, Truth};
use crate::effects::{Conditions, EffectKind};
use crate::sim::SimError;

/// A spindle campaign and the generator's truth model.
#[derive(Debug, Clone)]
pub struct SpindleCampaign {
    pub campaign: Campaign,
    pub truth_model: ThermalModel,
}

/// The generator's settings for a campaign of about `rows` rows (sample interval stretched or shrunk),
/// seeded with `seed`, with the axis' measurement noise σ on the error.
pub fn spindle_config(axis: &Axis, seed: u64, rows: Option<usize>) -> SynthConfig {
    let mut cfg = SynthConfig {
        seed,
        error_noise_um: axis.noise.deviation_um,
        ..SynthConfig::default()
    };
    if let Some(rows) = rows {
        let duration = cfg.speeds_rpm.len() as f64 * (cfg.heat_s + cfg.cool_s);
        cfg.dt_s = duration / rows.max(2) as f64;
    }
    cfg
}

/// Runs the generator with `cfg` and holds `axis` at `target_mm` (approached in `+` direction).
pub fn simulate_spindle(
    axis: &Axis,
    target_mm: f64,
    cfg: &SynthConfig,
) -> Result<SpindleCampaign, SimError> {
    axis.validate()?;
    if !target_mm.is_finite() {
        return Err(SimError::Sample {
            index: 0,
            why: "the spindle campaign's target is not finite",
        });
    }
    if !cfg.dt_s.is_finite() || cfg.dt_s <= 0.0 || cfg.speeds_rpm.is_empty() {
        return Err(SimError::EmptyPlan);
    }
    let data = generate(cfg);
    let n = data.time_s.len();
    if n == 0 {
        return Err(SimError::EmptyPlan);
    }
    // Positional part at the held target (reference conditions: no thermal/force/speed/time terms).
    let positional = [
        EffectKind::PitchError,
        EffectKind::Reversal,
        EffectKind::Cogging,
        EffectKind::InterpolationError,
        EffectKind::EndEffect,
    ];
    let scale_mm = axis.mm(axis.counts(target_mm));
    let reference = axis.reference_conditions();
    let mut base = [0.0; EffectKind::COUNT];
    for k in positional {
        base[k.index()] = axis.effect_contribution_um(k, scale_mm, 1, &reference);
    }
    let rounding_um = (scale_mm - target_mm) * 1e3;
    let positional_um: f64 = base.iter().sum::<f64>() + rounding_um;

    // The generator's thermal terms, booked per kind; the force term is what remains of its truth.
    let mut lag_um = vec![0.0; n];
    let mut drift_um = vec![data.truth.b0_um; n];
    for term in &data.truth.terms {
        let Some(s) = data
            .sensor_names
            .iter()
            .position(|name| *name == term.sensor)
        else {
            continue;
        };
        let lagged = lag(&data.time_s, &data.sensors_true_degc[s], term.tau_s);
        let sink = if term.tau_s > 0.0 {
            &mut lag_um
        } else {
            &mut drift_um
        };
        for (o, v) in sink.iter_mut().zip(lagged) {
            *o += term.coef_um_per_k * (v - term.reference_degc);
        }
    }

    let mut rows = Vec::with_capacity(n);
    let mut truth = Vec::with_capacity(n);
    for k in 0..n {
        let force_um = data.error_true_um[k] - lag_um[k] - drift_um[k];
        let mut contributions_um = base;
        contributions_um[EffectKind::ThermalLag.index()] = lag_um[k];
        contributions_um[EffectKind::ThermalDrift.index()] = drift_um[k];
        contributions_um[EffectKind::ForceDeflection.index()] = force_um;
        let temps_true: Vec<f64> = data.sensors_true_degc.iter().map(|s| s[k]).collect();
        let force_true = if data.truth.forces.is_empty() || data.truth.forces[0].chi_um_per_n == 0.0
        {
            data.force_n[k]
        } else {
            force_um / data.truth.forces[0].chi_um_per_n
        };
        rows.push(Row {
            target_mm,
            deviation_um: positional_um + data.error_um[k],
            run: data.condition[k] as u32 + 1,
            direction: 1,
            time_s: data.time_s[k],
            temps_degc: data.sensors_degc.iter().map(|s| s[k]).collect(),
            force_n: data.force_n[k],
            velocity_mm_s: 0.0,
            accel_mm_s2: 0.0,
            offset_mm: 0.0,
        });
        truth.push(Truth {
            deviation_um: positional_um + data.error_true_um[k],
            scale_mm,
            correction_um: 0.0,
            contributions_um,
            conditions: Conditions {
                time_s: data.time_s[k],
                lagged_degc: temps_true.clone(),
                temps_degc: temps_true,
                force_n: force_true,
                velocity_mm_s: 0.0,
                accel_mm_s2: 0.0,
                offset_mm: 0.0,
            },
        });
    }
    let extra_columns = vec![
        ExtraColumn {
            name: "spindle_rpm".into(),
            decimals: 1,
            values: data.spindle_rpm.clone(),
        },
        ExtraColumn {
            name: "ap_mm".into(),
            decimals: 3,
            values: data.ap_mm.clone(),
        },
        ExtraColumn {
            name: "fz_mm".into(),
            decimals: 4,
            values: data.fz_mm.clone(),
        },
    ];
    Ok(SpindleCampaign {
        campaign: Campaign {
            axis_name: axis.name.clone(),
            plan: "spindle".into(),
            seed: cfg.seed,
            compensated: false,
            sensor_names: data.sensor_names.clone(),
            rows,
            truth,
            extra_columns,
        },
        truth_model: data.truth,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spindle_truth_is_the_generators_plus_the_positional_part() {
        let axis = Axis::typical(
            "t",
            0.0,
            200.0,
            &[EffectKind::PitchError, EffectKind::Reversal],
        )
        .with_noise_um(0.3);
        let cfg = spindle_config(&axis, 5, Some(2000));
        let sc = simulate_spindle(&axis, 120.0, &cfg).unwrap();
        let c = &sc.campaign;
        assert!((1900..=2100).contains(&c.rows.len()), "{}", c.rows.len());
        assert_eq!(c.sensor_names.len(), 16);
        let cond = axis.reference_conditions();
        let positional = axis.true_deviation_um(c.truth[0].scale_mm, 1, &cond);
        for t in &c.truth {
            // The booked contributions add up to the truth (tolerance 1e-9 µm, rounding to counts
            // aside: 120 mm is a whole count).
            let sum: f64 = t.contributions_um.iter().sum();
            assert!((sum - t.deviation_um).abs() < 1e-9);
            assert!(
                (t.contributions_um[EffectKind::PitchError.index()]
                    + t.contributions_um[EffectKind::Reversal.index()]
                    - positional)
                    .abs()
                    < 1e-12
            );
        }
        // The force term is χ·F: zero while not cutting, positive while cutting.
        let force_k = EffectKind::ForceDeflection.index();
        let cutting: Vec<&Truth> = c
            .truth
            .iter()
            .filter(|t| t.conditions.force_n > 1.0)
            .collect();
        assert!(!cutting.is_empty());
        assert!(cutting.iter().all(|t| t.contributions_um[force_k] > 0.0));
        // Measured − truth is the noise σ 0.3 µm (2000 rows: tolerance ±15 %).
        let noise = axcomp_numeric::stats::rms(
            c.rows
                .iter()
                .zip(&c.truth)
                .map(|(r, t)| r.deviation_um - t.deviation_um),
        );
        assert!((0.255..0.345).contains(&noise), "{noise}");
        // CSV carries the process columns.
        let csv = c.to_csv_string();
        assert!(
            csv.lines()
                .nth(2)
                .unwrap()
                .ends_with(",offset_mm,spindle_rpm,ap_mm,fz_mm"),
            "{}",
            csv.lines().nth(2).unwrap()
        );
    }
}
