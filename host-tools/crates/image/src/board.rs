//! What a board would refuse of an image, found by the board's own code before the image reaches it:
//! `image build` warns, `image inspect` prints it.
//!
//! Glossary:
//! - *board*: the STM32G474 board (`axcomp_firmware::board_caps::stm32g474`): its counter width,
//!   axis ids, temperature sensors, named sensor inputs and table pool; `--board-inputs` replaces
//!   its sensor inputs (names and units) for a board wired otherwise.
//! - *refusal*: the board drive's answer to an image it will not run
//!   (`axcomp_firmware::drive::ImageRefusal`): from `BoardCaps::check` (counter width, axis id,
//!   sensor count), `axcomp_core::wiring::wire_axis` (each sensor to the input of its name: a
//!   `warmup` sensor on a board of RTDs), the axis-id check of the group and the group engine's own
//!   load (`GroupEngine::<POOL>::load_image`: the table pool). The drive stops at the first; here
//!   each axis is checked with the same functions so that every refusal is listed, and the drive's
//!   whole check (`drive::group::check_group_image_wired`) is run too, so nothing it refuses is missed.

use axcomp_core::group::GroupEngine;
use axcomp_core::group_image;
use axcomp_core::inspect_image;
use axcomp_core::wiring::{self, BoardInput, InputUnit};
use axcomp_firmware::board_caps::stm32g474;
use axcomp_firmware::drive::group::check_group_image_wired;

use crate::{Error, Result};

use axcomp_firmware::drive::{BoardCaps, ImageRefusal};

/// The board whose refusals `image build` and `image inspect` report.
pub const BOARD_NAME: &str = "STM32G474";

/// `--board-inputs` of the board: its sensor inputs as `NAME:UNIT,...`.
pub fn default_board_inputs() -> String {
    stm32g474::SENSOR_INPUTS
        .iter()
        .map(|i| {
            let unit = match i.unit {
                InputUnit::DegC => "degC",
                InputUnit::WarmupState => "warmup",
            };
            format!("{}:{unit}", i.name)
        })
        .collect::<Vec<_>>()
        .join(",")
}

/// Every refusal the board (its caps, with `inputs` as its sensor inputs) would make of `image`, as
/// sentences; empty when the board loads it. An image that does not parse is one refusal.
pub fn board_refusals(image: &[u8], inputs: &[(String, InputUnit)]) -> Vec<String> {
    let inputs: Vec<BoardInput> = inputs
        .iter()
        .map(|(name, unit)| BoardInput { name, unit: *unit })
        .collect();
    let caps = BoardCaps {
        sensors: inputs.len().min(usize::from(u16::MAX)) as u16,
        ..stm32g474::CAPS
    };
    let view = match group_image::parse(image) {
        Ok(v) => v,
        Err(e) => return vec![ImageRefusal::Invalid(e).to_string()],
    };
    let mut out = Vec::new();
    if let Err(e) = view.check_axis_ids() {
        out.push(ImageRefusal::Invalid(e).to_string());
    }
    let schema1 = view.version == 1;
    for a in view.axes() {
        let Ok(info) = inspect_image(a.axis.image) else {
            continue;
        };
        let who = axis_label(schema1, a.axis.name, info.axis_id);
        // The board's check stops at its first reason: each requirement is asked alone (the others
        // met), so that every reason is listed.
        let (id_ok, bits_ok) = (caps.axis_ids[0], caps.counter_bits);
        for (id, bits, n) in [
            (id_ok, info.counter_bits, 0),
            (info.axis_id, bits_ok, 0),
            (id_ok, bits_ok, info.n_sensors),
        ] {
            if let Err(e) = caps.check(id, bits, n) {
                out.push(format!("{who}: {}", with_way_out(&e)));
            }
        }
        if let Err(why) = wiring::wire_axis(a, info.n_sensors, &inputs) {
            let sensor = match why {
                wiring::WiringError::NotOnBoard { sensor }
                | wiring::WiringError::UnitMismatch { sensor } => a
                    .sensor_name(usize::from(sensor))
                    .map_or(String::new(), |n| format!(" (`{n}`)")),
                wiring::WiringError::NotWired { .. } => String::new(),
            };
            out.push(format!(
                "{who}: {why}{sensor}; the board's inputs are {} (name each sensor after the input \
                 that feeds it: `image build --sensor-input SENSOR=INPUT`)",
                inputs
                    .iter()
                    .map(|i| format!("`{}` ({})", i.name, i.unit.name()))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }
    // The drive's whole check, then the engine's load (the pool), as the board runs them.
    let drive = check_group_image_wired(&caps, Some(&inputs), image);
    match drive {
        Err(e) if out.is_empty() => out.push(e.to_string()),
        Err(_) => {}
        Ok(_) => {
            let mut engine = Box::new(GroupEngine::<{ stm32g474::POOL }>::new());
            if let Err(mut e) = engine.load_image(image) {
                // A schema-1 image names no axis (the core presents it as X): say its id instead.
                let id = view
                    .axes()
                    .next()
                    .and_then(|a| inspect_image(a.axis.image).ok());
                match id {
                    Some(info) if schema1 => {
                        e.axis = None;
                        out.push(format!(
                            "axis id {}: {}",
                            info.axis_id,
                            ImageRefusal::Group(e)
                        ));
                    }
                    _ => out.push(ImageRefusal::Group(e).to_string()),
                }
            }
        }
    }
    out
}

/// "axis Y (id 2)" for a group's axis; "axis id 2" for a schema-1 image, which names no axis.
pub fn axis_label(schema1: bool, name: axcomp_core::group::AxisName, axis_id: u16) -> String {
    if schema1 {
        format!("axis id {axis_id}")
    } else {
        format!("axis {} (id {axis_id})", name.letter())
    }
}

/// The refusal, with what to change where the board's own setting is the likelier fix.
fn with_way_out(e: &ImageRefusal) -> String {
    match e {
        ImageRefusal::AxisNotWired { .. } => format!(
            "{e} (the board's scale inputs carry axis ids {:?}: build with one of them, or set the \
             board's AXIS_IDS to the machine's)",
            stm32g474::AXIS_IDS
        ),
        ImageRefusal::CounterWidth { board, .. } => {
            format!("{e} (build with --counter-bits {board})")
        }
        ImageRefusal::SensorsNotWired { board, .. } => {
            format!("{e} (fit the model on at most {board} sensors)")
        }
        _ => e.to_string(),
    }
}

/// The refusals as `image build` and `image inspect` print them (empty when there are none).
pub fn describe_refusals(refusals: &[String]) -> String {
    if refusals.is_empty() {
        return format!("board {BOARD_NAME}: loads this image (its own checks, run here)\n");
    }
    let mut s = format!(
        "board {BOARD_NAME}: REFUSES this image ({} reason{}; its own checks, run here):\n",
        refusals.len(),
        if refusals.len() == 1 { "" } else { "s" }
    );
    for r in refusals {
        s.push_str(&format!("  - {r}\n"));
    }
    s
}

/// Why the firmware would refuse a thermo-force model in an image (the core's image check,
/// `axcomp_core::write_image`, on an image holding only this model), or `None` when it takes it.
/// `fit thermal` warns with it; `image build` refuses with it (naming the range of any other value).
pub fn thermal_model_refusal(
    model: &axcomp_thermal::model_file::ThermalModelFile,
) -> Option<(axcomp_core::ImageError, String)> {
    use axcomp_core::{Field, ImageError, ImageSpec, LimitSpec, image_len, write_image};
    let thermo = model.to_core();
    let spec = ImageSpec {
        axis_id: stm32g474::AXIS_IDS[0],
        um_per_count: 1.0,
        counter_bits: stm32g474::CAPS.counter_bits,
        table: None,
        thermo: Some(thermo.spec()),
        limits: LimitSpec {
            max_correction_um: 1000.0,
            max_slew_um_per_cycle: 5.0,
            direction_hysteresis_counts: 2,
        },
    };
    let mut buf = vec![0u8; image_len(&spec)];
    let e = write_image(&spec, &mut buf).err()?;
    let why = match e {
        ImageError::OutOfRange {
            field: Field::B0, ..
        }
        | ImageError::NonFinite {
            field: Field::B0, ..
        } => format!(
            "the model's intercept b0 = {} µm is beyond the firmware's ±{} µm ({e}): its target \
             is an absolute position, not a deviation; fit it with --zero-at-start N (the change since \
             the start) or --runs COL",
            model.b0_um,
            axcomp_core::image::MAX_B0_UM
        ),
        ImageError::NonFinite { field, index } | ImageError::OutOfRange { field, index } => {
            let sensor = model
                .sensors
                .get(usize::from(index))
                .map_or(String::new(), |s| {
                    format!(" (sensors[{index}] `{}`)", s.name)
                });
            format!("{e}{sensor}: outside the firmware's range for {field:?}")
        }
        _ => format!("the firmware's image check refuses it: {e}"),
    };
    Some((e, why))
}

/// `--board-inputs NAME:UNIT,...` (UNIT `degC` or `warmup`).
pub fn parse_board_inputs(list: &str) -> Result<Vec<(String, InputUnit)>> {
    list.split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| {
            let (name, unit) = s.trim().split_once(':').ok_or_else(|| {
                Error::Invalid(format!("--board-inputs `{s}`: expected NAME:UNIT"))
            })?;
            let unit = match unit {
                "degC" | "°C" => InputUnit::DegC,
                "warmup" => InputUnit::WarmupState,
                u => {
                    return Err(Error::Invalid(format!(
                        "--board-inputs `{s}`: unit `{u}` is not degC or warmup"
                    )));
                }
            };
            Ok((name.to_string(), unit))
        })
        .collect::<Result<Vec<_>>>()
        .and_then(|inputs| {
            // The firmware wires a sensor to the input of its name: a name given twice is ambiguous.
            for (k, (name, _)) in inputs.iter().enumerate() {
                ensure!(
                    !inputs[..k].iter().any(|(n, _)| n == name),
                    "--board-inputs `{list}`: input `{name}` is named twice"
                );
            }
            Ok(inputs)
        })
}
