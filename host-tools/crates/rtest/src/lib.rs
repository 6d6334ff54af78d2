//! `axcomp-rtest`: a five-axis machine's rotary-axis location errors (ISO 230-7) identified from R-test
//! readings (or probed sphere centres in the same form) by Levenberg–Marquardt on the exact HTM model.
//!
//! # Glossary
//! - **pose**, **displacement** `d = S − T` (µm), **location errors**, **set-up offsets**: see
//!   [`axcomp_kinematics::rotary`]. `d` is the sphere centre relative to the R-test head (tool point) along
//!   machine X, Y, Z.
//! - **set-up**: one placement of the sphere and the R-test head; rows with a `setup` column value share
//!   their 6 nuisance offsets (sphere dx, dy, dz and head dx, dy, dz; a second sphere height is a second
//!   set-up). Without the column every row is set-up `1`. The head's zero is taken as known unless
//!   `free_head_zero`.
//! - **identifiable** ([`identifiability`]): a parameter is estimated only when its column of the
//!   column-scaled sensitivity matrix has a part of at least [`CONFOUND_TOL`] (relative) outside the span of
//!   the parameters taken before it (set-up offsets first, then the location errors in [`PRIORITY`] order);
//!   otherwise it is fixed to zero and reported `identified: false` with the parameters it cannot be told
//!   apart from, and the location errors that absorb it are not identified either. An estimated parameter
//!   whose variance is inflated more than [`VIF_LIMIT`] by correlation is reported `identified: false`
//!   (weakly determined) with its (large) standard uncertainty.
//! - **standard uncertainty**: `sqrt(diag(Cov))`, `Cov = (JᵀJ)⁻¹·JᵀWJ·(JᵀJ)⁻¹`, J at the solution,
//!   `W = diag(σ̂_x², σ̂_y², σ̂_z²)` per reading, `σ̂_c² = RSS_c/(n − p/3)` for component `c` (n poses):
//!   `σ̂·sqrt(diag((JᵀJ)⁻¹))` with `σ̂² = RSS/(3n − p)` when the components' noise is alike. With
//!   [`FitOptions::head_zero_std_um`] (the R-test head's or touch probe's zero taken as known but known only
//!   to a standard uncertainty `s`, from its own calibration), the covariance adds the propagated zero error:
//!   the estimate is linear in the readings, a zero error `δh` (one offset common to every row) shifts it by
//!   `G·δh` with `G = (JᵀJ)⁻¹·Jᵀ·J_h` (`J_h`: the head-zero columns), so `Cov = σ̂²(JᵀJ)⁻¹ + G·diag(s²)·Gᵀ`.
//!   Without the option, the data's **shared-error** columns ([`SharedError`]: `zero1_dx_um` …, the probe
//!   route's calibration uncertainty that every pose's centre shares, as `axcomp fit probe --centres-out`
//!   writes it) are propagated the same way: the rows' readings carry `B·u` (`B`: one column per component,
//!   `u` independent unit variances), `Cov += G·Gᵀ` with `G = (JᵀJ)⁻¹·Jᵀ·B` ([`fit_shared`]).

pub mod analysis;
pub mod effect_model;
pub mod effects;
mod fit;
mod identify;
pub mod plan;
pub mod report;
pub mod revisit;

pub use fit::{displacement_with, fit_effects, param_names_with};
pub mod select;
pub mod warnings;

use axcomp_data::Dataset;
use axcomp_kinematics::rotary::{
    C_LIMIT_DEG, FiveAxis, LocationErrors, MachineKind, N_LOCATION, N_SETUP, Pose, SetupOffsets,
    TILT_LIMIT_DEG, location_unit,
};
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

pub use identify::{Identifiability, identifiability, identifiability_ordered};

/// A parameter whose column keeps less than this fraction of its (scaled) norm outside the span of the
/// parameters before it is not identifiable.
pub const CONFOUND_TOL: f64 = 1e-3;
/// Largest variance inflation factor (column-scaled `(JᵀJ)⁻¹` diagonal) of an identified location error: its
/// uncertainty at most √1000 ≈ 32× what it would be if its signature were its own alone. Above it the
/// parameter is still estimated (its std says how poorly) but reported `identified: false`.
pub const VIF_LIMIT: f64 = 1000.0;
/// Order in which location errors are taken (indices into the 11): axis offsets, axis tilts, squareness.
pub const PRIORITY: [usize; N_LOCATION] = [0, 1, 4, 5, 2, 3, 6, 7, 8, 9, 10];

/// Errors of this crate (each names what and where).
#[derive(Debug, thiserror::Error)]
pub enum RtestError {
    #[error(transparent)]
    Data(#[from] axcomp_data::DataError),
    #[error("{file}: machine {machine} needs column `{need}` {why}")]
    MachineColumns {
        file: String,
        machine: &'static str,
        need: String,
        why: String,
    },
    #[error("{at}: {what}")]
    BadValue { at: String, what: String },
    #[error(
        "{file}: pose repeated with {what} at lines {first} and {second} (same commanded position and angles in {group}; a genuine repeat or a revisit is a further run of its path: give it another `run` value)"
    )]
    RepeatedPose {
        file: String,
        first: usize,
        second: usize,
        what: &'static str,
        group: String,
    },
    #[error(
        "{file}: path `{path}` has a single pose (line {line}) over all its runs; a path needs at least two (a revisited pose is a further run of the path it was first measured on: same `path`, another `run`)"
    )]
    SinglePosePath {
        file: String,
        path: String,
        line: usize,
    },
    #[error("{0}")]
    Fit(String),
    #[error("{file}: not a valid R-test model: {what}")]
    BadModel { file: String, what: String },
}

/// R-test rows, validated.
#[derive(Debug, Clone)]
pub struct RtestData {
    pub machine: FiveAxis,
    pub source: String,
    pub poses: Vec<Pose>,
    /// Measured displacements (µm); empty when read without readings (prediction).
    pub d_um: Vec<[f64; 3]>,
    /// Path id per row (`""` without a `path` column).
    pub path: Vec<String>,
    /// Set-up index per row, into `setup_names`.
    pub setup: Vec<usize>,
    pub setup_names: Vec<String>,
    /// File line of each row.
    pub lines: Vec<usize>,
    /// Estimate the R-test head's zero (tool length, radial offset) per set-up as well; otherwise it is taken
    /// as known (zero), as in the seed.
    pub free_head_zero: bool,
}

fn finite_column(ds: &Dataset, col: &str) -> Result<Vec<f64>, RtestError> {
    let v = ds.numeric(col)?.to_vec();
    if let Some(r) = v
        .iter()
        .position(|x| !axcomp_data::sanity::plausible_number(*x))
    {
        return Err(RtestError::BadValue {
            at: ds.locate(col, r),
            what: format!(
                "`{col}` is {:e} (need a finite number below 1e12 in magnitude)",
                v[r]
            ),
        });
    }
    Ok(v)
}

impl RtestData {
    /// Reads the contract's R-test columns from `ds` for `machine`. With `need_readings`, `dx_um`, `dy_um`,
    /// `dz_um` are required and checked (repeats within a run, single-pose paths: [`revisit`]).
    pub fn from_dataset(
        ds: &Dataset,
        machine: FiveAxis,
        need_readings: bool,
    ) -> Result<RtestData, RtestError> {
        let file = ds.source().to_string();
        let tilt_col = format!("{}_deg", machine.kind.tilt_letter());
        let other = if tilt_col == "a_deg" {
            "b_deg"
        } else {
            "a_deg"
        };
        if !ds.has(&tilt_col) {
            let why = if ds.has(other) {
                format!(
                    "but the file has `{other}`: a {} machine? (--machine {})",
                    if other == "a_deg" { "AC" } else { "BC" },
                    if other == "a_deg" {
                        "ac-trunnion"
                    } else {
                        "bc-trunnion or bc-head"
                    }
                )
            } else {
                "(the tilt axis's commanded angle)".to_string()
            };
            return Err(RtestError::MachineColumns {
                file,
                machine: machine.kind.name(),
                need: tilt_col,
                why,
            });
        }
        if ds.has(other) {
            return Err(RtestError::MachineColumns {
                file,
                machine: machine.kind.name(),
                need: tilt_col.clone(),
                why: format!("only, but the file has both `{tilt_col}` and `{other}`"),
            });
        }
        if machine.kind == MachineKind::BcHead
            && (!machine.pivot_mm.is_finite() || machine.pivot_mm <= 0.0)
        {
            return Err(RtestError::BadValue {
                at: "--pivot-mm".into(),
                what: format!(
                    "bc-head needs the pivot length > 0 mm, got {}",
                    machine.pivot_mm
                ),
            });
        }
        let n = ds.n_rows();
        if n == 0 {
            return Err(RtestError::BadValue {
                at: file,
                what: "no data rows".into(),
            });
        }
        let x = finite_column(ds, "x_mm")?;
        let y = finite_column(ds, "y_mm")?;
        let z = finite_column(ds, "z_mm")?;
        let t = finite_column(ds, &tilt_col)?;
        let c = finite_column(ds, "c_deg")?;
        for (col, v, lim) in [
            (&tilt_col, &t, TILT_LIMIT_DEG),
            (&"c_deg".to_string(), &c, C_LIMIT_DEG),
        ] {
            if let Some(r) = v.iter().position(|a| a.abs() > lim) {
                return Err(RtestError::BadValue {
                    at: ds.locate(col, r),
                    what: format!("`{col}` = {} is out of range (|angle| ≤ {lim}°)", v[r]),
                });
            }
        }
        let d_um = if need_readings {
            let dx = finite_column(ds, "dx_um")?;
            let dy = finite_column(ds, "dy_um")?;
            let dz = finite_column(ds, "dz_um")?;
            (0..n).map(|i| [dx[i], dy[i], dz[i]]).collect()
        } else {
            Vec::new()
        };
        let path: Vec<String> = if ds.has("path") {
            ds.text("path")?
                .iter()
                .map(|s| s.trim().to_string())
                .collect()
        } else {
            vec![String::new(); n]
        };
        let run: Vec<String> = match ds.run() {
            Some(r) => r,
            None => vec![String::new(); n],
        };
        let (setup, setup_names) = if ds.has("setup") {
            let (ids, names) = axcomp_data::groups(ds, "setup")?;
            (ids, names)
        } else {
            (vec![0; n], vec!["1".to_string()])
        };
        let lines: Vec<usize> = (0..n).map(|r| ds.line_of_row(r)).collect();
        let poses: Vec<Pose> = (0..n)
            .map(|i| Pose {
                p_mm: [x[i], y[i], z[i]],
                tilt_deg: t[i],
                c_deg: c[i],
            })
            .collect();
        let data = RtestData {
            machine,
            source: file,
            poses,
            d_um,
            path,
            setup,
            setup_names,
            lines,
            free_head_zero: false,
        };
        if need_readings {
            revisit::check_repeats(&data, &run)?;
        }
        Ok(data)
    }

    /// Number of parameters: 11 location errors + 6 per set-up.
    pub fn n_params(&self) -> usize {
        N_LOCATION + N_SETUP * self.setup_names.len()
    }

    /// Parameter names: the 11 ISO names, then `sphere_dx_um`… (suffixed `@setup` with several set-ups).
    pub fn param_names(&self) -> Vec<String> {
        param_names(self.machine.kind, &self.setup_names)
    }
}

/// Parameter names for `kind` and set-ups.
pub fn param_names(kind: MachineKind, setups: &[String]) -> Vec<String> {
    let mut v: Vec<String> = kind
        .location_names()
        .iter()
        .map(|s| s.to_string())
        .collect();
    for s in setups {
        for c in [
            "sphere_dx",
            "sphere_dy",
            "sphere_dz",
            "head_dx",
            "head_dy",
            "head_dz",
        ] {
            if setups.len() == 1 {
                v.push(format!("{c}_um"));
            } else {
                v.push(format!("{c}_um@{s}"));
            }
        }
    }
    v
}

/// Split a full parameter vector into location errors and the set-up offsets of set-up `s`.
pub fn split_params(theta: &[f64], s: usize) -> (LocationErrors, SetupOffsets) {
    let mut le = [0.0; N_LOCATION];
    le.copy_from_slice(&theta[..N_LOCATION]);
    let b = N_LOCATION + N_SETUP * s;
    let mut so = [0.0; N_SETUP];
    so.copy_from_slice(&theta[b..b + N_SETUP]);
    (le, so)
}

/// Exact model displacement (µm) of row `pose` in set-up `s` with parameters `theta`.
pub fn model_displacement(machine: &FiveAxis, pose: &Pose, s: usize, theta: &[f64]) -> [f64; 3] {
    let (le, setup) = split_params(theta, s);
    machine.displacement(pose, &le, setup)
}

/// Which parameters are held at zero by assumption: the head offsets unless `free_head_zero`.
pub fn head_fixed(p: usize, free_head_zero: bool) -> Vec<Option<String>> {
    (0..p)
        .map(|k| {
            (!free_head_zero && k >= N_LOCATION && (k - N_LOCATION) % N_SETUP >= 3).then(|| {
                "taken as known (0): the R-test head's zero / tool length is calibrated; --free-head-zero estimates it".to_string()
            })
        })
        .collect()
}

/// Linearised sensitivity matrix (3 rows per pose) over all parameters.
pub fn sensitivity_matrix(
    machine: &FiveAxis,
    poses: &[Pose],
    setup: &[usize],
    n_setups: usize,
) -> DMatrix<f64> {
    let p = N_LOCATION + N_SETUP * n_setups;
    let mut j = DMatrix::zeros(3 * poses.len(), p);
    for (r, pose) in poses.iter().enumerate() {
        let cols = machine.sensitivity(pose);
        for (k, col) in cols.iter().enumerate() {
            let kk = if k < N_LOCATION {
                k
            } else {
                N_LOCATION + N_SETUP * setup[r] + (k - N_LOCATION)
            };
            for i in 0..3 {
                j[(3 * r + i, kk)] = col[i];
            }
        }
    }
    j
}

/// The result of one fit.
#[derive(Debug, Clone)]
pub struct Fit {
    /// Effect terms of the model (none for the location-error model alone); their parameters are
    /// `theta[data.n_params()..]`.
    pub effects: effects::EffectSet,
    /// All parameters (unidentified ones 0): 11 location errors then set-up offsets.
    pub theta: Vec<f64>,
    /// Standard uncertainty of estimated parameters (`None` for those fixed to 0).
    pub std: Vec<Option<f64>>,
    pub ident: Identifiability,
    /// Correlations of estimated parameters with |r| > 0.9: (i, j, r).
    pub correlations: Vec<(usize, usize, f64)>,
    /// RMS over the three components on the fitted rows, µm.
    pub fit_rms_um: f64,
    /// Residual standard deviation σ̂, µm.
    pub sigma_um: f64,
    /// Residual standard deviation per component (X, Y, Z), µm: the standard uncertainties use these.
    pub sigma_xyz_um: [f64; 3],
    pub iterations: usize,
    /// The head zero's standard uncertainty (µm, X, Y, Z) included in `std` (see the glossary), if given.
    pub head_zero_std_um: Option<[f64; 3]>,
    /// Which zero uncertainty `std` includes.
    pub zero_uncertainty: ZeroUncertainty,
}

/// Options of [`fit_with`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FitOptions {
    /// Standard uncertainty (µm, along the head's X, Y, Z) of the R-test head's / touch probe's zero when
    /// it is taken as known (not `free_head_zero`): one offset common to every row (one calibration), added
    /// to the parameters' covariance by propagation (see the glossary). `None`: the zero is exact.
    pub head_zero_std_um: Option<[f64; 3]>,
}

/// The error every row shares through one calibration of the touch probe's (or R-test head's) zero, as the
/// probe route's centres file carries it: columns `zero1_dx_um, zero1_dy_um, zero1_dz_um`, `zero2_…`, …
/// (optional, whole triplets). Row `i`'s reading carries `Σ_k u_k·b_ik` with `u_k` independent, mean 0,
/// variance 1, and `b_ik` the row's triplet `k` (µm): each triplet is one standard-uncertainty component of
/// the shared (fully correlated between rows) error, e.g. the probe calibration's coefficient uncertainty
/// propagated into each pose's fitted centre (`axcomp fit probe --centres-out`).
#[derive(Debug, Clone, PartialEq)]
pub struct SharedError {
    /// Column stems (`zero1`, `zero2`, …).
    pub components: Vec<String>,
    /// Per dataset row, per component: the loading (µm along machine X, Y, Z).
    pub loadings_um: Vec<Vec<[f64; 3]>>,
}

/// Reads [`SharedError`] columns from `ds`, if any: `None` without a `zero1_dx_um` column. A triplet with a
/// missing component, a gap in the numbering (`zero3_…` without `zero2_…`) or a non-finite value is an error
/// naming the column (and line).
pub fn read_shared_error(ds: &Dataset) -> Result<Option<SharedError>, RtestError> {
    let names = ds.column_names();
    let stems: Vec<String> = {
        let mut v: Vec<(usize, String)> = names
            .iter()
            .filter_map(|c| {
                let rest = c.strip_prefix("zero")?;
                let (num, tail) = rest.split_once('_')?;
                let k: usize = num.parse().ok()?;
                ["dx_um", "dy_um", "dz_um"]
                    .contains(&tail)
                    .then(|| (k, format!("zero{k}")))
            })
            .collect();
        v.sort();
        v.dedup();
        v.into_iter().map(|(_, s)| s).collect()
    };
    if stems.is_empty() {
        return Ok(None);
    }
    for (i, stem) in stems.iter().enumerate() {
        if *stem != format!("zero{}", i + 1) {
            return Err(RtestError::BadValue {
                at: ds.source().to_string(),
                what: format!(
                    "shared-zero columns numbered {} without `zero{}_dx_um`: number them zero1, zero2, … without gaps",
                    stem,
                    i + 1
                ),
            });
        }
        for c in ["dx_um", "dy_um", "dz_um"] {
            if !ds.has(&format!("{stem}_{c}")) {
                return Err(RtestError::BadValue {
                    at: ds.source().to_string(),
                    what: format!(
                        "column `{stem}_{c}` is missing: a shared-zero component needs all of {stem}_dx_um, {stem}_dy_um, {stem}_dz_um"
                    ),
                });
            }
        }
    }
    let cols: Vec<[Vec<f64>; 3]> = stems
        .iter()
        .map(|stem| {
            Ok([
                finite_column(ds, &format!("{stem}_dx_um"))?,
                finite_column(ds, &format!("{stem}_dy_um"))?,
                finite_column(ds, &format!("{stem}_dz_um"))?,
            ])
        })
        .collect::<Result<_, RtestError>>()?;
    let loadings_um = (0..ds.n_rows())
        .map(|r| cols.iter().map(|c| [c[0][r], c[1][r], c[2][r]]).collect())
        .collect();
    Ok(Some(SharedError {
        components: stems,
        loadings_um,
    }))
}

/// Which uncertainty of the head's / probe's zero the standard uncertainties include (the JSON's
/// `zero_uncertainty`).
#[derive(Debug, Clone, PartialEq)]
pub enum ZeroUncertainty {
    /// Taken as exact (none given).
    Exact,
    /// The R-test head's zero is estimated (`--free-head-zero`).
    Estimated,
    /// `--head-zero-std-um` (one offset common to every row).
    Given([f64; 3]),
    /// The data's shared-zero columns ([`SharedError`]).
    Columns(Vec<String>),
}

impl ZeroUncertainty {
    /// JSON form: `source` and what was used.
    pub fn to_json(&self) -> serde_json::Value {
        use serde_json::json;
        match self {
            ZeroUncertainty::Exact => {
                json!({ "source": "none: the zero is taken as exact (no zero*_d*_um columns, no --head-zero-std-um)" })
            }
            ZeroUncertainty::Estimated => {
                json!({ "source": "--free-head-zero: the head zero is estimated per set-up" })
            }
            ZeroUncertainty::Given(s) => json!({ "source": "--head-zero-std-um", "std_um": s }),
            ZeroUncertainty::Columns(c) => {
                json!({ "source": "data columns (the probe calibration's shared error)", "components": c })
            }
        }
    }
}

/// RMS of all components.
pub fn rms3(v: &[[f64; 3]]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    (v.iter().flat_map(|d| d.iter().map(|x| x * x)).sum::<f64>() / (3 * v.len()) as f64).sqrt()
}

/// Fits the model on `rows` of `data` by Levenberg–Marquardt (Jacobian: central differences of the exact
/// model at the current estimate).
pub fn fit(data: &RtestData, rows: &[usize]) -> Result<Fit, RtestError> {
    fit_with(data, rows, &FitOptions::default())
}

/// [`fit`] with options (the head zero's uncertainty).
pub fn fit_with(data: &RtestData, rows: &[usize], opts: &FitOptions) -> Result<Fit, RtestError> {
    fit_shared(data, rows, opts, None)
}

/// [`fit_with`] with the zero's shared error of the rows (indexed like `data`'s rows), propagated into the
/// standard uncertainties: `Cov += G·Gᵀ`, `G = (JᵀJ)⁻¹·Jᵀ·B` (`B`: the fitted rows' loadings, one column per
/// component). `opts.head_zero_std_um`, when given, overrides it.
pub fn fit_shared(
    data: &RtestData,
    rows: &[usize],
    opts: &FitOptions,
    shared: Option<&SharedError>,
) -> Result<Fit, RtestError> {
    fit_fixed(data, rows, opts, shared, &[])
}

/// [`fit_shared`] with location errors held at zero by choice: `fix[k] = Some(reason)` for location error
/// `k` (`fix` shorter than 11 leaves the rest free). They are reported not identified with the reason.
pub fn fit_fixed(
    data: &RtestData,
    rows: &[usize],
    opts: &FitOptions,
    shared: Option<&SharedError>,
    fix: &[Option<String>],
) -> Result<Fit, RtestError> {
    fit::fit_effects(
        data,
        rows,
        opts,
        shared,
        fix,
        &effects::EffectSet::default(),
    )
}

/// One location error in the JSON / model file.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct ParamValue {
    pub value: f64,
    pub unit: String,
    pub std: Option<f64>,
    pub identified: bool,
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub reason: Option<String>,
}

/// The model file written by `axcomp fit rtest --out` (read by `axcomp predict` through [`predict_rows`]).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct RtestModel {
    /// Always `"rtest"`.
    pub kind: String,
    pub machine: MachineKind,
    pub pivot_mm: f64,
    /// Keyed by ISO 230-7 name, in parameter order.
    pub location_errors: Vec<(String, ParamValue)>,
    /// Set-up offsets (µm) by set-up name: sphere dx, dy, dz, then R-test head dx, dy, dz.
    pub setup_offsets_um: Vec<(String, SetupOffsets)>,
    pub sign_convention: String,
    /// Effect terms added by `fit rtest --effects` (absent without), read by name.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub effects: Vec<effect_model::EffectModel>,
}

/// The sign convention, stated in the JSON, the model file and the report.
pub const SIGN_CONVENTION: &str = "d = sphere centre − R-test head (tool point), µm along machine X, Y, Z (probe route: fitted centre − commanded tool point). Location errors give the actual average line of each rotary axis: C through (EX0C, EY0C, 0) with direction ≈ (EB0C, −EA0C, 1) in the frame the tilt axis carries; A through (0, EY0A, EZ0A) with direction ≈ (1, EC0A, −EB0A); B through (EX0B, 0, EZ0B) with direction ≈ (−EC0B, 1, EA0B); origin at the nominal intersection of the rotary axes. Squareness: Y along ≈ (−EC0Y, 1, 0), Z along ≈ (EB0Z, −EA0Z, 1). Angles positive right-handed, µrad; offsets µm.";

impl RtestModel {
    /// Reads a model file of `fit rtest --out` (JSON): `kind` must be `rtest`, the location errors are
    /// read by name (each of the machine kind's 11 exactly once, in any order; stored in parameter order)
    /// with their units, set-up names unique, every value finite and of plausible size. The error names
    /// the file and the entry.
    pub fn from_json(text: &str, source: &str) -> Result<RtestModel, RtestError> {
        let bad = |what: String| RtestError::BadModel {
            file: source.to_string(),
            what,
        };
        let mut m: RtestModel = serde_json::from_str(text)
            .map_err(|e| bad(format!("not an R-test model file: {e}")))?;
        if m.kind != "rtest" {
            return Err(bad(format!("kind `{}`, expected `rtest`", m.kind)));
        }
        if !(m.pivot_mm.is_finite() && m.pivot_mm.abs() < MODEL_ABSURD) {
            return Err(bad(format!(
                "pivot_mm {} is not a finite length",
                m.pivot_mm
            )));
        }
        m.location_errors =
            location_by_name(m.machine, std::mem::take(&mut m.location_errors)).map_err(&bad)?;
        if m.setup_offsets_um.is_empty() {
            return Err(bad("setup_offsets_um: no set-up".into()));
        }
        effect_model::read(m.machine, &m.effects).map_err(&bad)?;
        for (i, (name, v)) in m.setup_offsets_um.iter().enumerate() {
            if m.setup_offsets_um[..i].iter().any(|(n, _)| n == name) {
                return Err(bad(format!(
                    "setup_offsets_um[{i}] ({name}): set-up named twice"
                )));
            }
            if let Some(x) = v
                .iter()
                .find(|x| !(x.is_finite() && x.abs() < MODEL_ABSURD))
            {
                return Err(bad(format!(
                    "setup_offsets_um[{i}] ({name}): {x:e} is not a finite number of plausible size"
                )));
            }
        }
        Ok(m)
    }
}

/// Largest magnitude a value of a model file may have (µm, µrad, mm): beyond it the file is corrupt.
pub const MODEL_ABSURD: f64 = 1e12;

/// The location errors of a model file in `kind`'s parameter order, each found by its name; the error
/// names the entry (`location_errors[2] (EA0C)`) and why.
fn location_by_name(
    kind: MachineKind,
    entries: Vec<(String, ParamValue)>,
) -> Result<Vec<(String, ParamValue)>, String> {
    let names = kind.location_names();
    let mut slots: Vec<Option<(String, ParamValue)>> = vec![None; N_LOCATION];
    for (i, (name, p)) in entries.into_iter().enumerate() {
        let entry = format!("location_errors[{i}] ({name})");
        let Some(k) = names.iter().position(|n| *n == name) else {
            return Err(format!(
                "{entry}: not a location error of the {} machine ({})",
                kind.name(),
                names.join(", ")
            ));
        };
        if p.unit != location_unit(k) {
            return Err(format!(
                "{entry}: unit `{}`, expected `{}`",
                p.unit,
                location_unit(k)
            ));
        }
        let values = [Some(p.value), p.std];
        if let Some(v) = values
            .into_iter()
            .flatten()
            .find(|v| !(v.is_finite() && v.abs() < MODEL_ABSURD))
        {
            return Err(format!(
                "{entry}: {v:e} is not a finite number of plausible size"
            ));
        }
        if slots[k].is_some() {
            return Err(format!("{entry}: {name} appears twice"));
        }
        slots[k] = Some((name, p));
    }
    let missing: Vec<&str> = (0..N_LOCATION)
        .filter(|&k| slots[k].is_none())
        .map(|k| names[k])
        .collect();
    if !missing.is_empty() {
        return Err(format!("location_errors: missing {}", missing.join(", ")));
    }
    Ok(slots.into_iter().flatten().collect())
}

impl RtestModel {
    /// From a fit on every row of `data`.
    pub fn from_fit(data: &RtestData, f: &Fit) -> RtestModel {
        let all: Vec<usize> = (0..data.poses.len()).collect();
        Self::from_fit_rows(data, f, &all)
    }

    /// From a fit on `fit_rows` (over which each effect's correction RMS is taken).
    pub fn from_fit_rows(data: &RtestData, f: &Fit, fit_rows: &[usize]) -> RtestModel {
        let names = data.param_names();
        let location_errors = (0..N_LOCATION)
            .map(|k| {
                (
                    names[k].clone(),
                    ParamValue {
                        value: f.theta[k],
                        unit: location_unit(k).into(),
                        std: f.std[k],
                        identified: f.ident.identified[k],
                        reason: f.ident.reasons[k].clone(),
                    },
                )
            })
            .collect();
        let setup_offsets_um = data
            .setup_names
            .iter()
            .enumerate()
            .map(|(s, n)| (n.clone(), split_params(&f.theta, s).1))
            .collect();
        RtestModel {
            kind: "rtest".into(),
            machine: data.machine.kind,
            pivot_mm: data.machine.pivot_mm,
            location_errors,
            setup_offsets_um,
            sign_convention: SIGN_CONVENTION.into(),
            effects: effect_model::from_fit(data, f, fit_rows),
        }
    }

    /// The machine.
    pub fn five_axis(&self) -> FiveAxis {
        FiveAxis::new(self.machine, self.pivot_mm)
    }

    /// The 11 location errors.
    pub fn location(&self) -> LocationErrors {
        let mut le = [0.0; N_LOCATION];
        for (k, (_, v)) in self.location_errors.iter().enumerate().take(N_LOCATION) {
            le[k] = v.value;
        }
        le
    }

    /// The effect terms and their values (signature order); the file was checked by [`Self::from_json`].
    pub fn effect_set(&self) -> (effects::EffectSet, Vec<f64>) {
        effect_model::read(self.machine, &self.effects).unwrap_or_default()
    }

    /// Predicted displacement (µm) at `pose` with the set-up offsets `setup_um` (location errors and the
    /// effects).
    pub fn predict(&self, pose: &Pose, setup_um: SetupOffsets) -> [f64; 3] {
        let (set, values) = self.effect_set();
        self.predict_with(pose, setup_um, &set, &values)
    }

    fn predict_with(
        &self,
        pose: &Pose,
        setup_um: SetupOffsets,
        set: &effects::EffectSet,
        values: &[f64],
    ) -> [f64; 3] {
        let m = self.five_axis();
        let le = self.location();
        let mut d = m.displacement(pose, &le, setup_um);
        let e = set.displacement(&m, pose, &le, setup_um, values);
        for c in 0..3 {
            d[c] += e[c];
        }
        d
    }
}

/// Predictions `pred_dx_um`, `pred_dy_um`, `pred_dz_um` for every row of `ds` (the columns `x_mm`, `y_mm`,
/// `z_mm`, `a_deg`|`b_deg`, `c_deg`; a `setup` column when the model has several set-ups, each value one
/// the model knows). Readings are not needed. For `axcomp predict`.
pub fn predict_rows(model: &RtestModel, ds: &Dataset) -> Result<Vec<[f64; 3]>, RtestError> {
    let data = RtestData::from_dataset(ds, model.five_axis(), false)?;
    if model.setup_offsets_um.len() > 1 && !ds.has("setup") {
        // Each set-up has its own sphere and head offsets (tens of µm apart): taking the first one for
        // rows that do not say theirs would be a silent guess.
        let names: Vec<&str> = model
            .setup_offsets_um
            .iter()
            .map(|(n, _)| n.as_str())
            .collect();
        return Err(RtestError::BadValue {
            at: ds.source().to_string(),
            what: format!(
                "missing column `setup`: the model was fitted on several set-ups ({}), each with its own \
                 sphere offsets, so every row must say which one it was measured in",
                names.join(", ")
            ),
        });
    }
    let (set, values) = model.effect_set();
    effects_cover(model, &set, &data, ds)?;
    let mut out = Vec::with_capacity(data.poses.len());
    for (i, pose) in data.poses.iter().enumerate() {
        let setup = if model.setup_offsets_um.len() == 1 && !ds.has("setup") {
            model.setup_offsets_um[0].1
        } else {
            let name = &data.setup_names[data.setup[i]];
            model
                .setup_offsets_um
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, v)| *v)
                .ok_or_else(|| RtestError::BadValue {
                    at: ds.locate("setup", i),
                    what: format!("set-up `{name}` is not one the model was fitted on"),
                })?
        };
        out.push(model.predict_with(pose, setup, &set, &values));
    }
    Ok(out)
}

/// A row whose linear axes lie outside the range a `linear_geometry` term was fitted over is an error
/// naming the row: the polynomial would extrapolate (contract: a row outside the model's stroke).
fn effects_cover(
    model: &RtestModel,
    set: &effects::EffectSet,
    data: &RtestData,
    ds: &Dataset,
) -> Result<(), RtestError> {
    for t in &set.terms {
        let effects::EffectBasis::Linear { axes, range_mm, .. } = &t.basis else {
            continue;
        };
        for (i, pose) in data.poses.iter().enumerate() {
            let q = model.five_axis().linear_positions(pose);
            for (&a, r) in axes.iter().zip(range_mm) {
                let slack = 1e-6 * (r[1] - r[0]);
                if q[a] < r[0] - slack || q[a] > r[1] + slack {
                    return Err(RtestError::BadValue {
                        at: format!("{} line {}", ds.source(), ds.line_of_row(i)),
                        what: format!(
                            "the {} axis sits at {:.3} mm, outside the range {:.3}…{:.3} mm the model's linear_geometry was fitted over (it would extrapolate)",
                            ["X", "Y", "Z"][a],
                            q[a],
                            r[0],
                            r[1]
                        ),
                    });
                }
            }
        }
    }
    Ok(())
}

/// ISO 10791-6 figures: range (max − min) of each displacement component, µm.
pub fn ranges(v: &[[f64; 3]]) -> [f64; 3] {
    let mut r = [0.0; 3];
    for (c, rc) in r.iter_mut().enumerate() {
        let lo = v.iter().map(|d| d[c]).fold(f64::INFINITY, f64::min);
        let hi = v.iter().map(|d| d[c]).fold(f64::NEG_INFINITY, f64::max);
        *rc = if v.is_empty() { f64::NAN } else { hi - lo };
    }
    r
}
