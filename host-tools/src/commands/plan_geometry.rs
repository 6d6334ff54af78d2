//! `axcomp plan geometry`: the laser lines (and reflector offsets) that make all 21 components
//! identifiable with the fewest lines (greedy D-optimal, see `axcomp_geometry::plan`), with the predicted
//! standard uncertainty of each component for noise σ. `--simulate F.csv` measures the plan (or a named
//! twin plan) on the three-axis twin and writes the contract's laser line CSV.

use std::path::PathBuf;

use anyhow::{Context, bail};
use axcomp_geometry::LineData;
use axcomp_geometry::plan::{FurtherLine, Plan, PlanOptions, plan_after};
use axcomp_kinematics::Topology;
use axcomp_kinematics::lines::LineSpec;
use axcomp_twin::geometry::{GeometryTwin, plan_by_name};

use crate::commands::common::{check_count, check_range};
use crate::output::OutputSet;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Strokes of X, Y, Z (mm).
    #[arg(long, value_name = "X,Y,Z")]
    pub stroke: String,
    /// Choose exactly N lines (default: as few as make all 21 identifiable).
    #[arg(long, value_name = "N")]
    pub lines: Option<usize>,
    /// Reflector offsets to consider, `X,Y,Z` mm (repeatable, or `;`-separated). Default: 0 and 150 mm along each axis.
    #[arg(long = "tool-offsets", value_name = "X,Y,Z")]
    pub tool_offsets: Vec<String>,
    /// Reading noise σ (µm) for the predicted uncertainties.
    #[arg(
        long,
        default_value_t = 1.0,
        value_name = "S",
        allow_negative_numbers = true
    )]
    pub sigma_um: f64,
    /// Targets per line (4 ..= 200).
    #[arg(long, default_value_t = 11, value_name = "N")]
    pub targets: usize,
    #[arg(long, default_value = "YX", value_name = "AXES")]
    pub work_axes: String,
    #[arg(long, default_value = "Z", value_name = "AXES")]
    pub tool_axes: String,
    /// Lines already measured (the laser line CSV): the plan adds to them, and the further lines listed
    /// are those that lower their identifiable floor.
    #[arg(long, value_name = "F.csv")]
    pub measured: Option<PathBuf>,
    /// Machine-readable plan.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
    /// Measure the lines on the three-axis twin and write the laser line CSV.
    #[arg(long, value_name = "F.csv")]
    pub simulate: Option<PathBuf>,
    /// With --simulate: measure a named twin plan instead (seven-line, step-diagonal, axis-lines,
    /// face-diagonals, tool-offsets, complete, point-cloud: points read along their own beams from four
    /// stations, as a tracking interferometer measures), plus the planned lines when both are wanted (`+plan`).
    #[arg(long, value_name = "NAME", requires = "simulate")]
    pub twin_plan: Option<String>,
    /// Twin seed (with --simulate).
    #[arg(long, default_value_t = 1, requires = "simulate")]
    pub seed: u64,
    /// Twin measurement runs (with --simulate).
    #[arg(long, default_value_t = 2, requires = "simulate")]
    pub runs: usize,
    /// Twin drift (µm/h along X, Y, Z; with --simulate).
    #[arg(
        long,
        default_value = "0,0,0",
        value_name = "X,Y,Z",
        requires = "simulate",
        allow_hyphen_values = true
    )]
    pub drift_um_per_h: String,
}

/// Most runs `--runs` takes (each run repeats every line; a billion ran out of memory).
const MAX_RUNS: usize = 1000;

/// Most targets per line `--targets` takes.
const MAX_TARGETS: usize = 200;

fn triple(s: &str, what: &str) -> anyhow::Result<[f64; 3]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("{what} {s}: expected three numbers X,Y,Z"))?;
    if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
        bail!("{what} {s}: expected three finite numbers X,Y,Z");
    }
    Ok([v[0], v[1], v[2]])
}

/// The further lines that lower the identifiable floor, one a line.
fn print_further(further: &[FurtherLine], measured: bool) {
    println!(
        "further lines that would lower the identifiable floor of the {} lines (rank they add: what the lines cannot separate that they reach; then information gain):",
        if measured {
            "measured and chosen"
        } else {
            "chosen"
        }
    );
    for f in further {
        let l = &f.line;
        println!(
            "  {}, {:?} → {:?}, step-wise {}, reflector offset {:?}: rank +{}{}, information gain {:.2}",
            l.name,
            l.start,
            l.end,
            l.stepwise,
            l.tool,
            f.rank_gain,
            if f.reaches.is_empty() {
                String::new()
            } else {
                format!(" (reaches {})", f.reaches.join(", "))
            },
            f.information_gain
        );
    }
}

fn further_json(f: &FurtherLine) -> serde_json::Value {
    let l = &f.line;
    serde_json::json!({
        "name": l.name, "start_mm": l.start, "end_mm": l.end, "targets": l.targets,
        "stepwise": l.stepwise, "tool_mm": l.tool, "rank_gain": f.rank_gain,
        "reaches": f.reaches, "information_gain": f.information_gain,
    })
}

pub fn run(a: Args) -> anyhow::Result<()> {
    // Every output path is checked before the plan; both files are written together at the end.
    let mut outputs = OutputSet::new();
    for p in [&a.json, &a.simulate].into_iter().flatten() {
        outputs.planned(p);
    }
    outputs.check()?;
    let stroke = triple(&a.stroke, "--stroke")?;
    for s in stroke {
        // 100 m: no machine axis is longer.
        check_range("--stroke", s, 1e-3, 1e5)?;
    }
    let topology = Topology::parse(&a.work_axes, &a.tool_axes)?;
    let offsets = tool_offsets(&a.tool_offsets)?;
    check_limits(&a)?;
    let drift = triple(&a.drift_um_per_h, "--drift-um-per-h")?;
    // A named twin plan is checked before anything is printed.
    let twin_lines = twin_plan(&a, stroke)?;
    let measured = match &a.measured {
        None => None,
        Some(path) => {
            let ds = axcomp_data::Dataset::load(path, &axcomp_data::LoadOptions::default())?;
            Some(LineData::from_dataset(&ds, false)?)
        }
    };
    let p = plan_after(
        &PlanOptions {
            stroke_mm: stroke,
            max_lines: a.lines,
            tool_offsets: offsets,
            sigma_um: a.sigma_um,
            targets: a.targets,
            topology: topology.clone(),
        },
        measured.as_ref(),
    )?;
    print_plan(&p, a.sigma_um, measured.is_some());
    if let Some(path) = &a.json {
        outputs.json(path, &plan_json(&p, a.sigma_um))?;
    }
    let mut simulated = None;
    if let Some(path) = &a.simulate {
        let mut twin = GeometryTwin::random(stroke, topology, a.seed);
        twin.noise_um = a.sigma_um;
        twin.drift_um_per_h = drift;
        let lines = match twin_lines {
            None => p.lines.clone(),
            Some((mut v, with_plan)) => {
                if with_plan {
                    v.extend(p.lines.iter().cloned());
                }
                v
            }
        };
        let camp = twin.measure(&lines, a.runs, a.seed.wrapping_add(1000));
        outputs.file(path, camp.to_csv_string());
        simulated = Some(format!(
            "simulated {} readings of {} lines into {}",
            camp.rows.len(),
            lines.len(),
            path.display()
        ));
    }
    outputs.commit()?;
    if let Some(line) = simulated {
        println!("{line}");
    }
    Ok(())
}

/// Reflector offsets from `--tool-offsets` (default: 0 and 150 mm along each axis).
fn tool_offsets(args: &[String]) -> anyhow::Result<Vec<[f64; 3]>> {
    let mut offsets = Vec::new();
    for s in args {
        for part in s.split(';').filter(|p| !p.trim().is_empty()) {
            offsets.push(triple(part, "--tool-offsets")?);
        }
    }
    if offsets.is_empty() {
        offsets = vec![
            [0.0; 3],
            [150.0, 0.0, 0.0],
            [0.0, 150.0, 0.0],
            [0.0, 0.0, 150.0],
        ];
    }
    Ok(offsets)
}

/// The noise, line, target and run options' limits.
fn check_limits(a: &Args) -> anyhow::Result<()> {
    if !a.sigma_um.is_finite() || a.sigma_um <= 0.0 {
        bail!("--sigma-um {}: must be positive", a.sigma_um);
    }
    if a.lines == Some(0) {
        bail!(
            "--lines 0: ask for at least one line (or leave --lines out for the fewest that identify all 21)"
        );
    }
    if a.targets > MAX_TARGETS {
        // The plan's cost grows with the cube of the readings: 200 targets take seconds, 1000 took 6 minutes.
        bail!(
            "--targets {}: at most {MAX_TARGETS} targets per line",
            a.targets
        );
    }
    if a.simulate.is_some() && a.runs == 0 {
        bail!("--runs 0: ask for at least one run");
    }
    check_count("--runs", a.runs, 0, MAX_RUNS)?;
    Ok(())
}

/// `--twin-plan NAME[+plan]`: the named plan's lines and whether the computed plan is added to them.
fn twin_plan(a: &Args, stroke: [f64; 3]) -> anyhow::Result<Option<(Vec<LineSpec>, bool)>> {
    let twin_lines = match a.twin_plan.as_deref() {
        None => None,
        Some(name) => {
            let (name, with_plan) = match name.strip_suffix("+plan") {
                Some(n) => (n, true),
                None => (name, false),
            };
            let v = plan_by_name(name, stroke, a.targets)
                .with_context(|| format!("--twin-plan {name}: unknown plan"))?;
            Some((v, with_plan))
        }
    };
    Ok(twin_lines)
}

/// The plan on stdout: lines, predicted uncertainties and further lines.
fn print_plan(p: &Plan, sigma_um: f64, measured: bool) {
    println!(
        "{} lines chosen from {} candidates; all 21 identifiable: {}",
        p.lines.len(),
        p.candidates,
        if p.complete { "yes" } else { "no" }
    );
    if !p.complete {
        println!(
            "not identifiable with these lines: {}",
            p.not_identifiable.join(", ")
        );
    }
    println!("line, from (mm), to (mm), step-wise, reflector offset (mm)");
    for l in &p.lines {
        println!(
            "{}, {:?}, {:?}, {}, {:?}",
            l.name, l.start, l.end, l.stepwise, l.tool
        );
    }
    println!(
        "predicted standard uncertainty (largest over the axis) for σ = {} µm:",
        sigma_um
    );
    for (name, unit, u) in &p.uncertainty {
        if u.is_finite() {
            println!("  {name:5} {u:8.3} {unit}");
        } else {
            println!("  {name:5} not identifiable");
        }
    }
    print_further(&p.further, measured);
}

/// The plan as `--json` writes it.
fn plan_json(p: &Plan, sigma_um: f64) -> serde_json::Value {
    serde_json::json!({
        "further_lines": p.further.iter().map(further_json).collect::<Vec<_>>(),
        "complete": p.complete,
        "not_identifiable": p.not_identifiable,
        "candidates": p.candidates,
        "sigma_um": sigma_um,
        "lines": p.lines.iter().map(|l| serde_json::json!({
            "name": l.name, "start_mm": l.start, "end_mm": l.end, "targets": l.targets,
            "stepwise": l.stepwise, "tool_mm": l.tool })).collect::<Vec<_>>(),
        "uncertainty": p.uncertainty.iter().map(|(n, u, v)| serde_json::json!({
            "component": n, "unit": u, "max_u": if v.is_finite() { serde_json::json!(v) } else { serde_json::Value::Null } })).collect::<Vec<_>>(),
    })
}
