//! The five-axis rotary chain of [`crate::all`]: an AC trunnion twin measured along K4 and C circles,
//! `fit rtest`'s fit with run 2 of K4 held out, the rotary section of a group image, the held-out K4
//! poses commanded through the core stage.

use axcomp_core::group::{AxisName, Group, GroupInput, GroupOutput, GroupState};
use axcomp_core::group_image::{self, AxisSectionSpec};
use axcomp_core::rotary::RotaryLocationSpec;
use axcomp_data::{Dataset, HoldoutSpec, LoadOptions};
use axcomp_kinematics::rotary::{FiveAxis, MachineKind, N_SETUP, Pose};
use axcomp_twin::five_axis::{FiveAxisTwin, standard_paths};

use crate::chains::bare;
use crate::row::{ChainOutputs, Row};
use crate::{DemoError, Result, StepContext};

/// Rotary axes' counts per revolution, X/Y/Z µm per count and the pivot of the five-axis chain.
const CPR: u32 = 3_600_000;
const UPC5: f64 = 0.1;
const PIVOT: [i64; 3] = [1_000_000, -2_000_000, 3_000_000];
/// Tool length of the five-axis chain, mm.
const TOOL_MM: f64 = 100.0;

fn angle_counts(deg: f64) -> i64 {
    (deg / 360.0 * CPR as f64).round() as i64
}

fn group_error(e: impl std::fmt::Display) -> DemoError {
    DemoError::Firmware(format!("rotary group image: {e}"))
}

/// The group image of X, Y, Z (identity linear axes) and A, C (identity rotary axes) with the rotary
/// section `spec`.
fn rotary_group_image(spec: &RotaryLocationSpec) -> Result<Vec<u8>> {
    let images = [(AxisName::X, 1), (AxisName::Y, 2), (AxisName::Z, 3)]
        .into_iter()
        .map(|(n, id)| Ok((n, 0, bare(id, UPC5 as f32)?)))
        .chain(
            [(AxisName::A, 4), (AxisName::C, 5)]
                .into_iter()
                .map(|(n, id)| Ok((n, CPR, bare(id, 360.0 * 3600.0 / CPR as f32)?))),
        )
        .collect::<Result<Vec<_>>>()?;
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
        vec![0u8; group_image::group_image_len_with_stages(&specs, Some(spec), None, None)];
    let n = group_image::write_group_image_with_stages(&specs, Some(spec), None, None, &mut buf)
        .map_err(group_error)?;
    buf.truncate(n);
    Ok(buf)
}

/// The largest range of one displacement component over the path, µm.
fn worst_range(v: &[[f64; 3]]) -> f64 {
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
}

/// The five-axis rotary chain (see the module documentation).
pub(crate) fn rotary(seed: u64, out: &mut ChainOutputs) -> Result<Row> {
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
    out.files
        .push(("rotary_rtest.csv".into(), csv.into_bytes()));
    let data = axcomp_rtest::RtestData::from_dataset(&ds, machine, true)?;
    let split = axcomp_data::Split::Holdout(HoldoutSpec::parse("run=2")?);
    let a = axcomp_rtest::analysis::analyse(&ds, &data, Some(&split))?;
    let spec = axcomp_image::rotary_from_rtest_model(&a.model, PIVOT, Some(TOOL_MM))?;
    let buf = rotary_group_image(&spec)?;
    let mut g: Box<Group<64>> = Box::new(Group::new());
    g.load_image(&buf).map_err(group_error)?;
    let (mut before, mut after) = (Vec::new(), Vec::new());
    // The held-out K4 path (run 2): the displacement at each pose, commanded plainly and through
    // the stage (the axes go where the corrected command says).
    for pose in &paths.last().step(|| "K4 run 2".into())?.poses {
        let lin = machine.linear_positions(pose);
        let c = |k: usize, mm: f64| PIVOT[k] + (mm * 1000.0 / UPC5).round() as i64;
        let cmd = [
            c(0, lin[0]),
            c(1, lin[1]),
            c(2, lin[2] + TOOL_MM),
            angle_counts(pose.tilt_deg),
            angle_counts(pose.c_deg),
        ];
        let pose_at = |xyz: [i64; 3]| Pose {
            p_mm: [0, 1, 2].map(|k| {
                (xyz[k] - PIVOT[k]) as f64 * UPC5 / 1000.0 - if k == 2 { TOOL_MM } else { 0.0 }
            }),
            tilt_deg: cmd[3] as f64 * 360.0 / CPR as f64,
            c_deg: cmd[4] as f64 * 360.0 / CPR as f64,
        };
        let nominal = pose_at([cmd[0], cmd[1], cmd[2]]);
        let s = machine.nominal_sphere(&nominal);
        before.push(machine.displacement_at(&nominal, s, &twin.location, [0.0; N_SETUP]));
        let mut st = Box::new(GroupState::new());
        let mut input = GroupInput::ZERO;
        for (axis, &c) in input.axes.iter_mut().zip(&cmd) {
            axis.command_counts = c;
            axis.scale_raw = c as u32;
        }
        let mut cycle_out = GroupOutput::ZERO;
        g.cycle(&mut st, &input, &mut cycle_out);
        let corrected = [0, 1, 2].map(|k| cycle_out.axes[k].corrected_command_counts);
        after.push(machine.displacement_at(&pose_at(corrected), s, &twin.location, [0.0; N_SETUP]));
    }
    out.files.push(("rotary_group.bin".into(), buf));
    Ok(Row {
        system: "five-axis rotary",
        figure: "largest K4 range (ISO 10791-6), held-out K4 run, µm",
        before: worst_range(&before),
        after: worst_range(&after),
        firmware: "Group rotary stage (AC trunnion location errors)".into(),
    })
}
