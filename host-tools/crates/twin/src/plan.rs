//! Measurement plans: where, when, how fast and under which load the twin is measured.
//!
//! Glossary:
//! - *target*: commanded position of a measurement.
//! - *run*: one cycle of an ISO 230-2 test, one scan pass, one measurement round or one load step
//!   (the CSV's `run` column).
//! - *overshoot*: the approach starts `overshoot_mm` before the target, so every target is reached from
//!   its approach direction (ISO 230-2 "linear cycle").
//! - *sample*: one planned measurement (one CSV row).
//!
//! Which plan makes which effect identifiable:
//!
//! | plan | what varies | shows |
//! |---|---|---|
//! | `iso230` | target, direction, slowly drifting ambient | `pitch_error`, `reversal`, `cogging`, `interpolation_error`, `end_effect`, some `scale_expansion`/`thermal_drift`/`time_drift` |
//! | `scan` | velocity (4 speeds), acceleration | `following_error` |
//! | `thermal` | warm-up then cool-down, 3 positions | `thermal_drift`, `thermal_lag`, `scale_expansion`, `time_drift` |
//! | `load` | force steps at 3 positions | `force_deflection` |
//! | `abbe` | ISO runs at several `offset_mm` | `abbe` |
//! | `survey` ([`SurveyPlan`]) | all of the above on one time line, with dense targets near both stroke ends and a non-monotonic heat load (warm-up, plateau, cool-down, re-heat) | every effect (one plan for a blind diagnosis) |
//! | `spindle` ([`crate::spindle`], not a [`Plan`]) | spindle speed, cutting force, 16 collinear sensors | `thermal_drift`, `thermal_lag`, `force_deflection` (from process parameters) |

use serde::{Deserialize, Serialize};

use crate::thermal::{DutyStep, Environment};

/// One planned measurement.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    pub run: u32,
    /// Approach (or motion) direction, `+1`/`-1`.
    pub direction: i8,
    pub target_mm: f64,
    pub time_s: f64,
    pub velocity_mm_s: f64,
    pub accel_mm_s2: f64,
    pub force_n: f64,
    pub offset_mm: f64,
    /// For a point approached and held: where the final approach starts (target − direction ·
    /// overshoot). `None` for a sample taken on the fly.
    pub approach_from_mm: Option<f64>,
}

/// ISO 230-2 positioning test (linear cycle): `cycles` times, every target in `+` direction, then every
/// target in `−` direction, each reached from its direction with an overshoot.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Iso230Plan {
    pub start_mm: f64,
    pub end_mm: f64,
    /// Number of targets (≥ 5; ISO 230-2 asks for at least 5 per metre and 5 in all).
    pub targets: usize,
    /// Number of bidirectional cycles (ISO 230-2: 5).
    pub cycles: usize,
    pub overshoot_mm: f64,
    /// Feed between targets.
    pub feed_mm_s: f64,
    /// Settle and read time at each target.
    pub dwell_s: f64,
    /// Spread interior targets irregularly by up to ±¼ of the spacing (ISO 230-2 recommends
    /// irregular spacing so that periodic errors are sampled at different phases).
    pub irregular: bool,
    /// The whole test is repeated at each Abbe offset (default: only 0).
    pub offsets_mm: Vec<f64>,
    pub environment: Environment,
}

impl Iso230Plan {
    /// The standard test on `start_mm..end_mm`: a target every ~10 mm (at least 5), 5 cycles, 2 mm
    /// overshoot, 50 mm/s, 2 s dwell, irregular targets, offset 0, in a workshop whose air drifts by
    /// 0.3 K/h while the axis works at duty 0.3 (so the campaign's temperatures and times move).
    pub fn standard(start_mm: f64, end_mm: f64) -> Iso230Plan {
        let targets = (((end_mm - start_mm) / 10.0).round() as usize + 1).max(5);
        Iso230Plan {
            start_mm,
            end_mm,
            targets,
            cycles: 5,
            overshoot_mm: 2.0,
            feed_mm_s: 50.0,
            dwell_s: 2.0,
            irregular: true,
            offsets_mm: vec![0.0],
            environment: Environment::workshop(0.3, 0.3),
        }
    }

    /// The target positions, ascending.
    pub fn target_positions(&self) -> Vec<f64> {
        let n = self.targets.max(2);
        let step = (self.end_mm - self.start_mm) / (n - 1) as f64;
        (0..n)
            .map(|i| {
                let base = self.start_mm + i as f64 * step;
                if self.irregular && i > 0 && i + 1 < n {
                    // Deterministic low-discrepancy spread in [−¼, ¼)·step (golden-ratio sequence).
                    let frac = (i as f64 * 0.618_033_988_749_895).fract();
                    base + (frac - 0.5) * 0.5 * step
                } else {
                    base
                }
            })
            .collect()
    }

    fn samples(&self) -> Vec<Sample> {
        let targets = self.target_positions();
        let mut out = Vec::with_capacity(targets.len() * self.cycles * 2 * self.offsets_mm.len());
        let mut t = 0.0;
        let mut x = self.start_mm - self.overshoot_mm;
        let mut run = 0u32;
        for &offset in &self.offsets_mm {
            for _ in 0..self.cycles {
                run += 1;
                for direction in [1i8, -1] {
                    let order: Vec<f64> = if direction > 0 {
                        targets.clone()
                    } else {
                        targets.iter().rev().copied().collect()
                    };
                    for target in order {
                        let from = target - f64::from(direction) * self.overshoot_mm;
                        t += move_time_s(x, from, self.feed_mm_s)
                            + move_time_s(from, target, self.feed_mm_s);
                        t += self.dwell_s;
                        x = target;
                        out.push(Sample {
                            run,
                            direction,
                            target_mm: target,
                            time_s: t,
                            velocity_mm_s: 0.0,
                            accel_mm_s2: 0.0,
                            force_n: 0.0,
                            offset_mm: offset,
                            approach_from_mm: Some(from),
                        });
                    }
                }
            }
        }
        out
    }
}

/// Time for a point-to-point move at `feed` (plus 0.2 s for acceleration and settling).
fn move_time_s(from: f64, to: f64, feed_mm_s: f64) -> f64 {
    (to - from).abs() / feed_mm_s + 0.2
}

/// Scans at several speeds: the axis moves over the stroke in both directions at each speed with a
/// trapezoidal profile and is sampled on the fly every `spacing_mm` (including the acceleration ramps).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScanPlan {
    pub start_mm: f64,
    pub end_mm: f64,
    pub speeds_mm_s: Vec<f64>,
    pub accel_mm_s2: f64,
    pub samples_per_pass: usize,
    pub environment: Environment,
}

impl ScanPlan {
    /// 10, 50, 100 and 200 mm/s at 1000 mm/s², 50 samples per pass, quiet workshop.
    pub fn standard(start_mm: f64, end_mm: f64) -> ScanPlan {
        ScanPlan {
            start_mm,
            end_mm,
            speeds_mm_s: vec![10.0, 50.0, 100.0, 200.0],
            accel_mm_s2: 1000.0,
            samples_per_pass: 50,
            environment: Environment::workshop(0.1, 0.5),
        }
    }

    fn samples(&self) -> Vec<Sample> {
        let len = self.end_mm - self.start_mm;
        let n = self.samples_per_pass.max(2);
        let mut out = Vec::with_capacity(self.speeds_mm_s.len() * 2 * n);
        let mut t0 = 0.0;
        let mut run = 0u32;
        for &v_max in &self.speeds_mm_s {
            let a = self.accel_mm_s2;
            // Trapezoid (or triangle when the stroke is too short to reach v_max).
            let v_peak = v_max.min((a * len).sqrt());
            let s_ramp = v_peak * v_peak / (2.0 * a);
            let t_ramp = v_peak / a;
            let t_cruise = (len - 2.0 * s_ramp) / v_peak;
            let t_move = 2.0 * t_ramp + t_cruise;
            for direction in [1i8, -1] {
                run += 1;
                for i in 0..n {
                    // Sample points inside the stroke, away from the exact ends (v = 0 there).
                    let s = len * (i as f64 + 0.5) / n as f64;
                    let (t, v, acc) = if s < s_ramp {
                        let t = (2.0 * s / a).sqrt();
                        (t, a * t, a)
                    } else if s <= len - s_ramp {
                        (t_ramp + (s - s_ramp) / v_peak, v_peak, 0.0)
                    } else {
                        let rest = len - s;
                        let t_rest = (2.0 * rest / a).sqrt();
                        (t_move - t_rest, a * t_rest, -a)
                    };
                    let sign = f64::from(direction);
                    let target = if direction > 0 {
                        self.start_mm + s
                    } else {
                        self.end_mm - s
                    };
                    out.push(Sample {
                        run,
                        direction,
                        target_mm: target,
                        time_s: t0 + t,
                        velocity_mm_s: sign * v,
                        accel_mm_s2: sign * acc,
                        force_n: 0.0,
                        offset_mm: 0.0,
                        approach_from_mm: None,
                    });
                }
                t0 += t_move + 1.0;
            }
        }
        out
    }
}

/// Warm-up then cool-down: the axis works at duty 1 for `warmup_s`, then rests for `cooldown_s`;
/// every `interval_s` a measurement round visits `positions_mm` (approached in `+` direction).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ThermalPlan {
    pub positions_mm: Vec<f64>,
    pub warmup_s: f64,
    pub cooldown_s: f64,
    pub interval_s: f64,
    pub overshoot_mm: f64,
    /// Ambient drift and swing (the duty schedule is set from warm-up/cool-down).
    pub environment: Environment,
}

impl ThermalPlan {
    /// 4 h warm-up, 3 h cool-down, a round every 5 min at 10 %, 50 % and 90 % of the stroke.
    pub fn standard(start_mm: f64, end_mm: f64) -> ThermalPlan {
        let len = end_mm - start_mm;
        let warmup_s = 4.0 * 3600.0;
        let mut environment = Environment::workshop(0.2, 1.0);
        environment.duty = vec![
            DutyStep {
                from_s: 0.0,
                duty: 1.0,
            },
            DutyStep {
                from_s: warmup_s,
                duty: 0.0,
            },
        ];
        ThermalPlan {
            positions_mm: vec![
                start_mm + 0.1 * len,
                start_mm + 0.5 * len,
                start_mm + 0.9 * len,
            ],
            warmup_s,
            cooldown_s: 3.0 * 3600.0,
            interval_s: 300.0,
            overshoot_mm: 2.0,
            environment,
        }
    }

    fn samples(&self) -> Vec<Sample> {
        let rounds = ((self.warmup_s + self.cooldown_s) / self.interval_s).floor() as usize + 1;
        let mut out = Vec::with_capacity(rounds * self.positions_mm.len());
        // Positions of a round 3 s apart, or closer when the rounds are dense (a resized plan), so a
        // round always ends before the next one starts (time never runs backwards).
        let step_s = 3.0f64.min(self.interval_s / (self.positions_mm.len() as f64 + 1.0));
        for r in 0..rounds {
            let t_round = r as f64 * self.interval_s;
            for (j, &target) in self.positions_mm.iter().enumerate() {
                out.push(Sample {
                    run: r as u32 + 1,
                    direction: 1,
                    target_mm: target,
                    time_s: t_round + step_s * (j as f64 + 1.0),
                    velocity_mm_s: 0.0,
                    accel_mm_s2: 0.0,
                    force_n: 0.0,
                    offset_mm: 0.0,
                    approach_from_mm: Some(target - self.overshoot_mm),
                });
            }
        }
        out
    }
}

/// Load steps: at each position and in both directions, the force steps up and down through
/// `forces_n` (each step is one run).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LoadPlan {
    pub positions_mm: Vec<f64>,
    pub forces_n: Vec<f64>,
    pub overshoot_mm: f64,
    pub dwell_s: f64,
    pub environment: Environment,
}

impl LoadPlan {
    /// Forces 0 → 400 N → 0 → −400 N → 0 in 100 N steps at 10 %, 50 % and 90 % of the stroke.
    pub fn standard(start_mm: f64, end_mm: f64) -> LoadPlan {
        let len = end_mm - start_mm;
        let mut forces: Vec<f64> = (0..=4).map(|i| 100.0 * i as f64).collect();
        forces.extend((0..4).rev().map(|i| 100.0 * i as f64));
        forces.extend((1..=4).map(|i| -100.0 * i as f64));
        forces.extend((0..4).rev().map(|i| -100.0 * i as f64));
        LoadPlan {
            positions_mm: vec![
                start_mm + 0.1 * len,
                start_mm + 0.5 * len,
                start_mm + 0.9 * len,
            ],
            forces_n: forces,
            overshoot_mm: 2.0,
            dwell_s: 5.0,
            environment: Environment::workshop(0.1, 0.2),
        }
    }

    fn samples(&self) -> Vec<Sample> {
        let mut out = Vec::new();
        let mut t = 0.0;
        for (k, &force) in self.forces_n.iter().enumerate() {
            for &target in &self.positions_mm {
                for direction in [1i8, -1] {
                    t += self.dwell_s;
                    out.push(Sample {
                        run: k as u32 + 1,
                        direction,
                        target_mm: target,
                        time_s: t,
                        velocity_mm_s: 0.0,
                        accel_mm_s2: 0.0,
                        force_n: force,
                        offset_mm: 0.0,
                        approach_from_mm: Some(target - f64::from(direction) * self.overshoot_mm),
                    });
                }
            }
        }
        out
    }
}

/// A survey: several plans measured one after another on one time line, in one environment (the
/// parts' own environments are ignored). Runs are renumbered consecutively over the parts.
///
/// The standard survey ([`SurveyPlan::standard`]) is a campaign designed so that *any* single effect
/// could show, whichever it is (for a blind diagnosis, the plan must not depend on the effect sought):
/// 1. ISO 230-2 runs over the stroke at Abbe offsets 0, 50 and 100 mm (positional effects, `abbe`);
/// 2. ISO 230-2 runs over the first and the last [`SurveyPlan::END_ZONE_MM`] of the stroke with
///    targets about every 0.5–1 mm (`end_effect`: a decay of a few mm touches many targets);
/// 3. scans at 10, 50, 100 and 200 mm/s (`following_error`);
/// 4. load steps ±400 N (`force_deflection`);
/// 5. measurement rounds at 10/50/90 % of the stroke while the axis heats and cools.
///
/// The heat load over the whole survey is not monotonic — duty 1 for the first 30 % of the time, a
/// plateau at 0.4 up to 50 %, idle (cool-down) up to 75 %, then duty 1 again — and the ambient air
/// swings by ±0.5 K with a 4 h period on top of a 0.1 K/h drift, so a lagged temperature, the
/// temperatures themselves and a polynomial in time all differ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SurveyPlan {
    pub parts: Vec<Plan>,
    /// Pause between two parts.
    pub gap_s: f64,
    pub environment: Environment,
}

impl SurveyPlan {
    /// Length of each end zone measured densely (capped at a tenth of the stroke).
    pub const END_ZONE_MM: f64 = 20.0;
    /// Share of the rows per part (ISO/Abbe, end zones, scans, load steps, thermal rounds).
    const SHARES: [f64; 5] = [0.30, 0.15, 0.15, 0.15, 0.25];

    /// The standard survey on `start_mm..end_mm` (about 5,000 rows; see [`Plan::resize`]).
    pub fn standard(start_mm: f64, end_mm: f64) -> SurveyPlan {
        let len = end_mm - start_mm;
        let zone = Self::END_ZONE_MM.min(0.1 * len);
        let zone_plan = |a: f64, b: f64| {
            Plan::Iso230(Iso230Plan {
                targets: 21,
                overshoot_mm: 1.0,
                ..Iso230Plan::standard(a, b)
            })
        };
        let mut thermal = ThermalPlan::standard(start_mm, end_mm);
        thermal.warmup_s = 2.0 * 3600.0;
        thermal.cooldown_s = 2.0 * 3600.0;
        let mut survey = SurveyPlan {
            parts: vec![
                Plan::Iso230(Iso230Plan {
                    offsets_mm: vec![0.0, 50.0, 100.0],
                    ..Iso230Plan::standard(start_mm, end_mm)
                }),
                zone_plan(start_mm, start_mm + zone),
                zone_plan(end_mm - zone, end_mm),
                Plan::Scan(ScanPlan::standard(start_mm, end_mm)),
                Plan::Load(LoadPlan::standard(start_mm, end_mm)),
                Plan::Thermal(thermal),
            ],
            gap_s: 60.0,
            environment: Environment::still(),
        };
        survey.resize(5000);
        survey
    }

    fn resize(&mut self, rows: usize) {
        let rows = rows as f64;
        for (i, part) in self.parts.iter_mut().enumerate() {
            let share = match i {
                0 => Self::SHARES[0],
                1 | 2 => 0.5 * Self::SHARES[1],
                3 => Self::SHARES[2],
                4 => Self::SHARES[3],
                _ => Self::SHARES[4],
            };
            part.resize((share * rows).round() as usize);
        }
        self.schedule();
    }

    /// Sets the environment from the survey's duration (see the type's docs).
    fn schedule(&mut self) {
        let duration = self.samples().last().map_or(0.0, |s| s.time_s);
        self.environment = Environment {
            ambient_offset_k: 0.0,
            ambient_rate_k_per_h: 0.1,
            ambient_swing_k: 0.5,
            ambient_period_h: 4.0,
            duty: [(0.0, 1.0), (0.3, 0.4), (0.5, 0.0), (0.75, 1.0)]
                .iter()
                .map(|&(f, duty)| DutyStep {
                    from_s: f * duration,
                    duty,
                })
                .collect(),
        };
    }

    fn samples(&self) -> Vec<Sample> {
        let mut out = Vec::new();
        let (mut t0, mut run0) = (0.0, 0u32);
        for part in &self.parts {
            let samples = part.samples();
            let (mut t_end, mut run_end) = (t0, run0);
            for s in samples {
                let s = Sample {
                    run: s.run + run0,
                    time_s: s.time_s + t0,
                    ..s
                };
                t_end = t_end.max(s.time_s);
                run_end = run_end.max(s.run);
                out.push(s);
            }
            t0 = t_end + self.gap_s;
            run0 = run_end;
        }
        out
    }
}

/// A measurement plan.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "plan", rename_all = "snake_case")]
pub enum Plan {
    Iso230(Iso230Plan),
    Scan(ScanPlan),
    Thermal(ThermalPlan),
    Load(LoadPlan),
    Survey(SurveyPlan),
}

/// A plan name that the twin does not know.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown plan `{0}` (expected one of: iso230, scan, thermal, load, abbe)")]
pub struct UnknownPlan(pub String);

impl Plan {
    /// The plan names [`Plan::by_name`] accepts.
    pub const NAMES: [&'static str; 6] = ["iso230", "scan", "thermal", "load", "abbe", "survey"];

    /// The standard plan of that name on `start_mm..end_mm`; `abbe` is the ISO 230-2 test repeated at
    /// offsets 0, 50 and 100 mm. With `rows`, the plan is resized to about that many rows.
    pub fn by_name(
        name: &str,
        start_mm: f64,
        end_mm: f64,
        rows: Option<usize>,
    ) -> Result<Plan, UnknownPlan> {
        let mut plan = match name {
            "iso230" => Plan::Iso230(Iso230Plan::standard(start_mm, end_mm)),
            "abbe" => Plan::Iso230(Iso230Plan {
                offsets_mm: vec![0.0, 50.0, 100.0],
                ..Iso230Plan::standard(start_mm, end_mm)
            }),
            "scan" => Plan::Scan(ScanPlan::standard(start_mm, end_mm)),
            "thermal" => Plan::Thermal(ThermalPlan::standard(start_mm, end_mm)),
            "load" => Plan::Load(LoadPlan::standard(start_mm, end_mm)),
            "survey" => Plan::Survey(SurveyPlan::standard(start_mm, end_mm)),
            other => return Err(UnknownPlan(other.to_owned())),
        };
        if let Some(rows) = rows {
            plan.resize(rows);
        }
        Ok(plan)
    }

    /// Short name (`iso230`, `scan`, `thermal`, `load`, `survey`).
    pub fn name(&self) -> &'static str {
        match self {
            Plan::Iso230(_) => "iso230",
            Plan::Scan(_) => "scan",
            Plan::Thermal(_) => "thermal",
            Plan::Load(_) => "load",
            Plan::Survey(_) => "survey",
        }
    }

    /// Changes the density of the plan so that it has about `rows` rows (at least the plan's minimum).
    pub fn resize(&mut self, rows: usize) {
        let rows = rows.max(1) as f64;
        match self {
            Plan::Iso230(p) => {
                let per_target = (2 * p.cycles * p.offsets_mm.len()).max(1) as f64;
                p.targets = ((rows / per_target).round() as usize).max(5);
            }
            Plan::Scan(p) => {
                let passes = (2 * p.speeds_mm_s.len()).max(1) as f64;
                p.samples_per_pass = ((rows / passes).round() as usize).max(2);
            }
            Plan::Thermal(p) => {
                let rounds = (rows / p.positions_mm.len().max(1) as f64).max(2.0);
                p.interval_s = (p.warmup_s + p.cooldown_s) / (rounds - 1.0);
            }
            Plan::Load(p) => {
                let per_position = (2 * p.forces_n.len()).max(1) as f64;
                let n = ((rows / per_position).round() as usize).max(1);
                let (lo, hi) = match (p.positions_mm.first(), p.positions_mm.last()) {
                    (Some(&a), Some(&b)) => (a, b),
                    _ => return,
                };
                p.positions_mm = if n == 1 {
                    vec![0.5 * (lo + hi)]
                } else {
                    (0..n)
                        .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
                        .collect()
                };
            }
            Plan::Survey(p) => p.resize(rows as usize),
        }
    }

    /// The plan's surroundings.
    pub fn environment(&self) -> &Environment {
        match self {
            Plan::Iso230(p) => &p.environment,
            Plan::Scan(p) => &p.environment,
            Plan::Thermal(p) => &p.environment,
            Plan::Load(p) => &p.environment,
            Plan::Survey(p) => &p.environment,
        }
    }

    /// The planned measurements, in time order.
    pub fn samples(&self) -> Vec<Sample> {
        match self {
            Plan::Iso230(p) => p.samples(),
            Plan::Scan(p) => p.samples(),
            Plan::Thermal(p) => p.samples(),
            Plan::Load(p) => p.samples(),
            Plan::Survey(p) => p.samples(),
        }
    }
}

impl From<SurveyPlan> for Plan {
    fn from(p: SurveyPlan) -> Plan {
        Plan::Survey(p)
    }
}

impl From<Iso230Plan> for Plan {
    fn from(p: Iso230Plan) -> Plan {
        Plan::Iso230(p)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iso230_standard_is_a_bidirectional_linear_cycle() {
        let plan = Iso230Plan::standard(0.0, 200.0);
        assert_eq!(plan.targets, 21);
        let targets = plan.target_positions();
        assert_eq!(targets.first(), Some(&0.0));
        assert_eq!(targets.last(), Some(&200.0));
        assert!(targets.windows(2).all(|w| w[1] > w[0]));
        let samples = Plan::from(plan).samples();
        assert_eq!(samples.len(), 21 * 5 * 2);
        assert!(samples.windows(2).all(|w| w[1].time_s > w[0].time_s));
        for run in 1..=5 {
            let of_run: Vec<_> = samples.iter().filter(|s| s.run == run).collect();
            assert_eq!(of_run.iter().filter(|s| s.direction == 1).count(), 21);
            assert_eq!(of_run.iter().filter(|s| s.direction == -1).count(), 21);
        }
        for s in &samples {
            let from = s.approach_from_mm.unwrap();
            assert_eq!((s.target_mm - from).signum() as i8, s.direction);
        }
    }

    #[test]
    fn every_plan_resizes_to_about_the_requested_rows() {
        for name in Plan::NAMES {
            let plan = Plan::by_name(name, 0.0, 200.0, Some(1000)).unwrap();
            let n = plan.samples().len();
            // Tolerance: rounding to whole targets / positions / rounds → within 15 %.
            assert!((850..=1150).contains(&n), "{name}: {n}");
        }
        assert_eq!(
            Plan::by_name("nope", 0.0, 1.0, None),
            Err(UnknownPlan("nope".into()))
        );
    }

    #[test]
    fn every_plan_keeps_time_monotonic_up_to_a_million_rows() {
        // Time runs forward at any size: a thermal round's positions are spaced by the round interval, so
        // long plans (`thermal` from ~14,000 rows, `survey` from ~29,000) do not fold back in time.
        for name in Plan::NAMES {
            for rows in [14_000, 30_000, 1_000_000] {
                let plan = Plan::by_name(name, 0.0, 200.0, Some(rows)).unwrap();
                let samples = plan.samples();
                assert!(
                    samples.windows(2).all(|w| w[1].time_s >= w[0].time_s),
                    "{name} at {rows} rows: time runs backwards"
                );
                // Rounding to whole targets / positions / rounds → within 15 %.
                let n = samples.len() as f64;
                assert!(
                    (n / rows as f64 - 1.0).abs() < 0.15,
                    "{name}: {n} rows for {rows}"
                );
            }
        }
    }

    #[test]
    fn scan_samples_on_the_fly_with_the_profile() {
        let plan = ScanPlan::standard(0.0, 200.0);
        let samples = Plan::Scan(plan.clone()).samples();
        assert_eq!(samples.len(), 4 * 2 * 50);
        for s in &samples {
            assert_eq!(s.velocity_mm_s.signum() as i8, s.direction);
            assert!(s.velocity_mm_s.abs() <= 200.0 + 1e-9);
            assert!(s.approach_from_mm.is_none());
        }
        // The slow pass cruises at 10 mm/s; the fast one ramps (nonzero acceleration samples exist).
        assert!(samples.iter().any(|s| s.velocity_mm_s == 10.0));
        assert!(samples.iter().any(|s| s.accel_mm_s2 != 0.0));
        assert!(samples.windows(2).all(|w| w[1].time_s > w[0].time_s));
    }

    #[test]
    fn survey_shows_every_variable_and_heats_non_monotonically() {
        let plan = Plan::from(SurveyPlan::standard(0.0, 400.0));
        let samples = plan.samples();
        // Resized to about 5,000 rows (rounding to whole targets / positions / rounds → within 10 %).
        assert!((4500..=5500).contains(&samples.len()), "{}", samples.len());
        assert!(samples.windows(2).all(|w| w[1].time_s > w[0].time_s));
        assert!(samples.windows(2).all(|w| w[1].run >= w[0].run));
        let distinct = |f: &dyn Fn(&Sample) -> f64| {
            let mut v: Vec<f64> = samples.iter().map(f).collect();
            v.sort_by(|a, b| a.total_cmp(b));
            v.dedup();
            v.len()
        };
        assert_eq!(distinct(&|s| s.offset_mm), 3);
        assert!(distinct(&|s| s.force_n) >= 9);
        assert!(distinct(&|s| s.velocity_mm_s.abs()) >= 4);
        assert!(
            samples.iter().any(|s| s.direction == 1) && samples.iter().any(|s| s.direction == -1)
        );
        // Dense near both ends: ≥ 10 distinct targets within the first and within the last 10 mm.
        let near = |lo: f64, hi: f64| {
            distinct(&|s| {
                if s.target_mm >= lo && s.target_mm <= hi && s.approach_from_mm.is_some() {
                    s.target_mm
                } else {
                    -1.0
                }
            }) - 1
        };
        assert!(near(0.0, 10.0) >= 10, "{}", near(0.0, 10.0));
        assert!(near(390.0, 400.0) >= 10, "{}", near(390.0, 400.0));
        // Heat load: on, plateau, off, on again (not monotonic in time).
        let duty: Vec<f64> = plan.environment().duty.iter().map(|d| d.duty).collect();
        assert_eq!(duty, vec![1.0, 0.4, 0.0, 1.0]);
        let end = samples.last().unwrap().time_s;
        assert!(plan.environment().duty[3].from_s < end);
    }
}
