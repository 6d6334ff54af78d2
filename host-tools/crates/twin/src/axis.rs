//! The simulated axis: stroke, scale, sensors, thermal behaviour, noise and the effects that make up
//! its true deviation.
//!
//! Glossary:
//! - *stroke*: `start_mm..=end_mm`, the measured range.
//! - *scale counts*: the axis' position scale reads `round(x_mm·1000 / scale_um_per_count)`, zero at
//!   0 mm (this is the count space of the core's tables: `start_counts`, `segment_counts`).
//! - *truth*: the noise-free deviation, the sum of the effects' contributions.

use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::effects::{Conditions, Effect, EffectKind, Layout, Point};
use crate::thermal::{self, ThermalModel};

/// A temperature sensor on the axis. Its CSV column is `<name>_degC`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sensor {
    pub name: String,
    /// ΔT is measured from here.
    pub reference_degc: f64,
}

/// Measurement and sensor noise (Gaussian, standard deviations).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Noise {
    /// On the measured deviation (laser interferometer, repeatability of the axis).
    pub deviation_um: f64,
    /// On each temperature reading.
    pub temperature_degc: f64,
    /// On the force reading.
    pub force_n: f64,
}

impl Default for Noise {
    fn default() -> Self {
        Noise {
            deviation_um: 0.5,
            temperature_degc: 0.02,
            force_n: 1.0,
        }
    }
}

/// What is wrong with an axis description.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AxisError {
    #[error("axis stroke {start_mm}..{end_mm} mm is empty or not finite")]
    Stroke { start_mm: f64, end_mm: f64 },
    #[error("scale resolution {0} µm/count must be positive and finite")]
    Resolution(f64),
    #[error("the twin has exactly {expected} sensors (ambient, motor, scale), got {got}")]
    SensorCount { expected: usize, got: usize },
    #[error("effect `{kind}` reads sensor {sensor}, but the axis has only {count} sensors")]
    SensorIndex {
        kind: EffectKind,
        sensor: usize,
        count: usize,
    },
    #[error("effect `{kind}` appears twice; give each kind once")]
    DuplicateEffect { kind: EffectKind },
    #[error("`thermal_lag` has two terms on sensor {sensor}; give one term (one τ) per sensor")]
    DuplicateLag { sensor: usize },
    #[error("effect `{kind}`: parameter `{param}` = {value} is out of range ({why})")]
    Parameter {
        kind: EffectKind,
        param: &'static str,
        value: f64,
        why: &'static str,
    },
    #[error("noise σ `{param}` = {value} must be finite and ≥ 0")]
    Noise { param: &'static str, value: f64 },
}

/// A simulated linear axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Axis {
    pub name: String,
    pub start_mm: f64,
    pub end_mm: f64,
    /// Scale resolution.
    pub scale_um_per_count: f64,
    /// The temperatures the twin measures: ambient, motor, scale (see [`crate::thermal`]).
    pub sensors: Vec<Sensor>,
    pub thermal: ThermalModel,
    pub noise: Noise,
    /// The effects, each kind at most once.
    pub effects: Vec<Effect>,
}

impl Axis {
    /// A bare axis of the given stroke with no effects: 0.05 µm scale, default sensors, thermal model
    /// and noise.
    pub fn bare(name: &str, start_mm: f64, end_mm: f64) -> Axis {
        Axis {
            name: name.to_owned(),
            start_mm,
            end_mm,
            scale_um_per_count: 0.05,
            sensors: thermal::SENSOR_NAMES
                .iter()
                .map(|n| Sensor {
                    name: (*n).to_owned(),
                    reference_degc: 20.0,
                })
                .collect(),
            thermal: ThermalModel::default(),
            noise: Noise::default(),
            effects: Vec::new(),
        }
    }

    /// A 200 mm linear-motor axis modelled on the one of the linear-motor article (seed 002: 200 mm
    /// stroke, laser-interferometer ISO runs; the parameters here are typical values, not its data):
    /// pitch error plus cogging about 10 µm peak to peak (8 µm slope, 6 and 2 µm waves), 4 µm
    /// reversal, 1.2 µm cogging at 32 mm, 0.15 µm interpolation error at 20 µm, a little scale
    /// expansion (10 µm/(m·K)); noise σ 0.5 µm; 0.05 µm scale resolution.
    pub fn linear_motor_demo() -> Axis {
        Axis::typical(
            "linear_motor_demo",
            0.0,
            200.0,
            &[
                EffectKind::PitchError,
                EffectKind::Reversal,
                EffectKind::Cogging,
                EffectKind::InterpolationError,
                EffectKind::ScaleExpansion,
            ],
        )
    }

    /// An axis with the documented typical parameters ([`Effect::typical`]) of each kind.
    pub fn typical(name: &str, start_mm: f64, end_mm: f64, kinds: &[EffectKind]) -> Axis {
        let axis = Axis::bare(name, start_mm, end_mm);
        let layout = axis.layout();
        axis.with_effects(kinds.iter().map(|&k| Effect::typical(k, &layout)).collect())
    }

    /// A 0–200 mm axis with random plausible parameters ([`Effect::random`]) for each kind.
    pub fn random<R: Rng + ?Sized>(kinds: &[EffectKind], rng: &mut R) -> Axis {
        let axis = Axis::bare("random", 0.0, 200.0);
        let layout = axis.layout();
        axis.with_effects(
            kinds
                .iter()
                .map(|&k| Effect::random(k, &layout, rng))
                .collect(),
        )
    }

    /// An axis on `start_mm..end_mm` with random plausible parameters for each kind, drawn from a
    /// generator seeded with `seed` (same seed → same axis).
    pub fn random_seeded(
        name: &str,
        start_mm: f64,
        end_mm: f64,
        kinds: &[EffectKind],
        seed: u64,
    ) -> Axis {
        let mut rng = <rand::rngs::StdRng as rand::SeedableRng>::seed_from_u64(seed);
        let axis = Axis::bare(name, start_mm, end_mm);
        let layout = axis.layout();
        axis.with_effects(
            kinds
                .iter()
                .map(|&k| Effect::random(k, &layout, &mut rng))
                .collect(),
        )
    }

    /// Replaces the effects.
    pub fn with_effects(mut self, effects: Vec<Effect>) -> Axis {
        self.effects = effects;
        self
    }

    /// Sets the measurement noise σ on the deviation.
    pub fn with_noise_um(mut self, sigma_um: f64) -> Axis {
        self.noise.deviation_um = sigma_um;
        self
    }

    /// Where the stroke is and which sensor is which (for drawing parameters).
    pub fn layout(&self) -> Layout {
        Layout {
            start_mm: self.start_mm,
            end_mm: self.end_mm,
            ambient_sensor: thermal::AMBIENT,
            motor_sensor: thermal::MOTOR,
            scale_sensor: thermal::SCALE,
        }
    }

    /// Checks everything the simulator relies on.
    pub fn validate(&self) -> Result<(), AxisError> {
        if !(self.start_mm.is_finite() && self.end_mm.is_finite() && self.end_mm > self.start_mm) {
            return Err(AxisError::Stroke {
                start_mm: self.start_mm,
                end_mm: self.end_mm,
            });
        }
        if !(self.scale_um_per_count.is_finite() && self.scale_um_per_count > 0.0) {
            return Err(AxisError::Resolution(self.scale_um_per_count));
        }
        if self.sensors.len() != thermal::SENSOR_NAMES.len() {
            return Err(AxisError::SensorCount {
                expected: thermal::SENSOR_NAMES.len(),
                got: self.sensors.len(),
            });
        }
        for (param, value) in [
            ("deviation_um", self.noise.deviation_um),
            ("temperature_degc", self.noise.temperature_degc),
            ("force_n", self.noise.force_n),
        ] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(AxisError::Noise { param, value });
            }
        }
        let mut seen = [false; EffectKind::COUNT];
        for effect in &self.effects {
            let kind = effect.kind();
            if std::mem::replace(&mut seen[kind.index()], true) {
                return Err(AxisError::DuplicateEffect { kind });
            }
            for sensor in effect.sensors() {
                if sensor >= self.sensors.len() {
                    return Err(AxisError::SensorIndex {
                        kind,
                        sensor,
                        count: self.sensors.len(),
                    });
                }
            }
            let positive = |param: &'static str, value: f64| {
                if value.is_finite() && value > 0.0 {
                    Ok(())
                } else {
                    Err(AxisError::Parameter {
                        kind,
                        param,
                        value,
                        why: "must be > 0",
                    })
                }
            };
            match effect {
                Effect::PitchError(e) => e
                    .waves
                    .iter()
                    .try_for_each(|w| positive("wavelength_mm", w.wavelength_mm))?,
                Effect::Cogging(e) => positive("period_mm", e.period_mm)?,
                Effect::InterpolationError(e) => positive("signal_period_um", e.signal_period_um)?,
                Effect::EndEffect(e) => positive("decay_mm", e.decay_mm)?,
                Effect::ThermalLag(e) => {
                    let mut lagged = [false; 3];
                    for t in &e.terms {
                        positive("tau_s", t.tau_s)?;
                        if std::mem::replace(&mut lagged[t.sensor], true) {
                            return Err(AxisError::DuplicateLag { sensor: t.sensor });
                        }
                    }
                }
                _ => {}
            }
        }
        Ok(())
    }

    /// Reference temperature of each sensor.
    pub fn reference_degc(&self) -> Vec<f64> {
        self.sensors.iter().map(|s| s.reference_degc).collect()
    }

    /// The `thermal_lag` time constant on `sensor`, if any.
    pub fn lag_tau_s(&self, sensor: usize) -> Option<f64> {
        self.effects.iter().find_map(|e| match e {
            Effect::ThermalLag(l) => l.terms.iter().find(|t| t.sensor == sensor).map(|t| t.tau_s),
            _ => None,
        })
    }

    /// Kinds present, in the axis' order.
    pub fn kinds(&self) -> Vec<EffectKind> {
        self.effects.iter().map(Effect::kind).collect()
    }

    /// The effect of `kind`, if present.
    pub fn effect(&self, kind: EffectKind) -> Option<&Effect> {
        self.effects.iter().find(|e| e.kind() == kind)
    }

    /// The effect of `kind`, if present, for changing its parameters.
    pub fn effect_mut(&mut self, kind: EffectKind) -> Option<&mut Effect> {
        self.effects.iter_mut().find(|e| e.kind() == kind)
    }

    /// Scales `kind`'s contribution by `factor` everywhere ([`Effect::scale`]); false if absent.
    /// Re-simulating with the same seed then gives the same noise: use it to set an effect's peak to
    /// k × noise σ.
    pub fn scale_effect(&mut self, kind: EffectKind, factor: f64) -> bool {
        self.effect_mut(kind).map(|e| e.scale(factor)).is_some()
    }

    /// Noise-free deviation at scale position `x_mm`, approached in `direction`, under `cond`.
    pub fn true_deviation_um(&self, x_mm: f64, direction: i8, cond: &Conditions) -> f64 {
        let reference = self.reference_degc();
        let p = Point {
            x_mm,
            direction,
            cond,
            reference_degc: &reference,
        };
        self.effects.iter().map(|e| e.contribution_um(&p)).sum()
    }

    /// Contribution of `kind` alone (0 when the axis has no such effect).
    pub fn effect_contribution_um(
        &self,
        kind: EffectKind,
        x_mm: f64,
        direction: i8,
        cond: &Conditions,
    ) -> f64 {
        let reference = self.reference_degc();
        let p = Point {
            x_mm,
            direction,
            cond,
            reference_degc: &reference,
        };
        self.effect(kind).map_or(0.0, |e| e.contribution_um(&p))
    }

    /// Every kind's contribution, indexed by [`EffectKind::index`].
    pub fn contributions_um(
        &self,
        x_mm: f64,
        direction: i8,
        cond: &Conditions,
    ) -> [f64; EffectKind::COUNT] {
        let reference = self.reference_degc();
        let p = Point {
            x_mm,
            direction,
            cond,
            reference_degc: &reference,
        };
        let mut out = [0.0; EffectKind::COUNT];
        for e in &self.effects {
            out[e.kind().index()] += e.contribution_um(&p);
        }
        out
    }

    /// Scale counts of a position (zero at 0 mm).
    pub fn counts(&self, x_mm: f64) -> i64 {
        (x_mm * 1e3 / self.scale_um_per_count).round() as i64
    }

    /// Position of a scale count.
    pub fn mm(&self, counts: i64) -> f64 {
        counts as f64 * self.scale_um_per_count * 1e-3
    }

    /// Reference conditions for this axis (see [`Conditions::reference`]).
    pub fn reference_conditions(&self) -> Conditions {
        Conditions::reference(&self.reference_degc())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn demo_axis_has_the_documented_magnitudes() {
        let axis = Axis::linear_motor_demo();
        axis.validate().unwrap();
        let cond = axis.reference_conditions();
        let xs: Vec<f64> = (0..=2000).map(|i| i as f64 * 0.1).collect();
        let fwd: Vec<f64> = xs
            .iter()
            .map(|&x| axis.true_deviation_um(x, 1, &cond))
            .collect();
        let bwd: Vec<f64> = xs
            .iter()
            .map(|&x| axis.true_deviation_um(x, -1, &cond))
            .collect();
        let span = fwd.iter().cloned().fold(f64::MIN, f64::max)
            - fwd.iter().cloned().fold(f64::MAX, f64::min);
        // Brief: pitch error "few-10 µm" over 200 mm → accept 5–40 µm peak to peak.
        assert!((5.0..=40.0).contains(&span), "span {span}");
        // Reversal 3–8 µm: forward − backward = lost motion + gradient·(x − centre) = 4 ± 0.5 µm.
        for (f, b) in fwd.iter().zip(&bwd) {
            assert!((3.0..=8.0).contains(&(f - b)), "{}", f - b);
        }
        assert_eq!(axis.noise.deviation_um, 0.5);
    }

    #[test]
    fn validate_names_the_problem() {
        let mut axis = Axis::linear_motor_demo();
        axis.effects.push(axis.effects[0].clone());
        assert_eq!(
            axis.validate(),
            Err(AxisError::DuplicateEffect {
                kind: EffectKind::PitchError
            })
        );
        let mut axis = Axis::typical("t", 0.0, 100.0, &[EffectKind::Cogging]);
        if let Some(Effect::Cogging(c)) = axis.effect_mut(EffectKind::Cogging) {
            c.period_mm = 0.0;
        }
        let err = axis.validate().unwrap_err();
        assert!(err.to_string().contains("period_mm"), "{err}");
        let axis = Axis::bare("t", 5.0, 5.0);
        assert!(matches!(axis.validate(), Err(AxisError::Stroke { .. })));
    }
}
