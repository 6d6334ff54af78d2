//! Identification of the 21 components from laser line readings: stacked design matrix, identifiability
//! (eigen-decomposition of the column-normalised normal matrix = SVD of the design), the sets the data
//! cannot separate (estimated at the damped minimum norm by default, fixed at zero by the plain and
//! seven-line methods), smoothing chosen by cross-validation over lines or, with [`Prior::Evidence`], the
//! prior and knot grid chosen by the training readings' evidence ([`crate::evidence`]), standard
//! uncertainties.

use axcomp_kinematics::{Axis, Component, ComponentKind, Topology};
use axcomp_numeric::lsq::{cholesky_with_ridge, max_abs_diagonal, symmetric_eigen};
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use crate::GeometryError;
use crate::data::LineData;
use crate::design::{Design, TOL};
use crate::evidence::{self, Evidence, PriorBlock, PriorCandidate, prior_group};
pub use crate::evidence::{Prior, PriorGroups};
pub use crate::layout::Layout;
use crate::model::{ComponentModel, GeometryModel, MODEL_FORMAT};

/// Identification method.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// General least squares, smoothing λ chosen by leave-one-line-out cross-validation (λ = 0 included).
    Auto,
    /// General least squares without smoothing (λ = 0): the plain reference.
    Plain,
    /// Seed 000's seven-line method: the 17 parameters of its eq. 9 (ECY, EAZ, EBZ, ECZ fixed at 0 because
    /// with the reflector on the tool reference point they have no lever arm), no smoothing.
    SevenLine,
}

impl Method {
    pub fn parse(s: &str) -> Option<Method> {
        match s {
            "auto" => Some(Method::Auto),
            "plain" => Some(Method::Plain),
            "seven-line" => Some(Method::SevenLine),
            _ => None,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Method::Auto => "auto",
            Method::Plain => "plain",
            Method::SevenLine => "seven-line",
        }
    }
}

/// The four components the seven-line method fixes (no lever arm with zero tool offset, seed eq. 9).
pub const SEVEN_LINE_FIXED: [Component; 4] = [
    Component::ECY,
    Component::EAZ,
    Component::EBZ,
    Component::ECZ,
];

/// [`FitOptions::damping`]'s default (chosen on held-back twin lines at other offsets and diagonals:
/// `cargo run --release -p axcomp-validation --example held_back`).
pub const DEFAULT_DAMPING: f64 = 1e-4;

/// [`FitOptions::roughness_order`]'s default: the third difference, so that the roughness prior leaves
/// quadratics free (held-back twin lines at other offsets and diagonals, seeds 0–99: lower median
/// held-out RMS than the second difference on every range of 20 seeds; `docs/figures.md`).
pub const DEFAULT_ROUGHNESS_ORDER: usize = 3;

/// The roughness orders the evidence compares when [`FitOptions::roughness_order`] is `None`.
pub const ROUGHNESS_ORDERS: [usize; 3] = [2, 3, 4];

/// Options of [`fit`].
#[derive(Debug, Clone)]
pub struct FitOptions {
    pub topology: Topology,
    pub method: Method,
    /// Knot intervals per axis; `None`: the distinct positions along the axis less 3, 1..=12 (so that
    /// plain least squares is still determined where each target is read).
    pub intervals: Option<usize>,
    /// Smoothing λ candidates for [`Method::Auto`].
    pub lambdas: Vec<f64>,
    /// [`Method::Auto`]'s damping of every parameter, relative to the mean diagonal of the normal matrix: a
    /// weak prior of size 0 that gives the directions the lines cannot separate their minimum-norm value
    /// and keeps noise in the barely separable ones from growing away from the measured lines. With
    /// [`Prior::Evidence`] the start of its search (the evidence chooses it).
    pub damping: f64,
    /// How [`Method::Auto`] chooses its smoothing and the components' size prior.
    pub prior: Prior,
    /// Order of the evidence prior's roughness penalty (the difference of the spline coefficients it
    /// penalises; the polynomials of lower degree are free of it); `None`: the evidence chooses among
    /// [`ROUGHNESS_ORDERS`]. The line-CV prior always penalises the second difference.
    pub roughness_order: Option<usize>,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            topology: Topology::default(),
            method: Method::Auto,
            intervals: None,
            lambdas: vec![0.0, 1e-4, 1e-3, 1e-2, 1e-1, 1.0],
            damping: DEFAULT_DAMPING,
            prior: Prior::Evidence(PriorGroups::Kind),
            roughness_order: Some(DEFAULT_ROUGHNESS_ORDER),
        }
    }
}

/// Identifiability of the stacked design.
#[derive(Debug, Clone, Serialize)]
pub struct Identifiability {
    /// Rank of the stacked design (column-normalised; singular values below 1e-6 × the largest count as 0).
    pub rank: usize,
    /// Number of parameters (spline coefficients and constants).
    pub parameters: usize,
    /// Largest / smallest singular value of the design actually solved (after fixing).
    pub condition_number: f64,
    /// Components or combinations the data cannot separate.
    pub not_separable: Vec<Vec<String>>,
    /// Singular values of the column-normalised stacked design, largest first.
    pub singular_values: Vec<f64>,
}

/// Per-component result of the identification.
#[derive(Debug, Clone)]
pub struct ComponentStatus {
    pub identified: bool,
    pub reason: String,
    /// Left out of the solve (value 0).
    pub fixed: bool,
    /// A member of a set the lines cannot separate.
    pub not_separable: bool,
}

/// A fitted model with everything the JSON and report need.
#[derive(Debug, Clone)]
pub struct Fit {
    pub model: GeometryModel,
    pub layout: Layout,
    pub params: Vec<f64>,
    /// Covariance of the active parameters, indexed like `active_cols`.
    pub covariance: DMatrix<f64>,
    pub active_cols: Vec<usize>,
    pub status: Vec<ComponentStatus>,
    pub identifiability: Identifiability,
    /// λ candidates and their leave-one-line-out RMS (µm) (Auto only).
    pub lambda_cv: Vec<(f64, f64)>,
    pub train_rows: usize,
    pub fit_rms_um: f64,
    /// The prior chosen by the evidence ([`Prior::Evidence`] only).
    pub evidence: Option<Evidence>,
}

fn priority(c: Component) -> u8 {
    // which member of a non-separable group is fixed first (lowest first): angular, straightness,
    // squareness, positioning (the seed: angular errors matter least)
    match c.kind() {
        ComponentKind::Angular { .. } => 0,
        ComponentKind::Linear { .. } if c.is_straightness() => 1,
        ComponentKind::Squareness => 2,
        _ => 3,
    }
}

/// Solves `(g + λP) β = r` by Cholesky, adding a tiny ridge (1e-12, then 1e-8 of the largest diagonal)
/// when the system is singular (components the fold's lines do not reach stay at their prior 0).
fn solve(m: &DMatrix<f64>, r: &DVector<f64>) -> (DVector<f64>, DMatrix<f64>) {
    if let Some(ch) = cholesky_with_ridge(m) {
        let inv = ch.inverse();
        return (&inv * r, inv);
    }
    let pinv = m
        .clone()
        .pseudo_inverse(1e-12 * max_abs_diagonal(m))
        .expect("finite matrix");
    (&pinv * r, pinv)
}

/// Solves `m β = r` (Cholesky, tiny ridge when singular) without forming the inverse.
fn solve_only(m: &DMatrix<f64>, r: &DVector<f64>) -> DVector<f64> {
    match cholesky_with_ridge(m) {
        Some(ch) => ch.solve(r),
        None => solve(m, r).0,
    }
}

/// Parameter columns of the components that are not fixed.
fn active_of(layout: &Layout, status: &[ComponentStatus]) -> Vec<usize> {
    let mut v = Vec::new();
    for (i, st) in status.iter().enumerate() {
        if !st.fixed {
            let (s, k) = layout.cols[i];
            v.extend(s..s + k);
        }
    }
    v
}

/// Every component estimated, except the seven-line method's four.
fn initial_status(method: Method) -> Vec<ComponentStatus> {
    let mut status: Vec<ComponentStatus> = Component::ALL
        .iter()
        .map(|_| ComponentStatus {
            identified: true,
            reason: String::new(),
            fixed: false,
            not_separable: false,
        })
        .collect();
    if method == Method::SevenLine {
        for c in SEVEN_LINE_FIXED {
            status[c.index()] = ComponentStatus {
                identified: false,
                reason: "fixed at 0 by the seven-line method: with the reflector on the tool reference point it has no lever arm (seed 000 eq. 9); measure lines with tool offsets to identify it".into(),
                fixed: true,
                not_separable: false,
            };
        }
    }
    status
}

/// Fixes the components no reading is sensitive to (each its own not-separable set).
fn fix_insensitive(
    layout: &Layout,
    design: &Design,
    status: &mut [ComponentStatus],
    not_separable: &mut Vec<Vec<String>>,
) {
    for (i, c) in Component::ALL.iter().enumerate() {
        if status[i].fixed || design.component_norm(layout, i) > 1e-9 * design.max_norm.max(1e-300)
        {
            continue;
        }
        let reason = match c.axis() {
            Some(ax) if !layout.moved[ax.index()] => {
                format!("axis {} does not move in these lines; fixed at 0", ax.letter())
            }
            _ => match c.kind() {
                ComponentKind::Angular { .. } => "no reading is sensitive to it: no line gives it a lever arm across its rotation (zero tool offset and no travel of the axes stacked after it in that direction); fixed at 0".to_string(),
                _ => "no reading is sensitive to it (no beam has a component along it); fixed at 0".to_string(),
            },
        };
        status[i] = ComponentStatus {
            identified: false,
            reason,
            fixed: true,
            not_separable: false,
        };
        not_separable.push(vec![c.name().to_string()]);
    }
}

/// The component sets spanned by the null directions of the active design (overlapping sets merged), and
/// each component's total share of them; `None` when the active design has full column rank.
fn null_groups(
    layout: &Layout,
    design: &Design,
    active: &[usize],
) -> Option<(Vec<Vec<usize>>, [f64; 21])> {
    let eig = symmetric_eigen(design.normalised(active));
    let lmax = eig.eigenvalues.iter().fold(0.0f64, |x, y| x.max(*y));
    let null: Vec<usize> = (0..active.len())
        .filter(|&i| eig.eigenvalues[i] <= TOL * TOL * lmax)
        .collect();
    if null.is_empty() {
        return None;
    }
    let comp_of_col = |col: usize| {
        (0..21)
            .find(|&i| {
                let (s, k) = layout.cols[i];
                col >= s && col < s + k
            })
            .expect("every column belongs to a component")
    };
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut share_total = [0.0f64; 21];
    for &ni in &null {
        let v = eig.eigenvectors.column(ni);
        let mut share = [0.0f64; 21];
        for (r, &col) in active.iter().enumerate() {
            share[comp_of_col(col)] += v[r] * v[r];
        }
        for i in 0..21 {
            share_total[i] += share[i];
        }
        let mut merged: Vec<usize> = (0..21).filter(|&i| share[i] > 0.01).collect();
        groups.retain(|g| {
            if g.iter().any(|m| merged.contains(m)) {
                merged.extend(g.iter().filter(|m| !merged.contains(m)).collect::<Vec<_>>());
                false
            } else {
                true
            }
        });
        merged.sort();
        groups.push(merged);
    }
    Some((groups, share_total))
}

/// Marks one not-separable set: the member fixed first (angular, straightness, squareness, positioning;
/// then the largest share of the null directions) leaves the identifiable design, the others carry the
/// combination.
fn mark_group(g: &[usize], share_total: &[f64; 21], status: &mut [ComponentStatus]) -> Vec<String> {
    let fix = *g
        .iter()
        .min_by(|&&x, &&y| {
            priority(Component::ALL[x])
                .cmp(&priority(Component::ALL[y]))
                .then(share_total[y].total_cmp(&share_total[x]))
        })
        .expect("a null direction has members");
    let names: Vec<String> = g
        .iter()
        .map(|&i| Component::ALL[i].name().to_string())
        .collect();
    let others = |i: usize| -> String {
        names
            .iter()
            .filter(|n| *n != Component::ALL[i].name())
            .cloned()
            .collect::<Vec<_>>()
            .join(", ")
    };
    status[fix] = ComponentStatus {
        identified: false,
        reason: if g.len() == 1 {
            "its shape along the axis is not determined by these lines (too few distinct positions where a reading is sensitive to it)".into()
        } else {
            format!("not separable from {} with these lines", others(fix))
        },
        fixed: true,
        not_separable: true,
    };
    for &i in g {
        if i != fix && !status[i].fixed {
            status[i].identified = false;
            status[i].not_separable = true;
            status[i].reason = format!("only its combination with {} is determined", others(i));
        }
    }
    names
}

/// Fixes members of the null directions' component sets until the remaining design has full column rank.
fn fix_null_groups(
    layout: &Layout,
    design: &Design,
    status: &mut [ComponentStatus],
    not_separable: &mut Vec<Vec<String>>,
) {
    for _ in 0..21 {
        let active = active_of(layout, status);
        if active.is_empty() {
            break;
        }
        let Some((groups, share_total)) = null_groups(layout, design, &active) else {
            break;
        };
        for g in &groups {
            let names = mark_group(g, &share_total, status);
            if !not_separable.contains(&names) {
                not_separable.push(names);
            }
        }
    }
}

/// How the not-separable sets end: fixed at 0 (plain, seven-line) or estimated with the others at the
/// damped minimum norm (auto): the reasons say which.
fn settle_not_separable(status: &mut [ComponentStatus], min_norm: bool) {
    for st in status.iter_mut().filter(|s| s.not_separable) {
        if min_norm {
            st.fixed = false;
            st.reason.push_str("; its value is the minimum-norm share of what the lines determine (not its own value)");
        } else if st.fixed {
            st.reason.push_str("; fixed at 0");
        } else {
            st.reason.push_str(
                " (the not-separable members fixed at 0); the value carries that combination",
            );
        }
    }
}

/// The prior blocks of the active parameters: each estimated component's second-difference penalty
/// (squareness: none), scaled by its columns' mean squared norm (so precisions are relative to the
/// data's weight on it).
fn prior_blocks(
    layout: &Layout,
    design: &Design,
    status: &[ComponentStatus],
    active: &[usize],
    groups: PriorGroups,
    order: usize,
) -> Vec<PriorBlock> {
    let mut blocks = Vec::new();
    for (i, st) in status.iter().enumerate() {
        if st.fixed {
            continue;
        }
        let c = Component::ALL[i];
        let (s, k) = layout.cols[i];
        let pos0 = active
            .iter()
            .position(|&col| col == s)
            .expect("an estimated component's columns are active");
        let w: f64 = (s..s + k)
            .map(|j| design.col_norm[j] * design.col_norm[j])
            .sum::<f64>()
            / k as f64;
        let rough = match c.axis() {
            Some(ax) => {
                let dn = layout.grids[ax.index()].difference(order) * &layout.bases[i];
                dn.transpose() * &dn * w
            }
            None => DMatrix::zeros(1, 1),
        };
        blocks.push(PriorBlock {
            cols: (pos0..pos0 + k).collect(),
            rough,
            weight: w,
            group: prior_group(c, groups),
            component: i,
        });
    }
    blocks
}

/// Second-difference penalty on the active parameters, each function's block scaled by its columns' mean
/// squared norm (so λ is relative to the data's weight on it).
fn penalty(
    layout: &Layout,
    design: &Design,
    status: &[ComponentStatus],
    active: &[usize],
) -> DMatrix<f64> {
    let blocks = prior_blocks(layout, design, status, active, PriorGroups::Global, 2);
    evidence::prior_matrix(&blocks, &[1.0], &[0.0], 0.0, active.len())
}

/// Damping of the solve: `damping` × the mean diagonal of the normal matrix on every active parameter (a
/// weak prior of size 0 in the parameters' own units: the minimum-norm solution where the lines say nothing).
fn damping_matrix(g: &DMatrix<f64>, damping: f64) -> DMatrix<f64> {
    let p = g.nrows();
    let mean = g.trace() / p.max(1) as f64;
    DMatrix::identity(p, p) * (damping * mean)
}

/// The active problem: normal equations restricted to the estimated parameters.
struct Active<'a> {
    cols: Vec<usize>,
    aa: DMatrix<f64>,
    g: DMatrix<f64>,
    r: DVector<f64>,
    pen: DMatrix<f64>,
    damp: DMatrix<f64>,
    design: &'a Design,
}

impl Active<'_> {
    fn sel(&self, g: &DMatrix<f64>) -> DMatrix<f64> {
        g.select_rows(self.cols.iter())
            .select_columns(self.cols.iter())
    }
    fn selv(&self, r: &DVector<f64>) -> DVector<f64> {
        DVector::from_iterator(self.cols.len(), self.cols.iter().map(|&j| r[j]))
    }
}

/// λ by leave-one-line-out cross-validation: `(λ, [(λ, RMS)], whether the folds could choose)`. A fold
/// whose removal leaves some identifiable parameter undetermined (an essential line) cannot be predicted
/// by any λ and is left out of the score (pivot of the fold's Cholesky factor, on the identifiable
/// columns `ident`, below 1e-9 of the column's own diagonal). When no fold is informative, the scores
/// differ by rounding only and λ = 0.
fn choose_lambda(act: &Active, ident: &[usize], lambdas: &[f64]) -> (f64, Vec<(f64, f64)>, bool) {
    let design = act.design;
    let g_ident = design
        .g_full
        .select_rows(ident.iter())
        .select_columns(ident.iter());
    let informative: Vec<bool> = design
        .folds
        .iter()
        .map(|(_, gf, _)| {
            let m = &g_ident - gf.select_rows(ident.iter()).select_columns(ident.iter());
            match m.clone().cholesky() {
                Some(ch) => {
                    let l = ch.l();
                    (0..m.nrows()).all(|i| l[(i, i)] * l[(i, i)] > 1e-9 * m[(i, i)].abs())
                }
                None => false,
            }
        })
        .collect();
    let any = informative.iter().any(|x| *x);
    let mut scores = Vec::new();
    let mut best = (f64::INFINITY, 0.0);
    for &lam in lambdas {
        let (mut sse, mut count) = (0.0, 0usize);
        for (fi, (rows, gf, rf)) in design.folds.iter().enumerate() {
            if any && !informative[fi] {
                continue;
            }
            let m = &act.g - act.sel(gf) + &act.pen * lam + &act.damp;
            let beta = solve_only(&m, &(&act.r - act.selv(rf)));
            for &i in rows {
                sse += (design.d[i] - act.aa.row(i).dot(&beta.transpose())).powi(2);
                count += 1;
            }
        }
        let rms = (sse / count.max(1) as f64).sqrt();
        scores.push((lam, rms));
        // prefer less smoothing unless more smoothing is better by 0.1 %
        if rms < best.0 * 0.999 {
            best = (rms, lam);
        }
    }
    if any {
        (best.1, scores, true)
    } else {
        (0.0, scores, false)
    }
}

/// The evidence's prior of the active problem (groups `groups`, damping free from `act.damp`), set as
/// its penalty and damping; `None` (the problem unchanged) when the posterior cannot be factored.
fn evidence_prior(
    act: &mut Active,
    layout: &Layout,
    status: &[ComponentStatus],
    groups: PriorGroups,
    order: usize,
) -> Option<Evidence> {
    let design = act.design;
    let blocks = prior_blocks(layout, design, status, &act.cols, groups, order);
    let normal = evidence::Normal {
        g: &act.g,
        r: &act.r,
        yty: design.d.norm_squared(),
        n: design.d.len(),
    };
    let start = evidence::Start {
        roughness: 1e-2,
        size: 1e-4,
        damping: act.damp.get((0, 0)).copied().unwrap_or(0.0),
        free_damping: true,
    };
    let mut ev = evidence::maximise(&normal, &blocks, start, 200)?;
    ev.roughness_order = order;
    ev.groups = (0..ev.size.len())
        .map(|gi| {
            let members = blocks.iter().filter(|b| b.group == gi);
            let names = members.map(|b| Component::ALL[b.component].name().to_string());
            (evidence::group_name(groups, gi), names.collect())
        })
        .collect();
    let p = act.cols.len();
    act.pen = evidence::prior_matrix(&blocks, &ev.roughness, &ev.size, 0.0, p);
    act.damp = DMatrix::identity(p, p) * ev.damping;
    Some(ev)
}

/// The final solve: parameters, covariance σ̂²·M⁻¹GM⁻¹, σ̂² with the effective degrees of freedom, and the
/// unsmoothed solution (for the smoothing bias) when λ > 0.
struct Solution {
    beta: DVector<f64>,
    cov: DMatrix<f64>,
    sigma2: f64,
    rss: f64,
    beta_unsmoothed: Option<DVector<f64>>,
}

fn solve_final(act: &Active, lambda: f64) -> Solution {
    let m = &act.g + &act.pen * lambda + &act.damp;
    let (beta, minv) = solve(&m, &act.r);
    let resid = &act.design.d - &act.aa * &beta;
    let rss = resid.norm_squared();
    let edf = (&minv * &act.g).trace();
    let n = act.design.d.len() as f64;
    let sigma2 = rss / (n - edf).max(1.0);
    let cov = &minv * &act.g * &minv * sigma2;
    let beta_unsmoothed = (lambda > 0.0).then(|| solve_only(&(&act.g + &act.damp), &act.r));
    Solution {
        beta,
        cov,
        sigma2,
        rss,
        beta_unsmoothed,
    }
}

/// Standard uncertainty of `gᵀβ_c` for component columns `idx` (positions in the active set): the
/// variance from the covariance plus the squared smoothing bias (difference from the unsmoothed solution).
fn uncertainty(sol: &Solution, idx: &[Option<usize>], g: &[f64]) -> f64 {
    let mut v = 0.0;
    if let Some(bp) = &sol.beta_unsmoothed {
        let b: f64 = idx
            .iter()
            .enumerate()
            .filter_map(|(a1, i1)| i1.map(|x| g[a1] * (sol.beta[x] - bp[x])))
            .sum();
        v += b * b;
    }
    for (a1, i1) in idx.iter().enumerate() {
        for (a2, i2) in idx.iter().enumerate() {
            if let (Some(x), Some(y)) = (i1, i2) {
                v += g[a1] * sol.cov[(*x, *y)] * g[a2];
            }
        }
    }
    v.max(0.0).sqrt()
}

/// Component `i`'s model entry.
fn component_model(
    layout: &Layout,
    act: &Active,
    sol: &Solution,
    params: &[f64],
    st: &ComponentStatus,
    i: usize,
) -> ComponentModel {
    let c = Component::ALL[i];
    let (s, k) = layout.cols[i];
    let idx: Vec<Option<usize>> = (s..s + k)
        .map(|j| act.cols.iter().position(|&x| x == j))
        .collect();
    let (coefficients, value, unc) = match c.axis() {
        Some(ax) => {
            let grid = layout.grids[ax.index()];
            let n = &layout.bases[i];
            let unc = grid
                .positions(21)
                .into_iter()
                .map(|q| {
                    let b = grid.basis(q);
                    let g: Vec<f64> = (0..k)
                        .map(|col| (0..b.len()).map(|r| b[r] * n[(r, col)]).sum())
                        .collect();
                    [q, uncertainty(sol, &idx, &g)]
                })
                .collect();
            (layout.coefficients(i, params), 0.0, unc)
        }
        None => (
            Vec::new(),
            params[s],
            vec![[0.0, uncertainty(sol, &idx, &[1.0])]],
        ),
    };
    let a = &act.design.a;
    let reason = if st.identified {
        let sensitive = (0..a.nrows())
            .filter(|&r| (s..s + k).any(|j| a[(r, j)] != 0.0))
            .count();
        format!("identified ({sensitive} readings sensitive to it)")
    } else {
        st.reason.clone()
    };
    ComponentModel {
        name: c.name().to_string(),
        identified: st.identified,
        reason,
        unit: c.unit().to_string(),
        coefficients,
        value,
        uncertainty: unc,
    }
}

/// The method line of the model file.
fn method_text(
    method: Method,
    layout: &Layout,
    lambda: f64,
    cv_chose: bool,
    evidence: bool,
) -> String {
    let [x, y, z] = [0, 1, 2].map(|k| layout.grids[k].intervals);
    let min_norm = "what the lines cannot separate at the damped minimum norm";
    match method {
        Method::Auto if evidence => format!(
            "general least squares on cubic B-splines (knot intervals X {x}, Y {y}, Z {z}) with a Gaussian prior of size 0 whose roughness and size precisions per component group, damping and knot grid maximise the training readings' evidence (marginal likelihood; model.prior in the JSON; smoothing_lambda 1 scales those precisions as they are); what the lines cannot separate is shared as the prior's sizes say"
        ),
        Method::Auto if !cv_chose => format!(
            "general least squares on cubic B-splines (knot intervals X {x}, Y {y}, Z {z}), {min_norm}, no smoothing (λ = 0): leave-one-line-out cross-validation cannot choose λ on these lines, since removing any one of them leaves parameters undetermined (the scores in lambda_cv_rms_um differ by rounding only)"
        ),
        Method::Auto => format!(
            "general least squares on cubic B-splines (knot intervals X {x}, Y {y}, Z {z}), {min_norm}, smoothing λ = {lambda} chosen by leave-one-line-out cross-validation"
        ),
        Method::Plain => "general least squares on cubic B-splines, no smoothing, what the lines cannot separate fixed at 0 (plain reference)".to_string(),
        Method::SevenLine => "seven-line method (seed 000): 17 parameters by least squares, ECY, EAZ, EBZ, ECZ fixed at 0".to_string(),
    }
}

/// The axis-position box of all readings (mm).
fn volume(data: &LineData) -> ([f64; 3], [f64; 3]) {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for r in &data.readings {
        for k in 0..3 {
            lo[k] = lo[k].min(r.q[k]);
            hi[k] = hi[k].max(r.q[k]);
        }
    }
    (lo, hi)
}

/// Identifiability of the design: components no reading sees and the not-separable sets, marked in the
/// status; rank, singular values and the condition of the identifiable part.
fn identify(
    layout: &Layout,
    design: &Design,
    status: &mut [ComponentStatus],
) -> Result<(Identifiability, Vec<usize>), GeometryError> {
    let mut not_separable = Vec::new();
    fix_insensitive(layout, design, status, &mut not_separable);
    let (rank, sv) = design.rank()?;
    fix_null_groups(layout, design, status, &mut not_separable);
    let ident = active_of(layout, status);
    if ident.is_empty() {
        return Err(GeometryError::NothingIdentifiable);
    }
    let identifiability = Identifiability {
        rank,
        parameters: layout.p,
        condition_number: design.condition(&ident),
        not_separable,
        singular_values: sv,
    };
    Ok((identifiability, ident))
}

/// Knot intervals per axis the evidence prior compares with the default grid when none are given.
pub const EVIDENCE_INTERVALS: [usize; 3] = [4, 6, 8];

/// Fits the model to the readings in `train` (indices into `data.readings`). With the evidence prior
/// and no knot intervals given, the grid is chosen too: the default grid and [`EVIDENCE_INTERVALS`],
/// the one whose evidence is highest (`Evidence::knot_grids` lists them).
pub fn fit(data: &LineData, train: &[usize], opts: &FitOptions) -> Result<Fit, GeometryError> {
    if !(opts.method == Method::Auto
        && matches!(opts.prior, Prior::Evidence(_))
        && opts.intervals.is_none())
    {
        return fit_on_grid(data, train, opts);
    }
    let orders: Vec<usize> = match opts.roughness_order {
        Some(o) => vec![o],
        None => ROUGHNESS_ORDERS.to_vec(),
    };
    let mut best: Option<Fit> = None;
    let mut scores = Vec::new();
    for intervals in [None].into_iter().chain(EVIDENCE_INTERVALS.map(Some)) {
        for &roughness_order in &orders {
            let on_grid = fit_on_grid(
                data,
                train,
                &FitOptions {
                    intervals,
                    roughness_order: Some(roughness_order),
                    ..opts.clone()
                },
            );
            // the default grid's failure is the fit's; a compared grid that cannot be fitted (e.g.
            // nothing identifiable on it) is left out of the comparison
            let f = match (on_grid, intervals) {
                (Ok(f), _) => f,
                (Err(e), None) => return Err(e),
                (Err(_), Some(_)) => continue,
            };
            let grid = f.layout.grids.map(|g| g.intervals);
            let Some(ev) = f.evidence.as_ref().map(|e| e.log_evidence) else {
                continue;
            };
            if scores.iter().any(|c: &PriorCandidate| {
                c.intervals == grid && c.roughness_order == roughness_order
            }) {
                continue;
            }
            scores.push(PriorCandidate {
                intervals: grid,
                roughness_order,
                log_evidence: ev,
            });
            if best
                .as_ref()
                .is_none_or(|b| b.evidence.as_ref().is_none_or(|e| ev > e.log_evidence))
            {
                best = Some(f);
            }
        }
    }
    match best {
        Some(mut f) => {
            if let Some(ev) = f.evidence.as_mut() {
                ev.knot_grids = scores;
            }
            Ok(f)
        }
        None => fit_on_grid(data, train, opts),
    }
}

/// [`fit`] on the knot grid of `opts.intervals`.
fn fit_on_grid(data: &LineData, train: &[usize], opts: &FitOptions) -> Result<Fit, GeometryError> {
    if train.is_empty() {
        return Err(GeometryError::NoRows);
    }
    // the design's rows, and so every floating-point sum below, in an order independent of the file's
    let train = &data.canonical_order(train)[..];
    let topo = &opts.topology;
    let layout = Layout::new(data, opts.intervals);
    let design = Design::new(data, train, &layout, topo);
    let mut status = initial_status(opts.method);
    let (identifiability, ident) = identify(&layout, &design, &mut status)?;
    let min_norm = opts.method == Method::Auto;
    settle_not_separable(&mut status, min_norm);
    let cols = active_of(&layout, &status);
    let damping = if min_norm { opts.damping } else { 0.0 };
    let mut act = Active {
        aa: design.a.select_columns(cols.iter()),
        g: design
            .g_full
            .select_rows(cols.iter())
            .select_columns(cols.iter()),
        r: DVector::from_iterator(cols.len(), cols.iter().map(|&j| design.r_full[j])),
        pen: penalty(&layout, &design, &status, &cols),
        damp: DMatrix::zeros(0, 0),
        cols,
        design: &design,
    };
    act.damp = damping_matrix(&act.g, damping);
    let prior = match (opts.method, opts.prior) {
        (Method::Auto, Prior::Evidence(groups)) => {
            let order = opts.roughness_order.unwrap_or(DEFAULT_ROUGHNESS_ORDER);
            evidence_prior(&mut act, &layout, &status, groups, order)
        }
        _ => None,
    };
    if prior.is_some() {
        for st in status.iter_mut().filter(|s| s.not_separable && !s.fixed) {
            st.reason = st
                .reason
                .replace("the minimum-norm share", "the evidence prior's share");
        }
    }
    let (lambda, lambda_cv, cv_chose) = match opts.method {
        _ if prior.is_some() => (1.0, Vec::new(), true),
        Method::Auto if design.folds.len() >= 3 && opts.lambdas.len() > 1 => {
            choose_lambda(&act, &ident, &opts.lambdas)
        }
        Method::Auto if opts.lambdas.len() == 1 => (opts.lambdas[0], Vec::new(), true),
        _ => (0.0, Vec::new(), true),
    };
    let sol = solve_final(&act, lambda);
    let mut params = vec![0.0; layout.p];
    for (k, &c) in act.cols.iter().enumerate() {
        params[c] = sol.beta[k];
    }
    let components = (0..21)
        .map(|i| component_model(&layout, &act, &sol, &params, &status[i], i))
        .collect();
    let (volume_min_mm, volume_max_mm) = volume(data);
    let model = GeometryModel {
        format: MODEL_FORMAT.to_string(),
        version: crate::model::MODEL_VERSION,
        topology: topo.clone(),
        grids: layout.grids,
        components,
        method: method_text(opts.method, &layout, lambda, cv_chose, prior.is_some()),
        smoothing_lambda: lambda,
        sigma_um: sol.sigma2.sqrt(),
        volume_min_mm,
        volume_max_mm,
    };
    let n = train.len();
    Ok(Fit {
        model,
        params,
        covariance: sol.cov,
        active_cols: act.cols,
        status,
        identifiability,
        lambda_cv,
        train_rows: n,
        fit_rms_um: (sol.rss / n as f64).sqrt(),
        evidence: prior,
        layout,
    })
}

/// Unused-axis helper for callers: the letter of an axis index.
pub fn axis_letter(k: usize) -> char {
    Axis::ALL[k].letter()
}
