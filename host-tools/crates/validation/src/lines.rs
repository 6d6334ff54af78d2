//! Withheld-effect validation of the laser-line diagnosis on the three-axis twin (`axcomp
//! validate-diagnosis --data-kind lines`).
//!
//! # Glossary
//! - **case**: one twin machine (`axcomp_twin::geometry::GeometryTwin::random`, all 21 components in the
//!   specified ranges), measured along the twin's `complete` plan (axis lines at four offsets, step-wise body
//!   diagonals, tool-offset lines: every component separable) in two runs, with reading noise σ, two
//!   temperature sensors and a time column; the model told to the diagnosis; one withheld effect or none.
//! - **withheld** (the effect present in the data but not in the model):
//!   - `abbe_angular`: a group of angular components the model lacks — the four that act only through
//!     the tool offsets (`ECY`, `EAZ`, `EBZ`, `ECZ`) or one axis's three — present in the twin;
//!   - `squareness`: one or all three squareness constants the model lacks, present in the twin;
//!   - `straightness`: one axis's two straightness components, or all six, the model lacks, present in the
//!     twin;
//!   - `time_drift`: the twin's own slow drift (µm/h along X, Y, Z, random direction), model complete;
//!   - `cross_coupling` and `thermal_drift` are not in the twin (it is rigid and has no temperature
//!     model), so the harness adds them to its readings, model complete: axis a's error
//!     `A·g(u_a)·h(u_c)` along a, with g(u) = u + c₂u² + c₃ sin(πu) and h(u) = u^p, p ∈ [1.5, 2.5] (not
//!     the candidate's polynomial basis), for a random ordered pair (a, c); thermal: a random sensor's
//!     ΔT times a random scale expansion (µm/m/K per axis) or a position-independent offset (µm/K per
//!     axis), projected on the beam.
//!   - null cases (every 4th): the model is complete and nothing is added.
//! - **temperatures** (every case, also null ones, so the columns never tell the withheld kind): `spindle`
//!   an asymmetric warm-up and cool-down hump over the campaign, `ambient` a cycle of 0.5–1 campaign
//!   durations with random phase, plus 0.01 K sensor noise.
//! - **held-out lines**: three lines (with both their runs) drawn at random, knowing nothing of the
//!   withheld kind, and redrawn while the complete model's design on the remaining lines loses rank or
//!   predicts them poorly (fitted to pure noise on the training lines, its held-out prediction exceeds
//!   [`MAX_NOISE_GAIN`]·σ): a line that alone carries a component cannot be predicted by any model. A case is kept when its
//!   withheld effect shows on the held-out lines (held-out peak ≥ 20 % of its peak over all lines, and the
//!   part the model cannot absorb ≥ 20 % of that); otherwise the effect's details are redrawn, and after
//!   30 tries the whole case (twin, lines, effect).
//! - **SNR**: the held-out peak of the withheld contribution, or of the part the told model cannot absorb
//!   when that is smaller (the model refitted to the contribution alone on the training rows), / σ. The
//!   contribution is scaled to the case's SNR.
//! - **oracle**: the told model plus the true withheld contribution as one column, refitted on the training
//!   rows; its held-out shrink is the best any diagnosis could do.
//! - **top-1**: the verdict is the withheld kind (`none` for a null case); **false alarm**: a verdict other
//!   than `none` on a null case; **shrink ratio**: shrink of the verdict's refit / oracle shrink (0 when
//!   the verdict is `none`), median over non-null cases.

use std::time::Instant;

use axcomp_diagnose::DiagnoseOptions;
use axcomp_diagnose::lines::{self, LineObservations, LineOptions};
use axcomp_diagnose::lsq;
use axcomp_diagnose::obs::Named;
use axcomp_effects::LineEffect;
use axcomp_geometry::LineData;
use axcomp_geometry::data::LineReading;
use axcomp_kinematics::lines::LineSpec;
use axcomp_kinematics::{Component, Topology};
use axcomp_twin::geometry::{GeometryTwin, LineCampaign, LineRow, plan_by_name};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;

use crate::harness::{self, CaseOutcome, Unlisted};

/// Settings of the line harness.
#[derive(Debug, Clone)]
pub struct LineValidateOptions {
    pub cases: usize,
    pub seed: u64,
    pub snrs: Vec<f64>,
    /// Reading noise σ, µm.
    pub noise_um: f64,
    pub stroke_mm: [f64; 3],
    /// Targets per line.
    pub targets: usize,
    pub runs: usize,
    /// Held-out lines per case.
    pub holdout_lines: usize,
    /// Every `null_every`-th case is a null case.
    pub null_every: usize,
}

impl Default for LineValidateOptions {
    fn default() -> Self {
        LineValidateOptions {
            cases: 100,
            seed: 1,
            snrs: vec![3.0, 4.0, 6.0, 8.0],
            noise_um: 0.5,
            stroke_mm: [600.0, 500.0, 400.0],
            targets: 11,
            runs: 2,
            holdout_lines: 3,
            null_every: 4,
        }
    }
}

impl LineValidateOptions {
    pub fn build(self) -> Result<Self, String> {
        harness::check_common(self.cases, &self.snrs, self.noise_um, self.null_every)?;
        if self.targets < 4 {
            return Err(format!(
                "targets per line must be ≥ 4, got {}",
                self.targets
            ));
        }
        Ok(self)
    }
}

/// One case's outcome.
#[derive(Debug, Clone, Serialize)]
pub struct LineCase {
    pub index: usize,
    /// The withheld kind (`none` for a null case).
    pub withheld: String,
    /// What exactly was withheld (components, axis pair, sensor and form, drift).
    pub detail: String,
    pub snr: Option<f64>,
    pub holdout_lines: Vec<String>,
    pub verdict: String,
    pub correct: bool,
    /// Held-out RMS of the told model, µm.
    pub gap_um: f64,
    /// Shrink of the verdict's refit (0 for `none`), %.
    pub shrink_pct: f64,
    pub oracle_shrink_pct: Option<f64>,
    pub seconds: f64,
}

/// The case's data and truth (for tests and examples).
pub struct LineCaseData {
    pub obs: LineObservations,
    pub model: Vec<Component>,
    pub withheld: Option<LineEffect>,
    pub detail: String,
    pub snr: Option<f64>,
    /// The withheld contribution over all rows, µm, at the case's SNR.
    pub contribution_um: Vec<f64>,
    pub holdout_lines: Vec<String>,
}

/// The withheld kind of case `index` (None = null) and its SNR.
pub fn case_kind(opts: &LineValidateOptions, index: usize) -> (Option<LineEffect>, Option<f64>) {
    let scheduled = harness::schedule(index, opts.null_every, LineEffect::ALL.len(), &opts.snrs);
    (
        scheduled.map(|(k, _)| LineEffect::ALL[k]),
        scheduled.map(|(_, s)| s),
    )
}

/// The rows of `c` as the geometry fit's readings, each valued by `value` (the truth, or the reading).
pub(crate) fn line_data(c: &LineCampaign, value: fn(&LineRow) -> f64) -> LineData {
    let mut lines: Vec<String> = Vec::new();
    let readings = c
        .rows
        .iter()
        .enumerate()
        .map(|(row, r)| {
            let line = lines.iter().position(|l| *l == r.line).unwrap_or_else(|| {
                lines.push(r.line.clone());
                lines.len() - 1
            });
            LineReading {
                q: std::array::from_fn(|k| r.pos_mm[k] - r.tool_mm[k]),
                tool: r.tool_mm,
                beam: r.beam,
                deviation_um: value(r),
                line,
                row,
            }
        })
        .collect();
    LineData { readings, lines }
}

/// Twin readings (noise-free, µm) of `twin` with the components in `zero` set to zero.
fn truth_without(twin: &GeometryTwin, zero: &[Component], plan_rows: &LineCampaign) -> Vec<f64> {
    let mut t = twin.clone();
    for c in zero {
        match c.index() {
            i if i >= 18 => t.squareness_urad[i - 18] = 0.0,
            i => t.curves[i].scale = 0.0,
        }
    }
    plan_rows
        .rows
        .iter()
        .map(|r| {
            let q = [
                r.pos_mm[0] - r.tool_mm[0],
                r.pos_mm[1] - r.tool_mm[1],
                r.pos_mm[2] - r.tool_mm[2],
            ];
            axcomp_kinematics::dot(t.error(q, r.tool_mm), r.beam)
        })
        .collect()
}

/// Largest RMS, in units of the reading noise σ, of the complete model's prediction on the held-out
/// lines when it is fitted to pure noise on the training lines: a held-out set whose lines the others
/// determine only poorly (an almost singular direction) amplifies noise beyond it and is redrawn.
pub const MAX_NOISE_GAIN: f64 = 1.0;

fn noise_gain(cols: &[Vec<f64>], train: &[usize], held: &[bool], seed: u64) -> f64 {
    let n = held.len();
    let mut g = axcomp_numeric::noise::TestNoise(seed ^ 0xa11);
    let e: Vec<f64> = (0..n).map(|_| g.normal()).collect();
    let fit = lsq::fit(cols, &e, train);
    let hold: Vec<usize> = (0..n).filter(|&i| held[i]).collect();
    (hold
        .iter()
        .map(|&i| fit.predict(cols, i).powi(2))
        .sum::<f64>()
        / hold.len().max(1) as f64)
        .sqrt()
}

fn rank_on(cols: &[Vec<f64>], rows: &[usize]) -> usize {
    let y = vec![0.0; cols.first().map_or(0, |c| c.len())];
    lsq::fit(cols, &y, rows).rank
}

/// Builds case `index`: the twin, the plan, the held-out lines, the withheld effect at its SNR. A draw
/// whose withheld effect does not show on its held-out lines is redrawn (twin, lines and effect; up to 10
/// rounds).
pub fn make_case(opts: &LineValidateOptions, index: usize) -> Result<LineCaseData, String> {
    let mut last = String::new();
    for round in 0..10 {
        match try_case(opts, index, round) {
            Ok(c) => return Ok(c),
            Err(e) => last = e,
        }
    }
    Err(last)
}

fn try_case(opts: &LineValidateOptions, index: usize, round: u64) -> Result<LineCaseData, String> {
    let (kind, snr) = case_kind(opts, index);
    let case_seed = opts
        .seed
        .wrapping_mul(0x9e37_79b9_7f4a_7c15)
        .wrapping_add(index as u64)
        .wrapping_add(round.wrapping_mul(0x1_0000_0001));
    let mut rng = StdRng::seed_from_u64(case_seed);
    let topology = Topology::default();
    let mut twin = GeometryTwin::random(opts.stroke_mm, topology.clone(), case_seed);
    twin.noise_um = 0.0;
    let plan = plan_by_name("complete", opts.stroke_mm, opts.targets).expect("twin plan");
    let clean = twin.measure(&plan, opts.runs, case_seed);
    let n = clean.rows.len();
    let mut data = line_data(&clean, |r| r.truth_um);
    let time: Vec<f64> = clean.rows.iter().map(|r| r.time_s).collect();
    let duration = time.last().copied().unwrap_or(1.0).max(1.0);
    let temperatures = case_temperatures(&time, duration, &mut rng, case_seed);

    // Held-out lines: three at random, redrawn while the complete model loses rank without them.
    let all_rows: Vec<usize> = (0..n).collect();
    let full_obs = LineObservations {
        data: data.clone(),
        target_name: "deviation_um".into(),
        held_out: vec![false; n],
        time_s: Some(time.clone()),
        temperatures: temperatures.clone(),
        topology: topology.clone(),
    };
    let (held_lines, held_out) = pick_held_out(opts, &full_obs, &mut rng, case_seed);
    let hold: Vec<usize> = (0..n).filter(|&i| held_out[i]).collect();

    // The withheld effect at unit size, and the model told to the diagnosis.
    // Redrawn (up to 30 times) until it shows on the held-out lines: its held-out peak ≥ 20 % of its
    // peak over all lines, and the part the model cannot absorb ≥ 20 % of that (the held-out lines were
    // drawn first, blind to the kind).
    let full_truth: Vec<f64> = clean.rows.iter().map(|r| r.truth_um).collect();
    let mut obs = LineObservations {
        data: data.clone(),
        target_name: "deviation_um".into(),
        held_out,
        time_s: Some(time),
        temperatures: temperatures.clone(),
        topology,
    };
    let case = CaseTwin {
        opts,
        twin: &twin,
        plan: &plan,
        clean: &clean,
        data: &data,
        temperatures: &temperatures,
        full_truth: &full_truth,
        case_seed,
    };
    let drawn = draw_shown(&case, kind, snr, &obs, &all_rows, &hold, &mut rng);
    let Some((model, base_truth, contribution, detail)) = drawn else {
        return Err(format!(
            "case {index}: no draw of the withheld {} shows on the held-out lines {}",
            kind.map_or("none", |k| k.name()),
            held_lines.join(", ")
        ));
    };
    let mut noise = axcomp_numeric::noise::TestNoise(case_seed ^ 0x5eed);
    for (i, r) in data.readings.iter_mut().enumerate() {
        r.deviation_um = base_truth[i] + contribution[i] + opts.noise_um * noise.normal();
    }
    obs.data = data;
    Ok(LineCaseData {
        obs,
        model,
        withheld: kind,
        detail,
        snr,
        contribution_um: contribution,
        holdout_lines: held_lines,
    })
}

/// The twin, plan, clean campaign and temperatures of one case: what its withheld effect is drawn from.
struct CaseTwin<'a> {
    opts: &'a LineValidateOptions,
    twin: &'a GeometryTwin,
    plan: &'a [LineSpec],
    clean: &'a LineCampaign,
    data: &'a LineData,
    temperatures: &'a [Named],
    /// The clean campaign's true deviation per reading, µm.
    full_truth: &'a [f64],
    case_seed: u64,
}

/// One draw of the withheld effect: the model told to the diagnosis, the truth without the effect, the
/// effect's contribution per reading (µm) and its description.
type Withheld = (Vec<Component>, Vec<f64>, Vec<f64>, String);

/// The case's two temperature sensors (see the module glossary), drawn from `rng`.
fn case_temperatures(time: &[f64], duration: f64, rng: &mut StdRng, case_seed: u64) -> Vec<Named> {
    // Temperatures (every case).
    let (a1, p1) = (rng.gen_range(1.0..3.0), rng.gen_range(0.6..1.6));
    let (a2, per2, ph2) = (
        rng.gen_range(0.5..1.5),
        rng.gen_range(0.5..1.0) * duration,
        rng.gen_range(0.0..std::f64::consts::TAU),
    );
    let mut sensor_noise = axcomp_numeric::noise::TestNoise(case_seed ^ 0x7e3d);
    let spindle: Vec<f64> = time
        .iter()
        .map(|&t| {
            22.0 + a1 * (std::f64::consts::PI * (t / duration).powf(p1)).sin()
                + 0.01 * sensor_noise.normal()
        })
        .collect();
    let ambient: Vec<f64> = time
        .iter()
        .map(|&t| {
            20.0 + a2 * (std::f64::consts::TAU * t / per2 + ph2).sin()
                + 0.01 * sensor_noise.normal()
        })
        .collect();
    vec![
        Named {
            name: "spindle".into(),
            values: spindle,
        },
        Named {
            name: "ambient".into(),
            values: ambient,
        },
    ]
}

/// The held-out lines (names) and row mask: drawn at random, redrawn (up to 50 times) while the complete
/// model loses rank or predicts them poorly without them.
fn pick_held_out(
    opts: &LineValidateOptions,
    full_obs: &LineObservations,
    rng: &mut StdRng,
    case_seed: u64,
) -> (Vec<String>, Vec<bool>) {
    let data = &full_obs.data;
    let n = full_obs.held_out.len();
    let all_rows: Vec<usize> = (0..n).collect();
    let design = lines::Design::new(full_obs, None);
    let full_cols = lines::base_columns(&design, &Component::ALL, &all_rows);
    let full_rank = rank_on(&full_cols, &all_rows);
    let mut held_lines = Vec::new();
    let mut held_out = vec![false; n];
    for attempt in 0..50 {
        let mut pick: Vec<usize> = Vec::new();
        while pick.len() < opts.holdout_lines.min(data.lines.len() - 1) {
            let l = rng.gen_range(0..data.lines.len());
            if !pick.contains(&l) {
                pick.push(l);
            }
        }
        let mask: Vec<bool> = data
            .readings
            .iter()
            .map(|r| pick.contains(&r.line))
            .collect();
        let train: Vec<usize> = (0..n).filter(|&i| !mask[i]).collect();
        if (rank_on(&full_cols, &train) == full_rank
            && noise_gain(&full_cols, &train, &mask, case_seed) <= MAX_NOISE_GAIN)
            || attempt == 49
        {
            held_lines = pick.iter().map(|&l| data.lines[l].clone()).collect();
            held_out = mask;
            break;
        }
    }
    (held_lines, held_out)
}

/// The withheld effect, redrawn (up to 30 times) until it shows on the held-out rows `hold`, scaled to the
/// SNR; at unit size for a case without SNR. None when no draw shows.
fn draw_shown(
    c: &CaseTwin,
    kind: Option<LineEffect>,
    snr: Option<f64>,
    obs: &LineObservations,
    all_rows: &[usize],
    hold: &[usize],
    rng: &mut StdRng,
) -> Option<Withheld> {
    let opts = c.opts;
    for _attempt in 0..30 {
        let (model, base_truth, mut contribution, detail) = draw_withheld(c, kind, rng);
        let Some(snr) = snr else {
            return Some((model, base_truth, contribution, detail));
        };
        let left = lines::model_residual(obs, &model, None, &contribution);
        let peak_of =
            |v: &[f64], rows: &[usize]| rows.iter().map(|&i| v[i].abs()).fold(0.0, f64::max);
        let raw_all = peak_of(&contribution, all_rows);
        let raw = peak_of(&contribution, hold);
        let un = peak_of(&left, hold);
        if raw >= 0.2 * raw_all && un >= 0.2 * raw && raw > 0.0 {
            let f = snr * opts.noise_um / raw.min(un);
            for v in contribution.iter_mut() {
                *v *= f;
            }
            return Some((model, base_truth, contribution, detail));
        }
    }
    None
}

/// One draw of the withheld effect of `kind` at unit size.
fn draw_withheld(c: &CaseTwin, kind: Option<LineEffect>, rng: &mut StdRng) -> Withheld {
    match kind {
        None => (
            Component::ALL.to_vec(),
            c.full_truth.to_vec(),
            vec![0.0; c.full_truth.len()],
            String::from("nothing withheld"),
        ),
        Some(k @ (LineEffect::AbbeAngular | LineEffect::Squareness | LineEffect::Straightness)) => {
            withheld_components(c, k, rng)
        }
        Some(LineEffect::TimeDrift) => time_drift(c, rng),
        Some(LineEffect::CrossCoupling) => cross_coupling(c, rng),
        Some(LineEffect::ThermalDrift) => thermal_drift(c, rng),
    }
}

/// A group of the twin's components left out of the model (`abbe_angular`, `squareness`, `straightness`).
fn withheld_components(c: &CaseTwin, k: LineEffect, rng: &mut StdRng) -> Withheld {
    use Component::*;
    let groups: Vec<Vec<Component>> = match k {
        LineEffect::AbbeAngular => vec![
            vec![ECY, EAZ, EBZ, ECZ],
            vec![EAX, EBX, ECX],
            vec![EAY, EBY, ECY],
            vec![EAZ, EBZ, ECZ],
        ],
        LineEffect::Squareness => {
            vec![vec![EC0Y, EB0Z, EA0Z], vec![EC0Y], vec![EB0Z], vec![EA0Z]]
        }
        _ => vec![
            vec![EYX, EZX, EXY, EZY, EXZ, EYZ],
            vec![EYX, EZX],
            vec![EXY, EZY],
            vec![EXZ, EYZ],
        ],
    };
    let g = groups[rng.gen_range(0..groups.len())].clone();
    let base_truth = truth_without(c.twin, &g, c.clean);
    let contribution = c
        .full_truth
        .iter()
        .zip(&base_truth)
        .map(|(a, b)| a - b)
        .collect();
    let mut model: Vec<Component> = Component::ALL.to_vec();
    model.retain(|c| !g.contains(c));
    let detail = format!(
        "twin components left out of the model: {}",
        g.iter().map(|c| c.name()).collect::<Vec<_>>().join(", ")
    );
    (model, base_truth, contribution, detail)
}

/// The twin's own drift in a random direction, model complete.
fn time_drift(c: &CaseTwin, rng: &mut StdRng) -> Withheld {
    let mut d = [0.0f64; 3];
    for v in d.iter_mut() {
        *v = rng.gen_range(-1.0..1.0);
    }
    let norm = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-9);
    let rate = [2.0 * d[0] / norm, 2.0 * d[1] / norm, 2.0 * d[2] / norm];
    let mut drifting = c.twin.clone();
    drifting.drift_um_per_h = rate;
    let m = drifting.measure(c.plan, c.opts.runs, c.case_seed);
    let contribution = m
        .rows
        .iter()
        .zip(&c.clean.rows)
        .map(|(a, b)| a.deviation_um - b.deviation_um)
        .collect();
    let detail = format!(
        "twin drift direction ({:.2}, {:.2}, {:.2})",
        d[0] / norm,
        d[1] / norm,
        d[2] / norm
    );
    (
        Component::ALL.to_vec(),
        c.full_truth.to_vec(),
        contribution,
        detail,
    )
}

/// A harness-added cross-coupling of two axes, model complete.
fn cross_coupling(case: &CaseTwin, rng: &mut StdRng) -> Withheld {
    let pairs = [(0, 1), (0, 2), (1, 0), (1, 2), (2, 0), (2, 1)];
    let (a, c) = pairs[rng.gen_range(0..pairs.len())];
    let (c2, c3, p) = (
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
        rng.gen_range(1.5..2.5),
    );
    let s = case.opts.stroke_mm;
    let contribution = case
        .data
        .readings
        .iter()
        .map(|r| {
            let ua = r.q[a] / s[a];
            let uc = (r.q[c] / s[c]).max(0.0);
            let g = ua + c2 * ua * ua + c3 * (std::f64::consts::PI * ua).sin();
            r.beam[a] * g * uc.powf(p)
        })
        .collect();
    let detail = format!(
        "harness-added: error of {} along its axis × ({}/stroke)^{p:.2}",
        ['X', 'Y', 'Z'][a],
        ['x', 'y', 'z'][c]
    );
    (
        Component::ALL.to_vec(),
        case.full_truth.to_vec(),
        contribution,
        detail,
    )
}

/// A harness-added thermal drift of one sensor, model complete.
fn thermal_drift(c: &CaseTwin, rng: &mut StdRng) -> Withheld {
    let s = rng.gen_range(0..c.temperatures.len());
    let t0 = c.temperatures[s].values[0];
    let scale_form = rng.gen_bool(0.5);
    let mut coef = [0.0; 3];
    for v in coef.iter_mut() {
        *v = rng.gen_range(0.5..1.0) * if rng.gen_bool(0.5) { 1.0 } else { -1.0 };
    }
    let contribution = c
        .data
        .readings
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let dt = c.temperatures[s].values[i] - t0;
            (0..3)
                .map(|k| {
                    let f = if scale_form { r.q[k] / 1000.0 } else { 1.0 };
                    r.beam[k] * coef[k] * f * dt
                })
                .sum()
        })
        .collect();
    let detail = format!(
        "harness-added: {} of sensor {} ({:.2}, {:.2}, {:.2})",
        if scale_form {
            "scale expansion, µm/m/K,"
        } else {
            "offset, µm/K,"
        },
        c.temperatures[s].name,
        coef[0],
        coef[1],
        coef[2]
    );
    (
        Component::ALL.to_vec(),
        c.full_truth.to_vec(),
        contribution,
        detail,
    )
}

/// Diagnoses case `index` blind and compares with the truth and the oracle.
pub fn run_case(opts: &LineValidateOptions, index: usize) -> Result<LineCase, String> {
    let c = make_case(opts, index)?;
    let t0 = Instant::now();
    let line_opts = LineOptions {
        skip_evidence: true,
        ..LineOptions::default()
    };
    let ld = lines::diagnose_lines(&c.obs, &c.model, &DiagnoseOptions::default(), &line_opts)
        .map_err(|e| e.to_string())?;
    let seconds = t0.elapsed().as_secs_f64();
    let d = &ld.diagnosis;
    let n = c.obs.n_rows();
    let train: Vec<usize> = (0..n).filter(|&i| !c.obs.held_out[i]).collect();
    let hold: Vec<usize> = (0..n).filter(|&i| c.obs.held_out[i]).collect();
    let y = c.obs.target();
    let oracle_shrink_pct = c.withheld.map(|_| {
        let mut cols = d.model_columns.clone();
        cols.push(c.contribution_um.clone());
        let after = harness::holdout_rms_after_fit(&cols, &y, &train, &hold);
        harness::shrink_pct(d.gap.holdout_rms_um, after)
    });
    let expected = c.withheld.map_or("none", |k| k.name());
    Ok(LineCase {
        index,
        withheld: expected.to_string(),
        detail: c.detail,
        snr: c.snr,
        holdout_lines: c.holdout_lines,
        verdict: d.verdict.clone(),
        correct: d.verdict == expected,
        gap_um: d.gap.holdout_rms_um,
        shrink_pct: d.verdict_candidate().map_or(0.0, |v| v.shrink_pct),
        oracle_shrink_pct,
        seconds,
    })
}

/// Figures of one SNR (non-null cases).
#[derive(Debug, Clone, Serialize)]
pub struct SnrRow {
    pub snr: f64,
    pub cases: usize,
    pub top1: f64,
    pub median_shrink_ratio_to_oracle: f64,
}

/// The harness's figures.
#[derive(Debug, Clone, Serialize)]
pub struct LineSummary {
    pub cases: usize,
    pub null_cases: usize,
    /// Share of null cases with a verdict other than `none`.
    pub false_alarm_rate: f64,
    /// Top-1 over non-null cases with SNR ≥ 4, and their number.
    pub top1_at_snr_ge4: f64,
    pub cases_at_snr_ge4: usize,
    /// Top-1 over all non-null cases.
    pub top1_all: f64,
    /// Median over non-null cases of shrink(verdict) / shrink(oracle) (`none` counts as 0).
    pub median_shrink_ratio_to_oracle: f64,
    pub by_snr: Vec<SnrRow>,
    /// Rows: withheld kind (then `none`); columns: verdict (the kinds, then `none`).
    pub confusion: Vec<(String, Vec<usize>)>,
    pub median_seconds: f64,
    pub max_seconds: f64,
    pub case_results: Vec<LineCase>,
}

harness::case_outcome!(LineCase, withheld);

/// The confusion matrix's labels: the kinds, then `none`.
fn confusion_labels() -> Vec<String> {
    LineEffect::ALL
        .iter()
        .map(|k| k.name().to_string())
        .chain(["none".to_string()])
        .collect()
}

fn ratio(c: &LineCase) -> f64 {
    match c.oracle_shrink_pct {
        Some(o) if o > 0.0 => (c.shrink_pct / o).max(0.0),
        _ => 0.0,
    }
}

/// The figures over the cases.
pub fn summarise(results: Vec<LineCase>) -> LineSummary {
    let null_cases = results.iter().filter(|c| c.is_null()).count();
    let real: Vec<&LineCase> = results.iter().filter(|c| !c.is_null()).collect();
    let top1 = |v: &[&LineCase]| harness::share(v.iter().map(|c| c.correct));
    let ge4 = harness::at_snr_ge(&results, 4.0);
    let by_snr = harness::snr_levels(real.iter().filter_map(|c| c.snr))
        .into_iter()
        .map(|s| {
            let v = harness::at_snr(&results, s);
            let mut r: Vec<f64> = v.iter().map(|c| ratio(c)).collect();
            SnrRow {
                snr: s,
                cases: v.len(),
                top1: top1(&v),
                median_shrink_ratio_to_oracle: axcomp_numeric::stats::median(&mut r),
            }
        })
        .collect();
    let labels = confusion_labels();
    let counts = harness::confusion(&labels, &results, Unlisted::Skip);
    let confusion = labels.into_iter().zip(counts).collect();
    let mut ratios: Vec<f64> = real.iter().map(|c| ratio(c)).collect();
    let (mut secs, max_seconds) = harness::seconds(&results);
    LineSummary {
        cases: results.len(),
        null_cases,
        false_alarm_rate: harness::false_alarm_rate(&results),
        top1_at_snr_ge4: top1(&ge4),
        cases_at_snr_ge4: ge4.len(),
        top1_all: top1(&real),
        median_shrink_ratio_to_oracle: axcomp_numeric::stats::median(&mut ratios),
        by_snr,
        confusion,
        median_seconds: axcomp_numeric::stats::median(&mut secs),
        max_seconds,
        case_results: results,
    }
}

impl LineSummary {
    /// The Markdown tables.
    pub fn to_markdown(&self) -> String {
        let mut s = String::from(
            "## Withheld-effect validation on laser-line data (three-axis twin)\n\n| SNR | cases | top-1 | median shrink / oracle |\n|---|---|---|---|\n",
        );
        for r in &self.by_snr {
            s.push_str(&format!(
                "| {} | {} | {:.1} % | {:.2} |\n",
                r.snr,
                r.cases,
                100.0 * r.top1,
                r.median_shrink_ratio_to_oracle
            ));
        }
        s.push_str(&format!(
            "\n| figure | value | target |\n|---|---|---|\n| top-1 at SNR ≥ 4 | {:.1} % ({} cases) | ≥ 90 % |\n| false alarms on nulls | {:.1} % ({} cases) | ≤ 5 % |\n| median held-out shrink / oracle | {:.2} | ≥ 0.8 |\n| top-1 (all SNR) | {:.1} % |  |\n| diagnosis time per case (median / max) | {:.2} s / {:.2} s |  |\n",
            100.0 * self.top1_at_snr_ge4,
            self.cases_at_snr_ge4,
            100.0 * self.false_alarm_rate,
            self.null_cases,
            self.median_shrink_ratio_to_oracle,
            100.0 * self.top1_all,
            self.median_seconds,
            self.max_seconds
        ));
        s.push_str("\nConfusion (rows: withheld, columns: verdict)\n\n");
        let rows: Vec<(String, &[usize])> = self
            .confusion
            .iter()
            .map(|(row, counts)| (row.clone(), counts.as_slice()))
            .collect();
        s.push_str(&harness::counts_markdown(
            "withheld",
            &confusion_labels(),
            &rows,
            false,
        ));
        s
    }
}

/// Runs every case (calling `progress` after each) and summarises.
pub fn validate_lines(
    opts: &LineValidateOptions,
    mut progress: impl FnMut(&LineCase),
) -> Result<LineSummary, String> {
    let results = harness::run_cases(opts.cases, |i| run_case(opts, i), &mut progress)?;
    Ok(summarise(results))
}
