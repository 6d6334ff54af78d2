//! `axcomp sim`: simulate a linear axis (the digital twin, crate `axcomp-twin`) and write the
//! contract's measurement CSV; with `--machine KIND` a five-axis machine with rotary-axis location
//! errors measured by an R-test (the contract's R-test CSV).
//!
//! Glossary:
//! - *effects*: the error sources the simulated axis has (contract names, e.g. `pitch_error,reversal`);
//!   each gets documented typical parameters, or random plausible ones with `--random-params`.
//! - *plan*: what is measured (`iso230` positioning runs, `scan` at several speeds, `thermal`
//!   warm-up/cool-down, `load` steps, `abbe` offsets).
//! - *truth*: the effect kinds and parameters behind the data (`--truth FILE`, JSON).

use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use axcomp_core::Compensator;
use axcomp_twin::{Axis, EffectKind, Plan, TruthReport, simulate};

use crate::output::OutputSet;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Where to write the measurement CSV.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Effects of the simulated axis, comma separated (contract names). Default: the linear-motor demo
    /// axis (pitch_error, reversal, cogging, interpolation_error, scale_expansion).
    #[arg(long, value_name = "K1,K2,..", conflicts_with = "axis")]
    pub effects: Option<String>,
    /// Measurement plan: iso230, scan, thermal, load, abbe, survey (all of them on one time line, the
    /// validation harness's plan), or spindle (thermo-force campaign under
    /// cutting load from axcomp-thermal's generator: 16 collinear sensors, spindle_rpm/ap_mm/fz_mm).
    #[arg(long, value_name = "PLAN", default_value = "iso230")]
    pub plan: String,
    /// Seed of the measurement noise (and of the parameters with --random-params).
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,
    /// Measurement noise σ on the deviation, µm [default: 0.5, or the --axis file's].
    #[arg(long = "noise-um", value_name = "SIGMA", allow_negative_numbers = true)]
    pub noise_um: Option<f64>,
    /// Resize the plan to about N rows.
    #[arg(long, value_name = "N")]
    pub rows: Option<usize>,
    /// Also write the truth (effect kinds and parameters, plan, seed) as JSON.
    #[arg(long, value_name = "FILE")]
    pub truth: Option<PathBuf>,
    /// Draw random plausible effect parameters from the seed instead of the typical ones.
    #[arg(long, conflicts_with = "axis")]
    pub random_params: bool,
    /// Simulate the axis described in FILE (the `axis` object of a truth JSON, or a bare axis).
    #[arg(long, value_name = "FILE")]
    pub axis: Option<PathBuf>,
    /// Run the campaign compensated: every move goes through the firmware's compensator
    /// (`axcomp_core::Compensator::cycle`) loaded from this image (`axcomp image build`).
    #[arg(long, value_name = "FILE")]
    pub image: Option<PathBuf>,
    /// Stroke start, mm (ignored with --axis).
    #[arg(
        long = "start-mm",
        value_name = "MM",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub start_mm: f64,
    /// Stroke end, mm (ignored with --axis).
    #[arg(
        long = "end-mm",
        value_name = "MM",
        default_value_t = 200.0,
        allow_negative_numbers = true
    )]
    pub end_mm: f64,
    /// Simulate a five-axis machine instead (ac-trunnion, bc-trunnion, bc-head) with rotary-axis location
    /// errors (offsets 5–50 µm, tilts and squareness 10–100 µrad, from the seed) measured by an R-test:
    /// writes the contract's R-test CSV; --plan rtest (default: K4 run 1, C circles at 0° and at the largest
    /// tilt, K4 run 2), rtest-h2 (the circles again with the sphere 50 mm higher, set-up 2) or k4 (K4 runs 1
    /// and 2); --effects from rotary_positioning, rotary_wobble, radial_runout, linear_geometry,
    /// thermal_drift, setup_drift; noise σ 0.3 µm unless --noise-um. --plan probe-rtest writes a touch
    /// probe's touches instead (the probe's σ 0.5 µm unless --noise-um; the twin's probe, pretravel by direction in the probe's frame, no glitches;
    /// top and four sides of a Ø25 mm sphere per pose, 300 mm/min; B = C = 0 as run 1 and revisited as
    /// run 3, tilts ±1, ±0.6, ±0.2 × --tilt-max-deg [default 50] at C = 0/90/180/270° as run 2), the input
    /// of `axcomp fit probe --machine KIND --group b_deg,c_deg,run --centres-out`.
    #[arg(long, value_name = "KIND", conflicts_with_all = ["axis", "image", "random_params", "rows"])]
    pub machine: Option<String>,
    /// Five-axis bc-head: distance from the B axis to the tool point, mm [default: 250].
    #[arg(long, value_name = "L", requires = "machine")]
    pub pivot_mm: Option<f64>,
    /// Five-axis: the sphere's nominal position, mm (table frame for a trunnion, machine frame for a head)
    /// [default: 150,0,100 for a trunnion, 0,0,0 for a head (150,50,-100 with --plan probe-rtest)].
    #[arg(
        long,
        value_name = "X,Y,Z",
        requires = "machine",
        allow_hyphen_values = true
    )]
    pub sphere_mm: Option<String>,
    /// Five-axis: the tilt axis's largest K4 angle, degrees [default: −60].
    #[arg(
        long,
        value_name = "DEG",
        requires = "machine",
        allow_negative_numbers = true
    )]
    pub tilt_max_deg: Option<f64>,
    /// Five-axis: poses per K4 run [default: 72] (C circles: half of it).
    #[arg(long, value_name = "N", requires = "machine")]
    pub k4_poses: Option<usize>,
}

/// Most rows `--rows` asks for.
const MAX_ROWS: usize = 10_000_000;

/// A standard twin plan, or a spindle campaign from the thermal generator (held at mid-stroke).
enum PlanChoice {
    Standard(Plan),
    Spindle(axcomp_twin::synth::SynthConfig),
}

/// The validated configuration.
struct Config {
    axis: Axis,
    plan: PlanChoice,
    seed: u64,
    out: PathBuf,
    truth: Option<PathBuf>,
    compensator: Option<Box<Compensator>>,
}

fn check_parent(path: &Path, what: &str) -> anyhow::Result<()> {
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        bail!(
            "{what} {}: directory {} does not exist",
            path.display(),
            parent.display()
        );
    }
    Ok(())
}

fn load_axis(path: &Path) -> anyhow::Result<Axis> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("reading axis file {}", path.display()))?;
    let value: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("{}: not valid JSON", path.display()))?;
    let axis_value = value.get("axis").cloned().unwrap_or(value);
    serde_json::from_value(axis_value)
        .with_context(|| format!("{}: not an axcomp-twin axis description", path.display()))
}

impl Config {
    fn from_args(a: Args) -> anyhow::Result<Config> {
        let mut axis = if let Some(path) = &a.axis {
            load_axis(path)?
        } else {
            if !(a.start_mm.is_finite() && a.end_mm.is_finite() && a.end_mm > a.start_mm) {
                bail!(
                    "--start-mm {} / --end-mm {}: the stroke must be a non-empty finite range",
                    a.start_mm,
                    a.end_mm
                );
            }
            let kinds = match &a.effects {
                Some(list) => {
                    let kinds = EffectKind::parse_list(list).context("--effects")?;
                    if kinds.is_empty() {
                        bail!(
                            "--effects: no effect named (give e.g. --effects pitch_error,reversal)"
                        );
                    }
                    kinds
                }
                None => Axis::linear_motor_demo().kinds(),
            };
            if a.random_params {
                // A parameter stream independent of the noise stream (which uses the seed itself).
                Axis::random_seeded(
                    "random",
                    a.start_mm,
                    a.end_mm,
                    &kinds,
                    a.seed ^ 0xA715_0000_0000_0001,
                )
            } else if a.effects.is_none() && (a.start_mm, a.end_mm) == (0.0, 200.0) {
                Axis::linear_motor_demo()
            } else {
                Axis::typical("typical", a.start_mm, a.end_mm, &kinds)
            }
        };
        if let Some(sigma) = a.noise_um {
            if !(sigma.is_finite() && sigma >= 0.0) {
                bail!("--noise-um {sigma}: must be a finite σ ≥ 0 µm");
            }
            axis.noise.deviation_um = sigma;
        }
        axis.validate().context("the simulated axis")?;
        if a.rows == Some(0) {
            bail!("--rows 0: ask for at least one row");
        }
        if let Some(n) = a.rows.filter(|&n| n > MAX_ROWS) {
            // A billion rows once aborted the process when the allocation failed (72 GB) instead of saying so.
            bail!("--rows {n}: at most {MAX_ROWS} rows (about 1 GB of CSV)");
        }
        let plan = if a.plan == "spindle" {
            if a.image.is_some() {
                bail!("--image: compensated runs are not available with --plan spindle");
            }
            PlanChoice::Spindle(axcomp_twin::spindle_config(&axis, a.seed, a.rows))
        } else {
            match Plan::by_name(&a.plan, axis.start_mm, axis.end_mm, a.rows) {
                Ok(plan) => PlanChoice::Standard(plan),
                Err(_) => bail!(
                    "--plan {}: unknown plan (expected one of: {}, spindle)",
                    a.plan,
                    Plan::NAMES.join(", ")
                ),
            }
        };
        let compensator = match &a.image {
            Some(path) => {
                let bytes = std::fs::read(path)
                    .with_context(|| format!("--image {}: cannot read", path.display()))?;
                let mut comp = Box::new(Compensator::IDENTITY);
                comp.load(&bytes).map_err(|e| {
                    anyhow::anyhow!("--image {}: not a valid table image: {e}", path.display())
                })?;
                Some(comp)
            }
            None => None,
        };
        check_parent(&a.out, "--out")?;
        if let Some(t) = &a.truth {
            check_parent(t, "--truth")?;
        }
        Ok(Config {
            axis,
            plan,
            seed: a.seed,
            out: a.out,
            truth: a.truth,
            compensator,
        })
    }
}

/// Progress on stderr for large campaigns (the steps take seconds from about 10⁵ rows on).
struct Progress {
    on: bool,
    t0: std::time::Instant,
}

impl Progress {
    fn step(&self, what: &str) {
        if self.on {
            eprintln!("[{:>6.1} s] {what}", self.t0.elapsed().as_secs_f64());
        }
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    if args.machine.is_some() {
        return run_five_axis(args);
    }
    let progress = Progress {
        on: args.rows.is_some_and(|n| n >= 100_000),
        t0: std::time::Instant::now(),
    };
    let cfg = Config::from_args(args)?;
    // Every output is planned and checked before the simulation; written together at the end.
    let mut outputs = OutputSet::new();
    outputs.planned(&cfg.out);
    if let Some(path) = &cfg.truth {
        outputs.planned(path);
    }
    outputs.check()?;
    progress.step(&format!(
        "simulating the {} campaign",
        match &cfg.plan {
            PlanChoice::Standard(p) => p.name(),
            PlanChoice::Spindle(_) => "spindle",
        }
    ));
    let (campaign, truth_json) = match &cfg.plan {
        PlanChoice::Standard(plan) => {
            let campaign = simulate(&cfg.axis, plan, cfg.compensator.as_deref(), cfg.seed)
                .context("simulating")?;
            let json = TruthReport::new(&cfg.axis, plan, &campaign).to_json();
            (campaign, json)
        }
        PlanChoice::Spindle(synth) => {
            let target_mm = 0.5 * (cfg.axis.start_mm + cfg.axis.end_mm);
            let sc = axcomp_twin::simulate_spindle(&cfg.axis, target_mm, synth)
                .context("simulating the spindle campaign")?;
            let json = serde_json::to_string_pretty(&serde_json::json!({
                "axis": &cfg.axis,
                "plan": { "plan": "spindle", "target_mm": target_mm, "dt_s": synth.dt_s },
                "seed": cfg.seed,
                "rows": sc.campaign.rows.len(),
                "compensated": false,
                "effects": ["thermal_drift", "thermal_lag", "force_deflection"],
                "positional_effects_at_target": cfg.axis.kinds().iter().map(|k| k.name()).collect::<Vec<_>>(),
                "synth_truth": &sc.truth_model,
                "synth_formula": sc.truth_model.formula(),
            }))?;
            (sc.campaign, json)
        }
    };
    progress.step(&format!(
        "writing {} rows to {}",
        campaign.rows.len(),
        cfg.out.display()
    ));
    let csv = campaign.to_csv_string();
    outputs.file(&cfg.out, csv);
    if let Some(path) = &cfg.truth {
        outputs.file(path, truth_json);
    }
    outputs.commit()?;
    progress.step("done");
    let kinds: Vec<&str> = cfg.axis.kinds().iter().map(|k| k.name()).collect();
    println!(
        "wrote {}: {} rows, plan {}, effects {}, seed {}, noise σ {} µm, {}; deviation RMS {:.3} µm (noise-free {:.3} µm)",
        cfg.out.display(),
        campaign.rows.len(),
        campaign.plan,
        kinds.join(","),
        cfg.seed,
        cfg.axis.noise.deviation_um,
        if campaign.compensated {
            "compensated"
        } else {
            "uncompensated"
        },
        campaign.rms_deviation_um(),
        campaign.rms_truth_um()
    );
    if let Some(path) = &cfg.truth {
        println!(
            "wrote {}: truth (effect kinds and parameters)",
            path.display()
        );
    }
    Ok(())
}

/// `axcomp sim --machine KIND`: the five-axis twin (`axcomp_twin::five_axis`) measured by an R-test along
/// K4 and C circles; the R-test CSV of the contract and, with --truth, the truth JSON (location errors
/// by ISO 230-7 name, set-up offsets, effects, plan).
fn run_five_axis(a: Args) -> anyhow::Result<()> {
    use axcomp_kinematics::rotary::{FiveAxis, MachineKind, location_unit};
    use axcomp_twin::five_axis::{FiveAxisTwin, standard_paths};

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
    let sphere = match &a.sphere_mm {
        // Touches about a sphere at the origin would hold coordinates near 0 next to ones near 14 mm, which
        // the unit-mix check takes for µm mixed with mm.
        None if head && a.plan == "probe-rtest" => [150.0, 50.0, -100.0],
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
    };
    let probing = a.plan == "probe-rtest";
    let tilt_max = a.tilt_max_deg.unwrap_or(if probing { 50.0 } else { -60.0 });
    if !(tilt_max.is_finite() && tilt_max != 0.0 && tilt_max.abs() <= 120.0) {
        bail!("--tilt-max-deg {tilt_max}: need a non-zero angle within ±120°");
    }
    let k4_poses = a.k4_poses.unwrap_or(72);
    if !(8..=100_000).contains(&k4_poses) {
        bail!("--k4-poses {k4_poses}: need 8..=100000 poses");
    }
    let machine = FiveAxis::new(kind, pivot_mm);
    let mut twin = FiveAxisTwin::random(machine, a.seed);
    if let Some(sigma) = a.noise_um {
        if !(sigma.is_finite() && sigma >= 0.0) {
            bail!("--noise-um {sigma}: must be a finite σ ≥ 0 µm");
        }
        twin.noise_um = sigma;
    }
    let mut enabled: Vec<&str> = Vec::new();
    if let Some(list) = &a.effects {
        for name in list.split(',').map(str::trim).filter(|n| !n.is_empty()) {
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
    }
    let circles = [0.0, tilt_max];
    let paths = match a.plan.as_str() {
        "iso230" | "rtest" => standard_paths(
            &machine,
            sphere,
            tilt_max,
            k4_poses,
            &circles,
            k4_poses / 2,
            None,
        ),
        "rtest-h2" => standard_paths(
            &machine,
            sphere,
            tilt_max,
            k4_poses,
            &circles,
            k4_poses / 2,
            Some(50.0),
        ),
        "k4" => standard_paths(&machine, sphere, tilt_max, k4_poses, &[], 0, None),
        "probe-rtest" => {
            axcomp_twin::five_axis_probe::probe_rtest_paths(&machine, sphere, tilt_max)
        }
        other => {
            bail!("--plan {other}: with --machine the plans are rtest, rtest-h2, k4, probe-rtest")
        }
    };
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
    let (rows, what, noise_um) = if probing {
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
        let names = kind.location_names();
        let location: serde_json::Map<String, serde_json::Value> = names
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
        for p in &paths {
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
        let json = serde_json::json!({
            "machine": kind.name(),
            "pivot_mm": pivot_mm,
            "seed": a.seed,
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
                "sphere_mm": sphere,
                "tilt_max_deg": tilt_max,
                "paths": paths.iter().map(|p| serde_json::json!({
                    "path": p.path, "run": p.run, "setup": p.setup, "sphere_mm": p.sphere_mm, "poses": p.poses.len()
                })).collect::<Vec<_>>(),
            },
            "sign_convention": axcomp_rtest::SIGN_CONVENTION,
        });
        outputs.file(path, serde_json::to_string_pretty(&json)?);
    }
    outputs.commit()?;
    println!(
        "wrote {}: {rows} {what}, machine {}, plan {plan_name}, seed {}, noise σ {} µm, effects beyond the location errors: {}",
        a.out.display(),
        kind.name(),
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
