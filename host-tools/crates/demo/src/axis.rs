//! `axcomp demo`: the whole loop on a simulated axis, in seconds.
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
//! Steps: simulate → `measurement.csv` → read it back with `axcomp-data` → ISO 230-2 → fit
//! (`axcomp_positioning::fit`, cross-validated, do-no-harm guard) → `table.json` → firmware image
//! `image.bin` → compensated campaign → ISO 230-2 after → console, `report.md`, `demo.json`, SVG plots.

mod evaluated;
mod plots;
mod report;

use std::fmt::Write as _;
use std::time::Instant;

use axcomp_core::{Compensator, ImageSpec};
use axcomp_data::Provenance;
use axcomp_plot::markdown_table;
use axcomp_positioning::fit::{FitOptions, FitResult, fit};
use axcomp_twin::{Axis, Campaign, IdealTable, Iso230Plan, Plan, simulate};

use crate::{DemoError, OutputFile, Result, StepContext};
use evaluated::{Evaluated, evaluate};
use report::{Demo, ReplayCheck, figures_row};

/// The files the demo returns, in the order it returns them (the command declares them before the
/// run and writes them all together).
pub const FILES: [&str; 11] = [
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

/// What the demo gives the command: the files of [`FILES`] and the console text.
pub struct AxisDemo {
    /// Name (one of [`FILES`]) and bytes, in the order of [`FILES`].
    pub files: Vec<OutputFile>,
    /// The console summary, the figures and the time taken by each step.
    pub console: String,
}

/// The files collected while the demo runs.
struct Files(Vec<OutputFile>);

impl Files {
    fn add(&mut self, name: &'static str, bytes: impl Into<Vec<u8>>) {
        debug_assert!(FILES.contains(&name), "{name} not in FILES");
        self.0.push((name.to_string(), bytes.into()));
    }
}

/// Runs the demo with noise seed `seed` (the compensated campaign uses seed + 1); `tool` (name and
/// version) goes into the table's and the image's provenance.
pub fn run(seed: u64, tool: &str) -> Result<AxisDemo> {
    let t0 = Instant::now();
    let mut files = Files(Vec::with_capacity(FILES.len()));

    // 1. The twin and its ISO 230-2 campaign.
    let axis = Axis::linear_motor_demo();
    let plan = Plan::from(Iso230Plan::standard(axis.start_mm, axis.end_mm));
    let measured = simulate(&axis, &plan, None, seed).step(|| "simulating the campaign".into())?;
    let (before, provenance, data_sha256) = record_measurement(measured, seed, tool, &mut files)?;
    let t_sim = t0.elapsed();

    // 2. Fit (cross-validated, guarded).
    let (fitted, table_json) = fit_table(&before, provenance, &mut files)?;
    let t_fit = t0.elapsed();

    // 3. Firmware image (the core's `write_image`, as `axcomp image build`), loaded as the firmware would.
    let table = TableFile {
        json: &table_json,
        data_sha256,
    };
    let (image, comp) = build_image(&axis, &fitted, &table, tool, &mut files)?;
    let image_text = axcomp_image::describe(&image)?;

    // 4. Compensated campaign (new noise), and the ideal floor.
    let (after, ideal) = compensated_campaigns(&axis, &plan, &comp, &fitted, seed, &mut files)?;
    let t_comp = t0.elapsed();

    // 5. The same moves as a recorded firmware trace, replayed through the core's engine from the file
    //    bytes (what `axcomp replay` and the QEMU firmware do).
    let replay = replay_moves(&axis, &image, &after, &mut files)?;

    // 6. Plots.
    for (name, svg) in plots::plots(&axis, &before, &after, &fitted)? {
        files.add(name, svg);
    }
    let t_plot = t0.elapsed();

    // 7. Figures: console, JSON, report.
    let demo = Demo {
        seed,
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
    writeln!(
        console,
        "time: simulate {:.2} s, fit {:.2} s, image + compensated campaigns {:.2} s, plots {:.2} s",
        t_sim.as_secs_f64(),
        (t_fit - t_sim).as_secs_f64(),
        (t_comp - t_fit).as_secs_f64(),
        (t_plot - t_comp).as_secs_f64()
    )?;
    files.add(
        "demo.json",
        serde_json::to_string_pretty(&demo.summary())? + "\n",
    );
    files.add(
        "report.md",
        demo.report(&markdown_table(&headers, &rows), &image_text),
    );
    Ok(AxisDemo {
        files: files.0,
        console,
    })
}

/// `measurement.csv` (the simulated campaign) added to the outputs, read back and evaluated, with the
/// provenance its table will carry and the raw SHA-256 of the file.
fn record_measurement(
    measured: Campaign,
    seed: u64,
    tool: &str,
    files: &mut Files,
) -> Result<(Evaluated, Provenance, [u8; 32])> {
    let measurement_csv = measured.to_csv_string();
    let provenance = Provenance {
        source_file: "measurement.csv".into(),
        source_sha256: axcomp_data::provenance::sha256_hex(measurement_csv.as_bytes()),
        source_bytes: measurement_csv.len() as u64,
        where_: vec![],
        rename: vec![],
        scale: vec![],
        holdout: None,
        cv: None,
        target: "deviation_um".into(),
        tool: tool.into(),
        command: format!("demo --seed {}", seed),
        created_utc: axcomp_data::provenance::utc_iso8601(std::time::SystemTime::now()),
    };
    let data_sha256 = axcomp_data::provenance::sha256(measurement_csv.as_bytes());
    files.add("measurement.csv", measurement_csv);
    let before = evaluate("measurement.csv", measured)?;
    Ok((before, provenance, data_sha256))
}

/// The table fitted on the uncompensated campaign (refused when the do-no-harm guard fails), added as
/// `table.json`.
fn fit_table(
    before: &Evaluated,
    provenance: Provenance,
    files: &mut Files,
) -> Result<(FitResult, String)> {
    let obs = crate::positioning_observations(&before.data)?;
    let mut fitted: FitResult =
        fit(&obs, &FitOptions::default()).step(|| "fitting the table".into())?;
    fitted.table.provenance = Some(provenance);
    if !fitted.guard.passed {
        return Err(DemoError::GuardRefused(fitted.guard.reasons.join("; ")));
    }
    fitted.table.validate()?;
    let table_json = serde_json::to_string_pretty(&fitted.table)? + "\n";
    files.add("table.json", table_json.clone());
    Ok((fitted, table_json))
}

/// The table file as written (`table.json`) and the raw SHA-256 of the data it was fitted on.
struct TableFile<'a> {
    json: &'a str,
    data_sha256: [u8; 32],
}

/// `image.bin` built from the fitted table (with its provenance, as `image build` writes it: the
/// table file's hash and its data's), and a compensator loaded from it.
fn build_image(
    axis: &Axis,
    fitted: &FitResult,
    table: &TableFile,
    tool: &str,
    files: &mut Files,
) -> Result<(Vec<u8>, Compensator)> {
    use axcomp_core::provenance::{ANY_AXIS, ProvenanceRecord, role};
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
    let record = ProvenanceRecord {
        axis: ANY_AXIS,
        role: role::POSITIONING_TABLE,
        model_sha256: axcomp_data::provenance::sha256(table.json.as_bytes()),
        data_sha256: table.data_sha256,
    };
    let date = axcomp_data::provenance::utc_iso8601(std::time::SystemTime::now());
    let block = axcomp_image::provenance_block(tool, &date, &[record])?;
    let image = axcomp_image::with_extension(crate::image_bytes(&spec)?, &block, &[])?;
    let mut comp = Compensator::IDENTITY;
    comp.load(&image)
        .step(|| "loading the built image".into())?;
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
    files: &mut Files,
) -> Result<(Evaluated, Evaluated)> {
    let compensated =
        simulate(axis, plan, Some(comp), seed + 1).step(|| "compensated campaign".into())?;
    files.add("measurement_compensated.csv", compensated.to_csv_string());
    let after = evaluate("measurement_compensated.csv", compensated)?;
    let ideal_table = IdealTable::new(axis, fitted.table.segment_mm);
    let ideal_image = ideal_table.image(axis)?;
    let mut ideal_comp = Compensator::IDENTITY;
    ideal_comp.load(&ideal_image)?;
    let ideal = evaluate(
        "ideal",
        simulate(axis, plan, Some(&ideal_comp), seed + 1).step(|| "ideal campaign".into())?,
    )?;
    Ok((after, ideal))
}

/// The compensated moves as a firmware trace (`trace.bin`), replayed through the core's engine
/// (`replay.bin`) and compared with the live outputs and the twin's corrections.
fn replay_moves(
    axis: &Axis,
    image: &[u8],
    after: &Evaluated,
    files: &mut Files,
) -> Result<ReplayCheck> {
    let live = crate::trace::closed_loop_trace(axis, image, &after.campaign, 2.0)?;
    files.add("trace.bin", live.trace.clone());
    let replayed = axcomp_image::replay::replay(None, &live.trace)?;
    let bit_for_bit = replayed.outputs == live.outputs && replayed.trace_errors.is_empty();
    let replay_bytes: Vec<u8> = replayed.outputs.iter().flat_map(|o| o.encode()).collect();
    files.add("replay.bin", replay_bytes);
    // At each measured row: the replayed correction vs the one the twin applied (same table, same
    // settled position up to count rounding).
    let agree_um = live
        .read_at
        .iter()
        .zip(&after.campaign.truth)
        .map(|(&k, t)| (replayed.outputs[k].correction_um() as f64 - t.correction_um).abs())
        .fold(0.0f64, f64::max);
    let summary = axcomp_image::replay::summary(&replayed);
    Ok(ReplayCheck {
        trace_bytes: live.trace.len(),
        replayed,
        bit_for_bit,
        points: live.read_at.len(),
        agree_um,
        summary,
    })
}
