//! Reading touches from a touch CSV (the contract's "Touch CSV"), their plausibility warnings, and the
//! rotation of touches into the probe's frame on a machine whose spindle tilts.
//!
//! Glossary:
//! - **probe frame**: the frame the stylus carries. On a head machine (`bc-head`) the spindle, and with it
//!   the probe, turns with C and tilts with B: a touch's approach direction, the pretravel that depends on it
//!   and the calibration made at the reference pose belong to that frame, not to the machine frame the
//!   latched positions are given in. The nominal kinematics give the rotation
//!   ([`FiveAxis::spindle_rotation`]); on a trunnion the probe frame is the machine frame.

use axcomp_data::sanity::{self, DataWarning};
use axcomp_data::{DataError, Dataset};
use axcomp_kinematics::rotary::{FiveAxis, MachineKind, Pose};
use nalgebra::{Matrix3, Vector3};

use crate::{ProbeError, Touch, UNIT_TOLERANCE};

/// The columns of a touch CSV that must hold plausible numbers.
const TOUCH_COLUMNS: [&str; 7] = [
    "x_mm",
    "y_mm",
    "z_mm",
    "approach_x",
    "approach_y",
    "approach_z",
    "feed_mm_min",
];

/// Names row `row` of `ds` in messages: `file:line (row n)`.
pub fn row_name(ds: &Dataset, row: usize) -> String {
    format!("{}:{} (row {})", ds.source(), ds.line_of_row(row), row + 1)
}

/// Reads the touch columns (names the cell of a non-numeric value) and names each row ([`row_name`]).
/// `feed_mm_min` is 0 when absent. An approach vector within [`UNIT_TOLERANCE`] of unit length is
/// normalised (its length error would otherwise move the contact point by r·(|u| − 1), up to 1.5 µm for a
/// Ø3 mm ball); one further off is left as given for [`crate::validate_touches`] to refuse, naming the row.
pub fn read_touches(ds: &Dataset) -> Result<(Vec<Touch>, Vec<String>), DataError> {
    sanity::absurd_values(ds, &TOUCH_COLUMNS)?;
    let col = |c: &str| -> Result<Vec<f64>, DataError> { Ok(ds.numeric(c)?.to_vec()) };
    let (x, y, z) = (col("x_mm")?, col("y_mm")?, col("z_mm")?);
    let (ax, ay, az) = (col("approach_x")?, col("approach_y")?, col("approach_z")?);
    let feed = if ds.has("feed_mm_min") {
        col("feed_mm_min")?
    } else {
        vec![0.0; ds.n_rows()]
    };
    let touches = (0..ds.n_rows())
        .map(|i| {
            let mut approach = [ax[i], ay[i], az[i]];
            let l = approach.iter().map(|v| v * v).sum::<f64>().sqrt();
            if (l - 1.0).abs() <= UNIT_TOLERANCE {
                approach = approach.map(|v| v / l);
            }
            Touch {
                position_mm: [x[i], y[i], z[i]],
                approach,
                feed_mm_min: feed[i],
            }
        })
        .collect();
    let labels = (0..ds.n_rows()).map(|i| row_name(ds, i)).collect();
    Ok((touches, labels))
}

/// Plausibility of touches (see `axcomp_data::sanity`): positions beyond 10 m or of mixed magnitudes
/// (µm taken for mm).
pub fn touch_warnings(ds: &Dataset, touches: &[Touch]) -> Vec<DataWarning> {
    let mut w = Vec::new();
    for (k, c) in ["x_mm", "y_mm", "z_mm"].into_iter().enumerate() {
        let v: Vec<f64> = touches.iter().map(|t| t.position_mm[k]).collect();
        w.extend(sanity::unit_mix(ds, c, &v, None));
        w.extend(sanity::implausible_magnitude(
            ds,
            c,
            &v,
            1.0e4,
            "touch positions beyond 10 m are not plausible in mm: µm?",
        ));
    }
    w
}

/// Parses a `--machine` name for the probe route (the kinds of `fit rtest --machine`).
pub fn parse_machine(name: &str) -> Result<MachineKind, ProbeError> {
    MachineKind::parse(name).ok_or_else(|| {
        ProbeError::BadOption(format!(
            "--machine `{name}`: expected ac-trunnion, bc-trunnion or bc-head"
        ))
    })
}

/// Whether the probe tilts with the rotary axes on a machine of `kind` (its directions then belong to the
/// probe's frame): the head machine's spindle carries B and C.
pub fn probe_tilts(kind: MachineKind) -> bool {
    FiveAxis::new(kind, 1.0)
        .spindle_rotation(&Pose {
            p_mm: [0.0; 3],
            tilt_deg: 90.0,
            c_deg: 90.0,
        })
        .ne(&Matrix3::identity())
}

/// Each row's rotation from the probe frame to the machine frame on a machine of `kind`, from the pose
/// columns `a_deg` (ac-trunnion) or `b_deg`, and `c_deg`, by the nominal kinematics.
pub fn probe_rotations(ds: &Dataset, kind: MachineKind) -> Result<Vec<Matrix3<f64>>, DataError> {
    let machine = FiveAxis::new(kind, 1.0);
    let tilt = ds.numeric(&format!("{}_deg", kind.tilt_letter()))?;
    let c = ds.numeric("c_deg")?;
    Ok((0..ds.n_rows())
        .map(|i| {
            machine.spindle_rotation(&Pose {
                p_mm: [0.0; 3],
                tilt_deg: tilt[i],
                c_deg: c[i],
            })
        })
        .collect())
}

/// Each row's probe frame ([`probe_rotations`]) on a machine of `kind` whose probe tilts; the identity
/// (the machine frame) for every row otherwise.
pub fn probe_frames(
    ds: &Dataset,
    kind: Option<MachineKind>,
) -> Result<Vec<Matrix3<f64>>, DataError> {
    match kind {
        Some(k) if probe_tilts(k) => probe_rotations(ds, k),
        _ => Ok(vec![Matrix3::identity(); ds.n_rows()]),
    }
}

/// A machine-frame vector in the frame `to_machine` maps to the machine frame.
pub fn into_frame(to_machine: &Matrix3<f64>, v: [f64; 3]) -> [f64; 3] {
    let w = to_machine.transpose() * Vector3::from(v);
    [w[0], w[1], w[2]]
}

/// A vector of the frame `to_machine` maps to the machine frame, in the machine frame.
pub fn out_of_frame(to_machine: &Matrix3<f64>, v: [f64; 3]) -> [f64; 3] {
    let w = to_machine * Vector3::from(v);
    [w[0], w[1], w[2]]
}

/// The touch seen in the probe frame `to_machine` maps to the machine frame: its latched position and
/// approach rotated (a rigid rotation about the machine origin, so distances, sphere fits and the contact
/// correction `p + r_eff·u` carry over; a centre fitted in the probe frame is [`out_of_frame`] in the
/// machine frame).
pub fn in_probe_frame(t: &Touch, to_machine: &Matrix3<f64>) -> Touch {
    Touch {
        position_mm: into_frame(to_machine, t.position_mm),
        approach: into_frame(to_machine, t.approach),
        feed_mm_min: t.feed_mm_min,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: at B = 90°, C = 0 the head's tool axis (−Z at B = 0) points along −X: a touch approaching
    /// along −X in the machine frame approaches along −Z in the probe frame (the "top" touch); the rotation
    /// keeps distances. Tolerance 1e-12.
    #[test]
    fn a_tilted_head_probe_sees_a_sideways_approach_as_its_top_touch() {
        let r = FiveAxis::new(MachineKind::BcHead, 250.0).spindle_rotation(&Pose {
            p_mm: [0.0; 3],
            tilt_deg: 90.0,
            c_deg: 0.0,
        });
        let u = into_frame(&r, [-1.0, 0.0, 0.0]);
        assert!((u[2] + 1.0).abs() < 1e-12 && u[0].abs() < 1e-12, "{u:?}");
        let back = out_of_frame(&r, u);
        assert!((back[0] + 1.0).abs() < 1e-12, "{back:?}");
        assert!(probe_tilts(MachineKind::BcHead));
        assert!(!probe_tilts(MachineKind::AcTrunnion) && !probe_tilts(MachineKind::BcTrunnion));
    }
}
