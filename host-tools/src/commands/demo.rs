//! `axcomp demo`: the whole loop on a simulated axis, in seconds, with no input files.
//!
//! Glossary:
//! - *twin*: the simulated axis (`axcomp_twin::Axis::linear_motor_demo`: 200 mm linear-motor axis with
//!   pitch error, reversal, cogging, interpolation error and a little scale expansion; noise σ 0.5 µm).
//! - *campaign*: an ISO 230-2 test on the twin (21 targets × 5 bidirectional runs).
//! - *before*: the uncompensated campaign; the table is fitted on it.
//! - *after*: a second campaign, with its own noise (seed + 1), driven through the firmware's compensator
//!   (`axcomp_core::Compensator::cycle`, loaded from the built image) — the table is judged on data it did
//!   not see.
//! - *ideal*: a third campaign compensated with the table built from the twin's known truth
//!   (`axcomp_twin::IdealTable`): the floor any fitted table could reach (noise, count rounding, errors
//!   finer than the knots).
//!
//! Steps: simulate → write `measurement.csv` → read it back with `axcomp-data` → ISO 230-2 → fit
//! (`axcomp_positioning::fit`, cross-validated, do-no-harm guard) → `table.json` → firmware image
//! `image.bin` → compensated campaign → ISO 230-2 after → console, `report.md`, `demo.json`, SVG plots.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use axcomp_core::trace::{OutputRecord, Record, Writer};
use axcomp_core::{Compensator, CycleInput, Engine, ImageSpec, image_len, write_image};
use axcomp_data::{Dataset, LoadOptions};
use axcomp_plot::{Figure, markdown_table};
use axcomp_positioning::fit::{FitOptions, FitResult, fit};
use axcomp_positioning::iso230::{self, Iso230Result};
use axcomp_twin::{Axis, Campaign, IdealTable, Iso230Plan, Plan, simulate};
use serde_json::json;

use crate::output::OutputSet;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Directory for the report, plots, measurement CSVs, table and image (written whole) [default:
    /// axcomp-demo, with --all axcomp-demo-all].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Seed of the simulated measurement noise (the compensated campaign uses seed + 1).
    #[arg(long, default_value_t = 2)]
    pub seed: u64,
    /// Every system's chain on the twin (positioning, thermo-force, three-axis geometry, five-axis
    /// rotary, touch probe): measure → fit → image → the firmware library applies it → before/after on
    /// data the fit never saw; one row per system.
    #[arg(long)]
    pub all: bool,
}

/// One evaluated campaign.
struct Evaluated {
    campaign: Campaign,
    data: Dataset,
    iso: Iso230Result,
    rms_um: f64,
}

fn evaluate(name: &str, campaign: Campaign) -> anyhow::Result<Evaluated> {
    let csv = campaign.to_csv_string();
    // Through the same reader the CLI uses for user files.
    let data = Dataset::from_csv_str(name, &csv, &LoadOptions::default())?;
    let points = iso230::points_from_dataset(&data, "deviation_um")?;
    let iso =
        iso230::evaluate(&points).with_context(|| format!("ISO 230-2 evaluation of {name}"))?;
    let dev = data.numeric("deviation_um")?;
    let rms_um = (dev.iter().map(|d| d * d).sum::<f64>() / dev.len() as f64).sqrt();
    Ok(Evaluated {
        campaign,
        data,
        iso,
        rms_um,
    })
}

fn image_bytes(spec: &ImageSpec) -> anyhow::Result<Vec<u8>> {
    let mut buf = vec![0u8; image_len(spec)];
    let n = write_image(spec, &mut buf)?;
    buf.truncate(n);
    Ok(buf)
}

/// The files the demo writes into `--out` (all together or none, see [`OutputSet`]).
const FILES: [&str; 11] = [
    "measurement.csv",
    "table.json",
    "image.bin",
    "measurement_compensated.csv",
    "trace.bin",
    "replay.bin",
    "deviation_before.svg",
    "deviation_after.svg",
    "iso230_before_after.svg",
    "demo.json",
    "report.md",
];

/// Output files, collected while the demo runs and written only once everything has been computed.
struct Outputs {
    dir: PathBuf,
    set: OutputSet,
}

impl Outputs {
    /// Declares `dir` and every file, and checks the paths before any work.
    fn new(dir: &Path) -> anyhow::Result<Self> {
        let mut set = OutputSet::new();
        set.folder(dir, "--out");
        for name in FILES {
            set.planned_in(dir, name);
        }
        set.check()?;
        Ok(Outputs {
            dir: dir.to_path_buf(),
            set,
        })
    }
    fn add(&mut self, name: &'static str, bytes: impl Into<Vec<u8>>) {
        debug_assert!(FILES.contains(&name), "{name} not in FILES");
        self.set.folder_file(&self.dir, name, bytes);
    }
    fn write_all(self) -> anyhow::Result<()> {
        self.set.commit()?;
        Ok(())
    }
}

/// Per direction: (targets, means, −2s, +2s) of an ISO evaluation.
fn per_direction(iso: &Iso230Result, direction: i8) -> [Vec<f64>; 4] {
    let t = &iso.targets;
    let (m, s): (Vec<f64>, Vec<f64>) = t
        .iter()
        .map(|f| {
            if direction > 0 {
                (f.mean_up_um, f.s_up_um)
            } else {
                (f.mean_down_um, f.s_down_um)
            }
        })
        .unzip();
    [
        t.iter().map(|f| f.target_mm).collect(),
        m.clone(),
        m.iter().zip(&s).map(|(m, s)| m - 2.0 * s).collect(),
        m.iter().zip(&s).map(|(m, s)| m + 2.0 * s).collect(),
    ]
}

fn split_by_direction(ds: &Dataset) -> anyhow::Result<[(Vec<f64>, Vec<f64>); 2]> {
    let x = ds.numeric("target_mm")?;
    let d = ds.numeric("deviation_um")?;
    let dir = ds.direction()?.context("no direction column")?;
    let mut out = [(Vec::new(), Vec::new()), (Vec::new(), Vec::new())];
    for i in 0..x.len() {
        let k = usize::from(dir[i] < 0);
        out[k].0.push(x[i]);
        out[k].1.push(d[i]);
    }
    Ok(out)
}

fn figures_row(name: &str, e: &Evaluated) -> Vec<String> {
    let i = &e.iso;
    vec![
        name.to_string(),
        format!("{:.2}", i.a_um),
        format!("{:.2}", i.e_um),
        format!("{:.2}", i.m_um),
        format!("{:.2}", i.r_um),
        format!("{:.2}", i.b_um),
        format!("{:.2}", e.rms_um),
    ]
}

/// Cycles per straight leg of an approach path in the recorded trace.
const LEG_CYCLES: i64 = 16;
/// Cycles at a target: at least this many, then until the corrected command is steady.
const MIN_DWELL_CYCLES: usize = 4;
const MAX_DWELL_CYCLES: usize = 2_000;

/// The compensated campaign's moves as the firmware would log them: a closed loop of the core's
/// [`Engine`] (image record first) with an ideal servo (the scale reads the previous corrected command),
/// each row approached over `overshoot_mm` from its direction. Returns the trace bytes, the outputs and
/// the index of the output at which each row was read.
fn closed_loop_trace(
    axis: &Axis,
    image: &[u8],
    campaign: &Campaign,
    overshoot_mm: f64,
) -> anyhow::Result<(Vec<u8>, Vec<OutputRecord>, Vec<usize>)> {
    let mut buf = vec![0u8; 64 + image.len() + campaign.rows.len() * 256 * 40];
    let mut w = Writer::new(&mut buf).map_err(|e| anyhow::anyhow!("trace: {e}"))?;
    let mut engine = Box::new(Engine::new());
    let mut outputs = Vec::new();
    let mut read_at = Vec::with_capacity(campaign.rows.len());
    fn push(
        w: &mut Writer<'_>,
        engine: &mut Engine,
        rec: Record<'_>,
    ) -> anyhow::Result<Option<OutputRecord>> {
        w.push(&rec).map_err(|e| anyhow::anyhow!("trace: {e}"))?;
        Ok(engine.step(&rec))
    }
    push(&mut w, &mut engine, Record::Image(image))?;
    let start = axis.counts(axis.start_mm - overshoot_mm);
    push(
        &mut w,
        &mut engine,
        Record::Reset {
            scale_raw: start as u32,
        },
    )?;
    let mut scale = start;
    let mut here = start;
    for row in &campaign.rows {
        let target = axis.counts(row.target_mm);
        let approach = axis.counts(row.target_mm - row.direction as f64 * overshoot_mm);
        let mut path = Vec::new();
        for (from, to) in [(here, approach), (approach, target)] {
            path.extend((1..=LEG_CYCLES).map(|k| from + (to - from) * k / LEG_CYCLES));
        }
        let mut steady = 0usize;
        let mut dwell = 0usize;
        let mut k = 0usize;
        loop {
            let command = path.get(k).copied().unwrap_or(target);
            k += 1;
            let input = CycleInput {
                scale_raw: scale as u32,
                command_counts: command,
                forces_n: [0.0; 3],
            };
            let out = push(&mut w, &mut engine, Record::Cycle(input))?
                .context("a cycle record gives an output")?;
            let moved = out.corrected_command_counts != scale;
            scale = out.corrected_command_counts;
            outputs.push(out);
            if k > path.len() {
                dwell += 1;
                steady = if moved { 0 } else { steady + 1 };
                if (dwell >= MIN_DWELL_CYCLES && steady >= 2) || dwell >= MAX_DWELL_CYCLES {
                    break;
                }
            }
        }
        read_at.push(outputs.len() - 1);
        here = target;
    }
    push(&mut w, &mut engine, Record::End)?;
    let n = w.finish();
    buf.truncate(n);
    Ok((buf, outputs, read_at))
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let out = &args
        .out
        .clone()
        .unwrap_or_else(|| PathBuf::from("axcomp-demo"));
    let mut files = Outputs::new(out)?;

    // 1. The twin and its ISO 230-2 campaign.
    let axis = Axis::linear_motor_demo();
    let plan = Plan::from(Iso230Plan::standard(axis.start_mm, axis.end_mm));
    let measured = simulate(&axis, &plan, None, args.seed).context("simulating the campaign")?;
    let (before, provenance) = record_measurement(measured, args.seed, &mut files)?;
    let t_sim = t0.elapsed();

    // 2. Fit (cross-validated, guarded).
    let (fitted, table_json) = fit_table(&before, provenance, &mut files)?;
    let t_fit = t0.elapsed();

    // 3. Firmware image (the core's `write_image`, as `axcomp image build`), loaded as the firmware would.
    let (image, comp) = build_image(&axis, &fitted, &table_json, &mut files)?;
    let image_text = axcomp_image::describe(&image)?;

    // 4. Compensated campaign (new noise), and the ideal floor.
    let (after, ideal) =
        compensated_campaigns(&axis, &plan, &comp, &fitted, args.seed, &mut files)?;
    let t_comp = t0.elapsed();

    // 5. The same moves as a recorded firmware trace, replayed through the core's engine from the file
    //    bytes (what `axcomp replay` and the QEMU firmware do).
    let replay = replay_moves(&axis, &image, &after, &mut files)?;

    // 6. Plots.
    plots(&axis, &before, &after, &fitted, &mut files)?;
    let t_plot = t0.elapsed();

    // 7. Figures: console, JSON, report.
    let demo = Demo {
        seed: args.seed,
        axis: &axis,
        before: &before,
        after: &after,
        ideal: &ideal,
        fitted: &fitted,
        image: &image,
        replay: &replay,
    };
    let headers = ["campaign", "A µm", "E µm", "M µm", "R µm", "B µm", "RMS µm"];
    let rows = vec![
        figures_row("before (uncompensated)", &before),
        figures_row("after (fitted table)", &after),
        figures_row("ideal table (truth)", &ideal),
    ];
    let mut console = demo.console(&rows);
    let _ = writeln!(
        console,
        "time: simulate {:.2} s, fit {:.2} s, image + compensated campaigns {:.2} s, plots {:.2} s",
        t_sim.as_secs_f64(),
        (t_fit - t_sim).as_secs_f64(),
        (t_comp - t_fit).as_secs_f64(),
        (t_plot - t_comp).as_secs_f64()
    );
    let _ = writeln!(
        console,
        "wrote {}/{{report.md, demo.json, *.svg, *.csv, table.json, image.bin, trace.bin, replay.bin}}",
        out.display()
    );
    files.add(
        "demo.json",
        serde_json::to_string_pretty(&demo.summary())? + "\n",
    );
    files.add(
        "report.md",
        demo.report(&markdown_table(&headers, &rows), &image_text),
    );
    files.write_all()?;
    print!("{console}");
    Ok(())
}

/// `measurement.csv` (the simulated campaign) added to the outputs, read back and evaluated, with the
/// provenance its table will carry.
fn record_measurement(
    measured: Campaign,
    seed: u64,
    files: &mut Outputs,
) -> anyhow::Result<(Evaluated, axcomp_data::Provenance)> {
    let measurement_csv = measured.to_csv_string();
    let provenance = axcomp_data::Provenance {
        source_file: "measurement.csv".into(),
        source_sha256: axcomp_data::provenance::sha256_hex(measurement_csv.as_bytes()),
        source_bytes: measurement_csv.len() as u64,
        where_: vec![],
        rename: vec![],
        scale: vec![],
        holdout: None,
        cv: None,
        target: "deviation_um".into(),
        tool: concat!("axcomp ", env!("CARGO_PKG_VERSION")).into(),
        command: format!("demo --seed {}", seed),
        created_utc: axcomp_data::provenance::utc_iso8601(std::time::SystemTime::now()),
    };
    files.add("measurement.csv", measurement_csv);
    let before = evaluate("measurement.csv", measured)?;
    Ok((before, provenance))
}

/// The table fitted on the uncompensated campaign (refused when the do-no-harm guard fails), added as
/// `table.json`.
fn fit_table(
    before: &Evaluated,
    provenance: axcomp_data::Provenance,
    files: &mut Outputs,
) -> anyhow::Result<(FitResult, String)> {
    let obs = super::common::positioning_observations(&before.data)?;
    let mut fitted: FitResult = fit(&obs, &FitOptions::default()).context("fitting the table")?;
    fitted.table.provenance = Some(provenance);
    if !fitted.guard.passed {
        return Err(crate::Refused {
            code: crate::EXIT_GUARD_REFUSED,
            reason: format!(
                "the do-no-harm guard refused the fitted table: {}",
                fitted.guard.reasons.join("; ")
            ),
        }
        .into());
    }
    fitted.table.validate()?;
    let table_json = serde_json::to_string_pretty(&fitted.table)? + "\n";
    files.add("table.json", table_json.clone());
    Ok((fitted, table_json))
}

/// `image.bin` built from the fitted table (with its provenance), and a compensator loaded from it.
fn build_image(
    axis: &Axis,
    fitted: &FitResult,
    table_json: &str,
    files: &mut Outputs,
) -> anyhow::Result<(Vec<u8>, Compensator)> {
    let table_core = fitted.table.try_to_core(axis.scale_um_per_count)?;
    let limits = axcomp_twin::ideal::default_limits(axis);
    let spec = ImageSpec {
        axis_id: 1,
        um_per_count: axis.scale_um_per_count as f32,
        counter_bits: 32,
        table: Some(table_core.spec()),
        thermo: None,
        limits,
    };
    // With its provenance (as `image build` writes it): the table file's hash and its data's.
    let image = axcomp_image::with_extension(
        image_bytes(&spec)?,
        &crate::provenance::image_block(&[crate::provenance::model_record_of(
            table_json.as_bytes(),
            axcomp_core::provenance::ANY_AXIS,
            axcomp_core::provenance::role::POSITIONING_TABLE,
        )])?,
        &[],
    )?;
    let mut comp = Compensator::IDENTITY;
    comp.load(&image).context("loading the built image")?;
    files.add("image.bin", image.clone());

    Ok((image, comp))
}

/// The compensated campaign (new noise, through `comp`) and the ideal table's campaign.
fn compensated_campaigns(
    axis: &Axis,
    plan: &Plan,
    comp: &Compensator,
    fitted: &FitResult,
    seed: u64,
    files: &mut Outputs,
) -> anyhow::Result<(Evaluated, Evaluated)> {
    let compensated = simulate(axis, plan, Some(comp), seed + 1).context("compensated campaign")?;
    files.add("measurement_compensated.csv", compensated.to_csv_string());
    let after = evaluate("measurement_compensated.csv", compensated)?;
    let ideal_table = IdealTable::new(axis, fitted.table.segment_mm);
    let ideal_image = ideal_table.image(axis)?;
    let mut ideal_comp = Compensator::IDENTITY;
    ideal_comp.load(&ideal_image)?;
    let ideal = evaluate(
        "ideal",
        simulate(axis, plan, Some(&ideal_comp), seed + 1).context("ideal campaign")?,
    )?;
    Ok((after, ideal))
}

/// What the replay of the compensated moves showed.
struct ReplayCheck {
    trace_bytes: usize,
    replayed: axcomp_image::replay::Replay,
    bit_for_bit: bool,
    /// Number of measured rows compared.
    points: usize,
    /// Largest |replayed correction − the twin's| at the measured rows, µm.
    agree_um: f64,
    summary: String,
}

/// The compensated moves as a firmware trace (`trace.bin`), replayed through the core's engine
/// (`replay.bin`) and compared with the live outputs and the twin's corrections.
fn replay_moves(
    axis: &Axis,
    image: &[u8],
    after: &Evaluated,
    files: &mut Outputs,
) -> anyhow::Result<ReplayCheck> {
    let (trace, live, read_at) = closed_loop_trace(axis, image, &after.campaign, 2.0)?;
    files.add("trace.bin", trace.clone());
    let replayed = axcomp_image::replay::replay(None, &trace)?;
    let bit_for_bit = replayed.outputs == live && replayed.trace_errors.is_empty();
    let replay_bytes: Vec<u8> = replayed.outputs.iter().flat_map(|o| o.encode()).collect();
    files.add("replay.bin", replay_bytes);
    // At each measured row: the replayed correction vs the one the twin applied (same table, same
    // settled position up to count rounding).
    let agree_um = read_at
        .iter()
        .zip(&after.campaign.truth)
        .map(|(&k, t)| (replayed.outputs[k].correction_um() as f64 - t.correction_um).abs())
        .fold(0.0f64, f64::max);
    let replay_summary = axcomp_image::replay::summary(&replayed);

    Ok(ReplayCheck {
        trace_bytes: trace.len(),
        replayed,
        bit_for_bit,
        points: read_at.len(),
        agree_um,
        summary: replay_summary,
    })
}

/// The SVG plots: deviation before (with table and truth), after, and ISO 230-2 before/after panels.
fn plots(
    axis: &Axis,
    before: &Evaluated,
    after: &Evaluated,
    fitted: &FitResult,
    files: &mut Outputs,
) -> anyhow::Result<()> {
    let cond = axis.reference_conditions();
    let n = 801;
    let xs: Vec<f64> = (0..n)
        .map(|k| axis.start_mm + (axis.end_mm - axis.start_mm) * k as f64 / (n - 1) as f64)
        .collect();
    let curve = |f: &dyn Fn(f64) -> f64| xs.iter().map(|&x| f(x)).collect::<Vec<f64>>();
    let [(xf, df), (xb, db)] = split_by_direction(&before.data)?;
    let (up, down) = (axcomp_plot::PALETTE[0], axcomp_plot::PALETTE[1]);
    let test = format!(
        "twin {}, ISO 230-2 {} targets × 5 runs",
        axis.name,
        before.iso.targets.len()
    );
    let mut fig = Figure::new(
        &format!(
            "{test}: measured deviation and fitted table ({}, CV RMS {:.2} µm, raw {:.2} µm)",
            fitted.chosen, fitted.cv_rms_um, fitted.raw_rms_um
        ),
        "target position (mm)",
        "deviation (µm)",
    );
    fig.points("measured ↑ (positive)", &xf, &df)
        .with_colour(up)
        .line("table ↑", &xs, &curve(&|x| fitted.table.deviation_um(x, 1)))
        .with_colour(up)
        .dashed(
            "truth ↑",
            &xs,
            &curve(&|x| axis.true_deviation_um(x, 1, &cond)),
        )
        .with_colour(up)
        .points("measured ↓ (negative)", &xb, &db)
        .with_colour(down)
        .line(
            "table ↓",
            &xs,
            &curve(&|x| fitted.table.deviation_um(x, -1)),
        )
        .with_colour(down)
        .dashed(
            "truth ↓",
            &xs,
            &curve(&|x| axis.true_deviation_um(x, -1, &cond)),
        )
        .with_colour(down);
    files.add("deviation_before.svg", fig.to_svg());

    let [(xf2, df2), (xb2, db2)] = split_by_direction(&after.data)?;
    let mut fig = Figure::new(
        &format!(
            "{test}: deviation after compensation (new campaign through the firmware compensator, RMS {:.2} µm)",
            after.rms_um
        ),
        "target position (mm)",
        "deviation (µm)",
    );
    fig.points("positive approach ↑", &xf2, &df2)
        .with_colour(up)
        .points("negative approach ↓", &xb2, &db2)
        .with_colour(down)
        .hline(0.0, "0");
    files.add("deviation_after.svg", fig.to_svg());

    // Before and after as two panels (each on its own scale), one colour per direction.
    let panel = |label: &str, e: &Evaluated| {
        let mut fig = Figure::new(
            &format!(
                "{label}: A {:.2}, E {:.2}, B {:.2} µm",
                e.iso.a_um, e.iso.e_um, e.iso.b_um
            ),
            "target position (mm)",
            "mean deviation ± 2s (µm)",
        );
        fig.size(700.0, 460.0);
        for (dname, d, colour) in [("↑", 1i8, up), ("↓", -1i8, down)] {
            let [t, m, lo, hi] = per_direction(&e.iso, d);
            fig.band(&format!("{dname} ±2s"), &t, &lo, &hi)
                .with_colour(colour)
                .line(&format!("{dname} mean"), &t, &m)
                .with_colour(colour);
        }
        fig.hline(0.0, "");
        fig
    };
    let (pb, pa) = (
        panel("Before (uncompensated)", before),
        panel("After (firmware compensator)", after),
    );
    files.add(
        "iso230_before_after.svg",
        axcomp_plot::panels_svg(&[&pb, &pa], 2),
    );
    Ok(())
}

/// The demo's results, for the console, `demo.json` and `report.md`.
struct Demo<'a> {
    seed: u64,
    axis: &'a Axis,
    before: &'a Evaluated,
    after: &'a Evaluated,
    ideal: &'a Evaluated,
    fitted: &'a FitResult,
    image: &'a [u8],
    replay: &'a ReplayCheck,
}

impl Demo<'_> {
    /// The console summary up to the figures table and the reductions (`rows`: the figures' rows).
    fn console(&self, rows: &[Vec<String>]) -> String {
        let (axis, before, after, fitted) = (self.axis, self.before, self.after, self.fitted);
        let (image, r) = (self.image, self.replay);
        let reduction = |b: f64, a: f64| 100.0 * (1.0 - a / b);
        let mut console = String::new();
        let _ = writeln!(
            console,
            "axcomp demo: twin `{}` ({:.0}..{:.0} mm), ISO 230-2: {} targets × {} runs × 2 directions",
            axis.name,
            axis.start_mm,
            axis.end_mm,
            before.iso.targets.len(),
            before.data.run().map_or(0, |r| {
                let mut u = r.clone();
                u.sort();
                u.dedup();
                u.len()
            })
        );
        let _ = writeln!(
            console,
            "fit: {} ({}), raw RMS {:.2} µm → cross-validated {:.2} µm ({}); guard: passed",
            fitted.chosen, fitted.reason, fitted.raw_rms_um, fitted.cv_rms_um, fitted.split.method
        );
        let _ = writeln!(
            console,
            "image: {} bytes, {} segments of {:.3} mm per direction",
            image.len(),
            fitted.table.segments(),
            fitted.table.segment_mm
        );
        let _ = write!(
            console,
            "replay of the compensated moves (trace.bin, {} bytes) through axcomp_core::Engine: {}",
            r.trace_bytes, r.summary
        );
        let _ = writeln!(
            console,
            "  replayed bit for bit: {}; correction at the {} measured points vs the twin's: max |diff| {:.4} µm",
            if r.bit_for_bit { "yes" } else { "NO" },
            r.points,
            r.agree_um
        );
        let _ = writeln!(console);
        let _ = writeln!(
            console,
            "{:<24} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}",
            "", "A µm", "E µm", "M µm", "R µm", "B µm", "RMS µm"
        );
        for row in rows {
            let _ = writeln!(
                console,
                "{:<24} {:>8} {:>8} {:>8} {:>8} {:>8} {:>8}",
                row[0], row[1], row[2], row[3], row[4], row[5], row[6]
            );
        }
        let _ = writeln!(console);
        let _ = writeln!(
            console,
            "accuracy A: {:.2} → {:.2} µm ({:.0} % less); systematic E: {:.2} → {:.2} µm ({:.0} % less)",
            before.iso.a_um,
            after.iso.a_um,
            reduction(before.iso.a_um, after.iso.a_um),
            before.iso.e_um,
            after.iso.e_um,
            reduction(before.iso.e_um, after.iso.e_um)
        );
        console
    }

    /// `demo.json`.
    fn summary(&self) -> serde_json::Value {
        let (axis, before, after, ideal, fitted) =
            (self.axis, self.before, self.after, self.ideal, self.fitted);
        let (image, r) = (self.image, self.replay);
        json!({
            "axis": axis.name,
            "seed": self.seed,
            "rows": before.campaign.rows.len(),
            "model": { "chosen": fitted.chosen, "reason": fitted.reason, "cv_method": fitted.split.method,
                       "raw_rms_um": fitted.raw_rms_um, "cv_rms_um": fitted.cv_rms_um,
                       "segments": fitted.table.segments(), "segment_mm": fitted.table.segment_mm },
            "iso230_2_before": before.iso,
            "iso230_2_after": after.iso,
            "iso230_2_ideal": ideal.iso,
            "rms_before_um": before.rms_um,
            "rms_after_um": after.rms_um,
            "rms_ideal_um": ideal.rms_um,
            "image_bytes": image.len(),
            "replay": { "cycles": r.replayed.outputs.len(), "bit_for_bit": r.bit_for_bit,
                        "max_abs_correction_um": r.replayed.outputs.iter().map(|o| o.correction_um().abs() as f64).fold(0.0, f64::max),
                        "max_diff_to_twin_um": r.agree_um, "trace_bytes": r.trace_bytes },
        })
    }

    /// `report.md` (`table_md`: the ISO 230-2 figures table; `image_text`: the image's description).
    fn report(&self, table_md: &str, image_text: &str) -> String {
        let (axis, before, fitted, r) = (self.axis, self.before, self.fitted, self.replay);
        let mut md = String::new();
        let _ = writeln!(md, "# axcomp demo\n");
        let _ = writeln!(
            md,
            "Simulated axis `{}` ({:.0}–{:.0} mm; effects: {}), measured with an ISO 230-2 test \
             ({} targets, 5 bidirectional runs, seed {}). A table was fitted on that campaign, built into a \
             firmware image, and a **second campaign with new noise** (seed {}) was driven through the \
             firmware's compensator loaded from that image. The ideal row uses a table built from the twin's \
             known truth: the floor any fitted table could reach.\n",
            axis.name,
            axis.start_mm,
            axis.end_mm,
            axis.kinds()
                .iter()
                .map(|k| k.name())
                .collect::<Vec<_>>()
                .join(", "),
            before.iso.targets.len(),
            self.seed,
            self.seed + 1
        );
        let _ = writeln!(md, "## ISO 230-2 figures (bidirectional, µm)\n\n{table_md}");
        let _ = writeln!(
            md,
            "A = accuracy, E = systematic positional deviation, M = mean bidirectional positional deviation \
             range, R = repeatability, B = reversal value; RMS over all measured deviations.\n"
        );
        let _ = writeln!(
            md,
            "## Fit\n\nChosen model: `{}` — {}.\nRaw RMS {:.3} µm, cross-validated ({}) RMS {:.3} µm. \
             Do-no-harm guard: passed ({}).\nTable: {} segments of {:.3} mm per direction, resampling error \
             ≤ {:.3} µm.\n",
            fitted.chosen,
            fitted.reason,
            fitted.raw_rms_um,
            fitted.split.method,
            fitted.cv_rms_um,
            fitted.guard.rule,
            fitted.table.segments(),
            fitted.table.segment_mm,
            fitted.resampling_max_um
        );
        let _ = writeln!(md, "## Firmware image\n\n```\n{image_text}```\n");
        let _ = writeln!(
            md,
            "## Replay\n\nThe compensated moves, logged as a firmware trace (`trace.bin`: the image record, then one \
             cycle record per control cycle with an ideal servo), replayed through `axcomp_core::Engine` from the \
             file bytes (`axcomp replay --trace trace.bin --out replay.bin`):\n\n```\n{}```\n\
             Replayed bit for bit: {}. Correction at the {} measured points vs the correction the twin applied: \
             max |difference| {:.4} µm.\n",
            r.summary,
            if r.bit_for_bit { "yes" } else { "no" },
            r.points,
            r.agree_um
        );
        let _ = writeln!(
            md,
            "## Plots\n\n![before](deviation_before.svg)\n\n![after](deviation_after.svg)\n\n\
             ![ISO 230-2 before/after](iso230_before_after.svg)\n"
        );
        let _ = writeln!(
            md,
            "## Files\n\n`measurement.csv` (uncompensated campaign), `measurement_compensated.csv`, `table.json` \
             (`axcomp export --table table.json --format linuxcnc1 --step 5 --out x.comp`), `image.bin` \
             (`axcomp image inspect image.bin`), `demo.json` (figures).\n"
        );
        md
    }
}
