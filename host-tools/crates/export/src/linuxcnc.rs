//! LinuxCNC `xyzac-trt-kins` / `xyzbc-trt-kins`: the rotary-point and offset values a table-rotary-tilting
//! machine's kinematics takes, from a rotary-axis model (`fit rtest`).
//!
//! # Glossary (LinuxCNC 2.9's `src/emc/kinematics/trtfuncs.c`, [`SOURCE`])
//! - **versions**: later LinuxCNC (master, commit 5c41560e, 2026) adds a `conventional-directions` pin
//!   (default off = 2.9's directions); there `xyzbcKinematicsInverse`'s B-offset terms (`dpx`, `dpz`) carry
//!   the other sign of sin(b), matching its main rotation only with the pin on, so the xyzbc `x-offset` /
//!   `z-offset` of this export hold for 2.9 (and xyzac for both).
//! - **HAL pins** (float, in): `x-rot-point`, `y-rot-point`, `z-rot-point` (machine coordinates of the
//!   rotary point: the C axis's line passes through (x, y)); xyzac: `y-offset`, `z-offset` (the A axis's
//!   line runs along X through y-rot-point + y-offset, z-rot-point + z-offset); xyzbc: `x-offset`,
//!   `z-offset` (the B axis's line runs along Y through x-rot-point + x-offset, z-rot-point + z-offset);
//!   `tool-offset` (added to z-offset; LinuxCNC's sample configuration nets `motion.tooloffset.z` to it).
//! - **inverse kinematics** ([`inverse`], transcribed from `xyzacKinematicsInverse` /
//!   `xyzbcKinematicsInverse`): the joints for a workpiece point `s` at angles (t, c):
//!   `J = R_t(t)·(R_z(c)·(s − o_C) + o_C − o_T) + o_T`, right-handed rotations, C turning first; this is the
//!   model's trunnion kinematics (`p = Rt(t)·Rc(c)·s`, `axcomp_kinematics::rotary`).
//! - **values from the model** ([`kins_values`]): the model's frame has its origin at the nominal rotary
//!   point, so x-rot-point = X0 + EX0C, y-rot-point = Y0 + EY0C, z-rot-point = Z0, and (xyzac) y-offset =
//!   EY0A − EY0C, z-offset = EZ0A; (xyzbc) x-offset = EX0B − EX0C, z-offset = EZ0B; mm, `(X0, Y0, Z0)` the
//!   nominal rotary point in the machine's coordinates (0 when not given).
//! - **what it cannot take**: the rotary axes' tilts (`EA0C`, `EB0C`, and `EB0A`, `EC0A` or `EA0B`, `EC0B`)
//!   and the linear axes' squareness (`EA0Z`, `EB0Z`, `EC0Y`): the kinematics has exact axis directions.
//! - **remaining error** ([`Remaining`]): over a set of poses, the sphere-to-tool displacement the model
//!   predicts (`FiveAxis::displacement_at`, the project's exact kinematics) when the controller commands the
//!   joints of [`inverse`] with the exported values, against the displacement with nominal kinematics.

use axcomp_kinematics::rotary::{FiveAxis, MachineKind, N_SETUP, Pose};
use axcomp_rtest::RtestModel;
use axcomp_rtest::plan::PlanGeometry;

use crate::{ExportError, ExportFile, Format};

/// The LinuxCNC source the formulas and pin names were read from: `trtfuncs.c` as LinuxCNC 2.9 has it
/// (last changed in commit 5fadeccc, 2021; Debian 12 ships 2.9.0~pre1 of 2023-02-08).
pub const SOURCE: &str = "https://github.com/LinuxCNC/linuxcnc/blob/5fadecccd75564050ae549a5fb26fc412e0b1836/src/emc/kinematics/trtfuncs.c";

/// The kinematics values (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KinsValues {
    pub x_rot_point: f64,
    pub y_rot_point: f64,
    pub z_rot_point: f64,
    pub x_offset: f64,
    pub y_offset: f64,
    pub z_offset: f64,
}

fn machine_of(format: Format) -> (MachineKind, &'static str) {
    match format {
        Format::LinuxCncXyzacTrt => (MachineKind::AcTrunnion, "xyzac-trt-kins"),
        _ => (MachineKind::BcTrunnion, "xyzbc-trt-kins"),
    }
}

/// The values of `format`'s kinematics for `model`, the nominal rotary point at `rot_point_mm`.
pub fn kins_values(
    model: &RtestModel,
    format: Format,
    rot_point_mm: [f64; 3],
) -> Result<KinsValues, ExportError> {
    let (kind, _) = machine_of(format);
    if format.model_kind() != crate::ModelKind::Rotary {
        return Err(ExportError::WrongModel {
            format: format.name(),
            want: format.model_kind().name(),
            got: crate::ModelKind::Rotary.name(),
        });
    }
    if model.machine != kind {
        return Err(ExportError::WrongMachine {
            format: format.name(),
            want: kind.name(),
            got: model.machine.name(),
        });
    }
    let le = model.location();
    let mm = 1e-3;
    let (x_offset, y_offset) = match kind {
        MachineKind::AcTrunnion => (0.0, (le[4] - le[1]) * mm),
        _ => ((le[4] - le[0]) * mm, 0.0),
    };
    Ok(KinsValues {
        x_rot_point: rot_point_mm[0] + le[0] * mm,
        y_rot_point: rot_point_mm[1] + le[1] * mm,
        z_rot_point: rot_point_mm[2],
        x_offset,
        y_offset,
        z_offset: le[5] * mm,
    })
}

/// LinuxCNC 2.9's inverse kinematics (tool-offset 0): the joints X, Y, Z (mm) for the workpiece point `s`
/// (mm) at tilt `t_deg` (A or B) and `c_deg`. Transcribed term by term from [`SOURCE`].
pub fn inverse(format: Format, k: &KinsValues, s: [f64; 3], t_deg: f64, c_deg: f64) -> [f64; 3] {
    let (t, c) = (t_deg.to_radians(), c_deg.to_radians());
    let (x, y, z) = (
        s[0] - k.x_rot_point,
        s[1] - k.y_rot_point,
        s[2] - k.z_rot_point,
    );
    let (dx, dy, dz) = (k.x_offset, k.y_offset, k.z_offset);
    match format {
        Format::LinuxCncXyzacTrt => [
            c.cos() * x - c.sin() * y + k.x_rot_point,
            c.sin() * t.cos() * x + c.cos() * t.cos() * y - t.sin() * z - t.cos() * dy
                + t.sin() * dz
                + dy
                + k.y_rot_point,
            c.sin() * t.sin() * x + c.cos() * t.sin() * y + t.cos() * z
                - t.sin() * dy
                - t.cos() * dz
                + dz
                + k.z_rot_point,
        ],
        _ => {
            let dpx = -t.cos() * dx - t.sin() * dz + dx;
            let dpz = t.sin() * dx - t.cos() * dz + dz;
            [
                c.cos() * t.cos() * x - c.sin() * t.cos() * y + t.sin() * z + dpx + k.x_rot_point,
                c.sin() * x + c.cos() * y + k.y_rot_point,
                -c.cos() * t.sin() * x + c.sin() * t.sin() * y + t.cos() * z + dpz + k.z_rot_point,
            ]
        }
    }
}

/// The remaining error over a pose set (µm, RMS of |d| over the poses).
#[derive(Debug, Clone, PartialEq)]
pub struct Remaining {
    pub poses: usize,
    /// Where the poses come from (a file, or the default plan).
    pub pose_source: String,
    /// Nominal kinematics (every location error uncompensated).
    pub before_rms_um: f64,
    /// With the exported values (what the kinematics cannot take remains).
    pub after_rms_um: f64,
}

/// The default poses: the K4 path of `plan rtest`'s default geometry at both sphere heights.
pub fn default_poses(machine: FiveAxis) -> Vec<Pose> {
    let g = PlanGeometry::default_for(machine);
    ["K4", "K4-h2"]
        .iter()
        .filter_map(|p| g.path(p))
        .flat_map(|(v, _)| v)
        .collect()
}

/// [`Remaining`] of `values` (computed in the model's frame: nominal rotary point 0).
pub fn remaining(
    model: &RtestModel,
    format: Format,
    poses: &[Pose],
    pose_source: &str,
) -> Result<Remaining, ExportError> {
    if poses.is_empty() {
        return Err(ExportError::NoPoses);
    }
    let k = kins_values(model, format, [0.0; 3])?;
    let machine = model.five_axis();
    let le = model.location();
    let zero = [0.0; N_SETUP];
    let (mut sb, mut sa) = (0.0, 0.0);
    for pose in poses {
        let s = machine.nominal_sphere(pose);
        let before = machine.displacement_at(pose, s, &le, zero);
        let commanded = Pose {
            p_mm: inverse(format, &k, s, pose.tilt_deg, pose.c_deg),
            ..*pose
        };
        let after = machine.displacement_at(&commanded, s, &le, zero);
        sb += before.iter().map(|v| v * v).sum::<f64>();
        sa += after.iter().map(|v| v * v).sum::<f64>();
    }
    let n = poses.len() as f64;
    Ok(Remaining {
        poses: poses.len(),
        pose_source: pose_source.to_string(),
        before_rms_um: (sb / n).sqrt(),
        after_rms_um: (sa / n).sqrt(),
    })
}

fn not_taken(model: &RtestModel) -> Vec<String> {
    let names = model.machine.location_names();
    [2, 3, 6, 7, 8, 9, 10]
        .iter()
        .map(|&k| {
            let (n, p) = &model.location_errors[k];
            debug_assert_eq!(n, names[k]);
            format!(
                "{n} = {:.3} {}{}",
                p.value,
                p.unit,
                if p.identified {
                    ""
                } else {
                    " (not identified)"
                }
            )
        })
        .collect()
}

/// The LinuxCNC export: a HAL file setting the pins and an INI snippet, both stating units, signs, what the
/// kinematics cannot take and the remaining error.
pub fn export(
    model: &RtestModel,
    format: Format,
    rot_point_mm: [f64; 3],
    poses: &[Pose],
    pose_source: &str,
) -> Result<(Vec<ExportFile>, Remaining), ExportError> {
    let k = kins_values(model, format, rot_point_mm)?;
    let r = remaining(model, format, poses, pose_source)?;
    let (_, kins) = machine_of(format);
    let mut head = format!(
        "# axcomp: LinuxCNC {kins} values from a rotary-axis model (fit rtest, {} machine)\n\
         # Pins and formulas: LinuxCNC 2.9, {SOURCE}\n\
         # Units: mm (machine units LINEAR_UNITS = mm), angles in degrees.\n\
         # Sign: rotary point = where the C axis's line crosses the XY plane, in machine coordinates; \
         rotations right-handed as {kins} turns them with conventional-directions off (the model's frame).\n\
         # Nominal rotary point (X0, Y0, Z0) = ({}, {}, {}) mm; the location errors are added to it.\n",
        model.machine.name(),
        rot_point_mm[0],
        rot_point_mm[1],
        rot_point_mm[2]
    );
    head.push_str("# Not taken (the kinematics has exact axis directions): ");
    head.push_str(&not_taken(model).join(", "));
    for e in &model.effects {
        // Effect terms (fit rtest --effects) vary with the angles; no kinematics parameter holds them.
        head.push_str(&format!(
            "\n# Not taken: the effect {} (RMS {:.3} µm over the fitted poses; the remaining error below is \
             of the location errors only)",
            e.kind, e.rms_over_fit_um
        ));
    }
    head.push_str(&format!(
        "\n# Remaining error over {} poses ({}), the project's kinematics (FiveAxis::displacement_at): \
         RMS |d| {:.3} µm with these values, {:.3} µm with nominal kinematics.\n",
        r.poses, r.pose_source, r.after_rms_um, r.before_rms_um
    ));
    let pins = match format {
        Format::LinuxCncXyzacTrt => vec![
            ("x-rot-point", k.x_rot_point),
            ("y-rot-point", k.y_rot_point),
            ("z-rot-point", k.z_rot_point),
            ("y-offset", k.y_offset),
            ("z-offset", k.z_offset),
        ],
        _ => vec![
            ("x-rot-point", k.x_rot_point),
            ("y-rot-point", k.y_rot_point),
            ("z-rot-point", k.z_rot_point),
            ("x-offset", k.x_offset),
            ("z-offset", k.z_offset),
        ],
    };
    let mut hal = head.clone();
    hal.push_str(&format!(
        "# Load with [KINS]KINEMATICS = {kins}; keep tool-offset netted to motion.tooloffset.z.\n"
    ));
    for (pin, v) in &pins {
        hal.push_str(&format!("setp {kins}.{pin} {v:.9}\n"));
    }
    let mut ini = head;
    let coords = if format == Format::LinuxCncXyzacTrt {
        "XYZAC"
    } else {
        "XYZBC"
    };
    ini.push_str(&format!(
        "[KINS]\nKINEMATICS = {kins}\nJOINTS = 5\n\n[TRAJ]\nCOORDINATES = {coords}\nLINEAR_UNITS = mm\n\
         ANGULAR_UNITS = degree\n\n[HAL]\nHALFILE = {kins}.hal\n"
    ));
    Ok((
        vec![
            ExportFile::new(format!("{kins}.hal"), hal),
            ExportFile::new(format!("{kins}.ini"), ini),
        ],
        r,
    ))
}

/// Reads the `setp PIN VALUE` lines of a HAL file (`#` comments). The error names the line.
pub fn parse_setp(text: &str) -> Result<Vec<(String, f64)>, String> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let w: Vec<&str> = t.split_whitespace().collect();
        match w.as_slice() {
            ["setp", pin, v] => out.push((
                pin.to_string(),
                v.parse().map_err(|e| format!("line {}: {e}", i + 1))?,
            )),
            _ => return Err(format!("line {}: not `setp PIN VALUE`: {t}", i + 1)),
        }
    }
    Ok(out)
}
