//! Held-back evaluation of `fit geometry` on the three-axis twin: how well a model fitted to a few lines
//! predicts lines it never saw.
//!
//! # Glossary
//! - **case**: one twin machine (`GeometryTwin::random`, all 21 components in the specified ranges, reading
//!   noise σ) measured in two runs along the training lines — seed 000's seven lines plus the Y and Z axis
//!   lines through the origin — and the held-back lines, drawn per case: an X, a Y and a Z axis line at
//!   random offsets of the other two axes, the XZ and YZ face diagonals at a random offset, a body diagonal
//!   with a random 100–200 mm tool offset along Z, and an axis line read point by point along the beams
//!   from a tracking interferometer's station (each point along its own beam).
//! - **held-out RMS**: RMS of (held-back reading − prediction) along each reading's beam, µm; noise
//!   included, as `holdout_rms_um` of `fit geometry --holdout` reports it. Given for the lines at other
//!   offsets and the diagonals together (`lines`), and per group (`axis`, `diagonal`, `beam`).
//! - **identifiable floor**: the held-out RMS of the best model these training lines can determine: the
//!   minimum-norm least-squares solution of the noise-free training readings in the default fit's basis
//!   (all 21 components, cubic B-splines on its knot grid, no smoothing), judged against the same noisy
//!   held-back readings. What the lines cannot separate it leaves at the minimum norm, so it is the floor
//!   of the span of the measured lines, not the truth.
//! - **plain reference**: `fit geometry --method plain` (general least squares, no smoothing, what the lines
//!   cannot separate fixed at 0).
//! - **minimum-norm reference**: all 21 components as cubic B-splines with 10 intervals per axis, a light
//!   second-difference penalty (λ = [`MIN_NORM_LAMBDA`] of the design's mean diagonal), the minimum-norm
//!   solution of the stacked system (the first solver an engineer with numpy would write).
//! - **Gaussian oracle**: what the training readings allow a linear estimator that knows the twin: the
//!   posterior mean of the default fit's basis under the twin generator's own prior (mean and covariance
//!   of the spline coefficients over [`ORACLE_TWINS`] twins drawn by `GeometryTwin::random`, components
//!   independent) and the true noise σ. The identifiable floor has no noise in its training readings;
//!   this oracle has the same noise as every fit, so it shows how much of the gap to the floor any
//!   linear fit of these lines must keep.

use axcomp_geometry::fit::Layout;
use axcomp_geometry::{FitOptions, Judge, LineData, analyse};
use axcomp_kinematics::lines::{LineSpec, axis_line, face_diagonals, seven_line};
use axcomp_kinematics::{Component, Topology};
use axcomp_twin::geometry::GeometryTwin;
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;

/// Second-difference penalty of the minimum-norm reference, relative to the design's mean diagonal.
pub const MIN_NORM_LAMBDA: f64 = 1e-3;

/// Twins drawn for the Gaussian oracle's prior.
pub const ORACLE_TWINS: usize = 3000;

/// Settings of the held-back cases.
#[derive(Debug, Clone)]
pub struct HeldBackOptions {
    pub stroke_mm: [f64; 3],
    /// Targets per line.
    pub targets: usize,
    pub runs: usize,
    /// Reading noise σ, µm.
    pub noise_um: f64,
}

impl Default for HeldBackOptions {
    fn default() -> Self {
        HeldBackOptions {
            stroke_mm: [800.0, 600.0, 500.0],
            targets: 15,
            runs: 2,
            noise_um: 0.3,
        }
    }
}

/// Which group a held-back line belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HeldGroup {
    Axis,
    Diagonal,
    Beam,
}

/// One case: the campaign as the fit reads it, the held-back mask and each reading's group.
pub struct HeldBackCase {
    pub data: LineData,
    /// Noise-free readings (µm along the beam).
    pub truth_um: Vec<f64>,
    pub held: Vec<bool>,
    /// The group of each held-back reading (`None` for training readings).
    pub group: Vec<Option<HeldGroup>>,
}

/// The held-back lines of case `seed`, each with its group.
fn held_lines(opts: &HeldBackOptions, rng: &mut StdRng) -> Vec<(LineSpec, HeldGroup)> {
    let s = opts.stroke_mm;
    let n = opts.targets;
    let mut frac = || rng.gen_range(0.3..1.0);
    let mut v = vec![
        (
            axis_line("hX", 0, s, [0.0, frac() * s[1], frac() * s[2]], n),
            HeldGroup::Axis,
        ),
        (
            axis_line("hY", 1, s, [frac() * s[0], 0.0, frac() * s[2]], n),
            HeldGroup::Axis,
        ),
        (
            axis_line("hZ", 2, s, [frac() * s[0], frac() * s[1], 0.0], n),
            HeldGroup::Axis,
        ),
    ];
    for (a, b) in [(0usize, 2usize), (1, 2)] {
        let at = frac() * s[3 - a - b];
        for l in face_diagonals(s, a, b, at, n, false) {
            v.push((l, HeldGroup::Diagonal));
        }
    }
    let tool = [0.0, 0.0, 100.0 + 100.0 * frac()];
    v.push((
        LineSpec::new("hDT", [0.0; 3], s, n).with_tool(tool),
        HeldGroup::Diagonal,
    ));
    let station = [-150.0, -150.0, 0.0];
    let at = [0.0, frac() * s[1], frac() * s[2]];
    v.push((
        axis_line("hBX", 0, s, at, n).from_station(station),
        HeldGroup::Beam,
    ));
    v
}

/// The twin of case `seed`.
fn case_twin(stroke_mm: [f64; 3], seed: u64) -> GeometryTwin {
    GeometryTwin::random(stroke_mm, Topology::default(), 7000 + seed)
}

/// Builds case `seed`.
pub fn make_case(opts: &HeldBackOptions, seed: u64) -> HeldBackCase {
    make_case_with(opts, seed, &[]).0
}

/// The training lines of every case: seed 000's seven lines and the Y and Z axis lines.
pub fn training_lines(opts: &HeldBackOptions) -> Vec<LineSpec> {
    let s = opts.stroke_mm;
    let mut lines = seven_line(s, opts.targets);
    lines.push(axis_line("Y0", 1, s, [0.0; 3], opts.targets));
    lines.push(axis_line("Z0", 2, s, [0.0; 3], opts.targets));
    lines
}

/// Case `seed` with further lines `extra` measured in the same campaign (after the training lines,
/// before the held-back ones; not held out) and the mask of their readings.
pub fn make_case_with(
    opts: &HeldBackOptions,
    seed: u64,
    extra: &[LineSpec],
) -> (HeldBackCase, Vec<bool>) {
    let mut rng = StdRng::seed_from_u64(seed ^ 0x4e1d_bac4);
    let s = opts.stroke_mm;
    let mut lines = training_lines(opts);
    let n_train = lines.len();
    lines.extend(extra.iter().cloned());
    let n_fit = lines.len();
    let held = held_lines(opts, &mut rng);
    let groups: Vec<HeldGroup> = held.iter().map(|(_, g)| *g).collect();
    lines.extend(held.into_iter().map(|(l, _)| l));
    let mut twin = case_twin(s, seed);
    twin.noise_um = opts.noise_um;
    let camp = twin.measure(&lines, opts.runs, seed);
    let data = crate::lines::line_data(&camp, |r| r.deviation_um);
    let line_index: Vec<usize> = data
        .lines
        .iter()
        .map(|name| lines.iter().position(|l| l.name == *name).unwrap())
        .collect();
    let group: Vec<Option<HeldGroup>> = data
        .readings
        .iter()
        .map(|r| {
            let li = line_index[r.line];
            (li >= n_fit).then(|| groups[li - n_fit])
        })
        .collect();
    let is_extra = data
        .readings
        .iter()
        .map(|r| (n_train..n_fit).contains(&line_index[r.line]))
        .collect();
    let case = HeldBackCase {
        truth_um: camp.rows.iter().map(|r| r.truth_um).collect(),
        held: group.iter().map(Option::is_some).collect(),
        group,
        data,
    };
    (case, is_extra)
}

/// Held-out RMS of one case's predictions (µm), per group.
#[derive(Debug, Clone, Copy, Serialize, Default)]
pub struct HeldScore {
    /// Lines at other offsets and diagonals together.
    pub lines: f64,
    pub axis: f64,
    pub diagonal: f64,
    pub beam: f64,
}

/// The held-out scores of predictions `pred` (along each reading's beam) against the noisy readings.
pub fn score(case: &HeldBackCase, pred: &[f64]) -> HeldScore {
    let rms_of = |keep: &dyn Fn(HeldGroup) -> bool| {
        axcomp_numeric::stats::rms(
            case.data
                .readings
                .iter()
                .enumerate()
                .filter(|(i, _)| case.group[*i].is_some_and(keep))
                .map(|(i, r)| r.deviation_um - pred[i]),
        )
    };
    HeldScore {
        lines: rms_of(&|g| g != HeldGroup::Beam),
        axis: rms_of(&|g| g == HeldGroup::Axis),
        diagonal: rms_of(&|g| g == HeldGroup::Diagonal),
        beam: rms_of(&|g| g == HeldGroup::Beam),
    }
}

/// Minimum-norm solution (raw parameter units) of the training rows' design on `intervals` knot intervals
/// per axis (`None`: the fit's default grid) with a second-difference penalty `lambda` and a ridge `ridge`
/// (both relative to the design's mean diagonal); predictions for every reading.
pub fn min_norm_predictions(
    data: &LineData,
    train: &[usize],
    values: &[f64],
    intervals: Option<usize>,
    lambda: f64,
    ridge: f64,
) -> Vec<f64> {
    let layout = Layout::new(data, intervals);
    let rows = design_rows(&layout, data);
    let a = rows.select_rows(train.iter());
    let mean_diag = (0..layout.p)
        .map(|j| a.column(j).norm_squared())
        .sum::<f64>()
        / layout.p as f64;
    let mut pen_rows: Vec<Vec<f64>> = Vec::new();
    if lambda > 0.0 {
        for (i, c) in Component::ALL[..18].iter().enumerate() {
            let g = &layout.grids[c.axis().unwrap().index()];
            let dn = g.second_difference() * &layout.bases[i];
            let (s, _) = layout.cols[i];
            for r in 0..dn.nrows() {
                let mut row = vec![0.0; layout.p];
                for k in 0..dn.ncols() {
                    row[s + k] = (lambda * mean_diag).sqrt() * dn[(r, k)];
                }
                pen_rows.push(row);
            }
        }
    }
    if ridge > 0.0 {
        for j in 0..layout.p {
            let mut row = vec![0.0; layout.p];
            row[j] = (ridge * mean_diag).sqrt();
            pen_rows.push(row);
        }
    }
    let n = train.len() + pen_rows.len();
    let stacked = DMatrix::from_fn(n, layout.p, |i, j| {
        if i < train.len() {
            a[(i, j)]
        } else {
            pen_rows[i - train.len()][j]
        }
    });
    let y = DVector::from_fn(n, |i, _| {
        if i < train.len() {
            values[train[i]]
        } else {
            0.0
        }
    });
    let svd = stacked.svd(true, true);
    let smax = svd.singular_values.max();
    let beta = svd.solve(&y, 1e-10 * smax).expect("SVD with U and V");
    (&rows * beta).iter().copied().collect()
}

/// The design rows (µm per parameter of `layout`, along each reading's beam) of every reading of `data`.
fn design_rows(layout: &Layout, data: &LineData) -> DMatrix<f64> {
    let topo = Topology::default();
    let mut rows = DMatrix::zeros(data.readings.len(), layout.p);
    for (i, r) in data.readings.iter().enumerate() {
        let row = layout.row(&topo, r.q, r.tool, r.beam);
        rows.row_mut(i).copy_from_slice(&row);
    }
    rows
}

/// One case's figures.
#[derive(Debug, Clone, Serialize)]
pub struct HeldBackResult {
    pub seed: u64,
    pub default: HeldScore,
    pub plain: HeldScore,
    pub min_norm: HeldScore,
    pub floor: HeldScore,
    pub oracle: HeldScore,
}

/// Fits case `seed` with `fit geometry`'s default and the references, and scores all on the held-back lines.
pub fn run_case(opts: &HeldBackOptions, seed: u64, fit: &FitOptions) -> HeldBackResult {
    let case = make_case(opts, seed);
    let judge = Judge::Holdout(case.held.clone());
    let n = case.held.len();
    let train: Vec<usize> = (0..n).filter(|&i| !case.held[i]).collect();
    let predict = |fo: &FitOptions| {
        let an = analyse(&case.data, &judge, fo).expect("held-back case fits");
        axcomp_geometry::analysis::predict_readings(&an.fit.model, &case.data)
    };
    let default = score(&case, &predict(fit));
    let plain = score(
        &case,
        &predict(&FitOptions {
            method: axcomp_geometry::Method::Plain,
            ..fit.clone()
        }),
    );
    let values: Vec<f64> = case.data.readings.iter().map(|r| r.deviation_um).collect();
    let min_norm = score(
        &case,
        &min_norm_predictions(&case.data, &train, &values, Some(10), MIN_NORM_LAMBDA, 0.0),
    );
    let floor = score(
        &case,
        &min_norm_predictions(&case.data, &train, &case.truth_um, None, 0.0, 0.0),
    );
    let oracle = score(
        &case,
        &gaussian_oracle_predictions(opts, &case, &train, ORACLE_TWINS),
    );
    HeldBackResult {
        seed,
        default,
        plain,
        min_norm,
        floor,
        oracle,
    }
}

/// Spline parameters (the layout's raw units) of a twin's 21 components: each function's least-squares
/// fit on 200 points of its grid (`maps`: the pseudo-inverse of each function's basis there).
fn twin_parameters(
    layout: &Layout,
    maps: &[(Vec<f64>, DMatrix<f64>)],
    twin: &GeometryTwin,
) -> DVector<f64> {
    let mut theta = DVector::zeros(layout.p);
    for (i, c) in Component::ALL.iter().enumerate() {
        let (s, k) = layout.cols[i];
        match maps.get(i) {
            Some((qs, pinv)) => {
                let v = DVector::from_iterator(qs.len(), qs.iter().map(|&q| twin.component(*c, q)));
                theta.rows_mut(s, k).copy_from(&(pinv * v));
            }
            None => theta[s] = twin.component(*c, 0.0),
        }
    }
    theta
}

/// Per function of `layout`: 200 positions over its grid and the pseudo-inverse of its basis there.
fn parameter_maps(layout: &Layout) -> Vec<(Vec<f64>, DMatrix<f64>)> {
    Component::ALL[..18]
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let g = layout.grids[c.axis().unwrap().index()];
            let qs = g.positions(200);
            let b = DMatrix::from_fn(qs.len(), g.n_basis(), |r, j| g.basis(qs[r])[j])
                * &layout.bases[i];
            let pinv = b.pseudo_inverse(1e-12).expect("a basis's pseudo-inverse");
            (qs, pinv)
        })
        .collect()
}

/// The Gaussian oracle's predictions for every reading of `case` (see the module docs): the prior of the
/// default basis's parameters estimated from `twins` twins, the posterior mean given the training
/// readings `train` and the true noise σ.
pub fn gaussian_oracle_predictions(
    opts: &HeldBackOptions,
    case: &HeldBackCase,
    train: &[usize],
    twins: usize,
) -> Vec<f64> {
    let topo = Topology::default();
    let layout = Layout::new(&case.data, None);
    let p = layout.p;
    let maps = parameter_maps(&layout);
    let mut mean = DVector::zeros(p);
    let mut second = DMatrix::zeros(p, p);
    for s in 0..twins {
        let twin = GeometryTwin::random(opts.stroke_mm, topo.clone(), 1_000_000 + s as u64);
        let theta = twin_parameters(&layout, &maps, &twin);
        mean += &theta;
        second += &theta * theta.transpose();
    }
    mean /= twins as f64;
    let mut cov = second / twins as f64 - &mean * mean.transpose();
    // the twin draws its components independently: only each component's own block is kept
    for (i, &(si, ki)) in layout.cols.iter().enumerate() {
        for (j, &(sj, kj)) in layout.cols.iter().enumerate() {
            if i != j {
                cov.view_mut((si, sj), (ki, kj)).fill(0.0);
            }
        }
    }
    let rows = design_rows(&layout, &case.data);
    let a = rows.select_rows(train.iter());
    let y = DVector::from_iterator(
        train.len(),
        train.iter().map(|&i| case.data.readings[i].deviation_um),
    );
    let k = &a * &cov * a.transpose()
        + DMatrix::identity(train.len(), train.len()) * opts.noise_um.powi(2).max(1e-12);
    let w = k
        .cholesky()
        .expect("prior covariance plus noise is positive definite")
        .solve(&(y - &a * &mean));
    let posterior = &mean + &cov * a.transpose() * w;
    (&rows * posterior).iter().copied().collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The oracle's parameter map: a case's own twin, mapped into the default basis, reproduces the
    /// case's noise-free readings. Reference: the twin's exact readings (`truth_um`); tolerance 0.005 µm
    /// RMS (the basis's approximation of the smooth truth curves).
    #[test]
    fn twin_parameters_reproduce_the_noise_free_readings() {
        let opts = HeldBackOptions::default();
        let case = make_case(&opts, 3);
        let layout = Layout::new(&case.data, None);
        let theta = twin_parameters(
            &layout,
            &parameter_maps(&layout),
            &case_twin(opts.stroke_mm, 3),
        );
        let pred = design_rows(&layout, &case.data) * theta;
        let rms = axcomp_numeric::stats::rms(pred.iter().zip(&case.truth_um).map(|(p, t)| p - t));
        assert!(rms < 0.005, "{rms} µm");
    }
}

/// What further lines buy on one case: the default fit's held-out RMS (lines at other offsets and
/// diagonals, µm) on the training lines alone, with the first `k` further lines `plan geometry --measured`
/// lists after them, and with `k` lines drawn at random among the plan's other candidates, all measured
/// in one campaign.
#[derive(Debug, Clone, Serialize)]
pub struct FurtherGain {
    pub seed: u64,
    pub before: f64,
    pub planned: f64,
    pub random: f64,
    /// The planned lines (the plan's names).
    pub lines: Vec<String>,
}

/// Reflector offsets the plan may give its candidate lines (mm): none, and 150 mm along Z.
pub const PLAN_TOOL_OFFSETS: [[f64; 3]; 2] = [[0.0; 3], [0.0, 0.0, 150.0]];

/// [`FurtherGain`] of case `seed` with `k` further lines.
pub fn further_gain(opts: &HeldBackOptions, seed: u64, fit: &FitOptions, k: usize) -> FurtherGain {
    use axcomp_geometry::plan::{PlanOptions, candidates, plan_after};
    let plan_opts = PlanOptions {
        stroke_mm: opts.stroke_mm,
        max_lines: Some(0),
        tool_offsets: PLAN_TOOL_OFFSETS.to_vec(),
        sigma_um: opts.noise_um,
        targets: opts.targets,
        topology: Topology::default(),
    };
    let measured = LineData::from_specs(&training_lines(opts));
    let plan = plan_after(&plan_opts, Some(&measured)).expect("the plan of the training lines");
    let planned: Vec<LineSpec> = plan
        .further
        .iter()
        .take(k)
        .map(|f| f.line.clone())
        .collect();
    let mut rng = StdRng::seed_from_u64(seed ^ 0x0f0e_11e5);
    let others: Vec<LineSpec> = candidates(&plan_opts)
        .into_iter()
        .filter(|c| planned.iter().all(|p| p.name != c.name))
        .collect();
    let mut random = Vec::new();
    while random.len() < k.min(others.len()) {
        let c = &others[rng.gen_range(0..others.len())];
        if random.iter().all(|r: &LineSpec| r.name != c.name) {
            random.push(c.clone());
        }
    }
    let rename = |l: &LineSpec, tag: &str| LineSpec {
        name: format!("{tag}{}", l.name),
        ..l.clone()
    };
    let extra: Vec<LineSpec> = planned
        .iter()
        .map(|l| rename(l, "p"))
        .chain(random.iter().map(|l| rename(l, "r")))
        .collect();
    let (case, is_extra) = make_case_with(opts, seed, &extra);
    let score_without = |leave_out: &dyn Fn(usize) -> bool| {
        let mask: Vec<bool> = (0..case.held.len())
            .map(|i| case.held[i] || (is_extra[i] && leave_out(i)))
            .collect();
        let an = analyse(&case.data, &Judge::Holdout(mask), fit).expect("held-back case fits");
        score(
            &case,
            &axcomp_geometry::analysis::predict_readings(&an.fit.model, &case.data),
        )
        .lines
    };
    let line_name = |i: usize| case.data.lines[case.data.readings[i].line].clone();
    FurtherGain {
        seed,
        before: score_without(&|_| true),
        planned: score_without(&|i| !line_name(i).starts_with('p')),
        random: score_without(&|i| !line_name(i).starts_with('r')),
        lines: planned.iter().map(|l| l.name.clone()).collect(),
    }
}
