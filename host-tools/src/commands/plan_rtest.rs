//! `axcomp plan rtest`: which paths, added to K4, make all 11 location errors identifiable, and with what
//! standard uncertainty at a given reading noise (`axcomp_rtest::plan`).

use std::path::PathBuf;

use axcomp_rtest::plan::{PlanGeometry, plan};

use crate::commands::common::machine_from;
use crate::output::OutputSet;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Machine kind: ac-trunnion, bc-trunnion, bc-head.
    #[arg(long, default_value = "ac-trunnion", value_name = "KIND")]
    pub machine: String,
    /// bc-head: nominal distance from the B axis to the tool point, mm.
    #[arg(long, value_name = "L")]
    pub pivot_mm: Option<f64>,
    /// Reading noise σ per displacement component, µm.
    #[arg(long, default_value_t = 0.5, value_name = "S")]
    pub sigma_um: f64,
    /// Sphere distance from the C axis, mm (trunnions).
    #[arg(long, default_value_t = 150.0, value_name = "R")]
    pub sphere_radius_mm: f64,
    /// Sphere height above the tilt axis, mm (trunnions).
    #[arg(long, default_value_t = 100.0, value_name = "H")]
    pub sphere_height_mm: f64,
    /// Second set-up: sphere raised by this much, mm.
    #[arg(long, default_value_t = 100.0, value_name = "DH")]
    pub second_height_mm: f64,
    /// K4 tilt swing (0 → T → 0), degrees.
    #[arg(long, default_value_t = -60.0, value_name = "T", allow_hyphen_values = true)]
    pub tilt_max_deg: f64,
    /// Poses on K4.
    #[arg(long, default_value_t = 72, value_name = "N")]
    pub k4_poses: usize,
    /// Poses per C circle.
    #[arg(long, default_value_t = 36, value_name = "N")]
    pub circle_poses: usize,
    /// The R-test head's zero is unknown (estimated per set-up).
    #[arg(long)]
    pub free_head_zero: bool,
    /// Machine-readable result.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // The output path is checked before the plan is computed.
    let mut outputs = OutputSet::new();
    if let Some(j) = &args.json {
        outputs.planned(j);
    }
    outputs.check()?;
    let machine = machine_from(&args.machine, args.pivot_mm)?;
    if !(args.sigma_um.is_finite() && args.sigma_um > 0.0) {
        anyhow::bail!("--sigma-um {}: need a noise > 0 µm", args.sigma_um);
    }
    use crate::commands::common::{check_count, check_range};
    // Bounds: a pose per 0.1° of a circle at most; the sphere within 10 m of the axes.
    check_count("--k4-poses", args.k4_poses, 8, 3600)?;
    check_count("--circle-poses", args.circle_poses, 4, 3600)?;
    check_range("--sphere-radius-mm", args.sphere_radius_mm, -1e4, 1e4)?;
    check_range("--sphere-height-mm", args.sphere_height_mm, -1e4, 1e4)?;
    check_range("--second-height-mm", args.second_height_mm, -1e4, 1e4)?;
    if !(args.tilt_max_deg.abs() > 0.0 && args.tilt_max_deg.abs() <= 150.0) {
        anyhow::bail!("--tilt-max-deg {}: need 0 < |T| ≤ 150", args.tilt_max_deg);
    }
    let mut g = PlanGeometry::default_for(machine);
    if machine.kind != axcomp_kinematics::rotary::MachineKind::BcHead {
        g.sphere_mm = [args.sphere_radius_mm, 0.0, args.sphere_height_mm];
    }
    g.second_height_mm = args.second_height_mm;
    g.tilt_max_deg = args.tilt_max_deg;
    g.k4_poses = args.k4_poses;
    g.circle_poses = args.circle_poses;
    g.free_head_zero = args.free_head_zero;
    let p = plan(&g, args.sigma_um);
    if let Some(j) = &args.json {
        outputs.json(j, &p)?;
    }
    outputs.commit()?;
    println!(
        "plan rtest ({}), σ = {} µm per component; predicted standard uncertainties (µm | µrad):",
        p.machine, p.sigma_um
    );
    for (i, c) in p.candidates.iter().enumerate() {
        let mark = if Some(i) == p.recommended {
            " <- recommended"
        } else {
            ""
        };
        println!(
            "  {} ({} poses, condition {:.1}){}",
            c.paths.join(" + "),
            c.poses,
            c.condition_number,
            mark
        );
        let cells: Vec<String> = c
            .std
            .iter()
            .map(|(n, s)| match s {
                Some(s) => format!("{n} {s:.2}"),
                None => format!("{n} –"),
            })
            .collect();
        println!("    {}", cells.join(", "));
        if !c.not_identified.is_empty() {
            println!("    not identifiable: {}", c.not_identified.join(", "));
        }
    }
    match p.recommended {
        Some(i) => println!("recommended: {}", p.candidates[i].paths.join(" + ")),
        None => println!(
            "no candidate identifies all 11 (see the reasons in fit rtest; with --free-head-zero the rotary axes' absolute position relative to the spindle is never determined by R-test readings)"
        ),
    }
    Ok(())
}
