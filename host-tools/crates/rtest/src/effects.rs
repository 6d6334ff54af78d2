//! Effects beyond the location errors as model terms: the first-order signatures (µm of displacement per
//! unit of parameter) of `rotary_positioning`, `rotary_wobble` and `linear_geometry` at one pose. One
//! implementation, used by `fit rtest --effects` / `predict` (as model parameters, [`EffectSet`]) and by
//! `axcomp diagnose` (as candidate columns, `axcomp_diagnose::rtest`).
//!
//! # Glossary
//! - **signature**: the displacement `d` (µm, machine X, Y, Z) a unit parameter adds at a pose, to first
//!   order; a term's contribution is `Σ_k value_k · signature_k(pose)`.
//! - `rotary_positioning` ([`EffectBasis::Positioning`]): the actual angle of C differs from the commanded
//!   one by `ε_C(c) = a_0 + Σ_{k≤H} (a_k cos kc + b_k sin kc)` µrad, and that of the tilt axis by
//!   `ε_T(t) = Σ_{d≤D} g_d t^d` µrad (t in rad); each mapped through the derivative of the exact
//!   displacement with respect to that axis's angle (central differences of `FiveAxis::displacement_at` at
//!   the location errors and set-up offsets). This is what a rotary axis's angular compensation table holds.
//! - `rotary_wobble` ([`EffectBasis::Wobble`]): the C axis tilting about the two axes perpendicular to it
//!   (µrad) and moving radially (run-out, µm), each as `cos kc`, `sin kc` for the listed harmonics k; with
//!   `tilt_degree > 0` also the tilt axis (A or B) tilting about its two perpendicular axes and moving
//!   radially as `t^d` (d = 1…tilt_degree; d = 0 is a location error): small rotations / translations of
//!   what the axis carries (trunnion: the table; head: the tool).
//! - `linear_geometry` ([`EffectBasis::Linear`]): errors of the tool point along X, Y, Z as Legendre
//!   polynomials `P_k` (k = 1…degree) of each listed linear axis's position mapped to −1…1 over
//!   `range_mm` (positioning and straightness, µm). Identifiable only over the range the poses move the
//!   axes through; the constant part is the set-up offsets', the linear parts partly the squareness's and
//!   the location errors' (these, taken first, keep what they share: see `identifiability`).

use axcomp_effects::RotaryEffect;
use axcomp_kinematics::rotary::{FiveAxis, LocationErrors, MachineKind, N_SETUP, Pose};
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// The parametrisation of one effect kind.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "basis", rename_all = "snake_case")]
pub enum EffectBasis {
    /// C harmonics 0…`c_harmonics`, tilt-axis polynomial degree 0…`tilt_degree`.
    Positioning {
        c_harmonics: usize,
        tilt_degree: usize,
    },
    /// C wobble per listed harmonic; tilt-axis wobble as powers 1…`tilt_degree` of its angle.
    Wobble {
        per_revolution: Vec<usize>,
        #[serde(default)]
        tilt_degree: usize,
    },
    /// Legendre degree 1…`degree` of each listed axis (0 = X, 1 = Y, 2 = Z) over its range (mm).
    Linear {
        axes: Vec<usize>,
        degree: usize,
        range_mm: Vec<[f64; 2]>,
    },
}

/// One effect term: its kind and parametrisation.
#[derive(Debug, Clone, PartialEq)]
pub struct EffectTerm {
    pub kind: RotaryEffect,
    pub basis: EffectBasis,
}

/// The effect kinds `fit rtest --effects` models (the drifts are not: a drift over one campaign's time
/// does not predict another campaign).
pub const MODELLED: [RotaryEffect; 3] = [
    RotaryEffect::RotaryPositioning,
    RotaryEffect::RotaryWobble,
    RotaryEffect::LinearGeometry,
];

/// Legendre polynomial `P_k(x)`, k ≤ 3.
pub fn legendre(k: usize, x: f64) -> f64 {
    match k {
        0 => 1.0,
        1 => x,
        2 => 0.5 * (3.0 * x * x - 1.0),
        _ => 0.5 * (5.0 * x * x * x - 3.0 * x),
    }
}

/// Per linear axis, the range (mm) the poses move it through (`None` when it does not move).
pub fn linear_ranges(machine: &FiveAxis, poses: &[Pose]) -> [Option<[f64; 2]>; 3] {
    std::array::from_fn(|a| {
        let q: Vec<f64> = poses
            .iter()
            .map(|p| machine.linear_positions(p)[a])
            .collect();
        let lo = q.iter().cloned().fold(f64::INFINITY, f64::min);
        let hi = q.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
        (hi - lo > 1e-9).then_some([lo, hi])
    })
}

fn rot(axis: usize, a: f64) -> Matrix3<f64> {
    let mut w = Vector3::zeros();
    w[axis] = a;
    *nalgebra::Rotation3::new(w).matrix()
}

fn v3(a: [f64; 3]) -> Vector3<f64> {
    Vector3::new(a[0], a[1], a[2])
}

/// Index of the tilt axis (0 = about X for `ac-trunnion`, 1 = about Y).
fn tilt_axis(kind: MachineKind) -> usize {
    if kind == MachineKind::AcTrunnion {
        0
    } else {
        1
    }
}

/// Per-pose geometry the signatures need.
pub struct PoseGeometry {
    /// Commanded tool point, mm.
    pub p: Vector3<f64>,
    /// Linear axes' positions, mm.
    pub q: Vector3<f64>,
    /// Nominal rotation of the tilt axis.
    pub rt: Matrix3<f64>,
    /// Nominal rotation of C.
    pub rc: Matrix3<f64>,
    pub tilt_rad: f64,
    pub c_rad: f64,
}

/// The geometry of `pose` on `machine`.
pub fn geometry(machine: &FiveAxis, pose: &Pose) -> PoseGeometry {
    PoseGeometry {
        p: v3(pose.p_mm),
        q: v3(machine.linear_positions(pose)),
        rt: rot(tilt_axis(machine.kind), pose.tilt_deg.to_radians()),
        rc: rot(2, pose.c_deg.to_radians()),
        tilt_rad: pose.tilt_deg.to_radians(),
        c_rad: pose.c_deg.to_radians(),
    }
}

/// Derivative (µm per µrad) of the exact displacement with respect to the actual angle of the tilt axis
/// (`which = 0`) or of C (`which = 1`), the linear axes staying where they were commanded: central
/// differences of `FiveAxis::displacement_at` at the location errors `le` and set-up offsets `setup`.
pub fn angle_derivative(
    machine: &FiveAxis,
    pose: &Pose,
    le: &LocationErrors,
    setup: [f64; N_SETUP],
    which: usize,
) -> [f64; 3] {
    let q = machine.linear_positions(pose);
    let s = machine.nominal_sphere(pose);
    let h_urad: f64 = 10.0;
    let h_deg = (h_urad * 1e-6).to_degrees();
    let at = |sign: f64| {
        let (t, c) = if which == 0 {
            (pose.tilt_deg + sign * h_deg, pose.c_deg)
        } else {
            (pose.tilt_deg, pose.c_deg + sign * h_deg)
        };
        // The commanded point for which the linear axes sit at `q` with the rotary axes at (t, c).
        let l0 = machine.linear_positions(&Pose {
            p_mm: [0.0; 3],
            tilt_deg: t,
            c_deg: c,
        });
        let p = [q[0] - l0[0], q[1] - l0[1], q[2] - l0[2]];
        machine.displacement_at(
            &Pose {
                p_mm: p,
                tilt_deg: t,
                c_deg: c,
            },
            s,
            le,
            setup,
        )
    };
    let (a, b) = (at(1.0), at(-1.0));
    [0, 1, 2].map(|i| (a[i] - b[i]) / (2.0 * h_urad))
}

/// Small rotation (per µrad) about `e` of what C carries → displacement µm: trunnion `(Rt·e) × p`, head
/// `−e × (p − q)` (the tool vector).
pub fn c_carried_rotation(kind: MachineKind, g: &PoseGeometry, e: Vector3<f64>) -> Vector3<f64> {
    match kind {
        MachineKind::BcHead => -e.cross(&(g.p - g.q)) * 1e-3,
        _ => (g.rt * e).cross(&g.p) * 1e-3,
    }
}

/// Radial motion (per µm) of the C axis along `e` → displacement µm.
pub fn c_carried_translation(kind: MachineKind, g: &PoseGeometry, e: Vector3<f64>) -> Vector3<f64> {
    match kind {
        MachineKind::BcHead => -e,
        _ => g.rt * e,
    }
}

/// Small rotation (per µrad) about `e` (machine frame at zero angles) of what the tilt axis carries →
/// displacement µm: trunnion `e × p` (the table and sphere turn about the tilt axis's line through the
/// origin); head `−(Rc·e) × (p − q)` (the tool, turned by C).
pub fn tilt_carried_rotation(kind: MachineKind, g: &PoseGeometry, e: Vector3<f64>) -> Vector3<f64> {
    match kind {
        MachineKind::BcHead => -(g.rc * e).cross(&(g.p - g.q)) * 1e-3,
        _ => e.cross(&g.p) * 1e-3,
    }
}

/// Radial motion (per µm) of the tilt axis along `e` → displacement µm.
pub fn tilt_carried_translation(
    kind: MachineKind,
    g: &PoseGeometry,
    e: Vector3<f64>,
) -> Vector3<f64> {
    match kind {
        MachineKind::BcHead => -(g.rc * e),
        _ => e,
    }
}

/// The two unit axes perpendicular to the tilt axis.
fn tilt_perpendiculars(kind: MachineKind) -> [(char, Vector3<f64>); 2] {
    if tilt_axis(kind) == 0 {
        [('y', Vector3::y()), ('z', Vector3::z())]
    } else {
        [('x', Vector3::x()), ('z', Vector3::z())]
    }
}

impl EffectTerm {
    /// Parameter names and units, in signature order. `tilt` is the tilt axis's letter (`A` or `B`).
    pub fn param_names(&self, kind: MachineKind) -> Vec<(String, &'static str)> {
        let tilt = kind.tilt_letter().to_ascii_uppercase();
        let mut v = Vec::new();
        match &self.basis {
            EffectBasis::Positioning {
                c_harmonics,
                tilt_degree,
            } => {
                v.push(("C_offset".to_string(), "urad"));
                for k in 1..=*c_harmonics {
                    v.push((format!("C_cos{k}"), "urad"));
                    v.push((format!("C_sin{k}"), "urad"));
                }
                for d in 0..=*tilt_degree {
                    v.push((format!("{tilt}_t{d}"), "urad"));
                }
            }
            EffectBasis::Wobble {
                per_revolution,
                tilt_degree,
            } => {
                for k in per_revolution {
                    for trig in ["cos", "sin"] {
                        for ax in ['x', 'y'] {
                            v.push((format!("C_tilt_{ax}_{trig}{k}"), "urad"));
                            v.push((format!("C_radial_{ax}_{trig}{k}"), "um"));
                        }
                    }
                }
                for d in 1..=*tilt_degree {
                    for (ax, _) in tilt_perpendiculars(kind) {
                        v.push((format!("{tilt}_tilt_{ax}_t{d}"), "urad"));
                        v.push((format!("{tilt}_radial_{ax}_t{d}"), "um"));
                    }
                }
            }
            EffectBasis::Linear { axes, degree, .. } => {
                for &a in axes {
                    for k in 1..=*degree {
                        for comp in ["dx", "dy", "dz"] {
                            v.push((format!("{}_P{k}_{comp}", ["X", "Y", "Z"][a]), "um"));
                        }
                    }
                }
            }
        }
        v
    }

    /// Number of parameters.
    pub fn n_params(&self, kind: MachineKind) -> usize {
        self.param_names(kind).len()
    }

    /// The signatures at `pose` (one per parameter, µm per unit), the location errors `le` and set-up
    /// offsets `setup` (used by `rotary_positioning`'s angle derivatives).
    pub fn signatures(
        &self,
        machine: &FiveAxis,
        pose: &Pose,
        le: &LocationErrors,
        setup: [f64; N_SETUP],
    ) -> Vec<[f64; 3]> {
        let g = geometry(machine, pose);
        let kind = machine.kind;
        let arr = |v: Vector3<f64>| [v[0], v[1], v[2]];
        let mut out = Vec::new();
        match &self.basis {
            EffectBasis::Positioning {
                c_harmonics,
                tilt_degree,
            } => {
                let jc = v3(angle_derivative(machine, pose, le, setup, 1));
                let jt = v3(angle_derivative(machine, pose, le, setup, 0));
                out.push(arr(jc));
                for k in 1..=*c_harmonics {
                    let kc = k as f64 * g.c_rad;
                    out.push(arr(jc * kc.cos()));
                    out.push(arr(jc * kc.sin()));
                }
                for d in 0..=*tilt_degree {
                    out.push(arr(jt * g.tilt_rad.powi(d as i32)));
                }
            }
            EffectBasis::Wobble {
                per_revolution,
                tilt_degree,
            } => {
                for &k in per_revolution {
                    let kc = k as f64 * g.c_rad;
                    for w in [kc.cos(), kc.sin()] {
                        for e in [Vector3::x(), Vector3::y()] {
                            out.push(arr(c_carried_rotation(kind, &g, e) * w));
                            out.push(arr(c_carried_translation(kind, &g, e) * w));
                        }
                    }
                }
                for d in 1..=*tilt_degree {
                    let w = g.tilt_rad.powi(d as i32);
                    for (_, e) in tilt_perpendiculars(kind) {
                        out.push(arr(tilt_carried_rotation(kind, &g, e) * w));
                        out.push(arr(tilt_carried_translation(kind, &g, e) * w));
                    }
                }
            }
            EffectBasis::Linear {
                axes,
                degree,
                range_mm,
            } => {
                for (&a, r) in axes.iter().zip(range_mm) {
                    let x = 2.0 * (g.q[a] - r[0]) / (r[1] - r[0]) - 1.0;
                    for k in 1..=*degree {
                        let p = legendre(k, x);
                        out.push([0, 1, 2].map(|c| if c == 0 { p } else { 0.0 }));
                        out.push([0, 1, 2].map(|c| if c == 1 { p } else { 0.0 }));
                        out.push([0, 1, 2].map(|c| if c == 2 { p } else { 0.0 }));
                    }
                }
            }
        }
        out
    }

    /// The term `fit rtest --effects KIND` adds on `poses` (the richest variant the diagnosis refits a told
    /// effect with): C harmonics 0…4 and tilt degree 0…2; C wobble at 1, 2, 3 per turn and the tilt axis's
    /// wobble to degree 2; Legendre degree 3 of each linear axis the poses move. `None` for a kind that
    /// is not modelled ([`MODELLED`]) or cannot be built (no linear axis moves).
    pub fn richest(kind: RotaryEffect, machine: &FiveAxis, poses: &[Pose]) -> Option<EffectTerm> {
        let basis = match kind {
            RotaryEffect::RotaryPositioning => EffectBasis::Positioning {
                c_harmonics: 4,
                tilt_degree: 2,
            },
            RotaryEffect::RotaryWobble => EffectBasis::Wobble {
                per_revolution: vec![1, 2, 3],
                tilt_degree: 2,
            },
            RotaryEffect::LinearGeometry => {
                let r = linear_ranges(machine, poses);
                let axes: Vec<usize> = (0..3).filter(|&a| r[a].is_some()).collect();
                if axes.is_empty() {
                    return None;
                }
                EffectBasis::Linear {
                    range_mm: axes.iter().filter_map(|&a| r[a]).collect(),
                    axes,
                    degree: 3,
                }
            }
            _ => return None,
        };
        Some(EffectTerm { kind, basis })
    }
}

/// The effect terms of a model, in order; their parameters follow the location errors and set-up offsets.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct EffectSet {
    pub terms: Vec<EffectTerm>,
}

impl EffectSet {
    /// Total number of parameters.
    pub fn n_params(&self, kind: MachineKind) -> usize {
        self.terms.iter().map(|t| t.n_params(kind)).sum()
    }

    /// Whether there is no term.
    pub fn is_empty(&self) -> bool {
        self.terms.is_empty()
    }

    /// Every term's signatures at `pose`, concatenated.
    pub fn signatures(
        &self,
        machine: &FiveAxis,
        pose: &Pose,
        le: &LocationErrors,
        setup: [f64; N_SETUP],
    ) -> Vec<[f64; 3]> {
        self.terms
            .iter()
            .flat_map(|t| t.signatures(machine, pose, le, setup))
            .collect()
    }

    /// The displacement (µm) the effects add at `pose` with parameter values `values` (concatenated).
    pub fn displacement(
        &self,
        machine: &FiveAxis,
        pose: &Pose,
        le: &LocationErrors,
        setup: [f64; N_SETUP],
        values: &[f64],
    ) -> [f64; 3] {
        let mut d = [0.0; 3];
        if self.terms.is_empty() {
            return d;
        }
        for (s, v) in self.signatures(machine, pose, le, setup).iter().zip(values) {
            for c in 0..3 {
                d[c] += s[c] * v;
            }
        }
        d
    }
}
