//! Five-axis twin: a machine with rotary-axis location errors (ISO 230-7, exact HTM model from
//! `axcomp_kinematics::rotary`) and effects beyond them, measured by an R-test along K4 and planned paths.
//!
//! Glossary:
//! - **truth**: the 11 location errors (offsets 5–50 µm, tilts and squareness 10–100 µrad, random signs,
//!   seedable) and the set-up offsets per set-up: the sphere's 2–20 µm per axis; the R-test head's zero 0
//!   (calibrated tool length, as in the seed) unless [`FiveAxisTwin::unknown_head_zero`].
//! - **effects beyond** ([`FiveAxisEffects`], each switchable, all off by default), added to first order on
//!   top of the exact location-error model: `rotary_positioning` (angular positioning error of C,
//!   1×+2× per turn, 5–20 µrad, and of the tilt axis, proportional to the tilt, 10–40 µrad/rad),
//!   `rotary_wobble` (tilt of C turning twice per turn, 3–10 µrad), `tilt_wobble` (the tilt axis A or B
//!   tilting about its two perpendicular axes as it turns, `a·(sin(t + φ) − sin φ)` with a 10–30 µrad
//!   by default, other shapes in [`TiltWobbleShape`], radial motion 1–4 µm for the shape that has one:
//!   a `rotary_wobble` in the contract's vocabulary), `radial_runout` (radial motion of C twice
//!   per turn, 0.5–2 µm), `linear_geometry` (X positioning 5–15 µm/m, straightness EYX and EZY 1–3 µm
//!   half-sines over ±300 mm), `thermal_drift` (tool point drifting 1–4 µm/h in Z, ±1 µm/h in X),
//!   `setup_drift` (sphere drifting 1–3 µm/h per axis in the table frame), `time_drift` (tool point
//!   creeping 1–3 µm/h per axis in the machine frame with no temperature behind it).
//! - **temperature sensor** ([`FiveAxisTwin::temperature_sensor`], off by default): the campaign carries a
//!   `spindle_degC` reading, `20 + ΔT(t)` with a warm-up `ΔT_rise·(1 − e^(−t/τ))` (0.5–1.5 K, τ 10–20 min)
//!   and the shop's air-conditioning cycle (0.2–0.5 K, period 12–20 min); `thermal_drift` then follows ΔT
//!   (its µm/h figures read as µm/K) instead of time, so a temperature column can explain it.
//! - **reading**: `d = S − T` (µm), the sphere centre relative to the R-test head along machine X, Y, Z, plus
//!   Gaussian noise σ per component.
//! - **campaign order**: paths are measured one after the other, `dwell_s` per pose; `time_s` counts from
//!   the first pose.

use axcomp_kinematics::rotary::{
    FiveAxis, LocationErrors, MachineKind, N_LOCATION, N_SETUP, Pose, SetupOffsets,
};
use axcomp_kinematics::rotary::{c_circle, k4_path, location_unit};
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

/// Effects beyond the location errors (each switchable).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FiveAxisEffects {
    pub rotary_positioning: bool,
    pub rotary_wobble: bool,
    /// The tilt axis (A or B) tilting about its two perpendicular axes as it turns (a `rotary_wobble`).
    pub tilt_wobble: bool,
    pub radial_runout: bool,
    pub linear_geometry: bool,
    pub thermal_drift: bool,
    pub setup_drift: bool,
    pub time_drift: bool,
}

impl FiveAxisEffects {
    /// Every effect beyond the location errors except `time_drift` (creep with no temperature behind it):
    /// the twin the R-test checks of effects beyond the model use.
    pub const fn all_but_time_drift() -> Self {
        Self {
            rotary_positioning: true,
            rotary_wobble: true,
            tilt_wobble: false,
            radial_runout: true,
            linear_geometry: true,
            thermal_drift: true,
            setup_drift: true,
            time_drift: false,
        }
    }

    /// Effect names (the contract's candidate kinds for R-test data; `radial_runout` belongs to
    /// `rotary_wobble` there).
    pub const NAMES: [&'static str; 8] = [
        "rotary_positioning",
        "rotary_wobble",
        "tilt_wobble",
        "radial_runout",
        "linear_geometry",
        "thermal_drift",
        "setup_drift",
        "time_drift",
    ];

    /// Switches one effect on by name; `false` for an unknown name.
    pub fn enable(&mut self, name: &str) -> bool {
        match name {
            "rotary_positioning" => self.rotary_positioning = true,
            "rotary_wobble" => self.rotary_wobble = true,
            "tilt_wobble" => self.tilt_wobble = true,
            "radial_runout" => self.radial_runout = true,
            "linear_geometry" => self.linear_geometry = true,
            "thermal_drift" => self.thermal_drift = true,
            "setup_drift" => self.setup_drift = true,
            "time_drift" => self.time_drift = true,
            _ => return false,
        }
        true
    }
}

/// Magnitudes of the effects beyond (drawn from the seed even when switched off).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EffectParams {
    /// C positioning: 1× and 2× amplitudes (µrad) and phases (rad); tilt positioning slope µrad/rad.
    pub c_pos: [f64; 4],
    pub tilt_pos_urad_per_rad: f64,
    /// Wobble amplitude µrad, phase rad.
    pub wobble: [f64; 2],
    /// Run-out amplitude µm, phase rad.
    pub runout: [f64; 2],
    /// X scale µm/m, EYX and EZY amplitudes µm.
    pub linear: [f64; 3],
    /// Tool-point drift µm/h along X and Z.
    pub thermal_um_h: [f64; 2],
    /// Sphere drift µm/h along table X, Y, Z.
    pub setup_um_h: [f64; 3],
    /// Tool-point creep µm/h along machine X, Y, Z (`time_drift`).
    pub time_um_h: [f64; 3],
    /// Temperature: warm-up rise K, its time constant s, air-conditioning amplitude K, period s, phase rad.
    pub temperature: [f64; 5],
    /// Tilt-axis wobble: amplitudes (µrad) about the two axes perpendicular to it (A: Y, Z; B: X, Z) and
    /// their phases (rad); the shape in `tilt_wobble_shape`, zero at tilt 0.
    pub tilt_wobble: [f64; 4],
    /// How the tilt-axis wobble varies with the tilt angle (default: first harmonic).
    pub tilt_wobble_shape: TiltWobbleShape,
    /// Radial motion (µm) of the tilt axis along its two perpendicular axes, twice per turn, and its phase
    /// (rad): used by [`TiltWobbleShape::Harmonic1Radial`] only.
    pub tilt_wobble_radial: [f64; 3],
}

/// How the tilt-axis wobble's two small rotations vary with the tilt angle `t` (rad), each zero at `t = 0`
/// (a constant part is a location error). `a` is the amplitude (µrad), `φ` the phase.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TiltWobbleShape {
    /// `a·(sin(t + φ) − sin φ)`: mostly what a tilted axis of rotation does, so mostly absorbed by the
    /// axis's orientation location errors.
    #[default]
    Harmonic1,
    /// `±a·t` (µrad per rad of tilt; the sign of `cos φ`).
    Linear,
    /// `±a·t²` (µrad per rad²; the sign of `cos φ`).
    Quadratic,
    /// `a·(sin(2t + φ) − sin φ)`: twice per turn.
    Harmonic2,
    /// A tilt only beyond 0.5 rad (≈ 29°) of travel, `±2a·max(0, |t| − 0.5)` (the sign of `cos φ`):
    /// a bearing that tilts over part of the range.
    Partial,
    /// The first harmonic plus a radial motion of the axis twice per turn,
    /// `r_k·(sin(2t + ψ + kπ/2) − sin(ψ + kπ/2))` along its two perpendicular axes.
    Harmonic1Radial,
}

impl TiltWobbleShape {
    pub const ALL: [TiltWobbleShape; 6] = [
        TiltWobbleShape::Harmonic1,
        TiltWobbleShape::Linear,
        TiltWobbleShape::Quadratic,
        TiltWobbleShape::Harmonic2,
        TiltWobbleShape::Harmonic1Radial,
        TiltWobbleShape::Partial,
    ];

    pub fn name(self) -> &'static str {
        match self {
            TiltWobbleShape::Harmonic1 => "harmonic1",
            TiltWobbleShape::Linear => "linear",
            TiltWobbleShape::Quadratic => "quadratic",
            TiltWobbleShape::Harmonic2 => "harmonic2",
            TiltWobbleShape::Harmonic1Radial => "harmonic1_radial",
            TiltWobbleShape::Partial => "partial",
        }
    }

    /// The rotation (µrad) of amplitude `a` and phase `phi` at tilt `t` (rad).
    pub fn tilt_urad(self, a: f64, phi: f64, t: f64) -> f64 {
        match self {
            TiltWobbleShape::Harmonic1 | TiltWobbleShape::Harmonic1Radial => {
                a * ((t + phi).sin() - phi.sin())
            }
            TiltWobbleShape::Linear => a * t * phi.cos().signum(),
            TiltWobbleShape::Quadratic => a * t * t * phi.cos().signum(),
            TiltWobbleShape::Harmonic2 => a * ((2.0 * t + phi).sin() - phi.sin()),
            TiltWobbleShape::Partial => 2.0 * a * (t.abs() - 0.5).max(0.0) * phi.cos().signum(),
        }
    }

    /// The radial motion (µm) along the tilt axis's two perpendicular axes at tilt `t` (rad).
    pub fn radial_um(self, radial: &[f64; 3], t: f64) -> [f64; 2] {
        if self != TiltWobbleShape::Harmonic1Radial {
            return [0.0; 2];
        }
        let half_pi = std::f64::consts::FRAC_PI_2;
        [0, 1].map(|k| {
            let p = radial[2] + k as f64 * half_pi;
            radial[k] * ((2.0 * t + p).sin() - p.sin())
        })
    }
}

impl EffectParams {
    /// The tilt-axis wobble at tilt `t` (rad) of the axis `tilt_axis` (0: A, 1: B): its small rotation
    /// (rad) and its radial motion (mm), both in the machine frame at zero angles.
    fn tilt_wobble_at(&self, t: f64, tilt_axis: usize) -> ([f64; 3], [f64; 3]) {
        let (tw, shape) = (&self.tilt_wobble, self.tilt_wobble_shape);
        let a = shape.tilt_urad(tw[0], tw[2], t) * 1e-6;
        let b = shape.tilt_urad(tw[1], tw[3], t) * 1e-6;
        let [p, q] = shape
            .radial_um(&self.tilt_wobble_radial, t)
            .map(|v| v * 1e-3);
        if tilt_axis == 0 {
            ([0.0, a, b], [0.0, p, q])
        } else {
            ([a, 0.0, b], [p, 0.0, q])
        }
    }
}

/// One planned path.
#[derive(Debug, Clone)]
pub struct RtestPathSpec {
    /// Path id written to the `path` column (`K4`, `C-circle@-60`, ...).
    pub path: String,
    pub run: u32,
    /// Set-up id (the sphere's placement).
    pub setup: String,
    /// The sphere's nominal position (table frame, or machine frame for a head), mm.
    pub sphere_mm: [f64; 3],
    pub poses: Vec<Pose>,
}

/// The five-axis machine.
#[derive(Debug, Clone)]
pub struct FiveAxisTwin {
    pub machine: FiveAxis,
    pub location: LocationErrors,
    /// Sphere set-up offsets (µm) of set-ups `1`, `2`, ... (by order of first use: index 0 for the first).
    pub setup_offsets_um: Vec<SetupOffsets>,
    pub effects: FiveAxisEffects,
    pub effect_params: EffectParams,
    /// Reading noise σ per component, µm.
    pub noise_um: f64,
    /// Seconds per pose.
    pub dwell_s: f64,
    /// The campaign carries a spindle temperature (`spindle_degC`) and `thermal_drift` follows it.
    pub temperature_sensor: bool,
}

fn signed(rng: &mut impl Rng, lo: f64, hi: f64) -> f64 {
    let v = rng.gen_range(lo..hi);
    if rng.gen_bool(0.5) { v } else { -v }
}

impl FiveAxisTwin {
    /// A random machine (see the glossary for the ranges), no effects beyond, noise 0.3 µm, 2 s per pose.
    pub fn random(machine: FiveAxis, seed: u64) -> FiveAxisTwin {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x0005_a715_7e57);
        let mut location = [0.0; N_LOCATION];
        for (k, v) in location.iter_mut().enumerate() {
            *v = if location_unit(k) == "um" {
                signed(&mut rng, 5.0, 50.0)
            } else {
                signed(&mut rng, 10.0, 100.0)
            };
        }
        // Sphere offsets random; the R-test head's zero known (0) unless `unknown_head_zero`.
        let setup_offsets_um = (0..4)
            .map(|_| {
                let mut v = [0; N_SETUP].map(|_| signed(&mut rng, 2.0, 20.0));
                v[3..].fill(0.0);
                v
            })
            .collect();
        let tau = std::f64::consts::TAU;
        let effect_params = EffectParams {
            c_pos: [
                rng.gen_range(5.0..20.0),
                rng.gen_range(5.0..20.0),
                rng.gen_range(0.0..tau),
                rng.gen_range(0.0..tau),
            ],
            tilt_pos_urad_per_rad: signed(&mut rng, 10.0, 40.0),
            wobble: [rng.gen_range(3.0..10.0), rng.gen_range(0.0..tau)],
            runout: [rng.gen_range(0.5..2.0), rng.gen_range(0.0..tau)],
            linear: [
                signed(&mut rng, 5.0, 15.0),
                signed(&mut rng, 1.0, 3.0),
                signed(&mut rng, 1.0, 3.0),
            ],
            thermal_um_h: [signed(&mut rng, 0.2, 1.0), -rng.gen_range(1.0..4.0)],
            setup_um_h: [
                signed(&mut rng, 1.0, 3.0),
                signed(&mut rng, 1.0, 3.0),
                signed(&mut rng, 1.0, 3.0),
            ],
            time_um_h: [0.0; 3],
            temperature: [0.0; 5],
            tilt_wobble: [0.0; 4],
            tilt_wobble_shape: TiltWobbleShape::Harmonic1,
            tilt_wobble_radial: [0.0; 3],
        };
        // Drawn from a second stream so that the first stream's values stay those of earlier versions.
        let mut rng2 = rand::rngs::StdRng::seed_from_u64(seed ^ 0x0074_696d_6564);
        let mut effect_params = effect_params;
        effect_params.time_um_h = [0; 3].map(|_| signed(&mut rng2, 1.0, 3.0));
        effect_params.temperature = [
            rng2.gen_range(0.5..1.5),
            rng2.gen_range(600.0..1200.0),
            rng2.gen_range(0.2..0.5),
            rng2.gen_range(720.0..1200.0),
            rng2.gen_range(0.0..tau),
        ];
        // A third stream, for the same reason.
        let mut rng3 = rand::rngs::StdRng::seed_from_u64(seed ^ 0x0074_696c_7477);
        effect_params.tilt_wobble = [
            rng3.gen_range(10.0..30.0),
            rng3.gen_range(10.0..30.0),
            rng3.gen_range(0.0..tau),
            rng3.gen_range(0.0..tau),
        ];
        // A fourth stream for the radial motion, so the earlier streams stay as they were.
        let mut rng4 = rand::rngs::StdRng::seed_from_u64(seed ^ 0x0072_6164_6961);
        effect_params.tilt_wobble_radial = [
            rng4.gen_range(1.0..4.0),
            rng4.gen_range(1.0..4.0),
            rng4.gen_range(0.0..tau),
        ];
        FiveAxisTwin {
            machine,
            location,
            setup_offsets_um,
            effects: FiveAxisEffects::default(),
            effect_params,
            noise_um: 0.3,
            dwell_s: 2.0,
            temperature_sensor: false,
        }
    }

    /// The same machine with the R-test head's zero off by 2–20 µm per axis and set-up (an uncalibrated tool
    /// length / radial offset, or readings zeroed at the first pose).
    pub fn unknown_head_zero(mut self, seed: u64) -> FiveAxisTwin {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x6865_6164);
        for v in self.setup_offsets_um.iter_mut() {
            for x in v[3..].iter_mut() {
                *x = signed(&mut rng, 2.0, 20.0);
            }
        }
        self
    }

    /// The temperature rise ΔT (K) of the spindle at `time_s` (see the glossary).
    pub fn temperature_rise(&self, time_s: f64) -> f64 {
        let [rise, tau, ac, period, phase] = self.effect_params.temperature;
        let t = time_s.max(0.0);
        rise * (1.0 - (-t / tau.max(1e-9)).exp())
            + ac * ((std::f64::consts::TAU * t / period.max(1e-9) + phase).sin() - phase.sin())
    }

    /// The noise-free reading (µm) at `pose` (commanded so that the tool point meets the nominal sphere
    /// `sphere_mm`) in set-up `setup`, at time `time_s`.
    pub fn reading(&self, pose: &Pose, sphere_mm: [f64; 3], setup: usize, time_s: f64) -> [f64; 3] {
        let e = &self.effects;
        let q = &self.effect_params;
        let mut setup_um = self.setup_offsets_um[setup % self.setup_offsets_um.len()];
        if e.setup_drift {
            for (i, s) in setup_um.iter_mut().take(3).enumerate() {
                *s += q.setup_um_h[i] * time_s / 3600.0;
            }
        }
        let mut d = self
            .machine
            .displacement_at(pose, sphere_mm, &self.location, setup_um);
        // Effects beyond, to first order (mm and rad inside, µm out).
        let c = pose.c_deg.to_radians();
        let t = pose.tilt_deg.to_radians();
        let tilt_axis = if self.machine.kind == MachineKind::AcTrunnion {
            0
        } else {
            1
        };
        let rot = |axis: usize, a: f64| -> [[f64; 3]; 3] {
            let (s, co) = a.sin_cos();
            match axis {
                0 => [[1.0, 0.0, 0.0], [0.0, co, -s], [0.0, s, co]],
                1 => [[co, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, co]],
                _ => [[co, -s, 0.0], [s, co, 0.0], [0.0, 0.0, 1.0]],
            }
        };
        let mul = |m: [[f64; 3]; 3], v: [f64; 3]| -> [f64; 3] {
            [0, 1, 2].map(|i| m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2])
        };
        let cross = |a: [f64; 3], b: [f64; 3]| -> [f64; 3] {
            [
                a[1] * b[2] - a[2] * b[1],
                a[2] * b[0] - a[0] * b[2],
                a[0] * b[1] - a[1] * b[0],
            ]
        };
        let mut unit = [0.0; 3];
        unit[tilt_axis] = 1.0;
        let eps_c = if e.rotary_positioning {
            (q.c_pos[0] * (c + q.c_pos[2]).sin() + q.c_pos[1] * (2.0 * c + q.c_pos[3]).sin()) * 1e-6
        } else {
            0.0
        };
        let eps_t = if e.rotary_positioning {
            q.tilt_pos_urad_per_rad * t * 1e-6
        } else {
            0.0
        };
        let w = if e.rotary_wobble {
            let a = 2.0 * c + q.wobble[1];
            [
                q.wobble[0] * a.cos() * 1e-6,
                q.wobble[0] * a.sin() * 1e-6,
                0.0,
            ]
        } else {
            [0.0; 3]
        };
        let r = if e.radial_runout {
            let a = 2.0 * c + q.runout[1];
            [
                q.runout[0] * a.cos() * 1e-3,
                q.runout[0] * a.sin() * 1e-3,
                0.0,
            ]
        } else {
            [0.0; 3]
        };
        // Tilt-axis wobble: a small rotation `wt` (machine frame at zero angles) of what the tilt axis
        // carries, and its radial motion `wr` (mm).
        let (wt, wr) = if e.tilt_wobble {
            q.tilt_wobble_at(t, tilt_axis)
        } else {
            ([0.0; 3], [0.0; 3])
        };
        let (rt, rc) = (rot(tilt_axis, t), rot(2, c));
        let mut extra = [0.0; 3];
        let lin_q = match self.machine.kind {
            MachineKind::BcHead => {
                let tool = [0.0, 0.0, -self.machine.pivot_mm];
                let v_b = mul(rt, tool);
                let v = mul(rc, v_b);
                let w_b = [0, 1, 2].map(|i| unit[i] * eps_t + wt[i]);
                let inner = cross(w_b, v_b);
                let rc_inner = mul(rc, [0, 1, 2].map(|i| inner[i] + wr[i]));
                let cz = cross([0.0, 0.0, eps_c], v);
                let wv = cross(w, v);
                for i in 0..3 {
                    extra[i] -= cz[i] + wv[i] + r[i] + rc_inner[i];
                }
                self.machine.linear_positions(pose)
            }
            _ => {
                let s: [f64; 3] = std::array::from_fn(|i| sphere_mm[i] + setup_um[i] * 1e-3);
                let u = mul(rc, s);
                let cz = cross([0.0, 0.0, eps_c], u);
                let wu = cross(w, u);
                let inner = [0, 1, 2].map(|i| cz[i] + wu[i] + r[i]);
                let outer = mul(rt, inner);
                let full = mul(rt, u);
                let tz = cross([0, 1, 2].map(|i| unit[i] * eps_t + wt[i]), full);
                for i in 0..3 {
                    extra[i] += outer[i] + tz[i] + wr[i];
                }
                pose.p_mm
            }
        };
        for i in 0..3 {
            d[i] += extra[i] * 1e3;
        }
        if e.linear_geometry {
            let half = |x: f64| (std::f64::consts::PI * (x + 300.0) / 600.0).sin();
            d[0] -= q.linear[0] * lin_q[0] * 1e-3;
            d[1] -= q.linear[1] * half(lin_q[0]);
            d[2] -= q.linear[2] * half(lin_q[1]);
        }
        if e.thermal_drift {
            // Per hour without a sensor; per kelvin of the spindle's rise with one.
            let x = if self.temperature_sensor {
                self.temperature_rise(time_s)
            } else {
                time_s / 3600.0
            };
            d[0] -= q.thermal_um_h[0] * x;
            d[2] -= q.thermal_um_h[1] * x;
        }
        if e.time_drift {
            for (i, v) in q.time_um_h.iter().enumerate() {
                d[i] -= v * time_s / 3600.0;
            }
        }
        d
    }

    /// Measures the paths in order (noise seeded by `seed`).
    pub fn measure(&self, paths: &[RtestPathSpec], seed: u64) -> RtestCampaign {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed ^ 0x0052_7465_7374);
        let noise = Normal::new(0.0, self.noise_um.max(0.0)).expect("finite σ");
        let mut setups: Vec<String> = Vec::new();
        let mut rows = Vec::new();
        let mut time = 0.0;
        for p in paths {
            let s = match setups.iter().position(|x| *x == p.setup) {
                Some(s) => s,
                None => {
                    setups.push(p.setup.clone());
                    setups.len() - 1
                }
            };
            for pose in &p.poses {
                let mut d = self.reading(pose, p.sphere_mm, s, time);
                for v in d.iter_mut() {
                    *v += noise.sample(&mut rng);
                }
                rows.push(RtestRow {
                    pose: *pose,
                    d_um: d,
                    path: p.path.clone(),
                    run: p.run,
                    setup: p.setup.clone(),
                    setup_index: s,
                    sphere_mm: p.sphere_mm,
                    time_s: time,
                    spindle_degc: 20.0 + self.temperature_rise(time),
                });
                time += self.dwell_s;
            }
        }
        RtestCampaign {
            machine: self.machine,
            rows,
            temperature_sensor: self.temperature_sensor,
        }
    }
}

/// One measured pose.
#[derive(Debug, Clone)]
pub struct RtestRow {
    pub pose: Pose,
    pub d_um: [f64; 3],
    pub path: String,
    pub run: u32,
    pub setup: String,
    pub setup_index: usize,
    pub sphere_mm: [f64; 3],
    pub time_s: f64,
    /// Spindle temperature, °C (written only when the twin has its sensor).
    pub spindle_degc: f64,
}

/// A measured R-test campaign.
#[derive(Debug, Clone)]
pub struct RtestCampaign {
    pub machine: FiveAxis,
    pub rows: Vec<RtestRow>,
    /// The rows carry a spindle temperature (`spindle_degC` column).
    pub temperature_sensor: bool,
}

impl RtestCampaign {
    /// The contract's R-test CSV: `x_mm,y_mm,z_mm,a_deg|b_deg,c_deg,dx_um,dy_um,dz_um,path,run,setup,time_s`
    /// (then `spindle_degC` when the twin has its temperature sensor).
    pub fn to_csv_string(&self) -> String {
        let t = self.machine.kind.tilt_letter();
        let mut s = format!(
            "# axcomp five-axis twin, machine {}\nx_mm,y_mm,z_mm,{t}_deg,c_deg,dx_um,dy_um,dz_um,path,run,setup,time_s{}\n",
            self.machine.kind.name(),
            if self.temperature_sensor {
                ",spindle_degC"
            } else {
                ""
            }
        );
        for r in &self.rows {
            s.push_str(&format!(
                "{},{},{},{},{},{:.4},{:.4},{:.4},{},{},{},{}",
                r.pose.p_mm[0],
                r.pose.p_mm[1],
                r.pose.p_mm[2],
                r.pose.tilt_deg,
                r.pose.c_deg,
                r.d_um[0],
                r.d_um[1],
                r.d_um[2],
                r.path,
                r.run,
                r.setup,
                r.time_s
            ));
            if self.temperature_sensor {
                s.push_str(&format!(",{:.4}", r.spindle_degc));
            }
            s.push('\n');
        }
        s
    }
}

/// The standard R-test plan: K4 run 1 (`k4_poses` poses, tilt 0 → `tilt_max_deg` → 0), C circles at the
/// tilts `circle_tilts_deg` (run 1), optionally the same circles with the sphere raised by
/// `second_height_mm` (set-up 2), then K4 run 2 (the one to hold out). Sphere at `sphere_mm`.
pub fn standard_paths(
    machine: &FiveAxis,
    sphere_mm: [f64; 3],
    tilt_max_deg: f64,
    k4_poses: usize,
    circle_tilts_deg: &[f64],
    circle_poses: usize,
    second_height_mm: Option<f64>,
) -> Vec<RtestPathSpec> {
    let k4 = |run| RtestPathSpec {
        path: "K4".into(),
        run,
        setup: "1".into(),
        sphere_mm,
        poses: k4_path(machine, sphere_mm, tilt_max_deg, k4_poses),
    };
    let mut v = vec![k4(1)];
    for &t in circle_tilts_deg {
        v.push(RtestPathSpec {
            path: format!("C-circle@{t}"),
            run: 1,
            setup: "1".into(),
            sphere_mm,
            poses: c_circle(machine, sphere_mm, t, circle_poses),
        });
    }
    if let Some(h) = second_height_mm {
        let s2 = [sphere_mm[0], sphere_mm[1], sphere_mm[2] + h];
        for &t in circle_tilts_deg {
            v.push(RtestPathSpec {
                path: format!("C-circle@{t}-h2"),
                run: 1,
                setup: "2".into(),
                sphere_mm: s2,
                poses: c_circle(machine, s2, t, circle_poses),
            });
        }
    }
    v.push(k4(2));
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    fn setup(kind: MachineKind) -> (FiveAxisTwin, Vec<RtestPathSpec>) {
        let m = FiveAxis::new(kind, 250.0);
        let twin = FiveAxisTwin::random(m, 11);
        let s = if kind == MachineKind::BcHead {
            [0.0; 3]
        } else {
            [150.0, 0.0, 100.0]
        };
        (
            twin,
            standard_paths(&m, s, -60.0, 72, &[0.0, -60.0], 36, None),
        )
    }

    /// Reference: the exact location-error model of `axcomp_kinematics::rotary`; with every effect beyond
    /// off and no noise the twin reads exactly that (tolerance 1e-12 µm).
    #[test]
    fn without_effects_the_twin_is_the_exact_model() {
        for kind in [
            MachineKind::AcTrunnion,
            MachineKind::BcTrunnion,
            MachineKind::BcHead,
        ] {
            let (mut twin, paths) = setup(kind);
            twin.noise_um = 0.0;
            let c = twin.measure(&paths, 1);
            assert_eq!(c.rows.len(), 2 * 72 + 2 * 36);
            for r in &c.rows {
                let d = twin.machine.displacement_at(
                    &r.pose,
                    r.sphere_mm,
                    &twin.location,
                    twin.setup_offsets_um[0],
                );
                #[allow(clippy::needless_range_loop)] // parallel arrays indexed together
                for i in 0..3 {
                    assert!((d[i] - r.d_um[i]).abs() < 1e-12);
                }
            }
        }
    }

    /// Each effect beyond, switched on alone, changes the readings by an amount of its stated size: RMS
    /// change between 0.05 µm and 20 µm over the campaign (reference: the ranges in the module glossary).
    #[test]
    fn each_effect_is_switchable_and_visible() {
        for kind in [
            MachineKind::AcTrunnion,
            MachineKind::BcTrunnion,
            MachineKind::BcHead,
        ] {
            let (mut base, paths) = setup(kind);
            base.noise_um = 0.0;
            let clean = base.measure(&paths, 1);
            for name in FiveAxisEffects::NAMES {
                let mut t = base.clone();
                assert!(t.effects.enable(name));
                let c = t.measure(&paths, 1);
                let rms = (c
                    .rows
                    .iter()
                    .zip(&clean.rows)
                    .map(|(a, b)| (0..3).map(|i| (a.d_um[i] - b.d_um[i]).powi(2)).sum::<f64>())
                    .sum::<f64>()
                    / (3 * c.rows.len()) as f64)
                    .sqrt();
                assert!((0.05..20.0).contains(&rms), "{kind:?} {name}: {rms}");
            }
        }
    }

    /// The CSV carries the contract's columns, with the tilt column named after the machine.
    #[test]
    fn csv_has_contract_columns() {
        let (twin, paths) = setup(MachineKind::BcTrunnion);
        let csv = twin.measure(&paths, 2).to_csv_string();
        let header = csv.lines().nth(1).unwrap();
        assert_eq!(
            header,
            "x_mm,y_mm,z_mm,b_deg,c_deg,dx_um,dy_um,dz_um,path,run,setup,time_s"
        );
        assert_eq!(csv.lines().count(), 2 + 216);
    }

    /// With the temperature sensor the CSV carries `spindle_degC` = 20 + ΔT(t) and `thermal_drift` follows
    /// ΔT: the Z change of the reading is −(µm/K)·ΔT exactly (reference: the glossary's definition,
    /// tolerance 1e-9 µm; noise off). `time_drift` is −(µm/h)·t along each machine axis.
    #[test]
    fn temperature_sensor_and_time_drift() {
        let (mut base, paths) = setup(MachineKind::AcTrunnion);
        base.noise_um = 0.0;
        base.temperature_sensor = true;
        let clean = base.measure(&paths, 1);
        let csv = clean.to_csv_string();
        assert!(
            csv.lines()
                .nth(1)
                .unwrap()
                .ends_with(",time_s,spindle_degC")
        );
        let mut th = base.clone();
        th.effects.thermal_drift = true;
        let mut td = base.clone();
        td.effects.time_drift = true;
        let (ct, cd) = (th.measure(&paths, 1), td.measure(&paths, 1));
        let q = base.effect_params;
        let mut spread = (f64::INFINITY, f64::NEG_INFINITY);
        for k in 0..clean.rows.len() {
            let r = &clean.rows[k];
            let dt = r.spindle_degc - 20.0;
            assert!((dt - base.temperature_rise(r.time_s)).abs() < 1e-12);
            spread = (spread.0.min(dt), spread.1.max(dt));
            let dz = ct.rows[k].d_um[2] - r.d_um[2];
            assert!((dz + q.thermal_um_h[1] * dt).abs() < 1e-9, "{dz}");
            for i in 0..3 {
                let d = cd.rows[k].d_um[i] - r.d_um[i];
                assert!((d + q.time_um_h[i] * r.time_s / 3600.0).abs() < 1e-9);
            }
        }
        assert!(spread.1 - spread.0 > 0.05, "{spread:?}");
    }

    /// Every tilt-wobble shape is zero at tilt 0 (a constant part would be a location error), only the
    /// radial shape moves the axis, and the default shape is the first harmonic.
    #[test]
    fn tilt_wobble_shapes_vanish_at_zero_tilt() {
        let twin = FiveAxisTwin::random(FiveAxis::new(MachineKind::AcTrunnion, 0.0), 5);
        assert_eq!(
            twin.effect_params.tilt_wobble_shape,
            TiltWobbleShape::Harmonic1
        );
        for shape in TiltWobbleShape::ALL {
            let mut q = twin.effect_params;
            q.tilt_wobble_shape = shape;
            let (w0, r0) = q.tilt_wobble_at(0.0, 0);
            assert!(w0.iter().chain(&r0).all(|v| v.abs() < 1e-15), "{shape:?}");
            let (w, r) = q.tilt_wobble_at(-1.2, 0);
            assert!(w[1].abs() > 1e-7, "{shape:?}: {w:?}");
            let moves = r.iter().any(|v| v.abs() > 1e-6);
            assert_eq!(
                moves,
                shape == TiltWobbleShape::Harmonic1Radial,
                "{shape:?}"
            );
        }
    }
}
