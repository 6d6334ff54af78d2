//! `axcomp demo --all`: every system's chain on the twin, one row per system.
//!
//! Glossary:
//! - *system*: positioning (one linear axis, ISO 230-2), thermo-force (drift with temperature on
//!   one axis), three-axis geometry (21 ISO 230-1 components), five-axis rotary (ISO 230-7 location
//!   errors, R-test), touch probe (stylus radius and pretravel).
//! - *chain*: measure on the twin → fit (the library the `fit` command calls) → image (the core's
//!   image writers, as `image build` / `image group`) → the firmware library applies the image
//!   (`axcomp_core::Compensator` / `group::Group`, loaded from the image bytes) → before / after on
//!   data the fit never saw.
//! - *before / after*: the figure named in the row, uncompensated and through the firmware library.
//!   The probe has no firmware stage for its calibration (the core's probe section only latches
//!   touches: filter, latency, lockout): its "after" is the host's correction (`axcomp predict`),
//!   and the row says so.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use axcomp_core::group::{AxisName, Group, GroupInput, GroupOutput, GroupState};
use axcomp_core::group_image::{self, AxisSectionSpec};
use axcomp_core::{Compensator, ImageSpec, LimitSpec, image_len, write_image};
use axcomp_data::{Dataset, LoadOptions};
use axcomp_kinematics::Topology;
use axcomp_kinematics::rotary::{FiveAxis, MachineKind, N_SETUP, Pose};
use axcomp_positioning::fit::{FitOptions, fit};
use axcomp_twin::{Axis, EffectKind, Iso230Plan, Plan, ThermalPlan, simulate};
use serde_json::json;

use crate::output::OutputSet;

/// One system's row of the table.
struct Row {
    system: &'static str,
    figure: &'static str,
    before: f64,
    after: f64,
    firmware: String,
}

/// Loose limits for the demo images: the figures show the model, not the clamp.
const LOOSE: LimitSpec = LimitSpec {
    max_correction_um: 1.0e4,
    max_slew_um_per_cycle: 1.0e4,
    direction_hysteresis_counts: 0,
};

fn image_bytes(spec: &ImageSpec) -> anyhow::Result<Vec<u8>> {
    let mut buf = vec![0u8; image_len(spec)];
    let n = write_image(spec, &mut buf).map_err(|e| anyhow::anyhow!("image: {e}"))?;
    buf.truncate(n);
    Ok(buf)
}

fn campaign_rms(c: &axcomp_twin::Campaign) -> f64 {
    c.rms_deviation_um()
}

/// Positioning: ISO 230-2 on the demo axis, `fit positioning`'s fit, the table image, a new
/// campaign through `Compensator::cycle`.
fn positioning(seed: u64, files: &mut Vec<(String, Vec<u8>)>) -> anyhow::Result<Row> {
    let axis = Axis::linear_motor_demo();
    let plan = Plan::from(Iso230Plan::standard(axis.start_mm, axis.end_mm));
    let measured = simulate(&axis, &plan, None, seed)?;
    let csv = measured.to_csv_string();
    let ds = Dataset::from_csv_str("positioning.csv", &csv, &LoadOptions::default())?;
    files.push(("positioning_measurement.csv".into(), csv.into_bytes()));
    let obs = super::common::positioning_observations(&ds)?;
    let fitted = fit(&obs, &FitOptions::default()).context("positioning fit")?;
    let table = fitted.table.try_to_core(axis.scale_um_per_count)?;
    let image = image_bytes(&ImageSpec {
        axis_id: 1,
        um_per_count: axis.scale_um_per_count as f32,
        counter_bits: 32,
        table: Some(table.spec()),
        thermo: None,
        limits: axcomp_twin::ideal::default_limits(&axis),
    })?;
    let mut comp = Compensator::IDENTITY;
    comp.load(&image)?;
    let plain = simulate(&axis, &plan, None, seed + 1)?;
    let after = simulate(&axis, &plan, Some(&comp), seed + 1)?;
    files.push(("positioning_image.bin".into(), image));
    Ok(Row {
        system: "positioning",
        figure: "deviation RMS, ISO 230-2 campaign, new noise, µm",
        before: campaign_rms(&plain),
        after: campaign_rms(&after),
        firmware: "Compensator::cycle on every move (table image)".into(),
    })
}

/// Thermo-force: a warm-up / cool-down campaign of an axis with thermal drift and scale expansion,
/// `fit thermal`'s fit (every sensor, the order the twin feeds them), the thermo-force image, a new
/// campaign through `Compensator` fed the temperatures.
fn thermo_force(seed: u64, files: &mut Vec<(String, Vec<u8>)>) -> anyhow::Result<Row> {
    use axcomp_thermal::model_file::ThermalModelFile;
    use axcomp_thermal::{Selection, Series, ThermalInput, ThermalOptions, fit_thermal};
    let axis = Axis::typical(
        "thermo_force",
        0.0,
        200.0,
        &[EffectKind::ThermalDrift, EffectKind::ScaleExpansion],
    );
    let plan = Plan::Thermal(ThermalPlan::standard(0.0, 200.0));
    let measured = simulate(&axis, &plan, None, seed)?;
    let csv = measured.to_csv_string();
    let ds = Dataset::from_csv_str("thermal.csv", &csv, &LoadOptions::default())?;
    files.push(("thermo_force_measurement.csv".into(), csv.into_bytes()));
    let sensors = ds
        .sensors()
        .iter()
        .map(|s| {
            Ok(Series {
                name: s.clone(),
                values: ds.numeric(&format!("{s}_degC"))?.to_vec(),
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let input = ThermalInput {
        time_s: ds
            .time_s()
            .context("the thermal campaign has time_s")?
            .to_vec(),
        sensors,
        forces: vec![],
        target: ds.numeric("deviation_um")?.to_vec(),
        conditions: None,
        holdout: None,
        runs: None,
    };
    // Every sensor, in the twin's order: the twin feeds the compensator's sensors by position.
    let opts = ThermalOptions {
        lags: false,
        selection: Selection::All,
        ..ThermalOptions::default()
    }
    .build()?;
    let fit = fit_thermal(&input, &opts).context("thermal fit")?;
    let model =
        ThermalModelFile::from_fit(&fit, &input, "deviation_um", axcomp_twin::SENSOR_PERIOD_MS);
    if let Some((_, why)) = axcomp_image::board::thermal_model_refusal(&model) {
        anyhow::bail!("thermo-force model: {why}");
    }
    let thermo = model.to_core();
    let image = image_bytes(&ImageSpec {
        axis_id: 1,
        um_per_count: axis.scale_um_per_count as f32,
        counter_bits: 32,
        table: None,
        thermo: Some(thermo.spec()),
        limits: LOOSE,
    })?;
    let mut comp = Compensator::IDENTITY;
    comp.load(&image)?;
    let plain = simulate(&axis, &plan, None, seed + 1)?;
    let after = simulate(&axis, &plan, Some(&comp), seed + 1)?;
    files.push(("thermo_force_image.bin".into(), image));
    Ok(Row {
        system: "thermo-force",
        figure: "deviation RMS, warm-up/cool-down campaign, new noise, µm",
        before: campaign_rms(&plain),
        after: campaign_rms(&after),
        firmware: format!(
            "Compensator::update_temperatures + cycle ({} sensors)",
            model.sensors.len()
        ),
    })
}

/// A linear or rotary axis image with no table (the stages alone).
fn bare(axis_id: u16, um_per_count: f32) -> anyhow::Result<Vec<u8>> {
    image_bytes(&ImageSpec {
        axis_id,
        um_per_count,
        counter_bits: 32,
        table: None,
        thermo: None,
        limits: LOOSE,
    })
}

/// Three-axis geometry: laser lines on the 800 × 600 × 500 mm twin, `fit geometry`'s fit, the
/// group image's geometric section (identity axes), the twin's volume commanded through the core
/// stage.
fn geometry(seed: u64, files: &mut Vec<(String, Vec<u8>)>) -> anyhow::Result<Row> {
    use axcomp_geometry::{FitOptions, Judge, LineData, analyse};
    use axcomp_twin::geometry::{GeometryTwin, plan_by_name};
    const STROKE: [f64; 3] = [800.0, 600.0, 500.0];
    const UPC: f64 = 0.1;
    let lines = plan_by_name("complete", STROKE, 11).context("the twin plan `complete`")?;
    let twin = GeometryTwin::random(STROKE, Topology::default(), seed);
    let csv = twin.measure(&lines, 2, seed + 100).to_csv_string();
    let ds = Dataset::from_csv_str("lines.csv", &csv, &LoadOptions::default())?;
    files.push(("geometry_lines.csv".into(), csv.into_bytes()));
    let data = LineData::from_dataset(&ds, true)?;
    let model = analyse(&data, &Judge::None, &FitOptions::default())?
        .fit
        .model;
    let section = axcomp_image::geometric_from_model(&model, [UPC; 3], [0.0; 3])?;
    let images = (1..=3)
        .map(|id| bare(id, UPC as f32))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let specs: Vec<AxisSectionSpec> = (0..3)
        .map(|k| AxisSectionSpec {
            name: AxisName::ALL[k],
            counts_per_rev: 0,
            stroke_counts: Some(section.strokes()[k]),
            image: &images[k],
            sensor_names: &[],
        })
        .collect();
    let spec = section.spec();
    let mut buf =
        vec![0u8; group_image::group_image_len_with_stages(&specs, None, Some(&spec), None)];
    let n = group_image::write_group_image_with_stages(&specs, None, Some(&spec), None, &mut buf)
        .map_err(|e| anyhow::anyhow!("geometry group image: {e}"))?;
    buf.truncate(n);
    let mut g: Box<Group<1024>> = Box::new(Group::new());
    g.load_image(&buf)
        .map_err(|e| anyhow::anyhow!("geometry group image: {e}"))?;
    let mut st = Box::new(GroupState::new());
    let per_mm = 1000.0 / UPC;
    let (lo, hi) = (model.volume_min_mm, model.volume_max_mm);
    // The twin's true error over an 11³ grid of the volume (not the measured lines).
    let r = twin.compensated_volume(lo, hi, 11, [0.0; 3], |q| {
        let mut input = GroupInput::ZERO;
        for k in 0..3 {
            let c = (q[k] * per_mm).round() as i64;
            input.axes[k].command_counts = c;
            input.axes[k].scale_raw = c as u32;
        }
        let mut out = GroupOutput::ZERO;
        g.cycle(&mut st, &input, &mut out);
        std::array::from_fn(|k| out.axes[k].corrected_command_counts as f64 / per_mm)
    });
    files.push(("geometry_group.bin".into(), buf));
    Ok(Row {
        system: "three-axis geometry",
        figure: "volumetric |e| RMS, 11³ points of the volume (twin truth), µm",
        before: r.before_rms_um,
        after: r.after_rms_um,
        firmware: "Group geometric stage (21 components, identity axes)".into(),
    })
}

/// Rotary axes' counts per revolution, X/Y/Z µm per count and the pivot of the five-axis chain.
const CPR: u32 = 3_600_000;
const UPC5: f64 = 0.1;
const PIVOT: [i64; 3] = [1_000_000, -2_000_000, 3_000_000];

fn angle_counts(deg: f64) -> i64 {
    (deg / 360.0 * CPR as f64).round() as i64
}

/// Five-axis rotary: an AC trunnion twin measured along K4 and C circles, `fit rtest`'s fit with
/// run 2 of K4 held out, the rotary section of a group image, the held-out K4 poses commanded
/// through the core stage.
fn rotary(seed: u64, files: &mut Vec<(String, Vec<u8>)>) -> anyhow::Result<Row> {
    use axcomp_data::HoldoutSpec;
    use axcomp_twin::five_axis::{FiveAxisTwin, standard_paths};
    let tool_mm = 100.0;
    let machine = FiveAxis::new(MachineKind::AcTrunnion, 0.0);
    let twin = FiveAxisTwin::random(machine, seed);
    let paths = standard_paths(
        &machine,
        [150.0, 0.0, 100.0],
        -60.0,
        72,
        &[0.0, -60.0],
        36,
        None,
    );
    let csv = twin.measure(&paths, seed).to_csv_string();
    let ds = Dataset::from_csv_str("rtest.csv", &csv, &LoadOptions::default())?;
    files.push(("rotary_rtest.csv".into(), csv.into_bytes()));
    let data = axcomp_rtest::RtestData::from_dataset(&ds, machine, true)?;
    let split = axcomp_data::Split::Holdout(HoldoutSpec::parse("run=2")?);
    let a = axcomp_rtest::analysis::analyse(&ds, &data, Some(&split))?;
    let spec = axcomp_image::rotary_from_rtest_model(&a.model, PIVOT, Some(tool_mm))?;
    let images = [(AxisName::X, 1), (AxisName::Y, 2), (AxisName::Z, 3)]
        .into_iter()
        .map(|(n, id)| Ok((n, 0, bare(id, UPC5 as f32)?)))
        .chain(
            [(AxisName::A, 4), (AxisName::C, 5)]
                .into_iter()
                .map(|(n, id)| Ok((n, CPR, bare(id, 360.0 * 3600.0 / CPR as f32)?))),
        )
        .collect::<anyhow::Result<Vec<_>>>()?;
    let specs: Vec<AxisSectionSpec> = images
        .iter()
        .map(|(name, cpr, image)| AxisSectionSpec {
            name: *name,
            counts_per_rev: *cpr,
            stroke_counts: None,
            image,
            sensor_names: &[],
        })
        .collect();
    let mut buf =
        vec![0u8; group_image::group_image_len_with_stages(&specs, Some(&spec), None, None)];
    let n = group_image::write_group_image_with_stages(&specs, Some(&spec), None, None, &mut buf)
        .map_err(|e| anyhow::anyhow!("rotary group image: {e}"))?;
    buf.truncate(n);
    let mut g: Box<Group<64>> = Box::new(Group::new());
    g.load_image(&buf)
        .map_err(|e| anyhow::anyhow!("rotary group image: {e}"))?;
    let (mut before, mut after) = (Vec::new(), Vec::new());
    // The held-out K4 path (run 2): the displacement at each pose, commanded plainly and through
    // the stage (the axes go where the corrected command says).
    for pose in &paths.last().context("K4 run 2")?.poses {
        let lin = machine.linear_positions(pose);
        let c = |k: usize, mm: f64| PIVOT[k] + (mm * 1000.0 / UPC5).round() as i64;
        let cmd = [
            c(0, lin[0]),
            c(1, lin[1]),
            c(2, lin[2] + tool_mm),
            angle_counts(pose.tilt_deg),
            angle_counts(pose.c_deg),
        ];
        let pose_at = |xyz: [i64; 3]| Pose {
            p_mm: [0, 1, 2].map(|k| {
                (xyz[k] - PIVOT[k]) as f64 * UPC5 / 1000.0 - if k == 2 { tool_mm } else { 0.0 }
            }),
            tilt_deg: cmd[3] as f64 * 360.0 / CPR as f64,
            c_deg: cmd[4] as f64 * 360.0 / CPR as f64,
        };
        let nominal = pose_at([cmd[0], cmd[1], cmd[2]]);
        let s = machine.nominal_sphere(&nominal);
        before.push(machine.displacement_at(&nominal, s, &twin.location, [0.0; N_SETUP]));
        let mut st = Box::new(GroupState::new());
        let mut input = GroupInput::ZERO;
        for k in 0..5 {
            input.axes[k].command_counts = cmd[k];
            input.axes[k].scale_raw = cmd[k] as u32;
        }
        let mut out = GroupOutput::ZERO;
        g.cycle(&mut st, &input, &mut out);
        let corrected = [0, 1, 2].map(|k| out.axes[k].corrected_command_counts);
        after.push(machine.displacement_at(&pose_at(corrected), s, &twin.location, [0.0; N_SETUP]));
    }
    files.push(("rotary_group.bin".into(), buf));
    let worst_range = |v: &[[f64; 3]]| {
        (0..3)
            .map(|c| {
                let (lo, hi) = v
                    .iter()
                    .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), d| {
                        (lo.min(d[c]), hi.max(d[c]))
                    });
                hi - lo
            })
            .fold(0.0f64, f64::max)
    };
    Ok(Row {
        system: "five-axis rotary",
        figure: "largest K4 range (ISO 10791-6), held-out K4 run, µm",
        before: worst_range(&before),
        after: worst_range(&after),
        firmware: "Group rotary stage (AC trunnion location errors)".into(),
    })
}

/// Touch probe: calibration touches and a held-out sphere on the probe twin, `axcomp fit probe`
/// (the command itself, into the report folder), its diameter error before / after on the held-out
/// sphere.
fn probe(seed: u64, dir: &Path, files: &mut Vec<(String, Vec<u8>)>) -> anyhow::Result<Row> {
    use axcomp_twin::probe::{ProbeModel, ProbePlan, simulate_touches, touches_csv};
    let model = ProbeModel::kinematic_demo();
    let mut t = simulate_touches(&model, &ProbePlan::standard_calibration(), seed);
    let held = simulate_touches(
        &model.without_glitches(),
        &ProbePlan::measurement(450.0, 1),
        seed + 1,
    );
    t.extend(held.into_iter().filter(|m| m.artefact == "sphere2"));
    let csv = touches_csv(&t);
    std::fs::create_dir_all(dir)?;
    let data = dir.join("touches.csv");
    let json = dir.join("fit.json");
    std::fs::write(&data, &csv)?;
    let args = [
        "axcomp",
        "fit",
        "probe",
        "--data",
        &data.display().to_string(),
        "--sphere-diameter-mm",
        "25",
        "--holdout",
        "artefact=sphere2",
        "--holdout-diameter-mm",
        "19.05",
        "--stylus-diameter-mm",
        "3",
        "--json",
        &json.display().to_string(),
    ]
    .map(String::from);
    crate::run(args).context("fit probe")?;
    let j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json)?)?;
    let de = &j["diameter_error_um"];
    let num = |k: &str| {
        de[k]
            .as_f64()
            .with_context(|| format!("fit probe JSON: diameter_error_um.{k}"))
    };
    let (before, after) = (num("before")?.abs(), num("after")?.abs());
    files.push(("probe_touches.csv".into(), csv.into_bytes()));
    files.push(("probe_fit.json".into(), std::fs::read(&json)?));
    Ok(Row {
        system: "touch probe",
        figure: "|diameter error|, held-out 19.05 mm sphere, µm",
        before,
        after,
        firmware: "none for the calibration: the core's probe stage only latches touches; \
                   `axcomp predict` corrects on the host"
            .into(),
    })
}

/// Runs every chain, prints one row per system and writes the report folder `out` whole
/// (`demo_all.json`, `report.md`, each chain's data and image).
pub fn run_all(out: &Path, seed: u64) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let mut set = OutputSet::new();
    set.folder(out, "--out");
    set.check()?;
    let scratch = std::env::temp_dir().join(format!("axcomp-demo-all-{}", std::process::id()));
    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    let mut rows = Vec::new();
    let mut times = Vec::new();
    let chains: [(
        &str,
        &dyn Fn(&mut Vec<(String, Vec<u8>)>) -> anyhow::Result<Row>,
    ); 5] = [
        ("positioning", &|f| positioning(seed, f)),
        ("thermo-force", &|f| thermo_force(seed, f)),
        ("geometry", &|f| geometry(seed, f)),
        ("rotary", &|f| rotary(seed, f)),
        ("probe", &|f| probe(seed, &scratch, f)),
    ];
    for (name, chain) in chains {
        let t = Instant::now();
        let row = chain(&mut files).with_context(|| format!("demo --all: the {name} chain"));
        let _ = std::fs::remove_dir_all(&scratch);
        rows.push(row?);
        times.push(t.elapsed().as_secs_f64());
    }
    let mut table = String::new();
    let _ = writeln!(
        table,
        "{:<20} {:>10} {:>10} {:>7}  {:<62} firmware stage",
        "system", "before", "after", "less", "figure (data the fit never saw)"
    );
    for r in &rows {
        let _ = writeln!(
            table,
            "{:<20} {:>10.3} {:>10.3} {:>6.1}%  {:<62} {}",
            r.system,
            r.before,
            r.after,
            100.0 * (1.0 - r.after / r.before),
            r.figure,
            r.firmware
        );
    }
    let total = t0.elapsed().as_secs_f64();
    print!("{table}");
    println!(
        "{} systems in {total:.2} s; report in {}",
        rows.len(),
        out.display()
    );
    let json = json!({
        "seed": seed,
        "seconds": total,
        "systems": rows.iter().zip(&times).map(|(r, s)| json!({
            "system": r.system, "figure": r.figure, "before": r.before, "after": r.after,
            "firmware": r.firmware, "seconds": s,
        })).collect::<Vec<_>>(),
    });
    let report = format!(
        "# axcomp demo --all\n\nEvery system's chain on the twin: measure → fit → image → the firmware \
         library applies the image → before/after on data the fit never saw (seed {seed}).\n\n```\n{table}```\n"
    );
    for (name, bytes) in files {
        set.folder_file(out, &name, bytes);
    }
    set.folder_file(
        out,
        "demo_all.json",
        serde_json::to_string_pretty(&json)? + "\n",
    );
    set.folder_file(out, "report.md", report);
    set.commit()?;
    Ok(())
}

/// Default report folder of `demo --all`.
pub fn default_out() -> PathBuf {
    PathBuf::from("axcomp-demo-all")
}
