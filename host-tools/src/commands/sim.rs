//! `axcomp sim` without `--machine`: simulate a linear axis (the digital twin, crate `axcomp-twin`) and
//! write the contract's measurement CSV (`--machine KIND`: [`crate::commands::sim_five_axis`]).
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

use crate::cli::SimArgs;
use crate::commands::common::check_parent;
use crate::output::OutputSet;

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
    fn from_args(a: SimArgs) -> anyhow::Result<Config> {
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

pub fn run(args: SimArgs) -> anyhow::Result<()> {
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
