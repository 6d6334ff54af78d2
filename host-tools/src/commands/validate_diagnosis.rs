//! `axcomp validate-diagnosis`: many twin campaigns, each withholding one effect (or none) from the model
//! at several SNRs, diagnosed blind; prints detection, top-1 attribution, false alarms, localisation,
//! parameter recovery, shrink relative to the oracle and the confusion matrix (progress on stderr).
//!
//! Terms: *SNR* = held-out peak of the withheld effect, or of its part the told model cannot absorb when
//! that is smaller, / noise σ; *oracle* = the model refitted
//! with the true withheld contribution. Every case is measured with the same plan, the twin's survey
//! (`axcomp_twin::SurveyPlan`: a campaign on which any single effect could show), so the plan never
//! tells which effect was withheld.

use std::path::PathBuf;

use axcomp_validation::axis::{self as validate, Profile, ValidateOptions};

use crate::output::OutputSet;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Which data the cases are: `axis` (single-axis campaigns, the `--harness` generators) or `lines`
    /// (laser lines of the three-axis twin: one of abbe_angular, squareness, straightness, cross_coupling,
    /// thermal_drift, time_drift withheld, or none; `axcomp_validation::lines`).
    #[arg(long, value_name = "KIND", default_value = "axis")]
    pub data_kind: String,
    /// Case generator: `standard` (5,000 rows, SNR 3–8, held out: every third run) or `hard` (1,500 rows,
    /// 3 ISO cycles, SNR 2–8, held out outside the training regime: last cycles, fastest scan, largest
    /// loads, the re-heat's thermal rounds).
    #[arg(long, value_name = "NAME", default_value = "standard")]
    pub harness: String,
    /// Number of simulated cases (every 4th is a null case: nothing withheld).
    #[arg(long, default_value_t = 100)]
    pub cases: usize,
    /// Seed of the case generator.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// SNRs to cycle through (held-out peak of the withheld effect, or of its part the model cannot absorb
    /// when smaller, / noise σ) [default: 3,4,6,8;
    /// hard: 2,4,6,8].
    #[arg(long, value_delimiter = ',')]
    pub snr: Option<Vec<f64>>,
    /// Rows per simulated campaign [default: 5000; hard: 1500].
    #[arg(long)]
    pub rows: Option<usize>,
    /// Measurement noise σ of the simulated deviation (µm).
    #[arg(long, default_value_t = 0.5)]
    pub noise_um: f64,
    /// Write the summary and every case here (JSON).
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Write the Markdown tables here.
    #[arg(long, value_name = "FILE")]
    pub markdown: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    match args.data_kind.as_str() {
        "axis" => {}
        "lines" => return run_lines(args),
        other => anyhow::bail!("--data-kind {other}: use axis or lines"),
    }
    let profile = Profile::parse(&args.harness).map_err(|e| anyhow::anyhow!("--harness: {e}"))?;
    let opts = ValidateOptions {
        profile,
        cases: args.cases,
        seed: args.seed,
        snrs: args.snr.clone().unwrap_or_else(|| profile.default_snrs()),
        rows: args.rows.unwrap_or_else(|| profile.default_rows()),
        noise_um: args.noise_um,
        ..ValidateOptions::default()
    }
    .build()
    .map_err(anyhow::Error::msg)?;
    // Both outputs are planned and checked before the (long) validation run.
    let mut outputs = OutputSet::new();
    if let Some(p) = &args.markdown {
        outputs.planned(p);
    }
    if let Some(p) = &args.json {
        outputs.planned(p);
    }
    outputs.check()?;
    let total = opts.cases;
    let summary = validate::validate(&opts, |c| {
        eprintln!(
            "[{}/{}] {} withheld {} snr {} → verdict {} ({}), shrink {:.1} % (oracle {}), {:.2} s",
            c.index + 1,
            total,
            c.plan,
            c.withheld,
            c.snr.map_or("–".to_string(), |s| s.to_string()),
            c.verdict,
            if c.correct { "right" } else { "wrong" },
            c.shrink_pct,
            c.oracle_shrink_pct
                .map_or("–".to_string(), |o| format!("{o:.1} %")),
            c.seconds
        );
    })
    .map_err(anyhow::Error::msg)?;
    let md = summary.to_markdown();
    print!("{md}");
    // The report and the JSON are committed together (both or neither).
    if let Some(p) = &args.markdown {
        outputs.file(p, md.as_bytes());
    }
    if let Some(p) = &args.json {
        outputs.json(p, &summary)?;
    }
    outputs.commit()?;
    Ok(())
}

/// `--data-kind lines`: the laser-line harness on the three-axis twin.
fn run_lines(args: Args) -> anyhow::Result<()> {
    use axcomp_validation::lines::{LineValidateOptions, validate_lines};
    if args.harness != "standard" || args.rows.is_some() {
        anyhow::bail!(
            "--harness and --rows belong to --data-kind axis (the line harness measures the twin's complete plan)"
        );
    }
    let defaults = LineValidateOptions::default();
    let opts = LineValidateOptions {
        cases: args.cases,
        seed: args.seed,
        snrs: args.snr.clone().unwrap_or(defaults.snrs.clone()),
        noise_um: args.noise_um,
        ..defaults
    }
    .build()
    .map_err(anyhow::Error::msg)?;
    let mut outputs = OutputSet::new();
    if let Some(p) = &args.markdown {
        outputs.planned(p);
    }
    if let Some(p) = &args.json {
        outputs.planned(p);
    }
    outputs.check()?;
    let total = opts.cases;
    let summary = validate_lines(&opts, |c| {
        eprintln!(
            "[{}/{}] withheld {} ({}) snr {} held out {} → verdict {} ({}), shrink {:.1} % (oracle {}), {:.2} s",
            c.index + 1,
            total,
            c.withheld,
            c.detail,
            c.snr.map_or("–".to_string(), |s| s.to_string()),
            c.holdout_lines.join(","),
            c.verdict,
            if c.correct { "right" } else { "wrong" },
            c.shrink_pct,
            c.oracle_shrink_pct
                .map_or("–".to_string(), |o| format!("{o:.1} %")),
            c.seconds
        );
    })
    .map_err(anyhow::Error::msg)?;
    let md = summary.to_markdown();
    print!("{md}");
    if let Some(p) = &args.markdown {
        outputs.file(p, md.as_bytes());
    }
    if let Some(p) = &args.json {
        outputs.json(p, &summary)?;
    }
    outputs.commit()?;
    Ok(())
}
