//! The error effects of a linear axis, one struct of physical parameters per effect.
//!
//! Glossary:
//! - *scale position* `x_mm`: where the axis' own position scale says the carriage is (what the drive
//!   controls). Every effect is evaluated there.
//! - *deviation*: position actually reached minus target, in µm (ISO 230-2). An effect's *contribution* is
//!   its share of the deviation.
//! - *direction*: approach direction, `+1` or `-1`.
//! - *ΔT*: a sensor's true temperature minus its reference temperature ([`crate::Sensor::reference_degc`]).
//! - *lagged temperature*: a sensor's temperature passed through the first-order lag (time constant τ)
//!   of a [`ThermalLag`] term; the simulator integrates it over the campaign's history.
//!
//! Typical magnitudes (used by [`Effect::typical`] and the ranges drawn by [`Effect::random`]):
//!
//! | kind | parameters | typical | random range |
//! |---|---|---|---|
//! | `pitch_error` | slope, sinusoids along the stroke | 5–30 µm over 200 mm | slope ±40 µm/m, 2 waves of 1–8 µm, λ 0.5–2× stroke |
//! | `reversal` | lost motion + gradient | 2–8 µm (linear motor), 5–20 µm (ball screw) | 2–8 µm, ±10 µm/m |
//! | `scale_expansion` | expansion coefficient of scale vs. workpiece | 10–12 µm/(m·K) steel, 8 glass | 8–12 µm/(m·K) |
//! | `thermal_drift` | µm per K of a sensor's rise | 0.5–3 µm/K | 0.5–3 µm/K (either sign) |
//! | `thermal_lag` | µm per K through lag τ | 1–4 µm/K, τ 10–60 min | 1–4 µm/K, τ 600–3600 s |
//! | `force_deflection` | compliance | 0.005–0.03 µm/N (stiffness 30–200 N/µm) | 0.005–0.03 µm/N |
//! | `cogging` | motor magnet period, amplitude | period 5–60 mm, 0.5–3 µm | same |
//! | `interpolation_error` | scale signal period, amplitude | 20 µm period, 0.05–0.3 µm | period 4/20/40 µm, 0.05–0.3 µm |
//! | `end_effect` | amplitude, decay length, direction asymmetry | 1–5 µm over 3–15 mm | same, either end, either sign |
//! | `following_error` | µm per mm/s, µm per mm/s² | 1–5 µm at 100 mm/s | 0.01–0.05 µm/(mm/s), 0.0005–0.002 µm/(mm/s²) |
//! | `abbe` | pitch/yaw angle along the stroke × offset | 5–40 µrad, ±50 µrad/m | same |
//! | `time_drift` | linear drift + settling | 0.2–2 µm/h | 0.2–2 µm/h (either sign), settle 0–2 µm, τ 600–3600 s |

use core::f64::consts::TAU;

use rand::Rng;
use serde::{Deserialize, Serialize};

pub use axcomp_effects::{EffectKind, UnknownEffect};

/// The conditions under which the axis sits at a point: what the effects other than the purely
/// positional ones depend on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Conditions {
    /// Time since the start of the campaign.
    pub time_s: f64,
    /// True temperature at each sensor location, in the order of [`crate::Axis::sensors`].
    pub temps_degc: Vec<f64>,
    /// Each sensor's temperature after the first-order lag of its [`ThermalLag`] term (equal to
    /// `temps_degc` for sensors without one, and in steady state).
    pub lagged_degc: Vec<f64>,
    /// Axis load (process force) along the axis.
    pub force_n: f64,
    /// Axis velocity while measuring (signed; 0 for a point approached and held).
    pub velocity_mm_s: f64,
    /// Axis acceleration while measuring (signed).
    pub accel_mm_s2: f64,
    /// Abbe offset of the measuring point.
    pub offset_mm: f64,
}

impl Conditions {
    /// Reference conditions: time 0, every sensor at `reference_degc`, no load, at rest, no Abbe
    /// offset. Under these only the positional effects contribute.
    pub fn reference(reference_degc: &[f64]) -> Conditions {
        Conditions {
            time_s: 0.0,
            temps_degc: reference_degc.to_vec(),
            lagged_degc: reference_degc.to_vec(),
            force_n: 0.0,
            velocity_mm_s: 0.0,
            accel_mm_s2: 0.0,
            offset_mm: 0.0,
        }
    }
}

/// Everything an effect needs besides its own parameters.
#[derive(Debug, Clone, Copy)]
pub struct Point<'a> {
    /// Scale position.
    pub x_mm: f64,
    /// Approach direction, `+1` or `-1` (0 is treated as `+1`).
    pub direction: i8,
    pub cond: &'a Conditions,
    /// Reference temperature of each sensor.
    pub reference_degc: &'a [f64],
}

impl Point<'_> {
    fn sign(&self) -> f64 {
        if self.direction < 0 { -1.0 } else { 1.0 }
    }
    fn delta_t(&self, sensor: usize) -> f64 {
        self.cond.temps_degc[sensor] - self.reference_degc[sensor]
    }
    fn lagged_delta_t(&self, sensor: usize) -> f64 {
        self.cond.lagged_degc[sensor] - self.reference_degc[sensor]
    }
}

/// One sinusoid `amplitude · sin(2π (x − origin)/wavelength + phase)`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Wave {
    pub amplitude_um: f64,
    pub wavelength_mm: f64,
    pub phase_rad: f64,
}

impl Wave {
    fn eval(&self, u_mm: f64) -> f64 {
        self.amplitude_um * (TAU * u_mm / self.wavelength_mm + self.phase_rad).sin()
    }
}

/// `pitch_error`: smooth error along the stroke, `slope·(x − origin) + Σ waves(x − origin)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PitchError {
    pub origin_mm: f64,
    pub slope_um_per_m: f64,
    pub waves: Vec<Wave>,
}

/// `reversal`: `direction · ½·(lost_motion + gradient·(x − centre))`, so that the bidirectional
/// difference (forward minus backward) is `lost_motion + gradient·(x − centre)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Reversal {
    pub lost_motion_um: f64,
    pub gradient_um_per_m: f64,
    pub centre_mm: f64,
}

/// `scale_expansion`: `coefficient·(x − x_ref)·ΔT_sensor` with the coefficient in µm/(m·K) (the
/// mismatch between scale/structure expansion and the workpiece at reference temperature).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScaleExpansion {
    pub sensor: usize,
    pub um_per_m_k: f64,
    pub x_ref_mm: f64,
}

/// One term `um_per_k · ΔT_sensor`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DriftTerm {
    pub sensor: usize,
    pub um_per_k: f64,
}

/// `thermal_drift`: position-independent `Σ b_i·ΔT_i` of the instantaneous temperature rises.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ThermalDrift {
    pub terms: Vec<DriftTerm>,
}

/// One term `um_per_k · ΔT_lagged,sensor` with first-order lag time constant `tau_s`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LagTerm {
    pub sensor: usize,
    pub um_per_k: f64,
    pub tau_s: f64,
}

/// `thermal_lag`: like `thermal_drift`, through a first-order lag per sensor (at most one term per
/// sensor).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ThermalLag {
    pub terms: Vec<LagTerm>,
}

/// `force_deflection`: `compliance · force` (the axis yields under load).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ForceDeflection {
    pub um_per_n: f64,
}

/// `cogging`: periodic error with the motor's magnet period, `a1·sin(2πx/p + φ) + a2·sin(4πx/p + φ2)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Cogging {
    pub period_mm: f64,
    pub amplitude_um: f64,
    pub phase_rad: f64,
    pub harmonic2_um: f64,
    pub harmonic2_phase_rad: f64,
}

/// `interpolation_error`: periodic error with the scale's signal period (µm), `a·sin(2π·x/period + φ)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InterpolationError {
    pub signal_period_um: f64,
    pub amplitude_um: f64,
    pub phase_rad: f64,
}

/// `end_effect`: `a·exp(−|x − end|/decay)·(1 + asymmetry·direction)`, localised at one stroke end.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EndEffect {
    /// Position of the stroke end the effect sits at.
    pub end_mm: f64,
    pub amplitude_um: f64,
    pub decay_mm: f64,
    /// 0 = same for both directions; 1 = only when approaching in `+` direction; −1 = only in `−`.
    pub direction_asymmetry: f64,
}

/// `following_error`: the carriage trails its command while moving, `−(kv·v + ka·a)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FollowingError {
    pub um_per_mm_s: f64,
    pub um_per_mm_s2: f64,
}

/// `abbe`: `offset · θ(x)` with the angular error `θ = angle + gradient·(x − centre)` in µrad
/// (1 mm · 1 µrad = 0.001 µm).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Abbe {
    pub angle_urad: f64,
    pub gradient_urad_per_m: f64,
    pub centre_mm: f64,
}

/// `time_drift`: drift that temperatures do not explain, `rate·t + settle·(1 − exp(−t/τ))`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TimeDrift {
    pub um_per_h: f64,
    pub settle_um: f64,
    pub settle_tau_s: f64,
}

/// One effect with its parameters. Serialised as `{"kind": "<contract name>", <parameters>}`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Effect {
    PitchError(PitchError),
    Reversal(Reversal),
    ScaleExpansion(ScaleExpansion),
    ThermalDrift(ThermalDrift),
    ThermalLag(ThermalLag),
    ForceDeflection(ForceDeflection),
    Cogging(Cogging),
    InterpolationError(InterpolationError),
    EndEffect(EndEffect),
    FollowingError(FollowingError),
    Abbe(Abbe),
    TimeDrift(TimeDrift),
}

/// The layout an effect's typical / random parameters are drawn for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Layout {
    pub start_mm: f64,
    pub end_mm: f64,
    /// Sensor index of the ambient air, the motor (heat source) and the scale/structure.
    pub ambient_sensor: usize,
    pub motor_sensor: usize,
    pub scale_sensor: usize,
}

impl Layout {
    fn length_mm(&self) -> f64 {
        self.end_mm - self.start_mm
    }
    fn centre_mm(&self) -> f64 {
        0.5 * (self.start_mm + self.end_mm)
    }
}

fn signed<R: Rng + ?Sized>(rng: &mut R, lo: f64, hi: f64) -> f64 {
    let v = rng.gen_range(lo..=hi);
    if rng.gen_bool(0.5) { v } else { -v }
}

impl Effect {
    /// Which kind this is.
    pub fn kind(&self) -> EffectKind {
        match self {
            Effect::PitchError(_) => EffectKind::PitchError,
            Effect::Reversal(_) => EffectKind::Reversal,
            Effect::ScaleExpansion(_) => EffectKind::ScaleExpansion,
            Effect::ThermalDrift(_) => EffectKind::ThermalDrift,
            Effect::ThermalLag(_) => EffectKind::ThermalLag,
            Effect::ForceDeflection(_) => EffectKind::ForceDeflection,
            Effect::Cogging(_) => EffectKind::Cogging,
            Effect::InterpolationError(_) => EffectKind::InterpolationError,
            Effect::EndEffect(_) => EffectKind::EndEffect,
            Effect::FollowingError(_) => EffectKind::FollowingError,
            Effect::Abbe(_) => EffectKind::Abbe,
            Effect::TimeDrift(_) => EffectKind::TimeDrift,
        }
    }

    /// This effect's contribution to the deviation at `p`, in µm.
    pub fn contribution_um(&self, p: &Point<'_>) -> f64 {
        let x = p.x_mm;
        let c = p.cond;
        match self {
            Effect::PitchError(e) => {
                let u = x - e.origin_mm;
                e.slope_um_per_m * u * 1e-3 + e.waves.iter().map(|w| w.eval(u)).sum::<f64>()
            }
            Effect::Reversal(e) => {
                0.5 * p.sign() * (e.lost_motion_um + e.gradient_um_per_m * (x - e.centre_mm) * 1e-3)
            }
            Effect::ScaleExpansion(e) => {
                e.um_per_m_k * (x - e.x_ref_mm) * 1e-3 * p.delta_t(e.sensor)
            }
            Effect::ThermalDrift(e) => e
                .terms
                .iter()
                .map(|t| t.um_per_k * p.delta_t(t.sensor))
                .sum(),
            Effect::ThermalLag(e) => e
                .terms
                .iter()
                .map(|t| t.um_per_k * p.lagged_delta_t(t.sensor))
                .sum(),
            Effect::ForceDeflection(e) => e.um_per_n * c.force_n,
            Effect::Cogging(e) => {
                let arg = TAU * x / e.period_mm;
                e.amplitude_um * (arg + e.phase_rad).sin()
                    + e.harmonic2_um * (2.0 * arg + e.harmonic2_phase_rad).sin()
            }
            Effect::InterpolationError(e) => {
                e.amplitude_um * (TAU * x * 1e3 / e.signal_period_um + e.phase_rad).sin()
            }
            Effect::EndEffect(e) => {
                e.amplitude_um
                    * (-(x - e.end_mm).abs() / e.decay_mm).exp()
                    * (1.0 + e.direction_asymmetry * p.sign())
            }
            Effect::FollowingError(e) => {
                -(e.um_per_mm_s * c.velocity_mm_s + e.um_per_mm_s2 * c.accel_mm_s2)
            }
            Effect::Abbe(e) => {
                let theta = e.angle_urad + e.gradient_urad_per_m * (x - e.centre_mm) * 1e-3;
                c.offset_mm * theta * 1e-3
            }
            Effect::TimeDrift(e) => {
                let t = c.time_s;
                let settle = if e.settle_tau_s > 0.0 {
                    e.settle_um * (1.0 - (-t / e.settle_tau_s).exp())
                } else {
                    e.settle_um
                };
                e.um_per_h * t / 3600.0 + settle
            }
        }
    }

    /// Multiplies every amplitude-like parameter by `factor`, so the contribution scales exactly by
    /// `factor` everywhere (time constants, periods and positions are kept).
    pub fn scale(&mut self, factor: f64) {
        match self {
            Effect::PitchError(e) => {
                e.slope_um_per_m *= factor;
                e.waves.iter_mut().for_each(|w| w.amplitude_um *= factor);
            }
            Effect::Reversal(e) => {
                e.lost_motion_um *= factor;
                e.gradient_um_per_m *= factor;
            }
            Effect::ScaleExpansion(e) => e.um_per_m_k *= factor,
            Effect::ThermalDrift(e) => e.terms.iter_mut().for_each(|t| t.um_per_k *= factor),
            Effect::ThermalLag(e) => e.terms.iter_mut().for_each(|t| t.um_per_k *= factor),
            Effect::ForceDeflection(e) => e.um_per_n *= factor,
            Effect::Cogging(e) => {
                e.amplitude_um *= factor;
                e.harmonic2_um *= factor;
            }
            Effect::InterpolationError(e) => e.amplitude_um *= factor,
            Effect::EndEffect(e) => e.amplitude_um *= factor,
            Effect::FollowingError(e) => {
                e.um_per_mm_s *= factor;
                e.um_per_mm_s2 *= factor;
            }
            Effect::Abbe(e) => {
                e.angle_urad *= factor;
                e.gradient_urad_per_m *= factor;
            }
            Effect::TimeDrift(e) => {
                e.um_per_h *= factor;
                e.settle_um *= factor;
            }
        }
    }

    /// Sensors this effect reads (for validation against the axis' sensor list).
    pub fn sensors(&self) -> Vec<usize> {
        match self {
            Effect::ScaleExpansion(e) => vec![e.sensor],
            Effect::ThermalDrift(e) => e.terms.iter().map(|t| t.sensor).collect(),
            Effect::ThermalLag(e) => e.terms.iter().map(|t| t.sensor).collect(),
            _ => Vec::new(),
        }
    }

    /// Typical, documented parameters of `kind` for an axis with this layout (the middle of the
    /// ranges in the module table).
    pub fn typical(kind: EffectKind, l: &Layout) -> Effect {
        let len = l.length_mm();
        match kind {
            EffectKind::PitchError => Effect::PitchError(PitchError {
                origin_mm: l.start_mm,
                slope_um_per_m: 40.0,
                waves: vec![
                    Wave {
                        amplitude_um: 6.0,
                        wavelength_mm: 1.3 * len,
                        phase_rad: 0.4,
                    },
                    Wave {
                        amplitude_um: 2.0,
                        wavelength_mm: 0.45 * len,
                        phase_rad: 1.9,
                    },
                ],
            }),
            EffectKind::Reversal => Effect::Reversal(Reversal {
                lost_motion_um: 4.0,
                gradient_um_per_m: 5.0,
                centre_mm: l.centre_mm(),
            }),
            EffectKind::ScaleExpansion => Effect::ScaleExpansion(ScaleExpansion {
                sensor: l.scale_sensor,
                um_per_m_k: 10.0,
                x_ref_mm: l.start_mm,
            }),
            EffectKind::ThermalDrift => Effect::ThermalDrift(ThermalDrift {
                terms: vec![DriftTerm {
                    sensor: l.motor_sensor,
                    um_per_k: 1.5,
                }],
            }),
            EffectKind::ThermalLag => Effect::ThermalLag(ThermalLag {
                terms: vec![LagTerm {
                    sensor: l.ambient_sensor,
                    um_per_k: 2.5,
                    tau_s: 1800.0,
                }],
            }),
            EffectKind::ForceDeflection => {
                Effect::ForceDeflection(ForceDeflection { um_per_n: 0.015 })
            }
            EffectKind::Cogging => Effect::Cogging(Cogging {
                period_mm: 32.0,
                amplitude_um: 1.2,
                phase_rad: 0.7,
                harmonic2_um: 0.3,
                harmonic2_phase_rad: 2.1,
            }),
            EffectKind::InterpolationError => Effect::InterpolationError(InterpolationError {
                signal_period_um: 20.0,
                amplitude_um: 0.15,
                phase_rad: 0.3,
            }),
            EffectKind::EndEffect => Effect::EndEffect(EndEffect {
                end_mm: l.end_mm,
                amplitude_um: 3.0,
                decay_mm: 8.0,
                direction_asymmetry: 0.3,
            }),
            EffectKind::FollowingError => Effect::FollowingError(FollowingError {
                um_per_mm_s: 0.03,
                um_per_mm_s2: 0.001,
            }),
            EffectKind::Abbe => Effect::Abbe(Abbe {
                angle_urad: 20.0,
                gradient_urad_per_m: 40.0,
                centre_mm: l.centre_mm(),
            }),
            EffectKind::TimeDrift => Effect::TimeDrift(TimeDrift {
                um_per_h: 1.0,
                settle_um: 0.5,
                settle_tau_s: 1800.0,
            }),
        }
    }

    /// Random plausible parameters of `kind` (ranges in the module table).
    pub fn random<R: Rng + ?Sized>(kind: EffectKind, l: &Layout, rng: &mut R) -> Effect {
        let len = l.length_mm();
        match kind {
            EffectKind::PitchError => Effect::PitchError(PitchError {
                origin_mm: l.start_mm,
                slope_um_per_m: rng.gen_range(-40.0..=40.0),
                waves: (0..2)
                    .map(|_| Wave {
                        amplitude_um: rng.gen_range(1.0..=8.0),
                        wavelength_mm: rng.gen_range(0.5..=2.0) * len,
                        phase_rad: rng.gen_range(0.0..TAU),
                    })
                    .collect(),
            }),
            EffectKind::Reversal => Effect::Reversal(Reversal {
                lost_motion_um: rng.gen_range(2.0..=8.0),
                gradient_um_per_m: rng.gen_range(-10.0..=10.0),
                centre_mm: l.centre_mm(),
            }),
            EffectKind::ScaleExpansion => Effect::ScaleExpansion(ScaleExpansion {
                sensor: l.scale_sensor,
                um_per_m_k: rng.gen_range(8.0..=12.0),
                x_ref_mm: l.start_mm,
            }),
            EffectKind::ThermalDrift => Effect::ThermalDrift(ThermalDrift {
                terms: vec![DriftTerm {
                    sensor: l.motor_sensor,
                    um_per_k: signed(rng, 0.5, 3.0),
                }],
            }),
            EffectKind::ThermalLag => Effect::ThermalLag(ThermalLag {
                terms: vec![LagTerm {
                    sensor: if rng.gen_bool(0.5) {
                        l.ambient_sensor
                    } else {
                        l.motor_sensor
                    },
                    um_per_k: signed(rng, 1.0, 4.0),
                    tau_s: rng.gen_range(600.0..=3600.0),
                }],
            }),
            EffectKind::ForceDeflection => Effect::ForceDeflection(ForceDeflection {
                um_per_n: rng.gen_range(0.005..=0.03),
            }),
            EffectKind::Cogging => Effect::Cogging(Cogging {
                period_mm: rng.gen_range(5.0..=60.0),
                amplitude_um: rng.gen_range(0.5..=3.0),
                phase_rad: rng.gen_range(0.0..TAU),
                harmonic2_um: 0.0,
                harmonic2_phase_rad: 0.0,
            }),
            EffectKind::InterpolationError => Effect::InterpolationError(InterpolationError {
                signal_period_um: [4.0, 20.0, 40.0][rng.gen_range(0..3)],
                amplitude_um: rng.gen_range(0.05..=0.3),
                phase_rad: rng.gen_range(0.0..TAU),
            }),
            EffectKind::EndEffect => Effect::EndEffect(EndEffect {
                end_mm: if rng.gen_bool(0.5) {
                    l.start_mm
                } else {
                    l.end_mm
                },
                amplitude_um: signed(rng, 1.0, 5.0),
                decay_mm: rng.gen_range(3.0..=15.0),
                direction_asymmetry: rng.gen_range(-0.8..=0.8),
            }),
            EffectKind::FollowingError => Effect::FollowingError(FollowingError {
                um_per_mm_s: rng.gen_range(0.01..=0.05),
                um_per_mm_s2: rng.gen_range(0.0005..=0.002),
            }),
            EffectKind::Abbe => Effect::Abbe(Abbe {
                angle_urad: signed(rng, 5.0, 40.0),
                gradient_urad_per_m: rng.gen_range(-50.0..=50.0),
                centre_mm: l.centre_mm(),
            }),
            EffectKind::TimeDrift => Effect::TimeDrift(TimeDrift {
                um_per_h: signed(rng, 0.2, 2.0),
                settle_um: rng.gen_range(0.0..=2.0),
                settle_tau_s: rng.gen_range(600.0..=3600.0),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_match_the_contract() {
        // Reference: the "Effect kinds" table of interfaces.md, in its order.
        let contract = [
            "pitch_error",
            "reversal",
            "scale_expansion",
            "thermal_drift",
            "thermal_lag",
            "force_deflection",
            "cogging",
            "interpolation_error",
            "end_effect",
            "following_error",
            "abbe",
            "time_drift",
        ];
        for (i, name) in contract.iter().enumerate() {
            let kind = EffectKind::from_name(name).expect(name);
            assert_eq!(kind.name(), *name);
            assert_eq!(kind.index(), i);
            assert_eq!(EffectKind::ALL[i], kind);
            // serde uses the same spelling (the truth JSON's "kind").
            assert_eq!(serde_json::to_string(&kind).unwrap(), format!("\"{name}\""));
        }
        assert!(EffectKind::from_name("Pitch_Error").is_none());
        let err = EffectKind::parse_list("pitch_error, cogging,bogus").unwrap_err();
        assert_eq!(err.name, "bogus");
        assert!(err.to_string().contains("time_drift"), "{err}");
        assert_eq!(
            EffectKind::parse_list("reversal,cogging,reversal").unwrap(),
            vec![EffectKind::Reversal, EffectKind::Cogging]
        );
    }

    #[test]
    fn scale_scales_the_contribution_exactly() {
        let layout = Layout {
            start_mm: 0.0,
            end_mm: 200.0,
            ambient_sensor: 0,
            motor_sensor: 1,
            scale_sensor: 2,
        };
        let reference = [20.0, 20.0, 20.0];
        let cond = Conditions {
            time_s: 5000.0,
            temps_degc: vec![21.0, 24.0, 22.0],
            lagged_degc: vec![20.5, 23.0, 21.5],
            force_n: 150.0,
            velocity_mm_s: -80.0,
            accel_mm_s2: 300.0,
            offset_mm: 60.0,
        };
        let mut rng = rand::rngs::mock::StepRng::new(7, 0x9e37_79b9_7f4a_7c15);
        for kind in EffectKind::ALL {
            for mut effect in [
                Effect::typical(kind, &layout),
                Effect::random(kind, &layout, &mut rng),
            ] {
                assert_eq!(effect.kind(), kind);
                let p = Point {
                    x_mm: 3.0,
                    direction: -1,
                    cond: &cond,
                    reference_degc: &reference,
                };
                let before = effect.contribution_um(&p);
                effect.scale(2.5);
                let after = effect.contribution_um(&p);
                // Exact up to rounding: tolerance 1e-12 relative.
                assert!(
                    (after - 2.5 * before).abs() <= 1e-12 * before.abs().max(1.0),
                    "{kind}: {before} {after}"
                );
                // JSON round trip keeps the kind tag and the parameters (serde_json's float parsing
                // may differ in the last bit: tolerance 1e-12 relative on the contribution).
                let json = serde_json::to_string(&effect).unwrap();
                assert!(
                    json.contains(&format!("\"kind\":\"{}\"", kind.name())),
                    "{json}"
                );
                let back: Effect = serde_json::from_str(&json).unwrap();
                assert_eq!(back.kind(), kind);
                let again = back.contribution_um(&p);
                assert!(
                    (again - after).abs() <= 1e-12 * after.abs().max(1.0),
                    "{kind}: {after} {again}"
                );
            }
        }
    }
}
