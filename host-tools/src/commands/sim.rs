//! `axcomp sim`: simulate a linear axis (the digital twin, crate `axcomp-twin`) and write the
//! contract's measurement CSV.
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
}

/// A standard twin plan, or a spindle campaign from the thermal generator (held at mid-stroke).
enum PlanChoice {
    Standard(Plan),
    Spindle(axcomp_thermal::synth::SynthConfig),
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
