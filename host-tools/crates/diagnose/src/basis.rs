//! Regressor families per effect kind.
//!
//! Glossary: **family** = the columns (basis functions) an effect kind contributes to a model;
//! **variant** = one setting of the family's searched nonlinear parameter (a period, a time constant, a
//! decay length, a reference position); **x̃** = position scaled to [−1, 1] over the stroke; **d** =
//! approach direction (±1); **ΔT** = temperature rise since the first row.
//!
//! | kind | columns | searched |
//! |---|---|---|
//! | `pitch_error` | uniform cubic B-splines in `target_mm` (≤ `pitch_segments_max` segments, fewer when few distinct targets) | – |
//! | `reversal` | d (constant) or d, d·x̃ | form |
//! | `scale_expansion` | (x − x_ref)·ΔT_s | sensor s, x_ref (17 points from ½ range below to ½ range above the measured positions) |
//! | `thermal_drift` | ΔT_s of one sensor, or ΔT_i of every sensor | sensor |
//! | `thermal_lag` | first-order lag of ΔT_s of one sensor, or of every sensor (same τ) | sensor, τ (log grid, 0.05 % … 100 % of the duration) |
//! | `force_deflection` | every force column | – |
//! | `cogging` | sin, cos(2πx/P) | P in 5…60 mm (frequency step 1/(12·stroke)) |
//! | `interpolation_error` | sin, cos(2πx/P) | P in the usual scale signal periods 4…200 µm, and P/2 (periods that alias to > 2 mm on a regular position grid are left out) |
//! | `end_effect` | exp(−(x−x_min)/λ) or exp(−(x_max−x)/λ), optionally also × d; or both ends | end, λ (1 … 10 % of the stroke) |
//! | `following_error` | velocity and/or acceleration | terms |
//! | `abbe` | offset × Legendre P0…P_k(x̃), k ≤ 2 | degree |
//! | `time_drift` | Legendre P1…P_k of the scaled time, k ≤ 3; or trend + settle `1 − exp(−(t − t₀)/τ)` | degree, or τ (1–30 % of the duration) |
//!
//! Each variant counts its columns plus its searched parameters (`n_params`); variants are selected by
//! the training BIC of the whole refit, so a simpler variant wins unless the richer one pays for itself.

use std::sync::Arc;

use serde_json::{Map, Value, json};

use crate::EffectKind;
use crate::obs::{Named, Observations};

/// Builds a variant's columns over all rows, on demand.
pub type ColumnBuilder = Arc<dyn Fn(&Context, &Observations) -> Vec<Vec<f64>> + Send + Sync>;

/// One setting of a family. Its columns are built on demand ([`Variant::columns`]), so a family with
/// hundreds of searched variants holds only their parameters (memory O(rows), not O(rows·variants)).
#[derive(Clone)]
pub struct Variant {
    /// Searched parameters (and descriptive ones) for the report.
    pub params: Map<String, Value>,
    /// Parameters counted for "the simpler explanation": columns + searched nonlinear parameters.
    pub n_params: usize,
    /// Number of columns.
    pub n_cols: usize,
    build: ColumnBuilder,
}

impl std::fmt::Debug for Variant {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Variant")
            .field("params", &self.params)
            .field("n_params", &self.n_params)
            .field("n_cols", &self.n_cols)
            .finish_non_exhaustive()
    }
}

impl Variant {
    /// The columns over all rows.
    pub fn columns(&self, ctx: &Context, obs: &Observations) -> Vec<Vec<f64>> {
        (self.build)(ctx, obs)
    }

    /// The columns restricted to `rows` (indexed by position in `rows`).
    pub fn columns_on(&self, ctx: &Context, obs: &Observations, rows: &[usize]) -> Vec<Vec<f64>> {
        self.columns(ctx, obs)
            .into_iter()
            .map(|c| rows.iter().map(|&i| c[i]).collect())
            .collect()
    }
}

/// The regressors of one effect kind.
#[derive(Debug, Clone)]
pub struct Family {
    pub kind: EffectKind,
    pub variants: Vec<Variant>,
}

fn var(
    n_cols: usize,
    params: Map<String, Value>,
    searched: usize,
    build: impl Fn(&Context, &Observations) -> Vec<Vec<f64>> + Send + Sync + 'static,
) -> Variant {
    Variant {
        params,
        n_params: n_cols + searched,
        n_cols,
        build: Arc::new(build),
    }
}

/// Precomputed views of the observations shared by all families.
#[derive(Debug, Clone)]
pub struct Context {
    pub n: usize,
    pub train: Vec<usize>,
    pub x: Option<Vec<f64>>,
    pub x_min: f64,
    pub x_max: f64,
    /// x scaled to [−1, 1].
    pub xs: Option<Vec<f64>>,
    pub n_unique_x_train: usize,
    pub d: Option<Vec<f64>>,
    pub dt: Vec<Named>,
    pub time_order: Vec<usize>,
    pub t: Option<Vec<f64>>,
    pub duration_s: f64,
    pub pitch_segments_max: usize,
}

fn varies(v: &[f64], rows: &[usize]) -> bool {
    if rows.is_empty() {
        return false;
    }
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for &i in rows {
        lo = lo.min(v[i]);
        hi = hi.max(v[i]);
    }
    hi - lo > 1e-9 * hi.abs().max(lo.abs()).max(1e-12)
}

impl Context {
    pub fn new(obs: &Observations, pitch_segments_max: usize) -> Context {
        let n = obs.n_rows();
        let train = obs.train_rows();
        let x = obs.position_mm.clone().filter(|x| varies(x, &train));
        let (mut x_min, mut x_max) = (0.0, 1.0);
        let mut n_unique = 0;
        let xs = x.as_ref().map(|x| {
            x_min = x.iter().cloned().fold(f64::INFINITY, f64::min);
            x_max = x.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            let mut u: Vec<f64> = train.iter().map(|&i| x[i]).collect();
            u.sort_by(|a, b| a.total_cmp(b));
            let tol = 1e-6 * (x_max - x_min);
            u.dedup_by(|a, b| (*a - *b).abs() <= tol);
            n_unique = u.len();
            x.iter()
                .map(|v| 2.0 * (v - x_min) / (x_max - x_min) - 1.0)
                .collect()
        });
        let d = obs.direction.clone().filter(|d| varies(d, &train));
        let dt: Vec<Named> = obs
            .delta_t()
            .into_iter()
            .filter(|t| varies(&t.values, &train))
            .collect();
        let time_order = obs.time_order();
        let t = obs.time_s.clone().filter(|t| varies(t, &train));
        let duration_s = t.as_ref().map_or(0.0, |t| {
            let lo = t.iter().cloned().fold(f64::INFINITY, f64::min);
            let hi = t.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
            hi - lo
        });
        Context {
            n,
            train,
            x,
            x_min,
            x_max,
            xs,
            n_unique_x_train: n_unique,
            d,
            dt,
            time_order,
            t,
            duration_s,
            pitch_segments_max,
        }
    }

    fn stroke(&self) -> f64 {
        self.x_max - self.x_min
    }
}

/// The spacing of the distinct positions (of `rows`) when they form a regular grid (all gaps within 1 % of
/// the median gap), else `None`.
pub fn regular_spacing(x: &[f64], rows: &[usize]) -> Option<f64> {
    let mut u: Vec<f64> = rows.iter().map(|&i| x[i]).collect();
    u.sort_by(|a, b| a.total_cmp(b));
    let span = u.last()? - u.first()?;
    u.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * span.max(1.0));
    if u.len() < 3 {
        return None;
    }
    let mut gaps: Vec<f64> = u.windows(2).map(|w| w[1] - w[0]).collect();
    let med = axcomp_numeric::stats::upper_median(&mut gaps);
    (gaps.iter().all(|g| (g - med).abs() <= 0.01 * med)).then_some(med)
}

/// Uniform cubic B-spline basis (`k` segments → `k + 3` functions) over [lo, hi]
/// ([`axcomp_numeric::bspline::uniform_cubic_basis`]).
pub fn bspline_basis(x: &[f64], lo: f64, hi: f64, k: usize) -> Vec<Vec<f64>> {
    axcomp_numeric::bspline::uniform_cubic_basis(x, lo, hi, k)
}

/// First-order lag of `u` with time constant `tau_s`, rows visited in `order` (time order)
/// ([`axcomp_numeric::lag::lag_ordered`]; why it differs from the firmware-form lag is said there).
pub fn first_order_lag(u: &[f64], t: &[f64], order: &[usize], tau_s: f64) -> Vec<f64> {
    axcomp_numeric::lag::lag_ordered(u, t, order, tau_s)
}

fn sincos(x: &[f64], period: f64) -> Vec<Vec<f64>> {
    let w = 2.0 * core::f64::consts::PI / period;
    vec![
        x.iter().map(|v| (w * v).sin()).collect(),
        x.iter().map(|v| (w * v).cos()).collect(),
    ]
}

fn map(v: Value) -> Map<String, Value> {
    match v {
        Value::Object(m) => m,
        _ => Map::new(),
    }
}

/// Position scaled to [−1, 1] (`ctx.xs`), or an empty column when absent (never called then).
fn xs_of(ctx: &Context) -> &[f64] {
    ctx.xs.as_deref().unwrap_or(&[])
}

fn x_of(ctx: &Context) -> &[f64] {
    ctx.x.as_deref().unwrap_or(&[])
}

fn d_of(ctx: &Context) -> &[f64] {
    ctx.d.as_deref().unwrap_or(&[])
}

fn t_of(ctx: &Context) -> &[f64] {
    ctx.t.as_deref().unwrap_or(&[])
}

fn product(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(p, q)| p * q).collect()
}

/// Scaled time in [−1, 1] over the campaign.
fn time_scaled(ctx: &Context) -> Vec<f64> {
    let t = t_of(ctx);
    let lo = t.iter().cloned().fold(f64::INFINITY, f64::min);
    t.iter()
        .map(|v| 2.0 * (v - lo) / ctx.duration_s - 1.0)
        .collect()
}

/// The family of `kind` for these observations, or `None` when the columns it needs are absent or constant.
/// Columns are built on demand from `ctx` and `obs` (see [`Variant::columns`]).
pub fn family(kind: EffectKind, obs: &Observations, ctx: &Context) -> Option<Family> {
    let variants = match kind {
        EffectKind::PitchError => pitch_error(ctx)?,
        EffectKind::Reversal => reversal(ctx)?,
        EffectKind::ScaleExpansion => scale_expansion(ctx)?,
        EffectKind::ThermalDrift => thermal_drift(ctx)?,
        EffectKind::ThermalLag => thermal_lag(ctx)?,
        EffectKind::ForceDeflection => force_deflection(obs, ctx)?,
        EffectKind::Cogging => cogging(ctx)?,
        EffectKind::InterpolationError => interpolation_error(ctx)?,
        EffectKind::EndEffect => end_effect(ctx)?,
        EffectKind::FollowingError => following_error(obs, ctx)?,
        EffectKind::Abbe => abbe(obs, ctx)?,
        EffectKind::TimeDrift => time_drift(ctx)?,
    };
    Some(Family { kind, variants })
}

/// The `pitch_error` variants (see the module table).
fn pitch_error(ctx: &Context) -> Option<Vec<Variant>> {
    ctx.x.as_ref()?;
    let u = ctx.n_unique_x_train;
    if u < 2 {
        return None;
    }
    if u < 5 {
        // Polynomial of degree u−1 (the constant is the model's intercept).
        ctx.xs.as_ref()?;
        return Some(vec![var(
            u - 1,
            map(json!({"basis": "polynomial", "degree": u - 1})),
            0,
            move |ctx, _| {
                (1..u)
                    .map(|p| xs_of(ctx).iter().map(|v| v.powi(p as i32)).collect())
                    .collect()
            },
        )]);
    }
    let k = (u - 3).clamp(1, ctx.pitch_segments_max.max(1));
    Some(vec![var(
        k + 3,
        map(
            json!({"basis": "cubic_bspline", "segments": k, "knot_spacing_mm": ctx.stroke() / k as f64}),
        ),
        0,
        move |ctx, _| bspline_basis(x_of(ctx), ctx.x_min, ctx.x_max, k),
    )])
}

/// The `reversal` variants (see the module table).
fn reversal(ctx: &Context) -> Option<Vec<Variant>> {
    ctx.d.as_ref()?;
    let mut vars = vec![var(1, map(json!({"form": "constant"})), 0, |ctx, _| {
        vec![d_of(ctx).to_vec()]
    })];
    if ctx.xs.is_some() {
        vars.push(var(2, map(json!({"form": "linear_in_x"})), 0, |ctx, _| {
            vec![d_of(ctx).to_vec(), product(d_of(ctx), xs_of(ctx))]
        }));
    }
    Some(vars)
}

/// The `scale_expansion` variants (see the module table).
fn scale_expansion(ctx: &Context) -> Option<Vec<Variant>> {
    // c·(x − x_ref)·ΔT_s with x_ref on a grid reaching half a measured range beyond each end (the
    // reference may lie outside the measured positions); one column, so it never absorbs a
    // position-independent drift.
    ctx.x.as_ref()?;
    if ctx.dt.is_empty() {
        return None;
    }
    let searched = 1 + usize::from(ctx.dt.len() > 1);
    let mut vars = Vec::new();
    for (si, s) in ctx.dt.iter().enumerate() {
        for k in 0..=16 {
            let xr = ctx.x_min + ctx.stroke() * (k as f64 / 8.0 - 0.5);
            vars.push(var(
                1,
                map(json!({"sensor": s.name, "x_ref_mm": xr})),
                searched,
                move |ctx, _| {
                    let dt = &ctx.dt[si].values;
                    vec![
                        x_of(ctx)
                            .iter()
                            .zip(dt)
                            .map(|(x, t)| (x - xr) * t)
                            .collect(),
                    ]
                },
            ));
        }
    }
    Some(vars)
}

/// The `thermal_drift` variants (see the module table).
fn thermal_drift(ctx: &Context) -> Option<Vec<Variant>> {
    if ctx.dt.is_empty() {
        return None;
    }
    let names: Vec<&str> = ctx.dt.iter().map(|s| s.name.as_str()).collect();
    let mut vars = Vec::new();
    if ctx.dt.len() > 1 {
        for (si, s) in ctx.dt.iter().enumerate() {
            vars.push(var(
                1,
                map(json!({"sensors": [s.name]})),
                1,
                move |ctx, _| vec![ctx.dt[si].values.clone()],
            ));
        }
    }
    vars.push(var(
        ctx.dt.len(),
        map(json!({"sensors": names})),
        0,
        |ctx, _| ctx.dt.iter().map(|s| s.values.clone()).collect(),
    ));
    Some(vars)
}

/// The `thermal_lag` variants (see the module table).
fn thermal_lag(ctx: &Context) -> Option<Vec<Variant>> {
    ctx.t.as_ref()?;
    if ctx.dt.is_empty() || ctx.duration_s <= 0.0 {
        return None;
    }
    let names: Vec<&str> = ctx.dt.iter().map(|s| s.name.as_str()).collect();
    let mut vars = Vec::new();
    let m = 18;
    for k in 0..m {
        let frac = 0.0005 * (1.0f64 / 0.0005).powf(k as f64 / (m - 1) as f64);
        let tau = frac * ctx.duration_s;
        if ctx.dt.len() > 1 {
            for (si, s) in ctx.dt.iter().enumerate() {
                vars.push(var(
                    1,
                    map(json!({"tau_s": tau, "sensors": [s.name]})),
                    2,
                    move |ctx, _| {
                        vec![first_order_lag(
                            &ctx.dt[si].values,
                            t_of(ctx),
                            &ctx.time_order,
                            tau,
                        )]
                    },
                ));
            }
        }
        vars.push(var(
            ctx.dt.len(),
            map(json!({"tau_s": tau, "sensors": names})),
            1,
            move |ctx, _| {
                ctx.dt
                    .iter()
                    .map(|s| first_order_lag(&s.values, t_of(ctx), &ctx.time_order, tau))
                    .collect()
            },
        ));
    }
    Some(vars)
}

/// The `force_deflection` variants (see the module table).
fn force_deflection(obs: &Observations, ctx: &Context) -> Option<Vec<Variant>> {
    let idx: Vec<usize> = (0..obs.forces.len())
        .filter(|&j| varies(&obs.forces[j].values, &ctx.train))
        .collect();
    if idx.is_empty() {
        return None;
    }
    let names: Vec<&str> = obs.forces.iter().map(|f| f.name.as_str()).collect();
    Some(vec![var(
        idx.len(),
        map(json!({"forces": names})),
        0,
        move |_, obs| idx.iter().map(|&j| obs.forces[j].values.clone()).collect(),
    )])
}

/// The `cogging` variants (see the module table).
fn cogging(ctx: &Context) -> Option<Vec<Variant>> {
    ctx.x.as_ref()?;
    let l = ctx.stroke();
    if l < 5.0 {
        return None;
    }
    let (f_lo, f_hi) = (1.0 / 60.0, 1.0 / 5.0);
    // Frequency step 1/(12·stroke): at most π/12 of phase error across the stroke.
    let df = 1.0 / (12.0 * l);
    let steps = (((f_hi - f_lo) / df).ceil() as usize).clamp(60, 900);
    let vars = (0..=steps)
        .map(|k| {
            let f = f_lo + (f_hi - f_lo) * k as f64 / steps as f64;
            var(2, map(json!({"period_mm": 1.0 / f})), 1, move |ctx, _| {
                sincos(x_of(ctx), 1.0 / f)
            })
        })
        .collect();
    Some(vars)
}

/// The `interpolation_error` variants (see the module table).
fn interpolation_error(ctx: &Context) -> Option<Vec<Variant>> {
    let x = ctx.x.as_ref()?;
    let mut vars = Vec::new();
    let all: Vec<usize> = (0..ctx.n).collect();
    let grid = regular_spacing(x, &all);
    for p_um in [4.0, 8.0, 10.0, 20.0, 40.0, 100.0, 200.0] {
        for (h, label) in [(1.0, 1), (2.0, 2)] {
            let period_mm = p_um / 1000.0 / h;
            if let Some(s) = grid {
                // On a regular grid of spacing s a short period aliases to 1/|1/P − m/s|: when
                // that is longer than 2 mm it mimics cogging / pitch and is not identifiable.
                let f = 1.0 / period_mm;
                let alias = (f - (f * s).round() / s).abs();
                if alias < 0.5 {
                    continue;
                }
            }
            vars.push(var(
                2,
                map(json!({"signal_period_um": p_um, "harmonic": label})),
                1,
                move |ctx, _| sincos(x_of(ctx), period_mm),
            ));
        }
    }
    if vars.is_empty() {
        return None;
    }
    Some(vars)
}

/// The `end_effect` variants (see the module table).
fn end_effect(ctx: &Context) -> Option<Vec<Variant>> {
    ctx.x.as_ref()?;
    let l = ctx.stroke();
    let has_d = ctx.d.is_some();
    let mut vars = Vec::new();
    let decay = |ctx: &Context, lam: f64, end: bool| -> Vec<f64> {
        x_of(ctx)
            .iter()
            .map(|v| {
                if end {
                    (-(ctx.x_max - v) / lam).exp()
                } else {
                    (-(v - ctx.x_min) / lam).exp()
                }
            })
            .collect()
    };
    for frac in [0.01, 0.015, 0.02, 0.03, 0.04, 0.055, 0.075, 0.1] {
        let lam = frac * l;
        for (end, at_end) in [("start", false), ("end", true)] {
            let p = map(
                json!({"decay_mm": lam, "stroke_end": end, "end_mm": if end == "start" { ctx.x_min } else { ctx.x_max }}),
            );
            vars.push(var(1, p.clone(), 2, move |ctx, _| {
                vec![decay(ctx, lam, at_end)]
            }));
            if has_d {
                let mut p = p;
                p.insert("by_direction".into(), Value::Bool(true));
                vars.push(var(2, p, 2, move |ctx, _| {
                    let e = decay(ctx, lam, at_end);
                    let de = product(&e, d_of(ctx));
                    vec![e, de]
                }));
            }
        }
        vars.push(var(
            if has_d { 4 } else { 2 },
            map(json!({"decay_mm": lam, "stroke_end": "both"})),
            1,
            move |ctx, _| {
                let lo = decay(ctx, lam, false);
                let hi = decay(ctx, lam, true);
                let mut cols = Vec::new();
                if ctx.d.is_some() {
                    cols.push(product(&lo, d_of(ctx)));
                    cols.push(product(&hi, d_of(ctx)));
                }
                cols.insert(0, hi);
                cols.insert(0, lo);
                cols
            },
        ));
    }
    Some(vars)
}

/// The `following_error` variants (see the module table).
fn following_error(obs: &Observations, ctx: &Context) -> Option<Vec<Variant>> {
    let v = obs
        .velocity_mm_s
        .as_ref()
        .is_some_and(|v| varies(v, &ctx.train));
    let a = obs
        .accel_mm_s2
        .as_ref()
        .is_some_and(|a| varies(a, &ctx.train));
    let vel = |o: &Observations| o.velocity_mm_s.clone().unwrap_or_default();
    let acc = |o: &Observations| o.accel_mm_s2.clone().unwrap_or_default();
    let mut vars = Vec::new();
    if v {
        vars.push(var(
            1,
            map(json!({"terms": ["velocity"]})),
            0,
            move |_, o| vec![vel(o)],
        ));
    }
    if a {
        vars.push(var(
            1,
            map(json!({"terms": ["acceleration"]})),
            0,
            move |_, o| vec![acc(o)],
        ));
    }
    if v && a {
        vars.push(var(
            2,
            map(json!({"terms": ["velocity", "acceleration"]})),
            0,
            move |_, o| vec![vel(o), acc(o)],
        ));
    }
    if vars.is_empty() {
        return None;
    }
    Some(vars)
}

/// The `abbe` variants (see the module table).
fn abbe(obs: &Observations, ctx: &Context) -> Option<Vec<Variant>> {
    obs.offset_mm.as_ref().filter(|o| varies(o, &ctx.train))?;
    let off = |o: &Observations| o.offset_mm.clone().unwrap_or_default();
    let mut vars = vec![var(1, map(json!({"degree": 0})), 0, move |_, o| {
        vec![off(o)]
    })];
    if ctx.xs.is_some() {
        for degree in 1..=2usize {
            vars.push(var(
                degree + 1,
                map(json!({"degree": degree})),
                0,
                move |ctx, o| {
                    let o = off(o);
                    let xs = xs_of(ctx);
                    let mut cols = vec![product(&o, xs)];
                    if degree == 2 {
                        cols.push(
                            o.iter()
                                .zip(xs)
                                .map(|(a, b)| a * (1.5 * b * b - 0.5))
                                .collect(),
                        );
                    }
                    cols.insert(0, o);
                    cols
                },
            ));
        }
    }
    Some(vars)
}

/// The `time_drift` variants (see the module table).
fn time_drift(ctx: &Context) -> Option<Vec<Variant>> {
    ctx.t.as_ref()?;
    let mut vars: Vec<Variant> = (1..=3usize)
        .map(|degree| {
            var(
                degree,
                map(json!({"basis": "legendre", "degree": degree})),
                0,
                move |ctx, _| {
                    let ts = time_scaled(ctx);
                    let mut cols = Vec::new();
                    if degree >= 2 {
                        cols.push(ts.iter().map(|s| 1.5 * s * s - 0.5).collect());
                    }
                    if degree >= 3 {
                        cols.push(ts.iter().map(|s| 2.5 * s * s * s - 1.5 * s).collect());
                    }
                    cols.insert(0, ts);
                    cols
                },
            )
        })
        .collect();
    // A drift that settles: linear trend plus `1 − exp(−(t − t₀)/τ)`, τ searched on a
    // geometric grid from 1 % to 30 % of the campaign's duration.
    let m = 6;
    for k in 0..m {
        let tau = ctx.duration_s * 0.01 * 30f64.powf(k as f64 / (m - 1) as f64);
        vars.push(var(
            2,
            map(json!({"basis": "settle", "tau_s": tau})),
            1,
            move |ctx, _| {
                let t = t_of(ctx);
                let lo = t.iter().cloned().fold(f64::INFINITY, f64::min);
                let settle = t.iter().map(|v| 1.0 - (-(v - lo) / tau).exp()).collect();
                vec![time_scaled(ctx), settle]
            },
        ));
    }
    Some(vars)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bspline_partition_of_unity() {
        // Uniform cubic B-splines sum to 1 everywhere on [lo, hi] (reference: de Boor; tol 1e-12).
        let x: Vec<f64> = (0..=100).map(|i| i as f64 * 2.0).collect();
        let b = bspline_basis(&x, 0.0, 200.0, 7);
        for i in 0..x.len() {
            let s: f64 = b.iter().map(|c| c[i]).sum();
            assert!((s - 1.0).abs() < 1e-12, "x={} sum={s}", x[i]);
        }
    }

    #[test]
    fn short_periods_aliasing_on_a_regular_grid_are_left_out() {
        // Positions every 1.25 mm: a 20 µm period is sampled at one phase only (alias frequency 0) and a
        // 4 µm period also (1.25/0.004 = 312.5 → alias 0.4 /mm would be a 2.5 mm "period"): neither is
        // identifiable, so the family keeps only the periods whose alias is faster than 2 mm.
        let x: Vec<f64> = (0..400).map(|i| i as f64 * 1.25).collect();
        assert!((regular_spacing(&x, &(0..400).collect::<Vec<_>>()).unwrap() - 1.25).abs() < 1e-12);
        let obs = Observations {
            target_name: "deviation_um".into(),
            target: vec![0.0; 400],
            held_out: (0..400).map(|i| i % 5 == 0).collect(),
            position_mm: Some(x.clone()),
            ..Default::default()
        };
        let ctx = Context::new(&obs, 8);
        let kept: Vec<f64> = family(EffectKind::InterpolationError, &obs, &ctx)
            .map(|f| {
                f.variants
                    .iter()
                    .map(|v| v.params["signal_period_um"].as_f64().unwrap())
                    .collect()
            })
            .unwrap_or_default();
        assert!(!kept.contains(&20.0) && !kept.contains(&4.0), "{kept:?}");
        // Irregular positions keep every period.
        let xi: Vec<f64> = (0..400)
            .map(|i| i as f64 * 1.25 + 0.37 * ((i * 7919) % 13) as f64 / 13.0)
            .collect();
        assert!(regular_spacing(&xi, &(0..400).collect::<Vec<_>>()).is_none());
    }

    #[test]
    fn lag_step_response() {
        // Step input through a lag: the exact discretisation gives 1 − e^(−k·Δt/τ) after k updates (index 1
        // is the first), so y[100] = 1 − e^(−1) (reference: analytic; tol 1e-9).
        let t: Vec<f64> = (0..1000).map(|i| i as f64).collect();
        let u: Vec<f64> = t
            .iter()
            .map(|&s| if s >= 1.0 { 1.0 } else { 0.0 })
            .collect();
        let order: Vec<usize> = (0..1000).collect();
        let y = first_order_lag(&u, &t, &order, 100.0);
        assert!(
            (y[100] - (1.0 - (-1.0f64).exp())).abs() < 1e-9,
            "{}",
            y[100]
        );
    }
}
