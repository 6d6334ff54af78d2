//! `axcomp plan rtest`: which paths, added to K4, make all 11 location errors identifiable, and the standard
//! uncertainties they would give at a reading noise σ (`σ·sqrt(diag((JᵀJ)⁻¹))`, J the sensitivity matrix of
//! the planned poses, set-up offsets estimated alongside).

use axcomp_kinematics::rotary::{FiveAxis, MachineKind, N_LOCATION, Pose, c_circle, k4_path};
use serde::Serialize;

use crate::{head_fixed, identifiability, param_names, sensitivity_matrix};

/// Where the sphere sits and how the paths run.
#[derive(Debug, Clone, Copy)]
pub struct PlanGeometry {
    pub machine: FiveAxis,
    /// Sphere position (table frame for trunnions, machine frame for the head), mm.
    pub sphere_mm: [f64; 3],
    /// Second set-up: the sphere's height (z) raised by this much, mm.
    pub second_height_mm: f64,
    /// K4 tilt swing, degrees.
    pub tilt_max_deg: f64,
    pub k4_poses: usize,
    pub circle_poses: usize,
    /// The R-test head's zero is unknown (estimated per set-up).
    pub free_head_zero: bool,
}

impl PlanGeometry {
    /// Defaults: sphere at 150 mm radius, 100 mm above the table (trunnions) / at the origin (head); second
    /// height +100 mm; tilt 0 → −60° → 0; 72 K4 poses; 36 per circle.
    pub fn default_for(machine: FiveAxis) -> PlanGeometry {
        PlanGeometry {
            machine,
            sphere_mm: if machine.kind == MachineKind::BcHead {
                [0.0, 0.0, 0.0]
            } else {
                [150.0, 0.0, 100.0]
            },
            second_height_mm: 100.0,
            tilt_max_deg: -60.0,
            k4_poses: 72,
            circle_poses: 36,
            free_head_zero: false,
        }
    }

    /// A named path: `K4`, `C@T` (C circle at tilt T degrees), `K4-h2` / `C@T-h2` (second sphere height,
    /// set-up 1). Returns the poses and their set-up index.
    pub fn path(&self, name: &str) -> Option<(Vec<Pose>, usize)> {
        let (base, setup) = match name.strip_suffix("-h2") {
            Some(b) => (b, 1),
            None => (name, 0),
        };
        let mut s = self.sphere_mm;
        if setup == 1 {
            s[2] += self.second_height_mm;
        }
        if base == "K4" {
            return Some((
                k4_path(&self.machine, s, self.tilt_max_deg, self.k4_poses),
                setup,
            ));
        }
        let t: f64 = base.strip_prefix("C@")?.parse().ok()?;
        Some((c_circle(&self.machine, s, t, self.circle_poses), setup))
    }
}

/// One candidate measurement plan.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    pub paths: Vec<String>,
    pub poses: usize,
    pub rank: usize,
    pub condition_number: f64,
    pub all_identified: bool,
    /// Location errors: name, predicted standard uncertainty (µm or µrad), `None` when fixed to 0 (not
    /// separable); weakly determined ones have a std but are listed in `not_identified`.
    pub std: Vec<(String, Option<f64>)>,
    pub not_identified: Vec<String>,
}

/// Evaluates one set of paths.
pub fn evaluate(g: &PlanGeometry, paths: &[String], sigma_um: f64) -> Option<Candidate> {
    let mut poses = Vec::new();
    let mut setup = Vec::new();
    for p in paths {
        let (ps, s) = g.path(p)?;
        setup.extend(std::iter::repeat_n(s, ps.len()));
        poses.extend(ps);
    }
    let n_setups = setup.iter().max().map_or(1, |m| m + 1);
    let setups: Vec<String> = (1..=n_setups).map(|s| s.to_string()).collect();
    let names = param_names(g.machine.kind, &setups);
    let j = sensitivity_matrix(&g.machine, &poses, &setup, n_setups);
    let id = identifiability(&j, &names, &head_fixed(names.len(), g.free_head_zero));
    let free: Vec<usize> = (0..names.len()).filter(|&k| id.estimated[k]).collect();
    let jf = j.select_columns(free.iter());
    let inv = (jf.transpose() * &jf).try_inverse()?;
    let mut std = Vec::new();
    let mut not_identified = Vec::new();
    for (k, name) in names.iter().enumerate().take(N_LOCATION) {
        std.push((
            name.clone(),
            free.iter()
                .position(|&f| f == k)
                .map(|c| sigma_um * inv[(c, c)].sqrt()),
        ));
        if !id.identified[k] {
            not_identified.push(name.clone());
        }
    }
    Some(Candidate {
        paths: paths.to_vec(),
        poses: poses.len(),
        rank: id.rank,
        condition_number: id.condition_number,
        all_identified: not_identified.is_empty(),
        std,
        not_identified,
    })
}

/// The candidate plans, K4 alone first, then K4 with circles at two tilt angles and with a second sphere
/// height. `recommended` is the smallest plan (fewest poses) that identifies all 11.
#[derive(Debug, Clone, Serialize)]
pub struct Plan {
    pub machine: &'static str,
    pub sigma_um: f64,
    pub candidates: Vec<Candidate>,
    pub recommended: Option<usize>,
}

/// Plans for `g` at reading noise `sigma_um`.
pub fn plan(g: &PlanGeometry, sigma_um: f64) -> Plan {
    let t = g.tilt_max_deg;
    let h = g.tilt_max_deg / 2.0;
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    let c0 = "C@0".to_string();
    let ct = format!("C@{t}");
    let ch = format!("C@{h}");
    let mut sets = vec![
        s(&["K4"]),
        vec!["K4".into(), c0.clone()],
        vec!["K4".into(), ct.clone()],
        vec!["K4".into(), c0.clone(), ch.clone()],
        vec!["K4".into(), c0.clone(), ct.clone()],
    ];
    if g.machine.kind != MachineKind::BcHead {
        sets.push(s(&["K4", "K4-h2"]));
        sets.push(vec!["K4".into(), c0.clone(), ct.clone(), "K4-h2".into()]);
        sets.push(vec![
            "K4".into(),
            c0.clone(),
            ct.clone(),
            format!("{c0}-h2"),
            format!("{ct}-h2"),
        ]);
    }
    let candidates: Vec<Candidate> = sets
        .iter()
        .filter_map(|p| evaluate(g, p, sigma_um))
        .collect();
    let recommended = candidates
        .iter()
        .enumerate()
        .filter(|(_, c)| c.all_identified)
        .min_by_key(|(_, c)| c.poses)
        .map(|(i, _)| i);
    Plan {
        machine: g.machine.kind.name(),
        sigma_um,
        candidates,
        recommended,
    }
}
