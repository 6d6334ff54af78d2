//! The positioning, thermo-force and three-axis geometry chains of [`crate::all`].

use axcomp_core::group::{AxisName, Group, GroupInput, GroupOutput, GroupState};
use axcomp_core::group_image::{self, AxisSectionSpec};
use axcomp_core::{Compensator, ImageSpec, LimitSpec};
use axcomp_data::{Dataset, LoadOptions};
use axcomp_kinematics::Topology;
use axcomp_positioning::fit::{FitOptions, fit};
use axcomp_twin::{Axis, Campaign, EffectKind, Iso230Plan, Plan, ThermalPlan, simulate};

use crate::row::{ChainOutputs, Row};
use crate::{DemoError, Result, StepContext};

/// Loose limits for the demo images: the figures show the model, not the clamp.
const LOOSE: LimitSpec = LimitSpec {
    max_correction_um: 1.0e4,
    max_slew_um_per_cycle: 1.0e4,
    direction_hysteresis_counts: 0,
};

/// The image `spec` as bytes; a refusal of the core's writer is worded as an image error.
pub(crate) fn image_bytes(spec: &ImageSpec) -> Result<Vec<u8>> {
    crate::image_bytes(spec).map_err(|e| DemoError::Firmware(format!("image: {e}")))
}

/// A linear or rotary axis image with no table (the stages alone).
pub(crate) fn bare(axis_id: u16, um_per_count: f32) -> Result<Vec<u8>> {
    image_bytes(&ImageSpec {
        axis_id,
        um_per_count,
        counter_bits: 32,
        table: None,
        thermo: None,
        limits: LOOSE,
    })
}

fn campaign_rms(c: &Campaign) -> f64 {
    c.rms_deviation_um()
}

/// Positioning: ISO 230-2 on the demo axis, `fit positioning`'s fit, the table image, a new
/// campaign through `Compensator::cycle`.
pub(crate) fn positioning(seed: u64, out: &mut ChainOutputs) -> Result<Row> {
    let axis = Axis::linear_motor_demo();
    let plan = Plan::from(Iso230Plan::standard(axis.start_mm, axis.end_mm));
    let measured = simulate(&axis, &plan, None, seed)?;
    let csv = measured.to_csv_string();
    let ds = Dataset::from_csv_str("positioning.csv", &csv, &LoadOptions::default())?;
    out.files
        .push(("positioning_measurement.csv".into(), csv.into_bytes()));
    let obs = crate::positioning_observations(&ds)?;
    let fitted = fit(&obs, &FitOptions::default()).step(|| "positioning fit".into())?;
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
    out.files.push(("positioning_image.bin".into(), image));
    Ok(Row {
        system: "positioning",
        figure: "deviation RMS, ISO 230-2 campaign, new noise, µm",
        before: campaign_rms(&plain),
        after: campaign_rms(&after),
        firmware: "Compensator::cycle on every move (table image)".into(),
    })
}

/// The thermal fit's input from a thermal campaign: every sensor in the file's order, no forces.
fn thermal_input(ds: &Dataset) -> Result<axcomp_thermal::ThermalInput> {
    use axcomp_thermal::{Series, ThermalInput};
    let sensors = ds
        .sensors()
        .iter()
        .map(|s| {
            Ok(Series {
                name: s.clone(),
                values: ds.numeric(&format!("{s}_degC"))?.to_vec(),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(ThermalInput {
        time_s: ds
            .time_s()
            .step(|| "the thermal campaign has time_s".into())?
            .to_vec(),
        sensors,
        forces: vec![],
        target: ds.numeric("deviation_um")?.to_vec(),
        conditions: None,
        holdout: None,
        runs: None,
    })
}

/// Thermo-force: a warm-up / cool-down campaign of an axis with thermal drift and scale expansion,
/// `fit thermal`'s fit (every sensor, the order the twin feeds them), the thermo-force image, a new
/// campaign through `Compensator` fed the temperatures.
pub(crate) fn thermo_force(seed: u64, out: &mut ChainOutputs) -> Result<Row> {
    use axcomp_thermal::model_file::ThermalModelFile;
    use axcomp_thermal::{Selection, ThermalOptions, fit_thermal};
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
    out.files
        .push(("thermo_force_measurement.csv".into(), csv.into_bytes()));
    let input = thermal_input(&ds)?;
    // Every sensor, in the twin's order: the twin feeds the compensator's sensors by position.
    let opts = ThermalOptions {
        lags: false,
        selection: Selection::All,
        ..ThermalOptions::default()
    }
    .build()?;
    let fit = fit_thermal(&input, &opts).step(|| "thermal fit".into())?;
    let model =
        ThermalModelFile::from_fit(&fit, &input, "deviation_um", axcomp_twin::SENSOR_PERIOD_MS);
    if let Some((_, why)) = axcomp_image::board::thermal_model_refusal(&model) {
        return Err(DemoError::Invalid(format!("thermo-force model: {why}")));
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
    out.files.push(("thermo_force_image.bin".into(), image));
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

/// The group image of three identity axes of `um_per_count` with the geometric section `section`.
fn geometry_group_image(
    section: &axcomp_image::GeometricSection,
    um_per_count: f64,
) -> Result<Vec<u8>> {
    let images = (1..=3)
        .map(|id| bare(id, um_per_count as f32))
        .collect::<Result<Vec<_>>>()?;
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
        .map_err(|e| DemoError::Firmware(format!("geometry group image: {e}")))?;
    buf.truncate(n);
    Ok(buf)
}

/// Three-axis geometry: laser lines on the 800 × 600 × 500 mm twin, `fit geometry`'s fit, the
/// group image's geometric section (identity axes), the twin's volume commanded through the core
/// stage.
pub(crate) fn geometry(seed: u64, out: &mut ChainOutputs) -> Result<Row> {
    use axcomp_geometry::{FitOptions, Judge, LineData, analyse};
    use axcomp_twin::geometry::{GeometryTwin, plan_by_name};
    const STROKE: [f64; 3] = [800.0, 600.0, 500.0];
    const UPC: f64 = 0.1;
    let lines = plan_by_name("complete", STROKE, 11).step(|| "the twin plan `complete`".into())?;
    let twin = GeometryTwin::random(STROKE, Topology::default(), seed);
    let csv = twin.measure(&lines, 2, seed + 100).to_csv_string();
    let ds = Dataset::from_csv_str("lines.csv", &csv, &LoadOptions::default())?;
    out.files
        .push(("geometry_lines.csv".into(), csv.into_bytes()));
    let data = LineData::from_dataset(&ds, true)?;
    let model = analyse(&data, &Judge::None, &FitOptions::default())?
        .fit
        .model;
    let section = axcomp_image::geometric_from_model(&model, [UPC; 3], [0.0; 3])?;
    let buf = geometry_group_image(&section, UPC)?;
    let mut g: Box<Group<1024>> = Box::new(Group::new());
    g.load_image(&buf)
        .map_err(|e| DemoError::Firmware(format!("geometry group image: {e}")))?;
    let mut st = Box::new(GroupState::new());
    let per_mm = 1000.0 / UPC;
    let (lo, hi) = (model.volume_min_mm, model.volume_max_mm);
    // The twin's true error over an 11³ grid of the volume (not the measured lines).
    let r = twin.compensated_volume(lo, hi, 11, [0.0; 3], |q| {
        let mut input = GroupInput::ZERO;
        for (axis, q_mm) in input.axes.iter_mut().zip(q) {
            let c = (q_mm * per_mm).round() as i64;
            axis.command_counts = c;
            axis.scale_raw = c as u32;
        }
        let mut cycle_out = GroupOutput::ZERO;
        g.cycle(&mut st, &input, &mut cycle_out);
        std::array::from_fn(|k| cycle_out.axes[k].corrected_command_counts as f64 / per_mm)
    });
    out.files.push(("geometry_group.bin".into(), buf));
    Ok(Row {
        system: "three-axis geometry",
        figure: "volumetric |e| RMS, 11³ points of the volume (twin truth), µm",
        before: r.before_rms_um,
        after: r.after_rms_um,
        firmware: "Group geometric stage (21 components, identity axes)".into(),
    })
}
