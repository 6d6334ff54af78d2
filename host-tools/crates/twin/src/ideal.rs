//! The ideal compensation of a twin axis: a table built from the known truth instead of a fit.
//!
//! Glossary:
//! - *ideal table*: cubic Hermite segments through the true positional deviation (reference
//!   conditions: only `pitch_error`, `reversal`, `cogging`, `end_effect` contribute;
//!   `interpolation_error` is left out, it is finer than any knot spacing) at uniform knots, with the true slope at each knot (central difference), one table per
//!   direction. It is the best a fitted table could do, so a compensated run with it shows the floor:
//!   measurement noise plus what the table cannot hold (interpolation error finer than the knots,
//!   count rounding).

use axcomp_core::{
    ExpansionSpec, ForceSpec, ImageError, ImageSpec, LimitSpec, OutsideStroke, SensorSpec,
    TableSpec, ThermoForceSpec, image_len, write_image,
};
use axcomp_numeric::hermite::cubic_hermite;

use crate::axis::Axis;
use crate::effects::{Effect, EffectKind};
use crate::sim::SENSOR_PERIOD_MS;

/// Per-direction Horner segments `[c0, c1, c2, c3]` in the core's layout.
#[derive(Debug, Clone, PartialEq)]
pub struct IdealTable {
    pub start_counts: i64,
    pub segment_counts: u32,
    pub forward: Vec<[f32; 4]>,
    pub backward: Vec<[f32; 4]>,
}

/// Limits used by [`IdealTable::image`]: ±200 µm, 1 µm per cycle, 1 µm direction hysteresis.
pub fn default_limits(axis: &Axis) -> LimitSpec {
    LimitSpec {
        max_correction_um: 200.0,
        max_slew_um_per_cycle: 1.0,
        direction_hysteresis_counts: (1.0 / axis.scale_um_per_count).ceil() as u32,
    }
}

impl IdealTable {
    /// The table over the axis' stroke with knots about `segment_mm` apart (whole counts; at most
    /// `axcomp_core::MAX_SEGMENTS` segments, widened if needed).
    pub fn new(axis: &Axis, segment_mm: f64) -> IdealTable {
        let start_counts = axis.counts(axis.start_mm);
        let end_counts = axis.counts(axis.end_mm);
        let span = (end_counts - start_counts).max(1);
        let mut segment_counts = axis.counts(segment_mm).max(1);
        let max = axcomp_core::MAX_SEGMENTS as i64;
        if (span + segment_counts - 1) / segment_counts > max {
            segment_counts = (span + max - 1) / max;
        }
        let n = ((span + segment_counts - 1) / segment_counts) as usize;
        let cond = axis.reference_conditions();
        // The interpolation error (µm period) is far finer than any knot spacing: a table cannot hold
        // it, and sampling it would only alias it into the segments.
        let mut smooth = axis.clone();
        smooth
            .effects
            .retain(|e| e.kind() != EffectKind::InterpolationError);
        let axis = &smooth;
        let h_mm = axis.mm(segment_counts);
        let d_mm = (h_mm * 1e-3).max(axis.mm(1));
        let table = |direction: i8| -> Vec<[f32; 4]> {
            let f = |x: f64| axis.true_deviation_um(x, direction, &cond);
            let slope = |x: f64| (f(x + d_mm) - f(x - d_mm)) / (2.0 * d_mm);
            (0..n)
                .map(|k| {
                    let x0 = axis.mm(start_counts + k as i64 * segment_counts);
                    let x1 = x0 + h_mm;
                    let (y0, y1) = (f(x0), f(x1));
                    cubic_hermite(y0, slope(x0) * h_mm, y1, slope(x1) * h_mm).map(|c| c as f32)
                })
                .collect()
        };
        IdealTable {
            start_counts,
            segment_counts: segment_counts as u32,
            forward: table(1),
            backward: table(-1),
        }
    }

    /// A firmware image holding only this table (32-bit counter, `OutsideStroke::Hold`, limits from
    /// [`default_limits`]).
    pub fn image(&self, axis: &Axis) -> Result<Vec<u8>, ImageError> {
        let spec = ImageSpec {
            axis_id: 1,
            um_per_count: axis.scale_um_per_count as f32,
            counter_bits: 32,
            table: Some(TableSpec {
                start_counts: self.start_counts,
                segment_counts: self.segment_counts,
                forward: &self.forward,
                backward: &self.backward,
                outside: OutsideStroke::Hold,
            }),
            thermo: None,
            limits: default_limits(axis),
        };
        let mut buf = vec![0u8; image_len(&spec)];
        let n = write_image(&spec, &mut buf)?;
        buf.truncate(n);
        Ok(buf)
    }
}

/// The ideal thermo-force term of an axis, in the core's form, built from its effects:
/// `thermal_drift` terms as unlagged sensor coefficients, `thermal_lag` terms as lagged ones (a sensor
/// that has both keeps only its drift term: the core holds one coefficient and one τ per sensor),
/// `scale_expansion` as the expansion term, `force_deflection` as one measured force term (force
/// index 0, which the twin's drive feeds). `None` when the axis has none of these. `time_drift`,
/// `following_error` and `abbe` have no place in the core's model and are left out.
#[derive(Debug, Clone, PartialEq)]
pub struct IdealThermo {
    pub sensors: Vec<SensorSpec>,
    pub b_um_per_k: Vec<f32>,
    pub expansion: Option<ExpansionSpec>,
    pub forces: Vec<ForceSpec>,
}

impl IdealThermo {
    /// See the type's documentation.
    pub fn new(axis: &Axis) -> Option<IdealThermo> {
        let n = axis.sensors.len();
        let mut b = vec![0.0f32; n];
        let mut tau = vec![0.0f32; n];
        let mut expansion = None;
        let mut forces = Vec::new();
        for effect in &axis.effects {
            match effect {
                Effect::ThermalLag(l) => {
                    for t in &l.terms {
                        b[t.sensor] = t.um_per_k as f32;
                        tau[t.sensor] = t.tau_s as f32;
                    }
                }
                Effect::ScaleExpansion(e) => {
                    expansion = Some(ExpansionSpec {
                        sensor: e.sensor as u8,
                        x_ref_counts: axis.counts(e.x_ref_mm),
                        c_um_per_mm_k: (e.um_per_m_k * 1e-3) as f32,
                    })
                }
                Effect::ForceDeflection(f) => forces.push(ForceSpec {
                    chi_um_per_n: f.um_per_n as f32,
                    law: None,
                }),
                _ => {}
            }
        }
        // Drift terms last: they win over a lag term on the same sensor.
        for effect in &axis.effects {
            if let Effect::ThermalDrift(d) = effect {
                for t in &d.terms {
                    b[t.sensor] = t.um_per_k as f32;
                    tau[t.sensor] = 0.0;
                }
            }
        }
        if b.iter().all(|&v| v == 0.0) && expansion.is_none() && forces.is_empty() {
            return None;
        }
        let sensors = axis
            .sensors
            .iter()
            .zip(&tau)
            .map(|(s, &lag_tau_s)| SensorSpec {
                reference_degc: s.reference_degc as f32,
                min_degc: -40.0,
                max_degc: 150.0,
                max_rate_degc_per_s: 5.0,
                lag_tau_s,
                stale_timeout_ms: 10 * SENSOR_PERIOD_MS,
            })
            .collect();
        Some(IdealThermo {
            sensors,
            b_um_per_k: b,
            expansion,
            forces,
        })
    }

    /// The core's view, borrowing from `self`.
    pub fn spec(&self) -> ThermoForceSpec<'_> {
        ThermoForceSpec {
            sensor_period_ms: SENSOR_PERIOD_MS,
            sensors: &self.sensors,
            b0_um: 0.0,
            b_um_per_k: &self.b_um_per_k,
            expansion: self.expansion,
            forces: &self.forces,
            reference: axcomp_core::ThermoReference::Fixed,
            rise_bounds_k: &[],
        }
    }
}

/// A firmware image with the ideal table (knots about `segment_mm` apart; left out when the axis has
/// no positional effect) and the ideal thermo-force term ([`IdealThermo`]): the best compensation the
/// core can hold for this axis.
pub fn ideal_image(axis: &Axis, segment_mm: f64) -> Result<Vec<u8>, ImageError> {
    let positional = axis.effects.iter().any(|e| {
        matches!(
            e.kind(),
            EffectKind::PitchError
                | EffectKind::Reversal
                | EffectKind::Cogging
                | EffectKind::EndEffect
        )
    });
    let table = positional.then(|| IdealTable::new(axis, segment_mm));
    let thermo = IdealThermo::new(axis);
    let spec = ImageSpec {
        axis_id: 1,
        um_per_count: axis.scale_um_per_count as f32,
        counter_bits: 32,
        table: table.as_ref().map(|t| TableSpec {
            start_counts: t.start_counts,
            segment_counts: t.segment_counts,
            forward: &t.forward,
            backward: &t.backward,
            outside: OutsideStroke::Hold,
        }),
        thermo: thermo.as_ref().map(IdealThermo::spec),
        limits: default_limits(axis),
    };
    let mut buf = vec![0u8; image_len(&spec)];
    let n = write_image(&spec, &mut buf)?;
    buf.truncate(n);
    Ok(buf)
}
