//! `axcomp sim --machine KIND`: the five-axis twin (`axcomp_twin::five_axis`) measured by an R-test along
//! K4 and C circles, or probed by a touch probe (`--plan probe-rtest`); the contract's R-test CSV (or touch
//! CSV) and, with `--truth`, the truth JSON (location errors by ISO 230-7 name, set-up offsets, effects,
//! plan).
//!
//! Glossary:
//! - *K4*: the ISO 10791-6 test moving the tilt and the rotary axis together about a sphere on the table.
//! - *C circle*: the rotary table turning a full circle at one tilt.
//! - *set-up*: one placement of the sphere; `rtest-h2` adds a second, 50 mm higher.
//! - *location errors*: the rotary axes' offsets, tilts and squareness of ISO 230-7.

use anyhow::{Context, bail};
use axcomp_kinematics::rotary::{FiveAxis, MachineKind, location_unit};
use axcomp_twin::five_axis::{FiveAxisTwin, RtestPathSpec, standard_paths};

use crate::cli::SimArgs;
use crate::commands::common::check_parent;
use crate::output::OutputSet;

/// The validated machine, sphere and plan of a five-axis simulation.
struct Setup {
    kind: MachineKind,
    pivot_mm: f64,
    sphere_mm: [f64; 3],
    tilt_max_deg: f64,
    k4_poses: usize,
    probing: bool,
}

pub fn run(a: SimArgs) -> anyhow::Result<()> {
    let setup = setup_from(&a)?;
    let machine = FiveAxis::new(setup.kind, setup.pivot_mm);
    let mut twin = FiveAxisTwin::random(machine, a.seed);
    if let Some(sigma) = a.noise_um {
        if !(sigma.is_finite() && sigma >= 0.0) {
            bail!("--noise-um {sigma}: must be a finite σ ≥ 0 µm");
        }
        twin.noise_um = sigma;
    }
    let enabled = enable_effects(&mut twin, a.effects.as_deref())?;
    let paths = paths_for(&a.plan, &machine, &setup)?;
    let plan_name = if a.plan == "iso230" { "rtest" } else { &a.plan };
    check_parent(&a.out, "--out")?;
    if let Some(t) = &a.truth {
        check_parent(t, "--truth")?;
    }
    let mut outputs = OutputSet::new();
    outputs.planned(&a.out);
    if let Some(path) = &a.truth {
        outputs.planned(path);
    }
    outputs.check()?;
    let (rows, what, noise_um) = if setup.probing {
        use axcomp_twin::five_axis_probe::{PoseProbing, probe_campaign_csv};
        let mut probe = axcomp_twin::probe::ProbeModel::kinematic_demo().without_glitches();
        if a.noise_um.is_some() {
            probe.noise_um = twin.noise_um;
        }
        let csv = probe_campaign_csv(
            &twin,
            &probe,
            &paths,
            &PoseProbing::top_and_four_sides(),
            a.seed,
        );
        let n = csv.lines().count() - 1;
        outputs.file(&a.out, csv);
        (n, "touches", probe.noise_um)
    } else {
        let campaign = twin.measure(&paths, a.seed);
        outputs.file(&a.out, campaign.to_csv_string());
        (campaign.rows.len(), "R-test rows", twin.noise_um)
    };
    if let Some(path) = &a.truth {
        let json = truth_json(&setup, &twin, a.seed, &enabled, plan_name, &paths);
        outputs.file(path, serde_json::to_string_pretty(&json)?);
    }
    outputs.commit()?;
    println!(
        "wrote {}: {rows} {what}, machine {}, plan {plan_name}, seed {}, noise σ {} µm, effects beyond the location errors: {}",
        a.out.display(),
        setup.kind.name(),
        a.seed,
        noise_um,
        a.effects.as_deref().unwrap_or("none")
    );
    if let Some(path) = &a.truth {
        println!(
            "wrote {}: truth (location errors, set-up offsets, effects, plan)",
            path.display()
        );
    }
    Ok(())
}

/// The machine kind, pivot, sphere, largest tilt and K4 poses from the options, each checked.
fn setup_from(a: &SimArgs) -> anyhow::Result<Setup> {
    let kind_name = a.machine.as_deref().unwrap_or_default();
    let Some(kind) = MachineKind::parse(kind_name) else {
        bail!("--machine `{kind_name}`: expected ac-trunnion, bc-trunnion or bc-head");
    };
    if a.effects.is_none() && a.random_params {
        bail!("--random-params is for a linear axis");
    }
    if (a.start_mm, a.end_mm) != (0.0, 200.0) {
        bail!("--start-mm/--end-mm are for a linear axis, not with --machine");
    }
    let head = kind == MachineKind::BcHead;
    let pivot_mm = match (head, a.pivot_mm) {
        (true, None) => 250.0,
        (true, Some(l)) if l.is_finite() && l > 0.0 => l,
        (true, Some(l)) => bail!("--pivot-mm {l}: need a length > 0 mm"),
        (false, Some(_)) => bail!("--pivot-mm is for --machine bc-head only"),
        (false, None) => 0.0,
    };
    let probing = a.plan == "probe-rtest";
    let sphere_mm = sphere_from(a.sphere_mm.as_deref(), head, probing)?;
    let tilt_max_deg = a.tilt_max_deg.unwrap_or(if probing { 50.0 } else { -60.0 });
    if !(tilt_max_deg.is_finite() && tilt_max_deg != 0.0 && tilt_max_deg.abs() <= 120.0) {
        bail!("--tilt-max-deg {tilt_max_deg}: need a non-zero angle within ±120°");
    }
    let k4_poses = a.k4_poses.unwrap_or(72);
    if !(8..=100_000).contains(&k4_poses) {
        bail!("--k4-poses {k4_poses}: need 8..=100000 poses");
    }
    Ok(Setup {
        kind,
        pivot_mm,
        sphere_mm,
        tilt_max_deg,
        k4_poses,
        probing,
    })
}

/// `--sphere-mm X,Y,Z`, or the default for the machine (`head`) and plan (`probing`).
fn sphere_from(text: Option<&str>, head: bool, probing: bool) -> anyhow::Result<[f64; 3]> {
    Ok(match text {
        // Touches about a sphere at the origin would hold coordinates near 0 next to ones near 14 mm, which
        // the unit-mix check takes for µm mixed with mm.
        None if head && probing => [150.0, 50.0, -100.0],
        None if head => [0.0; 3],
        None => [150.0, 0.0, 100.0],
        Some(text) => {
            let v: Vec<f64> = text
                .split(',')
                .map(|t| t.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .with_context(|| format!("--sphere-mm {text}: expected three numbers X,Y,Z"))?;
            if v.len() != 3 || v.iter().any(|x| !x.is_finite() || x.abs() > 2000.0) {
                bail!("--sphere-mm {text}: expected three finite numbers X,Y,Z within ±2000 mm");
            }
            [v[0], v[1], v[2]]
        }
    })
}

/// Turns on the `--effects` (comma separated, five-axis names) in the twin; the names, in order, once each.
fn enable_effects<'a>(
    twin: &mut FiveAxisTwin,
    list: Option<&'a str>,
) -> anyhow::Result<Vec<&'a str>> {
    let mut enabled: Vec<&str> = Vec::new();
    for name in list
        .unwrap_or_default()
        .split(',')
        .map(str::trim)
        .filter(|n| !n.is_empty())
    {
        if !enabled.contains(&name) {
            enabled.push(name);
        }
        if !twin.effects.enable(name) {
            bail!(
                "--effects: `{name}` is not a five-axis effect (expected: {})",
                axcomp_twin::five_axis::FiveAxisEffects::NAMES.join(", ")
            );
        }
    }
    Ok(enabled)
}

/// The measured paths of `--plan` (`iso230` is `rtest`, the default).
fn paths_for(plan: &str, machine: &FiveAxis, s: &Setup) -> anyhow::Result<Vec<RtestPathSpec>> {
    let circles = [0.0, s.tilt_max_deg];
    let (sphere, tilt, k4) = (s.sphere_mm, s.tilt_max_deg, s.k4_poses);
    Ok(match plan {
        "iso230" | "rtest" => standard_paths(machine, sphere, tilt, k4, &circles, k4 / 2, None),
        "rtest-h2" => standard_paths(machine, sphere, tilt, k4, &circles, k4 / 2, Some(50.0)),
        "k4" => standard_paths(machine, sphere, tilt, k4, &[], 0, None),
        "probe-rtest" => axcomp_twin::five_axis_probe::probe_rtest_paths(machine, sphere, tilt),
        other => {
            bail!("--plan {other}: with --machine the plans are rtest, rtest-h2, k4, probe-rtest")
        }
    })
}

/// The truth behind the data: location errors by ISO 230-7 name, set-up offsets by set-up, the effects and
/// their parameters, the plan.
fn truth_json(
    s: &Setup,
    twin: &FiveAxisTwin,
    seed: u64,
    enabled: &[&str],
    plan_name: &str,
    paths: &[RtestPathSpec],
) -> serde_json::Value {
    let location: serde_json::Map<String, serde_json::Value> = s
        .kind
        .location_names()
        .iter()
        .enumerate()
        .map(|(k, n)| {
            (
                n.to_string(),
                serde_json::json!({ "value": twin.location[k], "unit": location_unit(k) }),
            )
        })
        .collect();
    let mut setups: Vec<&str> = Vec::new();
    for p in paths {
        if !setups.contains(&p.setup.as_str()) {
            setups.push(&p.setup);
        }
    }
    let setup_offsets: serde_json::Map<String, serde_json::Value> = setups
        .iter()
        .enumerate()
        .map(|(i, name)| {
            (
                name.to_string(),
                serde_json::json!(twin.setup_offsets_um[i % twin.setup_offsets_um.len()]),
            )
        })
        .collect();
    let p = &twin.effect_params;
    serde_json::json!({
        "machine": s.kind.name(),
        "pivot_mm": s.pivot_mm,
        "seed": seed,
        "noise_um": twin.noise_um,
        "location_errors": location,
        "setup_offsets_um": setup_offsets,
        "setup_offsets_order": "sphere dx, dy, dz (table frame for a trunnion, machine frame for a head), then R-test head dx, dy, dz",
        "effects": enabled,
        "effect_params": {
            "c_positioning_urad_and_phase_rad": p.c_pos,
            "tilt_positioning_urad_per_rad": p.tilt_pos_urad_per_rad,
            "wobble_urad_and_phase_rad": p.wobble,
            "runout_um_and_phase_rad": p.runout,
            "linear_x_um_per_m_eyx_um_ezy_um": p.linear,
            "thermal_um_per_h_x_z": p.thermal_um_h,
            "setup_drift_um_per_h": p.setup_um_h,
        },
        "plan": {
            "plan": plan_name,
            "sphere_mm": s.sphere_mm,
            "tilt_max_deg": s.tilt_max_deg,
            "paths": paths.iter().map(|p| serde_json::json!({
                "path": p.path, "run": p.run, "setup": p.setup, "sphere_mm": p.sphere_mm, "poses": p.poses.len()
            })).collect::<Vec<_>>(),
        },
        "sign_convention": axcomp_rtest::SIGN_CONVENTION,
    })
}
