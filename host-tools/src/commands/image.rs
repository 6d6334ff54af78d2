//! `axcomp image build|inspect|group`: the firmware's binary image, from fitted model files.
//!
//! Glossary (the conversions and checks live in `axcomp_image`):
//! - *image*: the versioned, CRC-protected binary the firmware loads (`axcomp_core::write_image`).
//! - *table file*: a fitted positioning table (`fit positioning --out`), JSON, physical units.
//! - *thermal model file*: a fitted thermo-force model (`fit thermal --out`), JSON.
//! - *counts*: scale counts; `um_per_count` is the scale resolution.
//! - *group image*: schema 2, one section per axis (each holding that axis's schema-1 image), an
//!   optional rotary location-error model, geometric model and probe settings, built by `image
//!   group` from images of `image build`.
//! - *double correction*: two sources of one group image correcting the same error; `image group`
//!   refuses it (naming both sources) and writes nothing; with `--exclude-geometric` the geometric
//!   model's components are left out (`axcomp_image::group::refuse_double_correction`).

use std::path::PathBuf;

use anyhow::Context;
use axcomp_core::provenance;
use axcomp_core::{Compensator, ImageSpec, LimitSpec, image_len, inspect_image, write_image};
use axcomp_image::board::{self, parse_board_inputs};
use axcomp_image::extension::FieldSource;
use axcomp_image::{describe_any, describe_trust};
use axcomp_positioning::TableFile;
use axcomp_thermal::model_file::ThermalModelFile;

use crate::output::OutputSet;

#[derive(Debug, clap::Args)]
pub struct BuildArgs {
    /// Positioning table (JSON from `fit positioning --out`).
    #[arg(long, value_name = "TABLE.json")]
    pub table: Option<PathBuf>,
    /// Thermo-force model (JSON from `fit thermal --out`).
    #[arg(long, value_name = "MODEL.json")]
    pub thermal: Option<PathBuf>,
    /// An image with no table and no thermo-force term (only the limits): the axis of a group that has
    /// no correction of its own (`image group` needs an image for every axis; its geometric or rotary
    /// stage may still correct it). The firmware applies zero correction to it.
    #[arg(long, conflicts_with_all = ["table", "thermal", "sensor_input"])]
    pub identity: bool,
    /// Axis id stored in the image (the firmware refuses an image for another axis).
    #[arg(long, value_name = "N")]
    pub axis_id: u16,
    /// Scale resolution, µm per count.
    #[arg(long, value_name = "U")]
    pub um_per_count: f64,
    /// Width of the hardware position counter (16..=32). Default 16: the STM32G474 board's encoder
    /// timers are 16-bit, and an image for a wider counter would jump by 65 536 counts at each wrap
    /// there; give 32 for a 32-bit counter (e.g. a scale interface with a 32-bit position).
    #[arg(long, default_value_t = 16)]
    pub counter_bits: u8,
    /// Clamp of the total correction, µm.
    #[arg(long, default_value_t = 1000.0)]
    pub max_correction_um: f32,
    /// Largest change of the applied correction per control cycle, µm.
    #[arg(long, default_value_t = 5.0)]
    pub max_slew_um: f32,
    /// Hysteresis (counts) before a reversal switches between forward and backward tables.
    #[arg(long, default_value_t = 2)]
    pub hysteresis_counts: u32,
    /// Output image file.
    #[arg(long, value_name = "IMAGE")]
    pub out: PathBuf,
    /// Name a model sensor after the board input that feeds it (repeatable), e.g. `frame=rtd0`. The image
    /// keeps one name per sensor (the model's, or this one); the firmware wires each sensor to the board
    /// input of that name and refuses the image when the board has no such input (the STM32G474 board:
    /// `rtd0`, `rtd1`, °C).
    #[arg(long = "sensor-input", value_name = "SENSOR=INPUT")]
    pub sensor_input: Vec<String>,
    /// The board's sensor inputs in reading order, `NAME:UNIT,...` (UNIT `degC` or `warmup`), for the
    /// check of what the board would refuse (warned, the image is still written). Default: the
    /// STM32G474 board's.
    #[arg(long, value_name = "LIST", default_value_t = board::default_board_inputs())]
    pub board_inputs: String,
}

#[derive(Debug, clap::Args)]
pub struct InspectArgs {
    /// The image file.
    #[arg(value_name = "IMAGE")]
    pub image: PathBuf,
    /// The board's sensor inputs in reading order, `NAME:UNIT,...` (UNIT `degC` or `warmup`), to show
    /// which input feeds each sensor and what the board would refuse. Default: the STM32G474 board's
    /// (`axcomp_firmware::board_caps::stm32g474::SENSOR_INPUTS`).
    #[arg(long, value_name = "LIST", default_value_t = board::default_board_inputs())]
    pub board_inputs: String,
}

/// Builds the image bytes from the table/model files (validated; nothing is written here).
pub fn build_bytes(args: &BuildArgs) -> anyhow::Result<Vec<u8>> {
    if args.table.is_none() && args.thermal.is_none() && !args.identity {
        anyhow::bail!(
            "image build: give --table and/or --thermal, or --identity for an axis without correction"
        );
    }
    if !(args.um_per_count.is_finite() && args.um_per_count > 0.0) {
        anyhow::bail!(
            "--um-per-count {}: must be a finite number > 0",
            args.um_per_count
        );
    }
    let table = match &args.table {
        Some(p) => {
            let t = TableFile::load(p).with_context(|| format!("reading table {}", p.display()))?;
            Some(
                t.try_to_core(args.um_per_count)
                    .with_context(|| format!("{}: converting to scale counts", p.display()))?,
            )
        }
        None => None,
    };
    let model = match &args.thermal {
        Some(p) => Some(
            ThermalModelFile::load(p)
                .with_context(|| format!("reading thermal model {}", p.display()))?,
        ),
        None => None,
    };
    if let (Some(p), Some(m)) = (&args.thermal, &model) {
        // What the firmware's image check refuses of the model alone (an absolute b0); any other
        // value out of range: `spec_error` names its range below.
        if let Some((
            axcomp_core::ImageError::OutOfRange { field, .. }
            | axcomp_core::ImageError::NonFinite { field, .. },
            why,
        )) = board::thermal_model_refusal(m)
            && field == axcomp_core::Field::B0
        {
            anyhow::bail!("{}: {why}", p.display());
        }
    }
    let model_sensors: Vec<String> = model
        .iter()
        .flat_map(|m| &m.sensors)
        .map(|s| s.name.clone())
        .collect();
    let thermo = model.as_ref().map(ThermalModelFile::to_core);
    let spec = ImageSpec {
        axis_id: args.axis_id,
        um_per_count: args.um_per_count as f32,
        counter_bits: args.counter_bits,
        table: table.as_ref().map(|t| t.spec()),
        thermo: thermo.as_ref().map(|t| t.spec()),
        limits: LimitSpec {
            max_correction_um: args.max_correction_um,
            max_slew_um_per_cycle: args.max_slew_um,
            direction_hysteresis_counts: args.hysteresis_counts,
        },
    };
    let mut buf = vec![0u8; image_len(&spec)];
    let n = write_image(&spec, &mut buf).map_err(|e| spec_error(e, args, &model_sensors))?;
    buf.truncate(n);
    // The header extension: sensor names (the thermal model's, or --sensor-input) and provenance.
    let names = match (&args.thermal, &model) {
        (Some(p), Some(m)) => {
            axcomp_image::extension::sensor_names(&p.display().to_string(), m, &args.sensor_input)?
        }
        _ if !args.sensor_input.is_empty() => {
            anyhow::bail!("--sensor-input needs --thermal (the image has no sensors without it)")
        }
        _ => vec![],
    };
    let mut records = Vec::new();
    for (p, role) in [
        (&args.table, provenance::role::POSITIONING_TABLE),
        (&args.thermal, provenance::role::THERMAL_MODEL),
    ] {
        if let Some(p) = p {
            records.push(crate::provenance::model_record(
                p,
                provenance::ANY_AXIS,
                role,
            )?);
        }
    }
    let block = crate::provenance::image_block(&records)?;
    Ok(axcomp_image::with_extension(buf, &block, &names)?)
}

/// `write_image`'s refusal of the spec `image build` made, naming the file or option the value came
/// from and the firmware's range for it.
fn spec_error(e: axcomp_core::ImageError, args: &BuildArgs, sensors: &[String]) -> anyhow::Error {
    let file = |p: &Option<PathBuf>| {
        p.as_ref()
            .map_or_else(String::new, |p| p.display().to_string())
    };
    let shown = |source: FieldSource| match source {
        FieldSource::Table => file(&args.table),
        FieldSource::Thermal(_) => file(&args.thermal),
        FieldSource::Option(name) => {
            let value = match name {
                "--um-per-count" => args.um_per_count.to_string(),
                "--counter-bits" => args.counter_bits.to_string(),
                "--max-correction-um" => args.max_correction_um.to_string(),
                "--max-slew-um" => args.max_slew_um.to_string(),
                _ => args.hysteresis_counts.to_string(),
            };
            format!("{name} {value}")
        }
    };
    axcomp_image::extension::spec_error(e, shown, sensors).into()
}

pub fn build(args: BuildArgs) -> anyhow::Result<()> {
    let mut outputs = OutputSet::new();
    outputs.planned(&args.out);
    for p in [&args.table, &args.thermal].into_iter().flatten() {
        outputs.input(p);
    }
    outputs.check()?;
    let board = parse_board_inputs(&args.board_inputs)?;
    let bytes = build_bytes(&args)?;
    // Check what was built loads, before writing it.
    let mut comp = Compensator::IDENTITY;
    comp.load(&bytes)
        .context("the built image does not load (internal error)")?;
    outputs.file(&args.out, bytes.as_slice());
    outputs.commit()?;
    let info = inspect_image(&bytes)?;
    let table = match (info.n_segments, info.bidirectional) {
        (0, _) => "no table".to_string(),
        (n, true) => format!("{n} segments per direction"),
        (n, false) => format!("{n} segments"),
    };
    println!(
        "wrote {} ({} bytes, axis id {}, {table}, thermo: {}{}, CRC-32 {:08x})",
        args.out.display(),
        info.len,
        info.axis_id,
        if info.has_thermo { "yes" } else { "no" },
        if args.identity {
            "; identity: the firmware applies no correction to this axis"
        } else {
            ""
        },
        info.crc
    );
    let refusals = board::board_refusals(&bytes, &board);
    for r in &refusals {
        eprintln!(
            "axcomp: warning: {}: the {} board would refuse this image: {r}",
            args.out.display(),
            board::BOARD_NAME
        );
    }
    Ok(())
}

pub fn inspect(args: InspectArgs) -> anyhow::Result<()> {
    let bytes = std::fs::read(&args.image)
        .with_context(|| format!("cannot read {}", args.image.display()))?;
    let board = parse_board_inputs(&args.board_inputs)?;
    let text =
        describe_any(&bytes).with_context(|| format!("{}: invalid image", args.image.display()))?;
    print!("{text}");
    print!("{}", describe_trust(&bytes, &board)?);
    let refusals = board::board_refusals(&bytes, &board);
    print!("{}", board::describe_refusals(&refusals));
    Ok(())
}
