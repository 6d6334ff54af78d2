//! A blind-set-like check of the R-test diagnosis on an `ac-trunnion`: campaigns with nothing beyond the
//! location errors, a rotary positioning error, or a wobble of the A axis, where the amplitudes, the
//! reading noise and the K4-like path set all vary from seed to seed (so that no figure depends on the
//! twin's own magnitudes or on the fixed validation plan of [`crate::rtest`]).
//!
//! Glossary:
//! - **case kind** ([`BlindKind`]): `none`, `rotary_positioning` (the twin's C and A positioning errors)
//!   or `a_wobble` (the twin's `tilt_wobble`: A tilting about Y and Z as it turns, a `rotary_wobble`),
//!   its shape ([`TiltWobbleShape`]: first or second harmonic of the angle, linear, quadratic, first
//!   harmonic with a radial motion) drawn per seed.
//! - **varied plan** ([`varied_plan`]): set-up 1 at a random sphere position: a K4 (48–96 poses, tilt
//!   0 → t_max → 0 with t_max in −90…−40°) and C circles at 0° and t_max (24 or 36 poses); with even
//!   chance a second set-up (another sphere position, the same two circles); held out (`run = 2`): a C
//!   circle at a random tilt between 30 % and 70 % of t_max and a second K4.
//! - **scale**: the effect's magnitudes times a log-uniform factor in ½…2; **noise**: σ uniform in
//!   0.15…0.5 µm per component.
//! - **oracle shrink**: the held-out shrink of the linearised base model plus the true contribution as
//!   one column, refitted on the training rows ([`crate::harness`]); a case is **identifiable** when it
//!   reaches the verdict rule's materiality floor (5 %): below it no rule that keeps the null cases clean
//!   can name the effect, as the A-axis wobble is then almost all absorbed by the A axis's location
//!   errors (its orientation) on these paths.

use axcomp_diagnose::judge::{DiagnoseOptions, MIN_SHRINK_PCT};
use axcomp_kinematics::rotary::{FiveAxis, MachineKind, c_circle, k4_path};
use axcomp_numeric::noise::TestNoise;
use axcomp_twin::five_axis::{FiveAxisTwin, RtestPathSpec, TiltWobbleShape};
use serde::Serialize;

use crate::harness;
use crate::rtest::{observations, scale_effect};

/// What a blind case holds beyond the location errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BlindKind {
    None,
    RotaryPositioning,
    AWobble,
}

impl BlindKind {
    pub const ALL: [BlindKind; 3] = [
        BlindKind::None,
        BlindKind::RotaryPositioning,
        BlindKind::AWobble,
    ];

    /// The verdict that is right for this kind.
    pub fn want(self) -> &'static str {
        match self {
            BlindKind::None => "none",
            BlindKind::RotaryPositioning => "rotary_positioning",
            BlindKind::AWobble => "rotary_wobble",
        }
    }

    /// The twin's effect (None for a null case).
    fn twin_effect(self) -> Option<&'static str> {
        match self {
            BlindKind::None => None,
            BlindKind::RotaryPositioning => Some("rotary_positioning"),
            BlindKind::AWobble => Some("tilt_wobble"),
        }
    }
}

/// One diagnosed blind case.
#[derive(Debug, Clone, Serialize)]
pub struct BlindCase {
    pub kind: BlindKind,
    /// The wobble's shape (`a_wobble` cases only).
    pub shape: Option<&'static str>,
    pub seed: u64,
    pub noise_um: f64,
    pub scale: f64,
    pub poses: usize,
    pub verdict: String,
    pub correct: bool,
    pub holdout_rms_before_um: f64,
    /// None for a null case.
    pub oracle_shrink_pct: Option<f64>,
}

impl BlindCase {
    /// Oracle shrink ≥ the materiality floor (null cases count as identifiable).
    pub fn identifiable(&self) -> bool {
        self.oracle_shrink_pct.is_none_or(|o| o >= MIN_SHRINK_PCT)
    }
}

/// A K4-like path set on an `ac-trunnion` varied by `rng` (see the module glossary).
pub fn varied_plan(machine: &FiveAxis, rng: &mut TestNoise) -> Vec<RtestPathSpec> {
    let mut u = |lo: f64, hi: f64| lo + (hi - lo) * rng.uniform();
    let s1 = [u(60.0, 160.0), u(-120.0, 120.0), u(60.0, 160.0)];
    let s2 = [u(-160.0, -40.0), u(-120.0, 120.0), u(100.0, 200.0)];
    let t_max = u(-90.0, -40.0);
    let k4_n = [48, 60, 72, 96][(u(0.0, 4.0) as usize).min(3)];
    let circle_n = if u(0.0, 1.0) < 0.5 { 24 } else { 36 };
    let second_setup = u(0.0, 1.0) < 0.5;
    let t_held = t_max * u(0.3, 0.7);
    let spec = |path: &str, run, setup: &str, s: [f64; 3], poses| RtestPathSpec {
        path: path.into(),
        run,
        setup: setup.into(),
        sphere_mm: s,
        poses,
    };
    let mut paths = vec![
        spec("K4", 1, "1", s1, k4_path(machine, s1, t_max, k4_n)),
        spec("C@0", 1, "1", s1, c_circle(machine, s1, 0.0, circle_n)),
        spec("C@max", 1, "1", s1, c_circle(machine, s1, t_max, circle_n)),
    ];
    if second_setup {
        paths.push(spec(
            "C@0-s2",
            1,
            "2",
            s2,
            c_circle(machine, s2, 0.0, circle_n),
        ));
        paths.push(spec(
            "C@max-s2",
            1,
            "2",
            s2,
            c_circle(machine, s2, t_max, circle_n),
        ));
    }
    paths.push(spec(
        "C@held",
        2,
        "1",
        s1,
        c_circle(machine, s1, t_held, 36),
    ));
    paths.push(spec("K4", 2, "1", s1, k4_path(machine, s1, t_max, k4_n)));
    paths
}

/// Builds, measures and diagnoses the blind case of `kind` and `seed` (`--model location_errors`).
pub fn run_blind_case(kind: BlindKind, seed: u64) -> Result<BlindCase, String> {
    run_blind_case_shaped(kind, seed, None)
}

/// As [`run_blind_case`], with the wobble's shape forced to `shape` (None: drawn from the seed); every
/// other draw stays that of the seed.
pub fn run_blind_case_shaped(
    kind: BlindKind,
    seed: u64,
    shape: Option<TiltWobbleShape>,
) -> Result<BlindCase, String> {
    let machine = FiveAxis::new(MachineKind::AcTrunnion, 0.0);
    let mut rng = TestNoise(seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0x0062_6c69_6e64);
    let paths = varied_plan(&machine, &mut rng);
    let noise_um = 0.15 + 0.35 * rng.uniform();
    let scale = (0.5f64).powf(1.0 - 2.0 * rng.uniform());
    let all = TiltWobbleShape::ALL;
    let drawn = all[((rng.uniform() * all.len() as f64) as usize).min(all.len() - 1)];
    let shape = shape.unwrap_or(drawn);
    let mut twin = FiveAxisTwin::random(machine, 7000 + seed);
    twin.noise_um = noise_um;
    twin.dwell_s = 6.0;
    let mut contribution = Vec::new();
    if let Some(effect) = kind.twin_effect() {
        match effect {
            "tilt_wobble" => {
                let q = &mut twin.effect_params;
                q.tilt_wobble_shape = shape;
                q.tilt_wobble[..2].iter_mut().for_each(|a| *a *= scale);
                q.tilt_wobble_radial[..2]
                    .iter_mut()
                    .for_each(|a| *a *= scale);
            }
            other => scale_effect(&mut twin.effect_params, other, scale),
        }
        let mut clean = twin.clone();
        clean.noise_um = 0.0;
        let without = clean.measure(&paths, 0);
        clean.effects.enable(effect);
        let with = clean.measure(&paths, 0);
        contribution = with
            .rows
            .iter()
            .zip(&without.rows)
            .flat_map(|(a, b)| [0, 1, 2].map(|i| a.d_um[i] - b.d_um[i]))
            .collect();
        twin.effects.enable(effect);
    }
    let campaign = twin.measure(&paths, 9000 + seed);
    let obs = observations(&campaign);
    let (d, camp) = axcomp_diagnose::rtest::diagnose(&obs, &[], &DiagnoseOptions::default())
        .map_err(|e| e.to_string())?;
    let dg = &d.diagnosis;
    let oracle_shrink_pct = kind.twin_effect().map(|_| {
        let mut cols: Vec<&[f64]> = camp.base_columns.iter().map(|c| c.as_slice()).collect();
        let ones = vec![1.0; camp.y.len()];
        cols.push(&ones);
        let b = harness::holdout_rms_after_fit(&cols, &camp.y, &camp.train, &camp.holdout);
        cols.push(&contribution);
        let a = harness::holdout_rms_after_fit(&cols, &camp.y, &camp.train, &camp.holdout);
        harness::shrink_pct(b, a)
    });
    Ok(BlindCase {
        kind,
        shape: (kind == BlindKind::AWobble).then_some(shape.name()),
        seed,
        noise_um,
        scale,
        poses: obs.n_poses(),
        verdict: dg.verdict.clone(),
        correct: dg.verdict == kind.want(),
        holdout_rms_before_um: dg.gap.holdout_rms_um,
        oracle_shrink_pct,
    })
}

/// Right verdicts of one kind: (right, cases, right on identifiable cases, identifiable cases).
pub fn tally(cases: &[BlindCase], kind: BlindKind) -> (usize, usize, usize, usize) {
    tally_where(cases, |c| c.kind == kind)
}

/// Right verdicts of the wobble cases of one shape (as [`tally`]).
pub fn tally_shape(cases: &[BlindCase], shape: TiltWobbleShape) -> (usize, usize, usize, usize) {
    tally_where(cases, |c| c.shape == Some(shape.name()))
}

fn tally_where(
    cases: &[BlindCase],
    keep: impl Fn(&BlindCase) -> bool,
) -> (usize, usize, usize, usize) {
    let of: Vec<&BlindCase> = cases.iter().filter(|c| keep(c)).collect();
    let ident: Vec<&&BlindCase> = of.iter().filter(|c| c.identifiable()).collect();
    (
        of.iter().filter(|c| c.correct).count(),
        of.len(),
        ident.iter().filter(|c| c.correct).count(),
        ident.len(),
    )
}
