//! The twin's temperatures: a three-node thermal network driven by the hall's ambient air and the
//! axis' own heat load.
//!
//! Glossary:
//! - *ambient*: air temperature in the hall, `T_ref + rate·t + swing·sin(2πt/period)`.
//! - *duty*: how hard the axis works (0 idle … 1 continuous fast cycling); heats the motor.
//! - *motor*: first-order node, `τ_m·dT_m/dt = T_amb + duty·rise − T_m`.
//! - *scale*: structure around the scale, `τ_s·dT_s/dt = T_amb + coupling·(T_m − T_amb) − T_s`.
//! - *lagged temperature*: a sensor's temperature through a further first-order lag (the `thermal_lag`
//!   effect's time constant), integrated alongside.
//!
//! Each step is exact for inputs held constant over the step (exponential update); steps are at most
//! [`MAX_STEP_S`] long, so the network follows ambient swings and duty changes closely.
//!
//! This is intentionally minimal; `axcomp-thermal::synth` may replace it behind the same functions.

use serde::{Deserialize, Serialize};

/// Longest integration step.
pub const MAX_STEP_S: f64 = 1.0;

/// Index of each node in the twin's sensor list.
pub const AMBIENT: usize = 0;
pub const MOTOR: usize = 1;
pub const SCALE: usize = 2;
/// Names of the twin's sensors (CSV columns `<name>_degC`), indexed by [`AMBIENT`], [`MOTOR`], [`SCALE`].
pub const SENSOR_NAMES: [&str; 3] = ["ambient", "motor", "scale"];

/// How the axis heats up (part of the axis).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ThermalModel {
    /// Steady motor rise over ambient at duty 1 (typ. 4–10 K for a linear motor).
    pub motor_rise_k: f64,
    /// Motor time constant (typ. 10–30 min).
    pub motor_tau_s: f64,
    /// Fraction of the motor's rise that reaches the scale/structure (typ. 0.2–0.5).
    pub scale_coupling: f64,
    /// Scale/structure time constant (typ. 30–90 min).
    pub scale_tau_s: f64,
}

impl Default for ThermalModel {
    fn default() -> Self {
        ThermalModel {
            motor_rise_k: 6.0,
            motor_tau_s: 900.0,
            scale_coupling: 0.35,
            scale_tau_s: 2400.0,
        }
    }
}

/// One change of the heat load: from `from_s` on, the axis works at `duty`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct DutyStep {
    pub from_s: f64,
    pub duty: f64,
}

/// The surroundings during a campaign (part of the measurement plan).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Environment {
    /// Ambient temperature at t = 0 minus the sensors' reference temperature.
    pub ambient_offset_k: f64,
    /// Slow ambient drift.
    pub ambient_rate_k_per_h: f64,
    /// Amplitude and period of the ambient cycle (air conditioning, day/night).
    pub ambient_swing_k: f64,
    pub ambient_period_h: f64,
    /// Heat load schedule, sorted by `from_s`; duty 0 before the first step.
    pub duty: Vec<DutyStep>,
}

impl Environment {
    /// A quiet hall: no drift, no swing, idle axis.
    pub fn still() -> Environment {
        Environment {
            ambient_offset_k: 0.0,
            ambient_rate_k_per_h: 0.0,
            ambient_swing_k: 0.0,
            ambient_period_h: 1.0,
            duty: Vec::new(),
        }
    }

    /// A workshop during a measurement campaign: ambient drifting by `rate` K/h with a small swing,
    /// the axis working at a constant `duty`.
    pub fn workshop(rate_k_per_h: f64, duty: f64) -> Environment {
        Environment {
            ambient_offset_k: 0.0,
            ambient_rate_k_per_h: rate_k_per_h,
            ambient_swing_k: 0.2,
            ambient_period_h: 1.5,
            duty: vec![DutyStep { from_s: 0.0, duty }],
        }
    }

    /// Ambient temperature rise over the reference at time `t_s`.
    pub fn ambient_rise_k(&self, t_s: f64) -> f64 {
        let period_s = self.ambient_period_h * 3600.0;
        let swing = if period_s > 0.0 {
            self.ambient_swing_k * (core::f64::consts::TAU * t_s / period_s).sin()
        } else {
            0.0
        };
        self.ambient_offset_k + self.ambient_rate_k_per_h * t_s / 3600.0 + swing
    }

    /// Duty at time `t_s`.
    pub fn duty_at(&self, t_s: f64) -> f64 {
        self.duty
            .iter()
            .take_while(|d| d.from_s <= t_s)
            .last()
            .map_or(0.0, |d| d.duty)
    }
}

/// True temperatures of the three nodes and their lagged copies, advanced through time.
#[derive(Debug, Clone)]
pub struct ThermalState {
    pub t_s: f64,
    /// True temperatures, indexed by [`AMBIENT`], [`MOTOR`], [`SCALE`].
    pub temps_degc: [f64; 3],
    /// Lagged temperatures (one lag per sensor; equal to `temps_degc` where there is no lag).
    pub lagged_degc: [f64; 3],
    reference_degc: [f64; 3],
    lag_tau_s: [Option<f64>; 3],
}

impl ThermalState {
    /// Starts at t = 0 in equilibrium with the ambient air.
    pub fn new(
        reference_degc: [f64; 3],
        lag_tau_s: [Option<f64>; 3],
        env: &Environment,
    ) -> ThermalState {
        let amb = env.ambient_rise_k(0.0);
        let temps = reference_degc.map(|r| r + amb);
        ThermalState {
            t_s: 0.0,
            temps_degc: temps,
            lagged_degc: temps,
            reference_degc,
            lag_tau_s,
        }
    }

    /// Advances to `t_s` (no-op when `t_s` is not later than now), calling `on_step(state)` after every
    /// integration step (for feeding sensors to a compensator at a fixed period).
    pub fn advance_to(
        &mut self,
        t_s: f64,
        model: &ThermalModel,
        env: &Environment,
        mut on_step: impl FnMut(&ThermalState),
    ) {
        while self.t_s < t_s {
            let dt = (t_s - self.t_s).min(MAX_STEP_S);
            let mid = self.t_s + 0.5 * dt;
            let amb_rise = env.ambient_rise_k(mid);
            let duty = env.duty_at(mid);
            let relax = |value: f64, target: f64, tau: f64| -> f64 {
                if tau <= 0.0 {
                    target
                } else {
                    target + (value - target) * (-dt / tau).exp()
                }
            };
            let ambient = self.reference_degc[AMBIENT] + amb_rise;
            let motor_target = self.reference_degc[MOTOR] + amb_rise + duty * model.motor_rise_k;
            let motor = relax(self.temps_degc[MOTOR], motor_target, model.motor_tau_s);
            let motor_rise =
                0.5 * (motor + self.temps_degc[MOTOR]) - self.reference_degc[MOTOR] - amb_rise;
            let scale_target =
                self.reference_degc[SCALE] + amb_rise + model.scale_coupling * motor_rise;
            let scale = relax(self.temps_degc[SCALE], scale_target, model.scale_tau_s);
            let previous = self.temps_degc;
            self.temps_degc = [ambient, motor, scale];
            let nodes = self
                .lagged_degc
                .iter_mut()
                .zip(&self.lag_tau_s)
                .zip(previous.iter().zip(&self.temps_degc));
            for ((lagged, tau), (&before, &now)) in nodes {
                *lagged = match tau {
                    Some(tau) => relax(*lagged, 0.5 * (before + now), *tau),
                    None => now,
                };
            }
            self.t_s += dt;
            on_step(self);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn warm_up_approaches_the_steady_state_with_the_time_constants() {
        let model = ThermalModel::default();
        let env = Environment {
            duty: vec![DutyStep {
                from_s: 0.0,
                duty: 1.0,
            }],
            ..Environment::still()
        };
        let mut st = ThermalState::new([20.0; 3], [None, Some(600.0), None], &env);
        st.advance_to(model.motor_tau_s, &model, &env, |_| {});
        // Reference: first-order step response 1 − e^-1 = 0.632 of the rise after one τ; tolerance 1 %
        // of the rise for the 1 s discretisation.
        let rise = st.temps_degc[MOTOR] - 20.0;
        assert!(
            (rise - 0.632 * model.motor_rise_k).abs() < 0.01 * model.motor_rise_k,
            "{rise}"
        );
        // The lagged copy trails the motor.
        assert!(st.lagged_degc[MOTOR] < st.temps_degc[MOTOR]);
        st.advance_to(20.0 * model.scale_tau_s, &model, &env, |_| {});
        // Steady state: motor at full rise, scale at coupling × rise (tolerance 0.1 %).
        assert!((st.temps_degc[MOTOR] - 26.0).abs() < 6e-3);
        assert!((st.temps_degc[SCALE] - (20.0 + 0.35 * 6.0)).abs() < 6e-3);
        assert!((st.lagged_degc[MOTOR] - st.temps_degc[MOTOR]).abs() < 6e-3);
        assert_eq!(st.temps_degc[AMBIENT], 20.0);
    }
}
