//! `axcomp sim-probe`: touches of the twin's probe (`axcomp_twin::probe`) on reference artefacts as a touch
//! CSV (the five-axis probing campaign is `axcomp sim --machine KIND --plan probe-rtest`).

use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::bail;

use crate::output::OutputSet;

/// Arguments of `axcomp sim-probe`.
#[derive(Debug, clap::Args)]
pub struct SimArgs {
    /// `probe-cal` (Ø25 mm sphere, rings at 0/22.5/45/67.5/90°, 24 azimuths, 100/300/600 mm/min, 2 runs) or
    /// `probe-measure` (a Ø19.05 mm sphere, a Ø50 mm ring gauge and a plane at --feed).
    #[arg(long, value_name = "PLAN")]
    pub plan: String,
    /// Output touch CSV.
    #[arg(long, value_name = "F.csv")]
    pub out: PathBuf,
    /// Probing speed of `probe-measure`, mm/min.
    #[arg(long, default_value_t = 450.0, value_name = "F")]
    pub feed: f64,
    /// Repeats of the plan.
    #[arg(long, value_name = "N")]
    pub repeats: Option<u32>,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// No bounce and no false triggers.
    #[arg(long)]
    pub no_glitches: bool,
    /// Per-row truth (surface point, normal, pretravel, kind) as CSV.
    #[arg(long, value_name = "F.csv")]
    pub truth: Option<PathBuf>,
}

/// Runs `axcomp sim-probe`.
pub fn sim_probe(args: SimArgs) -> anyhow::Result<()> {
    use axcomp_twin::probe::{ProbeModel, ProbePlan, TouchKind, simulate_touches, touches_csv};
    /// Most repeats of a plan (the calibration plan's 584 touches × 1000; more once aborted the process
    /// when memory ran out instead of saying so).
    const MAX_REPEATS: u32 = 1000;
    if args.repeats.is_some_and(|r| r > MAX_REPEATS) {
        bail!(
            "--repeats {}: at most {MAX_REPEATS} repeats of the plan",
            args.repeats.unwrap_or_default()
        );
    }
    crate::commands::common::check_range("--feed", args.feed, 1e-3, 1e5)?;
    let plan = match args.plan.as_str() {
        "probe-cal" | "cal" => {
            let mut p = ProbePlan::standard_calibration();
            if let Some(r) = args.repeats {
                p = ProbePlan::calibration(
                    [100.0, 50.0, 20.0],
                    25.0,
                    &[0.0, 22.5, 45.0, 67.5, 90.0],
                    24,
                    &[100.0, 300.0, 600.0],
                    r,
                );
            }
            p
        }
        "probe-measure" | "measure" => {
            if !(args.feed.is_finite() && args.feed > 0.0) {
                bail!("--feed {}: must be > 0", args.feed);
            }
            ProbePlan::measurement(args.feed, args.repeats.unwrap_or(1))
        }
        other => bail!("--plan `{other}`: expected probe-cal or probe-measure"),
    };
    if args.repeats == Some(0) {
        bail!("--repeats must be ≥ 1");
    }
    let mut probe = ProbeModel::kinematic_demo();
    if args.no_glitches {
        probe = probe.without_glitches();
    }
    let t = simulate_touches(&probe, &plan, args.seed);
    let csv = touches_csv(&t);
    let truth = args.truth.as_ref().map(|_| {
        let mut s = String::from(
            "surface_x_mm,surface_y_mm,surface_z_mm,normal_x,normal_y,normal_z,pretravel_um,kind\n",
        );
        for x in &t {
            let kind = match x.kind {
                TouchKind::Good => "good",
                TouchKind::Bounce => "bounce",
                TouchKind::FalseTrigger => "false_trigger",
            };
            let _ = writeln!(
                s,
                "{:.7},{:.7},{:.7},{:.9},{:.9},{:.9},{:.4},{kind}",
                x.surface_mm[0],
                x.surface_mm[1],
                x.surface_mm[2],
                x.normal[0],
                x.normal[1],
                x.normal[2],
                x.pretravel_um
            );
        }
        s
    });
    let mut outputs = OutputSet::new();
    if let (Some(p), Some(text)) = (&args.truth, &truth) {
        outputs.file(p, text.as_bytes());
    }
    outputs.file(&args.out, csv);
    outputs.commit()?;
    println!(
        "sim-probe: {} touches ({} bounce / false-trigger rows) → {}",
        t.len(),
        t.iter().filter(|x| x.kind != TouchKind::Good).count(),
        args.out.display()
    );
    Ok(())
}
