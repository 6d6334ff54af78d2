//! Sphere centres per pose of a five-axis probing campaign (`axcomp fit probe --group COL,..`) and the R-test
//! rows they give (`--centres-out`, what `axcomp fit rtest` reads).
//!
//! Glossary:
//! - **group** / **pose**: the touches sharing the values of the `--group` columns (e.g. `b_deg,c_deg,run`:
//!   a revisited pose is a further run, its own group). The probe is calibrated on the first group's touches
//!   (file order: the reference pose); every group's sphere centre is then fitted with that calibration
//!   (the sphere's radius fixed), its gross outliers screened by [`crate::iterated_sphere_outliers`].
//! - **probe frame**: on a machine whose probe tilts (`bc-head`), each touch is taken into the probe's frame
//!   by the nominal kinematics before the calibration corrects it ([`crate::touches`]); the fitted centre is
//!   turned back into the machine frame.
//! - **commanded tool point** of a group: the columns `cmd_x_mm, cmd_y_mm, cmd_z_mm` (constant within the
//!   group): the position the linear axes were commanded to so that, by the nominal kinematics, the tool
//!   point (stylus-tip centre) sits at the sphere's nominal centre. Without them on a head machine (a TCPC
//!   campaign: `x_mm, y_mm, z_mm` are tool-point coordinates and the controller aims the tool point at the
//!   same sphere centre at every pose) it is the reference pose's fitted centre, for every group: the
//!   sphere's nominal position in `fit rtest --machine bc-head`, whose set-up offsets take up where that
//!   is. The R-test row's `dx_um, dy_um, dz_um` = fitted centre − commanded tool point.

use std::fmt::Write as _;

use axcomp_data::Dataset;
use nalgebra::Matrix3;

use crate::touches::out_of_frame;
use crate::{
    Calibration, CalibrationResult, ProbeError, SharedCentreError, Sphere, Touch, fit_center,
    iterated_sphere_outliers, shared_centre_error,
};

/// The commanded tool point's columns.
pub const COMMANDED_COLUMNS: [&str; 3] = ["cmd_x_mm", "cmd_y_mm", "cmd_z_mm"];

/// One pose's fitted sphere.
#[derive(Debug, Clone)]
pub struct PoseCentre {
    /// The group columns' values, then the carried columns' (`path`, `setup`).
    pub values: Vec<String>,
    /// Commanded tool point, mm (machine frame); `None` when not known.
    pub commanded_mm: Option<[f64; 3]>,
    /// The fitted sphere, centre in the machine frame.
    pub sphere: Sphere,
    /// The touches used (outliers left out), in the probe frame.
    pub kept: Vec<Touch>,
    /// Rows of the flagged touches.
    pub outliers: Vec<String>,
    /// The probe frame's rotation to the machine frame at this pose.
    pub to_machine: Matrix3<f64>,
}

impl PoseCentre {
    /// Fitted centre − commanded tool point, µm (when the commanded point is known).
    pub fn displacement_um(&self) -> Option<[f64; 3]> {
        self.commanded_mm
            .map(|p| [0, 1, 2].map(|k| (self.sphere.center_mm[k] - p[k]) * 1000.0))
    }
}

/// What [`fit_pose_centres`] needs besides the data.
pub struct PoseOptions<'a> {
    /// The `--group` columns.
    pub group: &'a [String],
    /// The reference sphere's radius, mm.
    pub radius_mm: f64,
    pub outlier_mad: f64,
    /// Each row's probe-frame rotation (the identity where the probe does not tilt).
    pub to_machine: &'a [Matrix3<f64>],
    /// The commanded tool point is needed (`--centres-out`).
    pub need_commanded: bool,
    /// Without the commanded columns, the reference pose's fitted centre is every group's commanded tool
    /// point (a head machine's TCPC campaign).
    pub tcpc_reference: bool,
}

/// Each row's group key (the group columns' trimmed values joined by U+001F).
pub fn group_keys(ds: &Dataset, cols: &[String]) -> Result<Vec<String>, ProbeError> {
    let texts: Vec<Vec<&str>> = cols.iter().map(|c| ds.text(c)).collect::<Result<_, _>>()?;
    Ok((0..ds.n_rows())
        .map(|i| {
            texts
                .iter()
                .map(|t| t[i].trim())
                .collect::<Vec<_>>()
                .join("\u{1f}")
        })
        .collect())
}

/// Columns an R-test row carries (`path`, `setup`) when the touches have them and they are not grouped on
/// (the touch CSV's `run` is a repeat id of touches; an R-test run goes into `--group`).
pub fn carried_columns(ds: &Dataset, group: &[String]) -> Vec<&'static str> {
    ["path", "setup"]
        .into_iter()
        .filter(|c| ds.has(c) && !group.iter().any(|g| g == c))
        .collect()
}

/// The commanded tool point's columns, when they are there or needed.
fn commanded_columns(ds: &Dataset, need: bool) -> Result<Option<Vec<Vec<f64>>>, ProbeError> {
    if !(need || ds.has(COMMANDED_COLUMNS[0])) {
        return Ok(None);
    }
    COMMANDED_COLUMNS
        .iter()
        .map(|c| {
            ds.numeric(c).map(<[f64]>::to_vec).map_err(|e| {
                ProbeError::Input(format!(
                    "--group: each group's commanded tool point comes from `{c}` (see `axcomp fit probe \
                     --help`): {e}"
                ))
            })
        })
        .collect::<Result<Vec<_>, _>>()
        .map(Some)
}

/// `column`'s value in `rows`, refused when it differs within the group.
fn constant_in_group(
    ds: &Dataset,
    column: &str,
    rows: &[usize],
    key: &str,
    labels: &[String],
) -> Result<String, ProbeError> {
    let t = ds.text(column)?;
    let v = t[rows[0]].trim();
    if let Some(&bad) = rows.iter().find(|&&i| t[i].trim() != v) {
        return Err(ProbeError::Input(format!(
            "{}: `{column}` differs within group `{}` (`{v}` at {}): each pose's touches carry one {column} \
             into its R-test row",
            ds.locate(column, bad),
            key.replace('\u{1f}', ","),
            labels[rows[0]]
        )));
    }
    Ok(v.to_string())
}

/// Fits one sphere centre per group (file order of first appearance) over the rows not `held`, with the
/// calibration `cal` (made in the probe frame): `touches` are in the probe frame (each row by its own
/// rotation `opts.to_machine`), `labels` name the rows.
pub fn fit_pose_centres(
    ds: &Dataset,
    touches: &[Touch],
    labels: &[String],
    held: &[bool],
    cal: &Calibration,
    opts: &PoseOptions,
) -> Result<Vec<PoseCentre>, ProbeError> {
    let g = group_keys(ds, opts.group)?;
    let mut order: Vec<&String> = Vec::new();
    for k in &g {
        if !order.contains(&k) {
            order.push(k);
        }
    }
    let tcpc = opts.tcpc_reference && !ds.has(COMMANDED_COLUMNS[0]);
    let cmd = commanded_columns(ds, opts.need_commanded && !tcpc)?;
    let carried = carried_columns(ds, opts.group);
    let mut poses: Vec<PoseCentre> = Vec::new();
    for key in order {
        let rows: Vec<usize> = (0..ds.n_rows())
            .filter(|&i| &g[i] == key && !held[i])
            .collect();
        if rows.is_empty() {
            continue;
        }
        let commanded = match &cmd {
            Some(cmd) => Some(commanded_point(ds, cmd, &rows, key, labels)?),
            None => None,
        };
        let mut pose = fit_one_pose(touches, labels, &rows, key, cal, opts)?;
        pose.commanded_mm = commanded;
        for c in &carried {
            pose.values
                .push(constant_in_group(ds, c, &rows, key, labels)?);
        }
        poses.push(pose);
    }
    if tcpc && let Some(first) = poses.first().map(|p| p.sphere.center_mm) {
        for p in &mut poses {
            p.commanded_mm = Some(first);
        }
    }
    Ok(poses)
}

/// The group's commanded tool point, refused when it differs within the group.
fn commanded_point(
    ds: &Dataset,
    cmd: &[Vec<f64>],
    rows: &[usize],
    key: &str,
    labels: &[String],
) -> Result<[f64; 3], ProbeError> {
    let mut point = [0.0; 3];
    for k in 0..3 {
        point[k] = cmd[k][rows[0]];
        if let Some(&bad) = rows.iter().find(|&&i| cmd[k][i] != point[k]) {
            return Err(ProbeError::Input(format!(
                "{}: the commanded tool point differs within group `{}` (first row {})",
                ds.locate(COMMANDED_COLUMNS[k], bad),
                key.replace('\u{1f}', ","),
                labels[rows[0]]
            )));
        }
    }
    Ok(point)
}

/// One group's sphere: its touches checked against the calibration, gross outliers flagged (listed, not
/// used), the centre fitted in the probe frame and turned into the machine frame.
fn fit_one_pose(
    touches: &[Touch],
    labels: &[String],
    rows: &[usize],
    key: &str,
    cal: &Calibration,
    opts: &PoseOptions,
) -> Result<PoseCentre, ProbeError> {
    let gname = key.replace('\u{1f}', ",");
    let in_group = |e: ProbeError| ProbeError::Input(format!("group `{gname}`: {e}"));
    let to_machine = opts.to_machine[rows[0]];
    if let Some(&bad) = rows.iter().find(|&&i| opts.to_machine[i] != to_machine) {
        return Err(ProbeError::Input(format!(
            "{}: the pose (rotary-axis angles) differs within group `{gname}`: group on the pose columns",
            labels[bad]
        )));
    }
    let gt: Vec<Touch> = rows.iter().map(|&i| touches[i]).collect();
    for (k, t) in gt.iter().enumerate() {
        cal.check_touch(t).map_err(|why| ProbeError::BadTouch {
            row: labels[rows[k]].clone(),
            what: why,
        })?;
    }
    let radius = opts.radius_mm;
    let flags = iterated_sphere_outliers(gt.len(), opts.outlier_mad, |kept| {
        let kt: Vec<Touch> = kept.iter().map(|&i| gt[i]).collect();
        let s = fit_center(cal, &kt, radius)?;
        Ok::<_, ProbeError>(crate::radial_residuals_um(cal, &gt, &s, radius))
    })
    .map_err(in_group)?;
    let kept: Vec<Touch> = (0..gt.len())
        .filter(|&k| !flags[k])
        .map(|k| gt[k])
        .collect();
    let outliers = (0..gt.len())
        .filter(|&k| flags[k])
        .map(|k| labels[rows[k]].clone())
        .collect();
    let mut sphere = fit_center(cal, &kept, radius).map_err(in_group)?;
    sphere.center_mm = out_of_frame(&to_machine, sphere.center_mm);
    Ok(PoseCentre {
        values: key.split('\u{1f}').map(str::to_string).collect(),
        commanded_mm: None,
        sphere,
        kept,
        outliers,
        to_machine,
    })
}

/// The error every pose's centre shares through the one calibration `result` (fitted on
/// `calibration_touches`, its outliers left out) ([`shared_centre_error`], computed in the probe frame), each pose's loadings turned into the machine frame. A rotation per pose keeps the
/// stacked loadings' singular values, so the components stay independent; the per-axis std is recomputed
/// in the machine frame.
pub fn shared_error(
    result: &CalibrationResult,
    calibration_touches: &[Touch],
    poses: &[PoseCentre],
) -> Result<SharedCentreError, ProbeError> {
    let cal = &result.calibration;
    let out: Vec<usize> = result.outliers.iter().map(|o| o.index).collect();
    let calibration_inliers: Vec<Touch> = (0..calibration_touches.len())
        .filter(|i| !out.contains(i))
        .map(|i| calibration_touches[i])
        .collect();
    let groups: Vec<(&[Touch], [f64; 3])> = poses
        .iter()
        .map(|p| {
            let centre = crate::touches::into_frame(&p.to_machine, p.sphere.center_mm);
            (p.kept.as_slice(), centre)
        })
        .collect();
    let mut z = shared_centre_error(cal, &calibration_inliers, &groups)?;
    if poses.iter().all(|p| p.to_machine == Matrix3::identity()) {
        return Ok(z);
    }
    for (l, p) in z.loadings_um.iter_mut().zip(poses) {
        for v in l.iter_mut() {
            *v = out_of_frame(&p.to_machine, *v);
        }
    }
    let n = poses.len().max(1) as f64;
    z.std_um = [0, 1, 2].map(|c| {
        (z.loadings_um
            .iter()
            .map(|l| l.iter().map(|v| v[c] * v[c]).sum::<f64>())
            .sum::<f64>()
            / n)
            .sqrt()
    });
    Ok(z)
}

/// The R-test CSV of `--centres-out`: `x_mm,y_mm,z_mm` (the commanded tool point), the group columns, the
/// carried columns, `dx_um,dy_um,dz_um`, then the shared error's `zero{k}_d{x,y,z}_um`.
pub fn rtest_csv(
    columns: &[&str],
    poses: &[PoseCentre],
    shared: Option<&SharedCentreError>,
) -> Result<String, ProbeError> {
    let mut s = String::from("x_mm,y_mm,z_mm");
    for c in columns {
        s.push(',');
        s.push_str(c);
    }
    s.push_str(",dx_um,dy_um,dz_um");
    let nz = shared.map_or(0, SharedCentreError::components);
    for k in 1..=nz {
        let _ = write!(s, ",zero{k}_dx_um,zero{k}_dy_um,zero{k}_dz_um");
    }
    s.push('\n');
    for (g, pose) in poses.iter().enumerate() {
        let (Some(p), Some(d)) = (pose.commanded_mm, pose.displacement_um()) else {
            return Err(ProbeError::Input(
                "--centres-out: a group without its commanded tool point".into(),
            ));
        };
        let _ = write!(s, "{},{},{}", p[0], p[1], p[2]);
        for x in &pose.values {
            let _ = write!(s, ",{x}");
        }
        let _ = write!(s, ",{},{},{}", d[0], d[1], d[2]);
        if let Some(z) = shared {
            for l in &z.loadings_um[g] {
                let _ = write!(s, ",{},{},{}", l[0], l[1], l[2]);
            }
        }
        s.push('\n');
    }
    Ok(s)
}
