//! A touch-trigger probe on the twin: touches on artefacts whose truth is known.
//!
//! # Glossary
//! - **normal** `n`: the unit outward normal of the artefact's surface at the contact, pointing from the
//!   material toward the stylus. Probing moves along the **approach** `u = −n` (toward the surface).
//!   Directions are given by the normal's **azimuth** θ = atan2(n_y, n_x) and **elevation** φ = asin(n_z)
//!   (0° on a sphere's equator, 90° at its top, i.e. a touch straight down).
//! - **contact centre**: the stylus-tip centre when the ball first touches, `c = s + r·n` for the surface
//!   point `s` and the stylus ball radius `r`.
//! - **pretravel** δ(n, v) (µm): how far the tip centre moves on along `u` after contact before the
//!   trigger is latched; the **latched** position is `p = c + δ·u + noise·u`.
//! - **three-lobe kinematic pretravel**: a resistive kinematic probe has three contact pairs at 120°; the
//!   lateral trigger force (so the bending before trigger) grows as 1/cos of the angle from the nearest pivot
//!   axis' normal, which gives three lobes with cusps: `δ_lat(θ) = base + lobe·(1/cos ψ − 1)` with
//!   ψ = ((θ − θ0 + 60°) mod 120°) − 60° ∈ [−60°, 60°); an axial (z) touch has its own pretravel `δ_axial`.
//!   The two mix as `δ_lat(θ)·cos²φ + δ_axial·sin²φ`.
//! - **speed-linear term**: `speed_um_per_mm_s · v` (mechanical pretravel grows with speed, seed 003).
//! - **latch latency** `latency_ms`: the controller latches `latency` after the switch, i.e. `v·latency`
//!   further along `u` (LinuxCNC / M700V read-out error). Both are linear in the probing speed `v`.
//! - **bounce**: with probability `bounce_prob` a touch gives a second trigger further on (`bounce_um`
//!   range) while decelerating — a second row for the same move.
//! - **false trigger**: with probability `false_trigger_prob` a wireless false trip latches before
//!   contact, `false_trigger_mm` range short of the surface along the approach.
//!
//! Plans ([`ProbePlan`]): calibration on a reference sphere (rings of azimuth × elevation at 2–3 speeds,
//! [`ProbePlan::calibration`]) and measurement (a second sphere, a ring gauge, a plane,
//! [`ProbePlan::measurement`]). [`simulate_touches`] runs a plan; [`touches_csv`] writes the contract's
//! touch CSV (`x_mm,y_mm,z_mm,approach_x,approach_y,approach_z,feed_mm_min,artefact,run`).

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// The probe's behaviour (truth of the twin).
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeModel {
    /// Stylus ball radius, mm (the nominal ball: half the stylus' catalogue diameter).
    pub stylus_radius_mm: f64,
    /// Lateral pretravel at a lobe minimum, µm.
    pub lateral_base_um: f64,
    /// Lobe amplitude: lateral pretravel at a cusp is `base + lobe`, µm.
    pub lobe_um: f64,
    /// Orientation of the lobes (azimuth of a lobe minimum), degrees.
    pub lobe_phase_deg: f64,
    /// Axial (touch straight down) pretravel, µm.
    pub axial_um: f64,
    /// Mechanical speed-linear pretravel, µm per mm/s of probing speed.
    pub speed_um_per_mm_s: f64,
    /// Latch latency, ms (adds v·latency along the approach).
    pub latency_ms: f64,
    /// Standard deviation of the trigger point along the approach, µm.
    pub noise_um: f64,
    pub bounce_prob: f64,
    /// Range of the extra travel of a bounce's second trigger, µm.
    pub bounce_um: (f64, f64),
    pub false_trigger_prob: f64,
    /// Range of how far short of contact a false trigger latches, mm.
    pub false_trigger_mm: (f64, f64),
}

impl ProbeModel {
    /// A plausible touch-trigger probe (2σ repeatability 1 µm like a Renishaw OMP-class probe, three lobes of
    /// 3 µm, 0.3 ms latch latency), with bounce and false triggers rare but present.
    pub fn kinematic_demo() -> Self {
        ProbeModel {
            stylus_radius_mm: 1.5,
            lateral_base_um: 4.0,
            lobe_um: 3.0,
            lobe_phase_deg: 10.0,
            axial_um: 2.0,
            speed_um_per_mm_s: 0.3,
            latency_ms: 0.3,
            noise_um: 0.5,
            bounce_prob: 0.005,
            bounce_um: (5.0, 30.0),
            false_trigger_prob: 0.005,
            false_trigger_mm: (0.02, 0.5),
        }
    }

    /// The same probe without bounce and false triggers.
    pub fn without_glitches(mut self) -> Self {
        self.bounce_prob = 0.0;
        self.false_trigger_prob = 0.0;
        self
    }

    /// True pretravel (µm) for a touch with surface normal `n` (unit) at probing speed `v_mm_s`.
    pub fn pretravel_um(&self, n: [f64; 3], v_mm_s: f64) -> f64 {
        let theta = n[1].atan2(n[0]).to_degrees();
        let sin_phi = n[2].clamp(-1.0, 1.0);
        let cos2 = 1.0 - sin_phi * sin_phi;
        let psi = (theta - self.lobe_phase_deg + 60.0).rem_euclid(120.0) - 60.0;
        let lateral = self.lateral_base_um + self.lobe_um * (1.0 / psi.to_radians().cos() - 1.0);
        lateral * cos2
            + self.axial_um * sin_phi * sin_phi
            + (self.speed_um_per_mm_s + self.latency_ms) * v_mm_s.abs()
    }

    /// Effective radius (mm) the latched points show: stylus radius minus pretravel.
    pub fn effective_radius_mm(&self, n: [f64; 3], v_mm_s: f64) -> f64 {
        self.stylus_radius_mm - self.pretravel_um(n, v_mm_s) * 1e-3
    }
}

/// An artefact with a known geometry.
#[derive(Debug, Clone, PartialEq)]
pub enum Artefact {
    /// A sphere (touched from outside).
    Sphere {
        centre_mm: [f64; 3],
        diameter_mm: f64,
    },
    /// A ring gauge with a vertical axis (touched from inside, in the plane `z = centre.z`).
    Ring {
        centre_mm: [f64; 3],
        diameter_mm: f64,
    },
    /// The plane `z = z_mm` touched from above.
    Plane { z_mm: f64 },
}

/// One commanded touch.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedTouch {
    /// Index into [`ProbePlan::artefacts`].
    pub artefact: usize,
    /// Azimuth and elevation of the surface normal (degrees); for a plane only the touch position matters.
    pub azimuth_deg: f64,
    pub elevation_deg: f64,
    /// For a plane: the touch position (x, y) in mm.
    pub at_xy_mm: [f64; 2],
    pub feed_mm_min: f64,
    pub run: u32,
}

/// What is touched and how.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbePlan {
    /// (name, artefact).
    pub artefacts: Vec<(String, Artefact)>,
    pub touches: Vec<PlannedTouch>,
}

impl ProbePlan {
    /// Calibration on a reference sphere of `diameter_mm` centred at `centre_mm`: rings at the elevations
    /// `elevations_deg` (an elevation ≥ 89.9° is a single touch at the top) with `azimuths` touches each, at
    /// each of `feeds_mm_min`, repeated `repeats` times (runs 1..=repeats).
    pub fn calibration(
        centre_mm: [f64; 3],
        diameter_mm: f64,
        elevations_deg: &[f64],
        azimuths: usize,
        feeds_mm_min: &[f64],
        repeats: u32,
    ) -> Self {
        let mut touches = Vec::new();
        for run in 1..=repeats {
            for &feed in feeds_mm_min {
                for &el in elevations_deg {
                    let n_az = if el >= 89.9 { 1 } else { azimuths.max(1) };
                    for k in 0..n_az {
                        touches.push(PlannedTouch {
                            artefact: 0,
                            azimuth_deg: 360.0 * k as f64 / n_az as f64,
                            elevation_deg: el.min(90.0),
                            at_xy_mm: [0.0, 0.0],
                            feed_mm_min: feed,
                            run,
                        });
                    }
                }
            }
        }
        ProbePlan {
            artefacts: vec![(
                "cal_sphere".into(),
                Artefact::Sphere {
                    centre_mm,
                    diameter_mm,
                },
            )],
            touches,
        }
    }

    /// The default calibration: a Ø25 mm sphere at (100, 50, 20) mm, rings at 0°, 22.5°, 45°, 67.5° and
    /// the top, 24 azimuths, at 100, 300 and 600 mm/min, twice: (4·24 + 1)·3·2 = 582 touches.
    pub fn standard_calibration() -> Self {
        Self::calibration(
            [100.0, 50.0, 20.0],
            25.0,
            &[0.0, 22.5, 45.0, 67.5, 90.0],
            24,
            &[100.0, 300.0, 600.0],
            2,
        )
    }

    /// Measurement at `feed_mm_min` of a second sphere (Ø19.05 mm at (160, 40, 15) mm; rings at 10°, 35°,
    /// 60° and 80° with 16 azimuths offset from the calibration's), a ring gauge (Ø50 mm at (60, 120, 5) mm,
    /// 36 touches) and a plane (z = 2 mm, a 5 × 5 grid), repeated `repeats` times.
    pub fn measurement(feed_mm_min: f64, repeats: u32) -> Self {
        let artefacts = vec![
            (
                "sphere2".to_string(),
                Artefact::Sphere {
                    centre_mm: [160.0, 40.0, 15.0],
                    diameter_mm: 19.05,
                },
            ),
            (
                "ring".to_string(),
                Artefact::Ring {
                    centre_mm: [60.0, 120.0, 5.0],
                    diameter_mm: 50.0,
                },
            ),
            ("plane".to_string(), Artefact::Plane { z_mm: 2.0 }),
        ];
        let mut touches = Vec::new();
        for run in 1..=repeats {
            for &el in &[10.0, 35.0, 60.0, 80.0] {
                for k in 0..16 {
                    touches.push(PlannedTouch {
                        artefact: 0,
                        azimuth_deg: 7.0 + 22.5 * k as f64,
                        elevation_deg: el,
                        at_xy_mm: [0.0, 0.0],
                        feed_mm_min,
                        run,
                    });
                }
            }
            for k in 0..36 {
                touches.push(PlannedTouch {
                    artefact: 1,
                    azimuth_deg: 3.0 + 10.0 * k as f64,
                    elevation_deg: 0.0,
                    at_xy_mm: [0.0, 0.0],
                    feed_mm_min,
                    run,
                });
            }
            for i in 0..5 {
                for j in 0..5 {
                    touches.push(PlannedTouch {
                        artefact: 2,
                        azimuth_deg: 0.0,
                        elevation_deg: 90.0,
                        at_xy_mm: [20.0 + 20.0 * i as f64, 20.0 + 15.0 * j as f64],
                        feed_mm_min,
                        run,
                    });
                }
            }
        }
        ProbePlan { artefacts, touches }
    }
}

/// What produced a row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TouchKind {
    Good,
    /// The second trigger of a bounce.
    Bounce,
    /// A false trip before contact.
    FalseTrigger,
}

/// One simulated trigger (a row of the touch CSV) with its truth.
#[derive(Debug, Clone, PartialEq)]
pub struct SimTouch {
    /// Latched stylus-tip centre, mm.
    pub latched_mm: [f64; 3],
    /// Unit approach vector.
    pub approach: [f64; 3],
    pub feed_mm_min: f64,
    pub artefact: String,
    pub run: u32,
    /// The true surface point touched, mm.
    pub surface_mm: [f64; 3],
    /// The surface normal at it.
    pub normal: [f64; 3],
    /// True pretravel of this touch, µm (0 for a false trigger).
    pub pretravel_um: f64,
    pub kind: TouchKind,
}

use axcomp_numeric::noise::gauss;

fn dir(az_deg: f64, el_deg: f64) -> [f64; 3] {
    let (a, e) = (az_deg.to_radians(), el_deg.to_radians());
    [e.cos() * a.cos(), e.cos() * a.sin(), e.sin()]
}

/// Runs `plan` with `probe`; deterministic in `seed`.
pub fn simulate_touches(probe: &ProbeModel, plan: &ProbePlan, seed: u64) -> Vec<SimTouch> {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut glitch_rng = StdRng::seed_from_u64(seed ^ 0x0b0b_cafe_f00d_1234);
    let mut out = Vec::with_capacity(plan.touches.len() + 8);
    for t in &plan.touches {
        let (name, art) = &plan.artefacts[t.artefact];
        let (surface, normal) = match art {
            Artefact::Sphere {
                centre_mm,
                diameter_mm,
            } => {
                let n = dir(t.azimuth_deg, t.elevation_deg);
                let r = diameter_mm / 2.0;
                (
                    [
                        centre_mm[0] + r * n[0],
                        centre_mm[1] + r * n[1],
                        centre_mm[2] + r * n[2],
                    ],
                    n,
                )
            }
            Artefact::Ring {
                centre_mm,
                diameter_mm,
            } => {
                let e = dir(t.azimuth_deg, 0.0);
                let r = diameter_mm / 2.0;
                (
                    [
                        centre_mm[0] + r * e[0],
                        centre_mm[1] + r * e[1],
                        centre_mm[2],
                    ],
                    [-e[0], -e[1], 0.0],
                )
            }
            Artefact::Plane { z_mm } => ([t.at_xy_mm[0], t.at_xy_mm[1], *z_mm], [0.0, 0.0, 1.0]),
        };
        let r = probe.stylus_radius_mm;
        let contact = [
            surface[0] + r * normal[0],
            surface[1] + r * normal[1],
            surface[2] + r * normal[2],
        ];
        let u = [-normal[0], -normal[1], -normal[2]];
        let v = t.feed_mm_min / 60.0;
        let delta_um = probe.pretravel_um(normal, v);
        let noise_um = gauss(&mut rng, probe.noise_um);
        let along = |d_um: f64| -> [f64; 3] {
            [
                contact[0] + d_um * 1e-3 * u[0],
                contact[1] + d_um * 1e-3 * u[1],
                contact[2] + d_um * 1e-3 * u[2],
            ]
        };
        let row = |p: [f64; 3], pre: f64, kind: TouchKind| SimTouch {
            latched_mm: p,
            approach: u,
            feed_mm_min: t.feed_mm_min,
            artefact: name.clone(),
            run: t.run,
            surface_mm: surface,
            normal,
            pretravel_um: pre,
            kind,
        };
        let false_trip = glitch_rng.gen_bool(probe.false_trigger_prob.clamp(0.0, 1.0));
        let bounce = glitch_rng.gen_bool(probe.bounce_prob.clamp(0.0, 1.0));
        let (lo, hi) = probe.false_trigger_mm;
        let short_mm = lo + (hi - lo) * glitch_rng.gen_range(0.0..1.0);
        let (blo, bhi) = probe.bounce_um;
        let extra_um = blo + (bhi - blo) * glitch_rng.gen_range(0.0..1.0);
        if false_trip {
            // The move stops at the false trip: no real touch follows in this row's move.
            out.push(row(
                along(-short_mm * 1000.0 + noise_um),
                0.0,
                TouchKind::FalseTrigger,
            ));
            continue;
        }
        out.push(row(along(delta_um + noise_um), delta_um, TouchKind::Good));
        if bounce {
            out.push(row(
                along(delta_um + extra_um + noise_um),
                delta_um + extra_um,
                TouchKind::Bounce,
            ));
        }
    }
    out
}

/// The touches as the contract's touch CSV (latched positions to 0.1 nm so rounding does not add noise).
pub fn touches_csv(touches: &[SimTouch]) -> String {
    let mut s =
        String::from("x_mm,y_mm,z_mm,approach_x,approach_y,approach_z,feed_mm_min,artefact,run\n");
    for t in touches {
        s.push_str(&format!(
            "{:.7},{:.7},{:.7},{:.9},{:.9},{:.9},{},{},{}\n",
            t.latched_mm[0],
            t.latched_mm[1],
            t.latched_mm[2],
            t.approach[0],
            t.approach[1],
            t.approach[2],
            t.feed_mm_min,
            t.artefact,
            t.run
        ));
    }
    s
}

/// Effects on the touches beyond [`ProbeModel`] (the withheld-effect validation of the diagnosis on probe
/// data): direction-dependent speed pretravel, stylus bending, the machine's geometric error at
/// the touched point and thermal drift with a warm-up of the frame. All off by default
/// ([`TouchDisturbances::default`]); [`simulate_disturbed_touches`] runs a plan with them.
///
/// - **direction-dependent speed pretravel**: extra pretravel `v·(s_lat·cos²φ + s_ax·sin²φ)` (µm, v in
///   mm/s): a stylus is less stiff sideways than along its axis, so the speed term of a lateral touch differs
///   from an axial one (the twin's `speed_um_per_mm_s` and `latency_ms` act the same in every direction).
/// - **stylus bending**: extra pretravel `stylus_bending_um·cos φ`, growing with the lateral (horizontal)
///   component of the approach.
/// - **machine geometric error**: the tip stands at `p + e(p)` when the machine reads `p`; `e` (µm) is a
///   polynomial of degree ≤ 2 in the scaled position `q = (p − origin)/scale`:
///   `e_k = Σ_j a_kj·q_j + Σ_j b_kj·q_j² + Σ_{j<l} c_k,jl·q_j·q_l`.
/// - **thermal drift**: the frame's temperature rises as `rise_K·(1 − exp(−t/τ))` over the campaign
///   (`seconds_per_touch` per touch); the tip moves relative to the artefacts by `drift_um_per_K·ΔT`.
/// - **forms outside the simple columns** (a harder test of the diagnosis): the speed term ∝
///   `v^speed_exponent`, bending ∝ `cos^stylus_bending_exponent φ`, cubic terms of the machine error
///   ([`MachineErrorField::cubic`]), a frame sensor lagging the temperature that moves the machine
///   (`sensor_lag_s`). The defaults (1, 1, 0, 0) give the simple forms.
#[derive(Debug, Clone, PartialEq)]
pub struct TouchDisturbances {
    pub speed_lateral_um_per_mm_s: f64,
    pub speed_axial_um_per_mm_s: f64,
    pub stylus_bending_um: f64,
    pub machine_error: Option<MachineErrorField>,
    pub drift_um_per_k: [f64; 3],
    /// Frame warm-up: total rise (K) and time constant (s).
    pub warmup_rise_k: f64,
    pub warmup_tau_s: f64,
    /// Start temperature of the frame sensor, °C.
    pub frame_start_degc: f64,
    /// Standard deviation of the temperature reading, K.
    pub sensor_noise_k: f64,
    /// Time between touches, s.
    pub seconds_per_touch: f64,
    /// Speed pretravel ∝ `v^speed_exponent` (1: linear in speed).
    pub speed_exponent: f64,
    /// Stylus bending ∝ `cos^exponent φ` (1: the horizontal approach component).
    pub stylus_bending_exponent: f64,
    /// The frame sensor lags the temperature that moves the machine by a first-order lag of this time
    /// constant, s (0: no lag).
    pub sensor_lag_s: f64,
}

impl Default for TouchDisturbances {
    fn default() -> Self {
        TouchDisturbances {
            speed_lateral_um_per_mm_s: 0.0,
            speed_axial_um_per_mm_s: 0.0,
            stylus_bending_um: 0.0,
            machine_error: None,
            drift_um_per_k: [0.0; 3],
            warmup_rise_k: 2.0,
            warmup_tau_s: 1800.0,
            frame_start_degc: 20.0,
            sensor_noise_k: 0.01,
            seconds_per_touch: 3.0,
            speed_exponent: 1.0,
            stylus_bending_exponent: 1.0,
            sensor_lag_s: 0.0,
        }
    }
}

/// The machine's geometric error field `e(p)` (µm), a polynomial of degree ≤ 2 in the scaled position.
#[derive(Debug, Clone, PartialEq)]
pub struct MachineErrorField {
    pub origin_mm: [f64; 3],
    pub scale_mm: f64,
    /// `linear[k][j]`: µm of `e_k` per unit `q_j`.
    pub linear: [[f64; 3]; 3],
    /// `square[k][j]`: µm of `e_k` per unit `q_j²`.
    pub square: [[f64; 3]; 3],
    /// `cross[k][m]`: µm of `e_k` per unit `q_0·q_1`, `q_0·q_2`, `q_1·q_2` (m = 0, 1, 2).
    pub cross: [[f64; 3]; 3],
    /// `cubic[k][j]`: µm of `e_k` per unit `q_j³` (beyond the degree-2 field).
    pub cubic: [[f64; 3]; 3],
}

impl MachineErrorField {
    /// The error vector at `p_mm`, µm.
    pub fn error_um(&self, p_mm: [f64; 3]) -> [f64; 3] {
        let q = [
            (p_mm[0] - self.origin_mm[0]) / self.scale_mm,
            (p_mm[1] - self.origin_mm[1]) / self.scale_mm,
            (p_mm[2] - self.origin_mm[2]) / self.scale_mm,
        ];
        let qq = [q[0] * q[1], q[0] * q[2], q[1] * q[2]];
        let mut e = [0.0; 3];
        #[allow(clippy::needless_range_loop)] // parallel arrays indexed together
        for k in 0..3 {
            for j in 0..3 {
                e[k] += self.linear[k][j] * q[j]
                    + self.square[k][j] * q[j] * q[j]
                    + self.cross[k][j] * qq[j]
                    + self.cubic[k][j] * q[j] * q[j] * q[j];
            }
        }
        e
    }

    /// The same field times `f`.
    pub fn scaled(&self, f: f64) -> Self {
        let m = |a: [[f64; 3]; 3]| a.map(|r| r.map(|x| x * f));
        MachineErrorField {
            linear: m(self.linear),
            square: m(self.square),
            cross: m(self.cross),
            cubic: m(self.cubic),
            ..self.clone()
        }
    }
}

impl TouchDisturbances {
    /// Frame temperature rise (K, without sensor noise) at time `t_s`.
    pub fn delta_t_k(&self, t_s: f64) -> f64 {
        if self.warmup_tau_s > 0.0 {
            self.warmup_rise_k * (1.0 - (-t_s / self.warmup_tau_s).exp())
        } else {
            0.0
        }
    }

    /// What the frame sensor reads of the rise (K, without noise): the rise through the sensor's
    /// first-order lag (`sensor_lag_s`).
    pub fn sensed_delta_t_k(&self, t_s: f64) -> f64 {
        let (tau, lag) = (self.warmup_tau_s, self.sensor_lag_s);
        if lag.is_nan() || lag <= 0.0 || tau.is_nan() || tau <= 0.0 {
            return self.delta_t_k(t_s);
        }
        // Response of a first-order lag to A·(1 − e^{−t/τ}) from rest.
        let resp = if (tau - lag).abs() < 1e-9 * tau {
            1.0 - (1.0 + t_s / tau) * (-t_s / tau).exp()
        } else {
            1.0 - (tau * (-t_s / tau).exp() - lag * (-t_s / lag).exp()) / (tau - lag)
        };
        self.warmup_rise_k * resp
    }

    /// Extra pretravel (µm) along the approach for a touch with surface normal `n` at speed `v_mm_s`.
    pub fn extra_pretravel_um(&self, n: [f64; 3], v_mm_s: f64) -> f64 {
        let s2 = n[2].clamp(-1.0, 1.0).powi(2);
        let c2 = 1.0 - s2;
        v_mm_s.abs().powf(self.speed_exponent)
            * (self.speed_lateral_um_per_mm_s * c2 + self.speed_axial_um_per_mm_s * s2)
            + self.stylus_bending_um * c2.max(0.0).sqrt().powf(self.stylus_bending_exponent)
    }
}

/// One disturbed touch: the simulated trigger, when it happened and the frame sensor's reading.
#[derive(Debug, Clone, PartialEq)]
pub struct DisturbedTouch {
    pub touch: SimTouch,
    pub time_s: f64,
    pub frame_degc: f64,
}

/// Runs `plan` with `probe` and the further effects `dist` (touches in plan order, `seconds_per_touch`
/// apart). Deterministic in `seed`; with `dist` all off the latched points equal [`simulate_touches`]'s
/// (same seed), and the noise draws do not depend on `dist`, so two runs that differ only in an effect's
/// size differ only by that effect.
pub fn simulate_disturbed_touches(
    probe: &ProbeModel,
    dist: &TouchDisturbances,
    plan: &ProbePlan,
    seed: u64,
) -> Vec<DisturbedTouch> {
    let base = simulate_touches(probe, plan, seed);
    let mut sensor_rng = StdRng::seed_from_u64(seed ^ 0x7e3a_91c5_0d2f_4b68);
    let mut out = Vec::with_capacity(base.len());
    for (i, t) in base.into_iter().enumerate() {
        let time_s = i as f64 * dist.seconds_per_touch;
        let dt = dist.delta_t_k(time_s);
        let u = t.approach;
        let extra_um = if t.kind == TouchKind::FalseTrigger {
            0.0
        } else {
            dist.extra_pretravel_um(t.normal, t.feed_mm_min / 60.0)
        };
        // The machine reads p where the tip is at p + e(p) (+ drift): the reading is the tip minus that.
        let mut shift_um = [0.0; 3];
        if let Some(f) = &dist.machine_error {
            let e = f.error_um(t.latched_mm);
            for k in 0..3 {
                shift_um[k] -= e[k];
            }
        }
        for k in 0..3 {
            shift_um[k] -= dist.drift_um_per_k[k] * dt;
            shift_um[k] += extra_um * u[k];
        }
        let mut touch = t;
        #[allow(clippy::needless_range_loop)] // parallel arrays indexed together
        for k in 0..3 {
            touch.latched_mm[k] += shift_um[k] * 1e-3;
        }
        touch.pretravel_um += extra_um;
        out.push(DisturbedTouch {
            touch,
            time_s,
            frame_degc: dist.frame_start_degc
                + dist.sensed_delta_t_k(time_s)
                + gauss(&mut sensor_rng, dist.sensor_noise_k),
        });
    }
    out
}

/// Disturbed touches as the contract's touch CSV plus `time_s` and `frame_degC`.
pub fn disturbed_touches_csv(touches: &[DisturbedTouch]) -> String {
    let mut s = String::from(
        "x_mm,y_mm,z_mm,approach_x,approach_y,approach_z,feed_mm_min,artefact,run,time_s,frame_degC\n",
    );
    for d in touches {
        let t = &d.touch;
        s.push_str(&format!(
            "{:.7},{:.7},{:.7},{:.9},{:.9},{:.9},{},{},{},{:.3},{:.4}\n",
            t.latched_mm[0],
            t.latched_mm[1],
            t.latched_mm[2],
            t.approach[0],
            t.approach[1],
            t.approach[2],
            t.feed_mm_min,
            t.artefact,
            t.run,
            d.time_s,
            d.frame_degc
        ));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_lobes_and_speed_term() {
        let p = ProbeModel::kinematic_demo();
        // Lobe minimum at the phase, cusp 60° away: base and base + lobe (1/cos 60° − 1 = 1).
        let at = |az: f64| p.pretravel_um(dir(az, 0.0), 0.0);
        assert!((at(10.0) - 4.0).abs() < 1e-9);
        assert!((at(70.0 - 1e-9) - 7.0).abs() < 1e-6);
        // Three-fold symmetry (exact up to rounding, 1e-9 µm).
        assert!((at(33.0) - at(153.0)).abs() < 1e-9 && (at(33.0) - at(273.0)).abs() < 1e-9);
        // Axial touch and the speed-linear term: (0.3 + 0.3) µm per mm/s.
        assert!((p.pretravel_um([0.0, 0.0, 1.0], 10.0) - (2.0 + 6.0)).abs() < 1e-9);
    }

    #[test]
    fn calibration_plan_size_and_latched_geometry() {
        let plan = ProbePlan::standard_calibration();
        assert_eq!(plan.touches.len(), (4 * 24 + 1) * 3 * 2);
        let probe = ProbeModel::kinematic_demo().without_glitches();
        let t = simulate_touches(&probe, &plan, 1);
        // Every latched point lies R + r − δ − noise from the centre along the normal (noise < 6σ).
        for s in &t {
            let d = ((s.latched_mm[0] - 100.0).powi(2)
                + (s.latched_mm[1] - 50.0).powi(2)
                + (s.latched_mm[2] - 20.0).powi(2))
            .sqrt();
            let want = 12.5 + 1.5 - s.pretravel_um * 1e-3;
            assert!((d - want).abs() < 6.0 * 0.5e-3, "{d} vs {want}");
        }
    }

    #[test]
    fn disturbances_off_reproduce_the_plain_touches_and_each_acts_as_documented() {
        let plan = ProbePlan::calibration([0.0, 0.0, 0.0], 20.0, &[0.0, 45.0], 8, &[120.0], 1);
        let probe = ProbeModel::kinematic_demo().without_glitches();
        let plain = simulate_touches(&probe, &plan, 3);
        let off = TouchDisturbances {
            warmup_rise_k: 0.0,
            ..TouchDisturbances::default()
        };
        let same = simulate_disturbed_touches(&probe, &off, &plan, 3);
        // Reference: the undisturbed simulation with the same seed; exact.
        for (a, b) in plain.iter().zip(&same) {
            assert_eq!(a.latched_mm, b.touch.latched_mm);
        }
        // Stylus bending 2 µm on an equator touch (cos φ = 1): 2 µm further along the approach; tolerance
        // 1e-9 mm (rounding only).
        let bend = TouchDisturbances {
            stylus_bending_um: 2.0,
            ..off.clone()
        };
        let b = simulate_disturbed_touches(&probe, &bend, &plan, 3);
        let d: f64 = (0..3)
            .map(|k| {
                (b[0].touch.latched_mm[k] - same[0].touch.latched_mm[k]) * same[0].touch.approach[k]
            })
            .sum();
        assert!((d - 2e-3).abs() < 1e-9, "{d}");
        // A linear machine error e_x = 3 µm per unit q_x shifts the reading by −e.
        let mut lin = [[0.0; 3]; 3];
        lin[0][0] = 3.0;
        let geo = TouchDisturbances {
            machine_error: Some(MachineErrorField {
                origin_mm: [0.0; 3],
                scale_mm: 10.0,
                linear: lin,
                square: [[0.0; 3]; 3],
                cross: [[0.0; 3]; 3],
                cubic: [[0.0; 3]; 3],
            }),
            ..off
        };
        let g = simulate_disturbed_touches(&probe, &geo, &plan, 3);
        let x = same[0].touch.latched_mm[0];
        assert!((g[0].touch.latched_mm[0] - (x - 3e-3 * x / 10.0)).abs() < 1e-9);
    }
}
