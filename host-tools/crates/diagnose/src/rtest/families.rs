//! The candidate families of an R-test campaign (see the glossary of [`super`]): one method per effect
//! kind, each adding its family or saying why it is not applicable.

use axcomp_effects::RotaryEffect;
use axcomp_kinematics::rotary::{MachineKind, N_LOCATION, N_SETUP};
use axcomp_rtest::effects::{EffectBasis, EffectTerm, linear_ranges};
use nalgebra::{DMatrix, Vector3};
use serde_json::json;

use super::observations::{RtestFamily, RtestObservations, stack, variant};

/// What the families are built from: the observations, the training fit and its sensitivity matrix.
pub(super) struct Builder<'a> {
    pub(super) obs: &'a RtestObservations,
    pub(super) fit: &'a axcomp_rtest::Fit,
    /// Sensitivity (Jacobian) matrix of every parameter, stacked rows.
    pub(super) j: &'a DMatrix<f64>,
}

/// The candidate families and the kinds not applicable, with why.
#[derive(Default)]
pub(super) struct Families {
    pub(super) families: Vec<RtestFamily>,
    pub(super) not_applicable: Vec<(RotaryEffect, String)>,
}

impl Builder<'_> {
    /// Every family the columns allow.
    pub(super) fn build(&self) -> Families {
        let mut out = Families::default();
        self.positioning(&mut out);
        self.wobble(&mut out);
        self.linear(&mut out);
        self.drifts(&mut out);
        self.thermal(&mut out);
        out
    }

    /// The families' columns: the signatures of `axcomp_rtest::effects` (the same terms `fit rtest
    /// --effects` fits) at the training fit's location errors and set-up offsets, one column per
    /// parameter.
    fn term_columns(&self, kind: RotaryEffect, basis: EffectBasis) -> Vec<Vec<f64>> {
        let data = &self.obs.data;
        let machine = data.machine;
        let n = self.obs.n_poses();
        let term = EffectTerm { kind, basis };
        let np = term.n_params(machine.kind);
        let mut cols = vec![vec![0.0; 3 * n]; np];
        for (i, pose) in data.poses.iter().enumerate() {
            let (le, so) = axcomp_rtest::split_params(&self.fit.theta, data.setup[i]);
            for (k, sig) in term.signatures(&machine, pose, &le, so).iter().enumerate() {
                cols[k][3 * i..3 * i + 3].copy_from_slice(sig);
            }
        }
        cols
    }

    fn tilt_letter(&self) -> char {
        self.obs
            .data
            .machine
            .kind
            .tilt_letter()
            .to_ascii_uppercase()
    }

    /// `rotary_positioning`: C harmonics 1…4 with the tilt axis's polynomial of degree 1…2.
    fn positioning(&self, out: &mut Families) {
        let term_columns = |k, b| self.term_columns(k, b);
        let tilt_letter = self.tilt_letter();
        let families = &mut out.families;
        let mut variants = Vec::new();
        for harmonics in 1..=4usize {
            for tilt_degree in 1..=2usize {
                let basis = EffectBasis::Positioning {
                    c_harmonics: harmonics,
                    tilt_degree,
                };
                variants.push(variant(
                    term_columns(RotaryEffect::RotaryPositioning, basis),
                    json!({"c_harmonics": harmonics, "tilt_degree": tilt_degree, "axes": format!("C and {tilt_letter}")}),
                ));
            }
        }
        families.push(RtestFamily {
            kind: RotaryEffect::RotaryPositioning,
            variants,
        });
    }

    /// `rotary_wobble`: C tilting about the two axes perpendicular to it and moving radially, per
    /// harmonic; or the tilt axis doing so as powers of its angle.
    fn wobble(&self, out: &mut Families) {
        let term_columns = |k, b| self.term_columns(k, b);
        let tilt_letter = self.tilt_letter();
        let families = &mut out.families;
        let mut variants = Vec::new();
        for set in [vec![1], vec![2], vec![3], vec![1, 2], vec![1, 2, 3]] {
            let basis = EffectBasis::Wobble {
                per_revolution: set.clone(),
                tilt_degree: 0,
            };
            variants.push(variant(
                term_columns(RotaryEffect::RotaryWobble, basis),
                json!({"per_revolution": set, "components": "tilt about two axes ⊥ C, radial run-out"}),
            ));
        }
        // The tilt axis's own wobble (A or B tilting about its two perpendicular axes as it turns, and its
        // radial motion): without it an A-axis wobble is named `linear_geometry`, whose position
        // polynomials absorb part of it. Powers 1…d of the tilt angle; the constant is a
        // location error.
        // The tilt alone (an angular error motion of the axis without radial motion) is a variant of its
        // own: half the columns, so on R-test paths, where the location errors absorb most of a tilt
        // varying with the angle, the part they leave is found with more power.
        for tilt_degree in 1..=2usize {
            let basis = EffectBasis::Wobble {
                per_revolution: Vec::new(),
                tilt_degree,
            };
            let names = EffectTerm {
                kind: RotaryEffect::RotaryWobble,
                basis: basis.clone(),
            }
            .param_names(self.obs.data.machine.kind);
            let cols = term_columns(RotaryEffect::RotaryWobble, basis);
            let tilt_only: Vec<Vec<f64>> = cols
                .iter()
                .zip(&names)
                .filter(|(_, (name, _))| name.contains("_tilt_"))
                .map(|(c, _)| c.clone())
                .collect();
            variants.push(variant(
                tilt_only,
                json!({"per_revolution": [], "tilt_degree": tilt_degree, "components": format!("tilt of the {tilt_letter} axis about its two perpendicular axes, powers 1…{tilt_degree} of its angle")}),
            ));
            variants.push(variant(
                cols,
                json!({"per_revolution": [], "tilt_degree": tilt_degree, "components": format!("tilt of the {tilt_letter} axis about its two perpendicular axes and its radial motion, powers 1…{tilt_degree} of its angle")}),
            ));
        }
        families.push(RtestFamily {
            kind: RotaryEffect::RotaryWobble,
            variants,
        });
    }

    /// `linear_geometry`: e_i · P_k(q_j) over the range the poses move the linear axes through.
    fn linear(&self, out: &mut Families) {
        let term_columns = |k, b| self.term_columns(k, b);
        let data = &self.obs.data;
        let machine = data.machine;
        let (families, not_applicable) = (&mut out.families, &mut out.not_applicable);
        let ranges = linear_ranges(&machine, &data.poses);
        let axis_names = ["X", "Y", "Z"];
        let cols_for = |axes: &[usize], degree: usize| -> Vec<Vec<f64>> {
            let basis = EffectBasis::Linear {
                axes: axes.to_vec(),
                degree,
                range_mm: axes.iter().filter_map(|&a| ranges[a]).collect(),
            };
            term_columns(RotaryEffect::LinearGeometry, basis)
        };
        let moving: Vec<usize> = (0..3).filter(|&a| ranges[a].is_some()).collect();
        if moving.is_empty() {
            not_applicable.push((
                RotaryEffect::LinearGeometry,
                "the linear axes do not move on these poses".to_string(),
            ));
        } else {
            let mut variants = Vec::new();
            for degree in 1..=3 {
                variants.push(variant(
                    cols_for(&moving, degree),
                    json!({"axes": moving.iter().map(|&a| axis_names[a]).collect::<String>(), "degree": degree}),
                ));
            }
            if moving.len() > 1 {
                for &a in &moving {
                    for degree in 2..=3 {
                        variants.push(variant(
                            cols_for(&[a], degree),
                            json!({"axes": axis_names[a], "degree": degree}),
                        ));
                    }
                }
            }
            families.push(RtestFamily {
                kind: RotaryEffect::LinearGeometry,
                variants,
            });
        }
    }

    /// The sphere's own set-up columns per pose (table frame for trunnions, machine frame for a head).
    fn sphere_columns(&self) -> Vec<[Vector3<f64>; 3]> {
        let (data, j) = (&self.obs.data, self.j);
        (0..self.obs.n_poses())
            .map(|i| {
                let b = N_LOCATION + N_SETUP * data.setup[i];
                [0, 1, 2].map(|a| {
                    Vector3::new(
                        j[(3 * i, b + a)],
                        j[(3 * i + 1, b + a)],
                        j[(3 * i + 2, b + a)],
                    )
                })
            })
            .collect()
    }

    /// `setup_drift` and `time_drift`: the sphere (table frame) or the tool point (machine frame) moving
    /// as powers 1…2 of the campaign's scaled time.
    fn drifts(&self, out: &mut Families) {
        let obs = self.obs;
        let kind = obs.data.machine.kind;
        let sphere = self.sphere_columns();
        let (families, not_applicable) = (&mut out.families, &mut out.not_applicable);
        let (machine_frame, table_frame) = frames(obs.n_poses(), &sphere);
        let tau: Option<Vec<f64>> = obs.time_s.as_ref().and_then(|t| {
            let lo = t.iter().cloned().fold(f64::INFINITY, f64::min);
            let hi = t.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            (hi - lo > 0.0).then(|| t.iter().map(|v| (v - lo) / (hi - lo)).collect())
        });
        match &tau {
            None => {
                let why = if obs.time_s.is_some() {
                    "`time_s` is constant"
                } else {
                    "no `time_s` column"
                };
                not_applicable.push((RotaryEffect::SetupDrift, why.to_string()));
                not_applicable.push((RotaryEffect::TimeDrift, why.to_string()));
            }
            Some(tau) => {
                let powers =
                    |d: usize| -> Vec<f64> { tau.iter().map(|t| t.powi(d as i32)).collect() };
                let mut sd = Vec::new();
                let mut td = Vec::new();
                for degree in 1..=2usize {
                    let mut cs = Vec::new();
                    let mut ct = Vec::new();
                    for d in 1..=degree {
                        cs.extend(table_frame(&powers(d)));
                        ct.extend(machine_frame(&powers(d)));
                    }
                    sd.push(variant(cs, json!({"time_degree": degree, "frame": if kind == MachineKind::BcHead { "machine" } else { "table" }})));
                    td.push(variant(
                        ct,
                        json!({"time_degree": degree, "frame": "machine"}),
                    ));
                }
                families.push(RtestFamily {
                    kind: RotaryEffect::SetupDrift,
                    variants: sd,
                });
                families.push(RtestFamily {
                    kind: RotaryEffect::TimeDrift,
                    variants: td,
                });
            }
        }
    }

    /// `thermal_drift`: ΔT of each sensor from its value at the earliest pose, moving the tool point
    /// (machine frame) and, on a trunnion, the sphere (table frame).
    fn thermal(&self, out: &mut Families) {
        let obs = self.obs;
        let n = obs.n_poses();
        let kind = obs.data.machine.kind;
        let sphere = self.sphere_columns();
        let (families, not_applicable) = (&mut out.families, &mut out.not_applicable);
        let (machine_frame, table_frame) = frames(n, &sphere);
        let first = match &obs.time_s {
            Some(t) => (0..n).min_by(|&a, &b| t[a].total_cmp(&t[b])).unwrap_or(0),
            None => 0,
        };
        let rises: Vec<(String, Vec<f64>)> = obs
            .temperatures
            .iter()
            .filter(|(_, v)| v.iter().any(|x| (x - v[0]).abs() > 1e-9))
            .map(|(name, v)| (name.clone(), v.iter().map(|x| x - v[first]).collect()))
            .collect();
        if rises.is_empty() {
            not_applicable.push((
                RotaryEffect::ThermalDrift,
                if obs.temperatures.is_empty() {
                    "no `*_degC` column".to_string()
                } else {
                    "the `*_degC` columns are constant".to_string()
                },
            ));
        } else {
            let mut variants = Vec::new();
            let mut sets: Vec<Vec<usize>> = vec![(0..rises.len()).collect()];
            if rises.len() > 1 {
                sets.extend((0..rises.len()).map(|k| vec![k]));
            }
            for set in sets {
                let sensors: Vec<&str> = set.iter().map(|&k| rises[k].0.as_str()).collect();
                let mut cm = Vec::new();
                let mut ct = Vec::new();
                for &k in &set {
                    cm.extend(machine_frame(&rises[k].1));
                    ct.extend(table_frame(&rises[k].1));
                }
                variants.push(variant(
                    cm.clone(),
                    json!({"sensors": sensors, "moves": "tool point (machine frame)"}),
                ));
                if kind != MachineKind::BcHead {
                    cm.extend(ct);
                    variants.push(variant(
                        cm,
                        json!({"sensors": sensors, "moves": "tool point and sphere"}),
                    ));
                }
            }
            families.push(RtestFamily {
                kind: RotaryEffect::ThermalDrift,
                variants,
            });
        }
    }
}

/// Columns of a per-pose weight `w` along machine X, Y, Z (`machine_frame`) and along the sphere's own
/// set-up directions (`table_frame`).
#[allow(clippy::type_complexity)]
fn frames(
    n: usize,
    sphere: &[[Vector3<f64>; 3]],
) -> (
    impl Fn(&[f64]) -> Vec<Vec<f64>> + '_,
    impl Fn(&[f64]) -> Vec<Vec<f64>> + '_,
) {
    let e = [Vector3::x(), Vector3::y(), Vector3::z()];
    let machine_frame = move |w: &[f64]| -> Vec<Vec<f64>> {
        e.iter()
            .map(|&ax| stack(&w.iter().map(|&x| ax * x).collect::<Vec<_>>()))
            .collect()
    };
    let table_frame = move |w: &[f64]| -> Vec<Vec<f64>> {
        (0..3)
            .map(|a| stack(&(0..n).map(|i| sphere[i][a] * w[i]).collect::<Vec<_>>()))
            .collect()
    };
    (machine_frame, table_frame)
}
