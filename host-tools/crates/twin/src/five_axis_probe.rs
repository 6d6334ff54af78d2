//! A five-axis probing campaign on the twin: at each pose a touch probe in the spindle touches the reference
//! sphere (the shop-floor substitute for an R-test head), giving the contract's touch CSV with the pose
//! columns; `axcomp fit probe --group .. --centres-out` turns it into R-test rows.
//!
//! Glossary:
//! - **probe frame**: the frame the probe's stylus carries. On a head machine (`bc-head`) it turns with C and
//!   tilts with B (`FiveAxis::spindle_rotation`): each pose's touches are planned in it (top and sides of the
//!   sphere as the probe sees them, as a head machine's probing cycle moves) and the probe's pretravel
//!   depends on the direction in it; the CSV gives positions and approach directions in the machine frame.
//!   On a trunnion the probe frame is the machine frame.
//! - **latched position**: tool-point coordinates (TCPC): the nominal tool point at the trigger. The sphere
//!   appears at the commanded tool point plus the twin's displacement `d = S − T` at that pose (its exact
//!   location-error model, set-up offsets and effects, no reading noise: the probe brings its own).
//! - **revisit**: the reference pose B = C = 0 probed at the start (run 1) and again at the end (run 3):
//!   a further run of a single pose each; the other poses are run 2.

use std::fmt::Write as _;

use axcomp_kinematics::rotary::{FiveAxis, MachineKind, Pose, pose_on_sphere};
use nalgebra::Vector3;

use crate::five_axis::{FiveAxisTwin, RtestPathSpec};
use crate::probe::{ProbeModel, ProbePlan, simulate_touches};

/// How each pose is probed.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseProbing {
    /// Reference sphere diameter, mm.
    pub sphere_diameter_mm: f64,
    /// Elevations of the touches' surface normals in the probe frame, degrees (90: the top).
    pub elevations_deg: Vec<f64>,
    /// Touches per elevation ring below the top.
    pub azimuths: usize,
    pub feed_mm_min: f64,
}

impl PoseProbing {
    /// Five touches per pose, the head-machine routine: the top and four sides (probe frame), 300 mm/min,
    /// a Ø25 mm sphere.
    pub fn top_and_four_sides() -> Self {
        PoseProbing {
            sphere_diameter_mm: 25.0,
            elevations_deg: vec![0.0, 90.0],
            azimuths: 4,
            feed_mm_min: 300.0,
        }
    }
}

/// The probing campaign's poses: B = C = 0 (run 1), the tilt at ±`tilt_max_deg`, ±0.6× and ±0.2× of it,
/// each at C = 0, 90, 180, 270° (run 2), and B = C = 0 again (run 3); path `probe`, set-up 1, the sphere
/// at `sphere_mm`.
pub fn probe_rtest_paths(
    machine: &FiveAxis,
    sphere_mm: [f64; 3],
    tilt_max_deg: f64,
) -> Vec<RtestPathSpec> {
    let t = tilt_max_deg.abs();
    let reference = |run| RtestPathSpec {
        path: "probe".into(),
        run,
        setup: "1".into(),
        sphere_mm,
        poses: vec![pose_on_sphere(machine, sphere_mm, 0.0, 0.0)],
    };
    let mut grid = Vec::new();
    for tilt in [-t, -0.6 * t, -0.2 * t, 0.2 * t, 0.6 * t, t] {
        for c in [0.0, 90.0, 180.0, 270.0] {
            grid.push(pose_on_sphere(machine, sphere_mm, tilt, c));
        }
    }
    vec![
        reference(1),
        RtestPathSpec {
            path: "probe".into(),
            run: 2,
            setup: "1".into(),
            sphere_mm,
            poses: grid,
        },
        reference(3),
    ]
}

/// The touch CSV of probing `paths` on `twin` with `probe` (seed `seed`): columns `x_mm, y_mm, z_mm,
/// approach_x, approach_y, approach_z, feed_mm_min, artefact, <a|b>_deg, c_deg, run, time_s`, and, where
/// the probe does not tilt (a trunnion: the commanded position differs by pose), `cmd_x_mm, cmd_y_mm,
/// cmd_z_mm`. `dwell_s` per pose as in `FiveAxisTwin::measure`.
pub fn probe_campaign_csv(
    twin: &FiveAxisTwin,
    probe: &ProbeModel,
    paths: &[RtestPathSpec],
    probing: &PoseProbing,
    seed: u64,
) -> String {
    let m = &twin.machine;
    let head = m.kind == MachineKind::BcHead;
    let mut csv = format!(
        "x_mm,y_mm,z_mm,approach_x,approach_y,approach_z,feed_mm_min,artefact,{}_deg,c_deg,run,time_s{}\n",
        m.kind.tilt_letter(),
        if head {
            ""
        } else {
            ",cmd_x_mm,cmd_y_mm,cmd_z_mm"
        }
    );
    let mut setups: Vec<&str> = Vec::new();
    let mut time = 0.0;
    let mut k = 0u64;
    for p in paths {
        let setup = match setups.iter().position(|s| *s == p.setup) {
            Some(s) => s,
            None => {
                setups.push(&p.setup);
                setups.len() - 1
            }
        };
        for pose in &p.poses {
            pose_touches(
                &mut csv,
                twin,
                probe,
                pose,
                p,
                setup,
                time,
                probing,
                seed * 1000 + k,
            );
            time += twin.dwell_s;
            k += 1;
        }
    }
    csv
}

/// One pose's touches appended to `csv`.
#[allow(clippy::too_many_arguments)] // one caller; each is one of the campaign's dimensions
fn pose_touches(
    csv: &mut String,
    twin: &FiveAxisTwin,
    probe: &ProbeModel,
    pose: &Pose,
    path: &RtestPathSpec,
    setup: usize,
    time_s: f64,
    probing: &PoseProbing,
    seed: u64,
) {
    let m = &twin.machine;
    let d = twin.reading(pose, path.sphere_mm, setup, time_s);
    let centre = Vector3::from([0, 1, 2].map(|i| pose.p_mm[i] + d[i] * 1e-3));
    let r = m.spindle_rotation(pose);
    let c_probe = r.transpose() * centre;
    let plan = ProbePlan::calibration(
        [c_probe[0], c_probe[1], c_probe[2]],
        probing.sphere_diameter_mm,
        &probing.elevations_deg,
        probing.azimuths,
        &[probing.feed_mm_min],
        1,
    );
    for t in simulate_touches(probe, &plan, seed) {
        let p = r * Vector3::from(t.latched_mm);
        let u = r * Vector3::from(t.approach);
        let _ = write!(
            csv,
            "{:.7},{:.7},{:.7},{:.9},{:.9},{:.9},{},sphere,{},{},{},{}",
            p[0],
            p[1],
            p[2],
            u[0],
            u[1],
            u[2],
            t.feed_mm_min,
            pose.tilt_deg,
            pose.c_deg,
            path.run,
            time_s
        );
        if m.kind != MachineKind::BcHead {
            let _ = write!(csv, ",{},{},{}", pose.p_mm[0], pose.p_mm[1], pose.p_mm[2]);
        }
        csv.push('\n');
    }
}
