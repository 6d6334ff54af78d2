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
    /// (laser lines of the three-axis twin, also `--harness lines`: one of abbe_angular, squareness, straightness, cross_coupling,
    /// thermal_drift, time_drift withheld, or none; `axcomp_validation::lines`).
    #[arg(long, value_name = "KIND", default_value = "axis")]
    pub data_kind: String,
    /// Case generator: `rtest` (five-axis twin, R-test data; see `axcomp_validation::rtest`),
    /// `standard` (5,000 rows, SNR 3–8, held out: every third run) or `hard` (1,500 rows,
    /// 3 ISO cycles, SNR 2–8, held out outside the training regime: last cycles, fastest scan, largest
    /// loads, the re-heat's thermal rounds), or `probe` (touch-probe twin: calibration sphere, plane, ring
    /// gauge and ball plate for training, a second sphere held out; `--rows` is not used) or `probe-hard`
    /// (the same with lobes and latency in the probe and the model, and withheld forms outside the
    /// candidates' columns).
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
    if args.harness == "lines" {
        return run_lines(args);
    }
    if args.harness == "rtest" {
        return run_rtest(&args);
    }
    if args.harness == "probe" || args.harness == "probe-hard" {
        return run_probe(args);
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
    let outputs = planned_outputs(&args)?;
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
    // The report and the JSON are committed together (both or neither).
    write_summary(&args, outputs, &summary.to_markdown(), &summary)?;
    Ok(())
}

/// `--harness rtest`: the five-axis twin's R-test campaigns (`axcomp_validation::rtest`); `--rows` does not
/// apply (the plan is fixed: 324 poses).
fn run_rtest(args: &Args) -> anyhow::Result<()> {
    use axcomp_validation::rtest::{RtestValidateOptions, validate};
    if args.rows.is_some() {
        anyhow::bail!("--rows does not apply to --harness rtest (its plan is fixed: 324 poses)");
    }
    let opts = RtestValidateOptions {
        cases: args.cases,
        seed: args.seed,
        snrs: args
            .snr
            .clone()
            .unwrap_or_else(|| RtestValidateOptions::default().snrs),
        noise_um: args.noise_um,
        ..RtestValidateOptions::default()
    }
    .build()
    .map_err(anyhow::Error::msg)?;
    let outputs = planned_outputs(args)?;
    let total = opts.cases;
    let summary = validate(&opts, |c| {
        eprintln!(
            "[{}/{}] {} withheld {} snr {} → verdict {} ({}{}), shrink {:.1} % (oracle {}), {:.2} s",
            c.index + 1,
            total,
            c.machine,
            c.withheld,
            c.snr.map_or("–".to_string(), |s| s.to_string()),
            c.verdict,
            if c.correct { "right" } else { "wrong" },
            if c.ties.is_empty() {
                String::new()
            } else {
                format!("; ties {}", c.ties.join(", "))
            },
            c.shrink_pct,
            c.oracle_shrink_pct
                .map_or("–".to_string(), |o| format!("{o:.1} %")),
            c.seconds
        );
    })
    .map_err(anyhow::Error::msg)?;
    write_summary(args, outputs, &summary.to_markdown(), &summary)?;
    Ok(())
}

/// `--harness probe`: withheld-effect validation on touch-probe twin campaigns (`axcomp_validation::probe`).
fn run_probe(args: Args) -> anyhow::Result<()> {
    use axcomp_validation::probe::{self as vprobe, ProbeValidateOptions};
    let opts = ProbeValidateOptions {
        cases: args.cases,
        seed: args.seed,
        snrs: args
            .snr
            .clone()
            .unwrap_or_else(|| ProbeValidateOptions::default().snrs),
        noise_um: args.noise_um,
        hard: args.harness == "probe-hard",
        ..ProbeValidateOptions::default()
    }
    .build()
    .map_err(anyhow::Error::msg)?;
    let outputs = planned_outputs(&args)?;
    let total = opts.cases;
    let summary = vprobe::validate(&opts, |c| {
        eprintln!(
            "[{}/{}] probe withheld {} snr {} → verdict {} ({}), shrink {:.1} % (oracle {}), {:.2} s",
            c.index + 1,
            total,
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
    write_summary(&args, outputs, &summary.to_markdown(), &summary)?;
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
    let outputs = planned_outputs(&args)?;
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
    write_summary(&args, outputs, &summary.to_markdown(), &summary)?;
    Ok(())
}

/// The outputs `--markdown` and `--json` name, checked before the cases run.
fn planned_outputs(args: &Args) -> anyhow::Result<OutputSet> {
    let mut outputs = OutputSet::new();
    for p in [&args.markdown, &args.json].into_iter().flatten() {
        outputs.planned(p);
    }
    outputs.check()?;
    Ok(outputs)
}

/// Prints the Markdown tables and writes them and the JSON summary (all or nothing).
fn write_summary<S: serde::Serialize>(
    args: &Args,
    mut outputs: OutputSet,
    md: &str,
    summary: &S,
) -> anyhow::Result<()> {
    print!("{md}");
    if let Some(p) = &args.markdown {
        outputs.file(p, md.as_bytes());
    }
    if let Some(p) = &args.json {
        outputs.json(p, summary)?;
    }
    outputs.commit()?;
    Ok(())
}
