//! `axcomp image build|inspect`: the firmware's binary table image.
//!
//! Glossary:
//! - *image*: the versioned, CRC-protected binary the firmware loads (`axcomp_core::write_image`).
//! - *table file*: a fitted positioning table (`fit positioning --out`), JSON, physical units.
//! - *thermal model file*: a fitted thermo-force model (`fit thermal --out`), JSON.
//! - *counts*: scale counts; `um_per_count` is the scale resolution.
//! - *group image*: schema 2, one section per axis (each holding that axis's schema-1 image), an
//!   optional rotary location-error model and sensor names (`axcomp_core::group_image`), built by
//!   `image group` from images of `image build`.
//! - *geometric section*: a `fit geometry` model converted for the core's volumetric stage
//!   (`axcomp_core::geometric`): each of the 18 component functions, a cubic B-spline on its axis's
//!   knot grid in mm, becomes per-segment Horner polynomials over the same knots in counts; the
//!   squareness constants, the stacking and the tool offset are copied. A component the fit marks
//!   `identified: false` goes in as zero (the model's prior) and `image inspect` says so.
//! - *double correction*: two sources of one group image correcting the same error: an axis's
//!   positioning table and the geometric model's positioning component of that axis (EXX, EYY,
//!   EZZ), or the rotary model's squareness and the geometric model's (EC0Y, EB0Z, EA0Z), both
//!   non-zero. `image group` refuses it (naming both sources) and writes nothing; with
//!   `--exclude-geometric` the geometric model's components are left out (stored as zero, their
//!   identified bit kept: `image inspect` lists an identified component stored as zero as
//!   excluded).

use std::path::PathBuf;

use anyhow::Context;
use axcomp_core::geometric::{
    COMPONENT_NAMES, FUNCTIONS_PER_AXIS, GeometricCoefficients, GeometricGrid, GeometricSpec,
};
use axcomp_core::group::AxisName;
use axcomp_core::group_image::{self, AxisSectionSpec};
use axcomp_core::probe::ProbeSettings;
use axcomp_core::provenance;
use axcomp_core::rotary::{RotaryLocationSpec, RotaryMachine};
use axcomp_core::wiring::{BoardInput, InputUnit};
use axcomp_core::{Compensator, ImageSpec, LimitSpec, image_len, inspect_image, write_image};
use axcomp_geometry::GeometryModel;
use axcomp_kinematics::rotary::MachineKind;
use axcomp_positioning::TableFile;
use axcomp_rtest::RtestModel;
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
    #[arg(long, value_name = "LIST", default_value_t = super::image_board::default_board_inputs())]
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
    #[arg(long, value_name = "LIST", default_value_t = super::image_board::default_board_inputs())]
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
    let mut model_sensors = Vec::new();
    let thermo = match &args.thermal {
        Some(p) => {
            let m = ThermalModelFile::load(p)
                .with_context(|| format!("reading thermal model {}", p.display()))?;
            model_sensors = m.sensors.iter().map(|s| s.name.clone()).collect();
            // What the firmware's image check refuses of the model alone (e.g. an absolute b0).
            // (Any other value out of range: `spec_error` names its range below.)
            if let Some((e, why)) = super::image_board::thermal_model_refusal(&m) {
                if matches!(
                    e,
                    axcomp_core::ImageError::OutOfRange {
                        field: axcomp_core::Field::B0,
                        ..
                    } | axcomp_core::ImageError::NonFinite {
                        field: axcomp_core::Field::B0,
                        ..
                    }
                ) {
                    anyhow::bail!("{}: {why}", p.display());
                }
            }
            Some(m.to_core())
        }
        None => None,
    };
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
    let names = match &args.thermal {
        Some(p) => sensor_names(
            p,
            &ThermalModelFile::load(p)
                .with_context(|| format!("reading thermal model {}", p.display()))?,
            &args.sensor_input,
        )?,
        None if !args.sensor_input.is_empty() => {
            anyhow::bail!("--sensor-input needs --thermal (the image has no sensors without it)")
        }
        None => vec![],
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
    with_extension(buf, &records, &names)
}

/// `write_image`'s refusal of the spec `image build` made, as a message naming where the value came
/// from (the table or thermal model file, or the option) and the firmware's range for it
/// (`axcomp_core` image, "Validation ranges").
fn spec_error(
    e: axcomp_core::ImageError,
    args: &BuildArgs,
    sensor_names: &[String],
) -> anyhow::Error {
    use axcomp_core::{Field, ImageError};
    let field = match e {
        ImageError::NonFinite { field, .. } | ImageError::OutOfRange { field, .. } => field,
        _ => return anyhow::anyhow!("the image spec is not valid: {e}"),
    };
    let file = |p: &Option<PathBuf>| {
        p.as_ref()
            .map_or_else(String::new, |p| p.display().to_string())
    };
    let (source, range) = match field {
        Field::ForwardCoefficient | Field::BackwardCoefficient => (
            file(&args.table),
            "a segment's deviation must stay within ±10 000 µm (f32 in the image)",
        ),
        Field::StartCounts | Field::SegmentCounts | Field::Outside => (
            file(&args.table),
            "in counts at this --um-per-count the table must start within ±2^62 counts and span at \
             most 4 294 967 295 counts",
        ),
        Field::UmPerCount => (
            format!("--um-per-count {}", args.um_per_count),
            "µm per count must be in [1e-6, 1e4]",
        ),
        Field::CounterBits => (
            format!("--counter-bits {}", args.counter_bits),
            "the counter has 16 to 32 bits",
        ),
        Field::MaxCorrection => (
            format!("--max-correction-um {}", args.max_correction_um),
            "must be in (0, 100000] µm",
        ),
        Field::MaxSlew => (
            format!("--max-slew-um {}", args.max_slew_um),
            "must be in (0, 100000] µm",
        ),
        Field::Hysteresis => (
            format!("--hysteresis-counts {}", args.hysteresis_counts),
            "at most 2147483647 counts",
        ),
        _ => {
            let (key, range) = match field {
                Field::ReferenceDegc | Field::SensorRange => (
                    "sensors",
                    "temperatures must be in [−273.15, 2000] °C, min < max",
                ),
                Field::MaxRate => ("sensors", "max_rate_degc_per_s must be in (0, 1e6] K/s"),
                Field::LagTau => ("sensors", "tau_s must be in [0, 1e7] s"),
                Field::StaleTimeout => ("sensors", "stale_timeout_ms must be ≥ 1 ms"),
                Field::BUmPerK => ("sensors", "|coef_um_per_k| must be ≤ 1e4 µm/K"),
                Field::RiseBounds => ("sensors", "rise_min_k < rise_max_k, both within ±2273.15 K"),
                Field::Chi => ("forces", "|chi_um_per_n| must be ≤ 1e3 µm/N"),
                Field::ForceLaw => ("forces", "a force law needs |k| ≤ 1e9 and |exponents| ≤ 10"),
                Field::B0 => ("", "|b0_um| must be ≤ 1e5 µm"),
                Field::SensorPeriod => ("", "sensor_period_ms must be ≥ 1 ms"),
                _ => ("", "outside the firmware's range"),
            };
            let at = match (key, e) {
                (
                    "sensors",
                    ImageError::NonFinite { index, .. } | ImageError::OutOfRange { index, .. },
                ) => match sensor_names.get(usize::from(index)) {
                    Some(n) => format!(" (sensors[{index}], `{n}`)"),
                    None => format!(" (sensors[{index}])"),
                },
                (
                    "forces",
                    ImageError::NonFinite { index, .. } | ImageError::OutOfRange { index, .. },
                ) => format!(" (forces[{index}])"),
                _ => String::new(),
            };
            (format!("{}{at}", file(&args.thermal)), range)
        }
    };
    anyhow::anyhow!("{source}: {e}: {range}")
}

/// A schema-1 image with its header extension: the provenance block (tool, date, `records`) and, if
/// any, the sensor names (`PROV`, `SNAM`; CRC-covered, ignored by the correction).
pub fn with_extension(
    image: Vec<u8>,
    records: &[axcomp_core::provenance::ProvenanceRecord],
    names: &[String],
) -> anyhow::Result<Vec<u8>> {
    let block = crate::provenance::image_block(records)?;
    let mut field = vec![0u8; group_image::SENSOR_NAME_LEN * names.len()];
    for (i, n) in names.iter().enumerate() {
        let at = group_image::SENSOR_NAME_LEN * i;
        field[at..at + n.len()].copy_from_slice(n.as_bytes());
    }
    let mut blocks = vec![(provenance::PROVENANCE_TAG, block.as_slice())];
    if !names.is_empty() {
        blocks.push((provenance::SENSOR_NAMES_TAG, field.as_slice()));
    }
    let mut out = vec![0u8; image.len() + provenance::extension_len(&blocks)];
    let n = provenance::with_header_extension(&image, &blocks, &mut out)
        .map_err(|e| anyhow::anyhow!("the image's sensor names or provenance: {e}"))?;
    out.truncate(n);
    Ok(out)
}

/// One name per sensor of the thermal model (its order is the firmware's): the model's name, or the board
/// input `--sensor-input SENSOR=INPUT` gives it; each 1..=15 bytes.
fn sensor_names(
    path: &std::path::Path,
    model: &ThermalModelFile,
    renames: &[String],
) -> anyhow::Result<Vec<String>> {
    let mut names: Vec<String> = model.sensors.iter().map(|s| s.name.clone()).collect();
    let mut given: Vec<(&str, &str)> = Vec::new();
    for r in renames {
        let (from, to) = r
            .split_once('=')
            .with_context(|| format!("--sensor-input `{r}`: expected SENSOR=INPUT"))?;
        if let Some((_, before)) = given.iter().find(|(f, t)| *f == from && *t != to) {
            anyhow::bail!(
                "--sensor-input `{r}`: sensor `{from}` is already given input `{before}` (one input per sensor)"
            );
        }
        given.push((from, to));
        let Some(k) = model.sensors.iter().position(|s| s.name == from) else {
            anyhow::bail!(
                "--sensor-input `{r}`: `{from}` is not a sensor of {} (have: {})",
                path.display(),
                names.join(", ")
            );
        };
        names[k] = to.to_string();
    }
    // The firmware wires each sensor to the board input of its name: two sensors of one name would
    // read one input, each with its own coefficient.
    for (j, n) in names.iter().enumerate() {
        if let Some(i) = names[..j].iter().position(|m| m == n) {
            let (a, b) = (&model.sensors[i].name, &model.sensors[j].name);
            if a == b {
                anyhow::bail!(
                    "{}: sensors[{i}] and sensors[{j}] are both named `{n}`; the image wires sensors by \
                     name, so both would read one input (rename one in the model, or wire it with \
                     --sensor-input)",
                    path.display()
                );
            }
            anyhow::bail!(
                "--sensor-input: sensors `{a}` and `{b}` of {} would both read input `{n}` (one input per \
                 sensor)",
                path.display()
            );
        }
    }
    for n in &names {
        anyhow::ensure!(
            !n.is_empty() && n.len() < group_image::SENSOR_NAME_LEN && !n.contains('\0'),
            "sensor `{n}` of {}: an image keeps sensor names of 1 to {} bytes; name it after its board \
             input with --sensor-input {n}=INPUT",
            path.display(),
            group_image::SENSOR_NAME_LEN - 1
        );
    }
    Ok(names)
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
    let refusals = super::image_board::board_refusals(&bytes, &board);
    for r in &refusals {
        eprintln!(
            "axcomp: warning: {}: the {} board would refuse this image: {r}",
            args.out.display(),
            super::image_board::BOARD_NAME
        );
    }
    Ok(())
}

/// The text `image inspect` prints for a valid image.
pub fn describe(bytes: &[u8]) -> anyhow::Result<String> {
    use std::fmt::Write;
    let info = inspect_image(bytes)?;
    let mut comp = Compensator::IDENTITY;
    comp.load(bytes)?;
    let mut s = String::new();
    writeln!(
        s,
        "image: {} bytes, schema version {}, CRC-32 {:08x} (ok)",
        info.len, info.version, info.crc
    )?;
    writeln!(s, "axis id: {}", info.axis_id)?;
    writeln!(
        s,
        "scale: {} µm/count, {}-bit counter",
        comp.um_per_count(),
        info.counter_bits
    )?;
    let l = comp.limits();
    writeln!(
        s,
        "limits: |correction| <= {} µm, slew <= {} µm/cycle, reversal hysteresis {} counts",
        l.max_correction_um, l.max_slew_um_per_cycle, l.direction_hysteresis_counts
    )?;
    if comp.has_table() {
        let um = comp.um_per_count() as f64;
        let start = comp.table_start_counts();
        let seg = comp.segment_counts() as i64;
        let n = info.n_segments as i64;
        writeln!(
            s,
            "table: {} segments{} of {} counts ({:.4} mm), {} .. {} counts ({:.4} .. {:.4} mm), outside: {:?}",
            info.n_segments,
            if info.bidirectional {
                " per direction"
            } else {
                " (unidirectional)"
            },
            seg,
            seg as f64 * um / 1000.0,
            start,
            start + seg * n,
            start as f64 * um / 1000.0,
            (start + seg * n) as f64 * um / 1000.0,
            comp.outside()
        )?;
        for (name, tab) in [
            ("forward", comp.forward_segments()),
            ("backward", comp.backward_segments()),
        ] {
            if tab.is_empty() {
                continue;
            }
            // Knot values c0 and the end value of the last segment.
            let mut lo = f32::INFINITY;
            let mut hi = f32::NEG_INFINITY;
            for c in tab {
                lo = lo.min(c[0]);
                hi = hi.max(c[0]);
            }
            // The last segment at its end, r = L (the coefficients are in the remainder r,
            // counts from the knot: c0 + r·(c1 + r·(c2 + r·c3))).
            let last = tab[tab.len() - 1].map(f64::from);
            let l = comp.segment_counts() as f64;
            let end = (last[0] + l * (last[1] + l * (last[2] + l * last[3]))) as f32;
            lo = lo.min(end);
            hi = hi.max(end);
            writeln!(s, "  {name}: deviation at knots {lo:.3} .. {hi:.3} µm")?;
        }
    } else {
        writeln!(s, "table: none")?;
    }
    if info.has_thermo {
        writeln!(
            s,
            "thermo-force: {} sensors (period {} ms), b0 = {} µm, {} force terms, expansion: {}",
            info.n_sensors,
            comp.sensor_period_ms(),
            comp.b0_um(),
            info.n_forces,
            if comp.expansion().is_some() {
                "yes"
            } else {
                "no"
            }
        )?;
        let switch_on = comp.thermo_reference() == axcomp_core::ThermoReference::SwitchOn;
        writeln!(
            s,
            "  reference: {}; range guard: {}",
            if switch_on {
                "each sensor's first reading after load/reset (switch-on); ref = nominal"
            } else {
                "fixed (ref per sensor)"
            },
            if comp.has_rise_guard() {
                "on (a sensor's term is left out while its rise is outside its bounds)"
            } else {
                "off"
            }
        )?;
        for i in 0..comp.sensor_count() {
            if let (Some(sp), Some(b)) = (comp.sensor(i), comp.b_um_per_k(i)) {
                write!(
                    s,
                    "  sensor {i}: ref {} °C, range {} .. {} °C, b = {} µm/K, lag τ = {} s",
                    sp.reference_degc, sp.min_degc, sp.max_degc, b, sp.lag_tau_s
                )?;
                match comp.rise_bounds_k(i) {
                    Some((lo, hi)) => writeln!(s, ", rise {lo} .. {hi} K")?,
                    None => writeln!(s)?,
                }
            }
        }
    } else {
        writeln!(s, "thermo-force: none")?;
    }
    Ok(s)
}

pub fn inspect(args: InspectArgs) -> anyhow::Result<()> {
    let bytes = std::fs::read(&args.image)
        .with_context(|| format!("cannot read {}", args.image.display()))?;
    let board = parse_board_inputs(&args.board_inputs)?;
    let text =
        describe_any(&bytes).with_context(|| format!("{}: invalid image", args.image.display()))?;
    print!("{text}");
    print!("{}", describe_trust(&bytes, &board)?);
    let refusals = super::image_board::board_refusals(&bytes, &board);
    print!("{}", super::image_board::describe_refusals(&refusals));
    Ok(())
}

/// `--board-inputs NAME:UNIT,...` (UNIT `degC` or `warmup`).
pub fn parse_board_inputs(list: &str) -> anyhow::Result<Vec<(String, InputUnit)>> {
    list.split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| {
            let (name, unit) = s
                .trim()
                .split_once(':')
                .with_context(|| format!("--board-inputs `{s}`: expected NAME:UNIT"))?;
            let unit = match unit {
                "degC" | "°C" => InputUnit::DegC,
                "warmup" => InputUnit::WarmupState,
                u => anyhow::bail!("--board-inputs `{s}`: unit `{u}` is not degC or warmup"),
            };
            Ok((name.to_string(), unit))
        })
        .collect::<anyhow::Result<Vec<_>>>()
        .and_then(|inputs| {
            // The firmware wires a sensor to the input of its name: a name given twice is ambiguous.
            for (k, (name, _)) in inputs.iter().enumerate() {
                anyhow::ensure!(
                    !inputs[..k].iter().any(|(n, _)| n == name),
                    "--board-inputs `{list}`: input `{name}` is named twice"
                );
            }
            Ok(inputs)
        })
}

/// Provenance, sensor names and their wiring onto `board` (the part of `image inspect` after the axes).
pub fn describe_trust(bytes: &[u8], board: &[(String, InputUnit)]) -> anyhow::Result<String> {
    use std::fmt::Write;
    let view = group_image::parse(bytes)?;
    let inputs: Vec<BoardInput> = board
        .iter()
        .map(|(name, unit)| BoardInput { name, unit: *unit })
        .collect();
    let mut s = String::new();
    match view.provenance {
        Some(p) => {
            writeln!(s, "provenance: built {} by {}", p.built_utc(), p.tool())?;
            for r in p.records() {
                let axis = AxisName::from_code(r.axis)
                    .map_or(String::new(), |a| format!("axis {}: ", a.letter()));
                writeln!(
                    s,
                    "  {axis}{} sha256 {}; data sha256 {}",
                    provenance::role::name(r.role),
                    crate::provenance::to_hex(&r.model_sha256),
                    if r.data_sha256 == [0; 32] {
                        "not recorded".to_string()
                    } else {
                        crate::provenance::to_hex(&r.data_sha256)
                    }
                )?;
            }
        }
        None => writeln!(s, "provenance: none (built before images carried it)")?,
    }
    writeln!(
        s,
        "board inputs: {}",
        board
            .iter()
            .enumerate()
            .map(|(k, (n, u))| format!("{k} {n} ({})", u.name()))
            .collect::<Vec<_>>()
            .join(", ")
    )?;
    for a in view.axes() {
        let n = inspect_image(a.axis.image)?.n_sensors;
        if n == 0 {
            continue;
        }
        let named = !a.sensor_names.is_empty();
        let wiring = axcomp_core::wiring::wire_axis(a, n, &inputs);
        writeln!(
            s,
            "{} sensors ({}): {}",
            super::image_board::axis_label(
                view.version == 1,
                a.axis.name,
                inspect_image(a.axis.image)?.axis_id
            ),
            if named {
                "wired by name"
            } else {
                "no names: wired by position"
            },
            match &wiring {
                Ok(_) => "every sensor has its input".to_string(),
                Err(e) => format!("REFUSED by this board: {e}"),
            }
        )?;
        for j in 0..n {
            let name = a.sensor_name(j).unwrap_or("(unnamed)");
            let to = match &wiring {
                Ok(w) => {
                    let k = usize::from(w[j]);
                    format!(
                        "board input {k} {} ({})",
                        inputs[k].name,
                        inputs[k].unit.name()
                    )
                }
                Err(_) => match inputs.iter().position(|i| i.name == name) {
                    Some(k) if named => format!("board input {k} {}", inputs[k].name),
                    _ if !named && j < inputs.len() => {
                        format!("board input {j} {} (by position)", inputs[j].name)
                    }
                    _ => "no board input".to_string(),
                },
            };
            writeln!(s, "  sensor {j} {name} -> {to}")?;
        }
    }
    Ok(s)
}

/// `image inspect` for any image: a group image (schema 2) per axis, a schema-1 image as before;
/// bytes after an image's declared end are an error.
pub fn describe_any(bytes: &[u8]) -> anyhow::Result<String> {
    use std::fmt::Write;
    let view = group_image::parse(bytes)?;
    if view.version == 1 {
        return describe(bytes);
    }
    view.check_group()
        .map_err(|e| anyhow::anyhow!("the group is not valid (every board refuses it): {e}"))?;
    let mut s = String::new();
    writeln!(
        s,
        "group image: {} bytes, schema version 2, {} axes, CRC-32 {:08x} (ok, every section's too)",
        bytes.len(),
        view.axis_count(),
        view.crc
    )?;
    for a in view.axes() {
        writeln!(
            s,
            "--- axis {} ({}{}) ---",
            a.axis.name.letter(),
            if a.axis.name.is_rotary() {
                format!("rotary, {} counts per revolution", a.axis.counts_per_rev)
            } else {
                "linear".to_string()
            },
            match a.stroke_counts {
                Some((lo, hi)) => format!(", stroke {lo} .. {hi} counts"),
                None => String::new(),
            }
        )?;
        s.push_str(&describe(a.axis.image)?);
        let n = inspect_image(a.axis.image)?.n_sensors;
        for i in 0..n {
            if let Some(name) = a.sensor_name(i) {
                writeln!(s, "  sensor {i} name: {name}")?;
            }
        }
    }
    match view.rotary {
        Some(r) => s.push_str(&describe_rotary(&r)),
        None => writeln!(s, "rotary location errors: none")?,
    }
    match &view.probe {
        Some(p) => writeln!(
            s,
            "probe settings: minimum pulse {} µs, latency {} µs, lockout {} ms, moving above {} mm/min",
            p.min_pulse_us,
            p.latency_ns as f64 / 1000.0,
            p.lockout_us as f64 / 1000.0,
            p.moving_um_per_s as f64 * 60.0 / 1000.0
        )?,
        None => writeln!(s, "probe settings: none")?,
    }
    match &view.geometric {
        Some(g) => s.push_str(&describe_geometric(g)),
        None => writeln!(s, "geometric model: none")?,
    }
    Ok(s)
}

/// The rotary section's lines of `image inspect`: machine kind, every constant by its ISO 230-7
/// name, which ones were not identified (fixed at 0), pivot and tool length.
fn describe_rotary(r: &RotaryLocationSpec) -> String {
    let names = r.machine.constant_names();
    let values = r.all_constants();
    let list = |range: std::ops::Range<usize>| {
        range
            .map(|k| {
                let unit = if matches!(k, 0 | 1 | 4 | 5) {
                    "µm"
                } else {
                    "µrad"
                };
                let fixed = if r.not_identified >> k & 1 == 1 {
                    " (not identified: fixed at 0)"
                } else {
                    ""
                };
                format!("{} {} {unit}{fixed}", names[k], values[k])
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    let not: Vec<&str> = (0..11)
        .filter(|k| r.not_identified >> k & 1 == 1)
        .map(|k| names[k])
        .collect();
    let length = if r.machine == RotaryMachine::BcHead {
        "pivot to tool tip"
    } else {
        "tool length"
    };
    format!(
        "rotary location errors ({}): {}\n  squareness: {}\n  not identified (fixed at their prior 0): {}\n  pivot {:?} counts, {length} {} µm\n",
        r.machine.name(),
        list(0..8),
        list(8..11),
        if not.is_empty() {
            "none".to_string()
        } else {
            not.join(", ")
        },
        r.pivot_counts,
        r.tool_length_um
    )
}

/// The `image inspect` lines of a geometric section: stacking, tool offset, grids, squareness
/// and each component's status and range of values over its grid.
pub fn describe_geometric(g: &GeometricSpec) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let label = String::from_utf8_lossy(&g.stacking_label()).into_owned();
    let n_id = (0..21).filter(|i| g.identified >> i & 1 == 1).count();
    let n_excluded = (0..21)
        .filter(|&i| g.identified >> i & 1 == 1 && !geometric_component_nonzero(g, i))
        .count();
    let _ = writeln!(
        s,
        "geometric model (21 ISO 230-1 components, volumetric stage): stacking {label} \
         (work axes / tool axes), tool offset ({}, {}, {}) µm, {n_id} of 21 components identified{}",
        g.tool_offset_um[0],
        g.tool_offset_um[1],
        g.tool_offset_um[2],
        match n_excluded {
            0 => String::new(),
            n => format!(", {n} of them excluded from this image (stored as zero)"),
        }
    );
    for (k, grid) in g.grids.iter().enumerate() {
        let _ = writeln!(
            s,
            "  grid {}: {} segments of {} counts from {} counts ({} knots)",
            ['X', 'Y', 'Z'][k],
            grid.n_segments,
            grid.segment_counts,
            grid.start_counts,
            grid.n_segments + 1
        );
    }
    let status = |i: usize| {
        if g.identified >> i & 1 == 0 {
            "NOT identified: stored as zero (the model's prior)"
        } else if geometric_component_nonzero(g, i) {
            "identified"
        } else {
            "identified by the fit, EXCLUDED from this image: stored as zero (`image group \
             --exclude-geometric`: an axis table or the rotary model corrects it)"
        }
    };
    for k in 0..3 {
        for f in 0..6 {
            let i = 6 * k + f;
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for seg in 0..g.grids[k].n_segments as usize {
                let c = g.segment(k, seg, f);
                for t in [0.0f32, 0.25, 0.5, 0.75, 1.0] {
                    let v = c[0] + t * (c[1] + t * (c[2] + t * c[3]));
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            let unit = if f < 3 { "µm" } else { "µrad" };
            let _ = writeln!(
                s,
                "  {:<4} {:.3} .. {:.3} {unit}, {}",
                COMPONENT_NAMES[i],
                lo,
                hi,
                status(i)
            );
        }
    }
    for q in 0..3 {
        let _ = writeln!(
            s,
            "  {:<4} {} µrad, {}",
            COMPONENT_NAMES[18 + q],
            g.squareness_urad[q],
            status(18 + q)
        );
    }
    s
}

/// A `fit geometry` model converted for the core's geometric stage (owned coefficients).
#[derive(Debug, Clone, PartialEq)]
pub struct GeometricSection {
    pub chain: [u8; 3],
    pub work_axes: u8,
    pub identified: u32,
    pub tool_offset_um: [f32; 3],
    pub squareness_urad: [f32; 3],
    pub grids: [GeometricGrid; 3],
    pub coefficients: Vec<[f32; 4]>,
}

impl GeometricSection {
    /// The core's view of it.
    pub fn spec(&self) -> GeometricSpec<'_> {
        GeometricSpec {
            chain: self.chain,
            work_axes: self.work_axes,
            identified: self.identified,
            tool_offset_um: self.tool_offset_um,
            squareness_urad: self.squareness_urad,
            grids: self.grids,
            coefficients: GeometricCoefficients::Values(&self.coefficients),
        }
    }
    /// The stroke (start, end counts) each grid spans, for X, Y, Z.
    pub fn strokes(&self) -> [(i64, i64); 3] {
        self.grids.map(|g| {
            (
                g.start_counts,
                g.end_counts().clamp(i64::MIN as i128, i64::MAX as i128) as i64,
            )
        })
    }
}

/// Horner coefficients `[c0, c1, c2, c3]` in t ∈ [0, 1) of the uniform cubic B-spline segment with
/// control coefficients `c` (the basis of `axcomp_geometry::spline::AxisGrid::local`).
pub fn bspline_segment_to_horner(c: [f64; 4]) -> [f64; 4] {
    [
        (c[0] + 4.0 * c[1] + c[2]) / 6.0,
        (c[2] - c[0]) / 2.0,
        (c[0] - 2.0 * c[1] + c[2]) / 2.0,
        (-c[0] + 3.0 * c[1] - 3.0 * c[2] + c[3]) / 6.0,
    ]
}

/// Converts a `fit geometry` model for the core's geometric stage: the axes' scales
/// `um_per_count` (X, Y, Z) put the grids on whole counts (else an error naming the axis), the
/// tool offset is in mm. Components the model marks `identified: false` are stored as zero.
pub fn geometric_from_model(
    model: &GeometryModel,
    um_per_count: [f64; 3],
    tool_offset_mm: [f64; 3],
) -> anyhow::Result<GeometricSection> {
    let mut grids = [GeometricGrid {
        start_counts: 0,
        segment_counts: 1,
        n_segments: 1,
    }; 3];
    for k in 0..3 {
        let g = &model.grids[k];
        let upc = um_per_count[k];
        anyhow::ensure!(
            upc.is_finite() && upc > 0.0,
            "axis {}: µm per count {upc} must be a finite number > 0",
            "XYZ".as_bytes()[k] as char
        );
        let per_mm = 1000.0 / upc;
        let start = g.lo * per_mm;
        let seg = (g.hi - g.lo) * per_mm / g.intervals.max(1) as f64;
        let whole = |x: f64| (x - x.round()).abs() <= 1e-9 * x.abs().max(1.0);
        anyhow::ensure!(
            g.intervals >= 1
                && g.intervals <= axcomp_core::geometric::MAX_GEOMETRIC_SEGMENTS as usize
                && whole(start)
                && whole(seg)
                && seg.round() >= 1.0
                && seg.round() * g.intervals as f64 <= u32::MAX as f64,
            "geometry model: the {} grid ({} .. {} mm, {} intervals) does not fall on whole counts \
             of {upc} µm (start {start} counts, knot spacing {seg} counts); the core's grid needs \
             whole counts and 1..=1024 intervals",
            "XYZ".as_bytes()[k] as char,
            g.lo,
            g.hi,
            g.intervals
        );
        grids[k] = GeometricGrid {
            start_counts: start.round() as i64,
            segment_counts: seg.round() as u32,
            n_segments: g.intervals as u32,
        };
    }
    let mut identified = 0u32;
    for (i, c) in model.components.iter().enumerate().take(21) {
        if c.identified {
            identified |= 1 << i;
        }
    }
    let mut coefficients = Vec::new();
    for k in 0..3 {
        let n = model.grids[k].intervals;
        for seg in 0..n {
            for f in 0..6 {
                let comp = &model.components[6 * k + f];
                if !comp.identified {
                    coefficients.push([0.0; 4]);
                    continue;
                }
                anyhow::ensure!(
                    comp.coefficients.len() == n + 3,
                    "geometry model: {} has {} spline coefficients, its axis's grid needs {}",
                    comp.name,
                    comp.coefficients.len(),
                    n + 3
                );
                let c = [0, 1, 2, 3].map(|j| comp.coefficients[seg + j]);
                coefficients.push(bspline_segment_to_horner(c).map(|v| v as f32));
            }
        }
    }
    let sq = |i: usize| {
        let c = &model.components[18 + i];
        if c.identified { c.value as f32 } else { 0.0 }
    };
    let chain = model.topology.chain();
    anyhow::ensure!(
        chain.len() == 3,
        "geometry model: the stacking must have 3 axes"
    );
    let section = GeometricSection {
        chain: [0, 1, 2].map(|i| chain[i].index() as u8),
        work_axes: model.topology.work.len() as u8,
        identified,
        tool_offset_um: tool_offset_mm.map(|v| (v * 1000.0) as f32),
        squareness_urad: [sq(0), sq(1), sq(2)],
        grids,
        coefficients,
    };
    section
        .spec()
        .validate()
        .map_err(|e| anyhow::anyhow!("geometry model: {e}"))?;
    Ok(section)
}

/// `--probe recommended` or `KEY=V,..` over [`ProbeSettings::RECOMMENDED`]; validated.
pub fn parse_probe_settings(arg: &str) -> anyhow::Result<ProbeSettings> {
    let mut p = ProbeSettings::RECOMMENDED;
    if arg.trim() != "recommended" {
        for kv in arg.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (k, v) = kv
                .split_once('=')
                .with_context(|| format!("--probe `{kv}`: expected KEY=VALUE or `recommended`"))?;
            let v: f64 = v
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite() && *v >= 0.0)
                .with_context(|| format!("--probe `{kv}`: the value must be a number >= 0"))?;
            let whole = |x: f64| -> anyhow::Result<u32> {
                anyhow::ensure!(x <= u32::MAX as f64, "--probe `{kv}`: {x} is out of range");
                Ok(x.round() as u32)
            };
            match k.trim() {
                "min_pulse_us" => p.min_pulse_us = whole(v)?,
                "latency_us" => p.latency_ns = whole(v * 1000.0)?,
                "lockout_ms" => p.lockout_us = whole(v * 1000.0)?,
                "moving_mm_min" => p.moving_um_per_s = (v * 1000.0 / 60.0) as f32,
                other => anyhow::bail!(
                    "--probe `{kv}`: unknown key `{other}` (min_pulse_us, latency_us, lockout_ms, \
                     moving_mm_min)"
                ),
            }
        }
    }
    p.validate()
        .map_err(|e| anyhow::anyhow!("--probe {arg}: {e}"))?;
    Ok(p)
}

fn parse_tool_offset(arg: &str) -> anyhow::Result<[f64; 3]> {
    let v: Vec<f64> = arg
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--tool-offset-mm {arg}: expected three numbers x,y,z"))?;
    anyhow::ensure!(
        v.len() == 3 && v.iter().all(|x| x.is_finite()),
        "--tool-offset-mm {arg}: expected three finite numbers x,y,z"
    );
    Ok([v[0], v[1], v[2]])
}

#[derive(Debug, clap::Args)]
pub struct GroupArgs {
    /// One axis, in slot order (1 to 5 times): `NAME=IMAGE` for a linear axis (X, Y, Z),
    /// `NAME:COUNTS_PER_REV=IMAGE` for a rotary one (A, B, C); IMAGE from `image build` (every axis
    /// needs one: `image build --identity` for an axis without correction of its own).
    #[arg(long = "axis", value_name = "NAME[:CPR]=IMAGE", required = true)]
    pub axes: Vec<String>,
    /// Sensor names of an axis, one per sensor of its image: `NAME=first,second,...`.
    #[arg(long = "sensor-names", value_name = "NAME=N1,N2,...")]
    pub sensor_names: Vec<String>,
    /// Rotary location-error model: the model file of `axcomp fit rtest --out` (ac-trunnion,
    /// bc-trunnion or bc-head; needs --pivot-counts, and --tool-length-mm for a trunnion), or the
    /// hand-written AC-trunnion form (JSON with `ex0c_um`, `ey0c_um`, `ea0c_urad`, `eb0c_urad`,
    /// `ey0a_um`, `ez0a_um`, `eb0a_urad`, `ec0a_urad`, `pivot_counts` [x, y, z],
    /// `tool_length_um`). The group needs X, Y, Z, the tilt axis (A or B) and C.
    #[arg(long, value_name = "MODEL.json")]
    pub rotary: Option<PathBuf>,
    /// With a `fit rtest` model: the X, Y, Z counts at which the tool point (trunnion) or the head's
    /// pivot (bc-head) sits at the R-test frame's origin, the nominal intersection of the rotary
    /// axes.
    #[arg(long, value_name = "X,Y,Z", allow_hyphen_values = true)]
    pub pivot_counts: Option<String>,
    /// With a `fit rtest` model: trunnion: tool length (spindle gauge line to tool tip), mm,
    /// required; bc-head: B axis to tool tip, mm (default: the model's --pivot-mm).
    #[arg(long, value_name = "L")]
    pub tool_length_mm: Option<f64>,
    /// Volumetric geometric model (JSON from `fit geometry --out`); the group needs X, Y and Z,
    /// whose strokes become the model's grids (an axis table must span the same grid).
    #[arg(long, value_name = "MODEL.json")]
    pub geometry: Option<PathBuf>,
    /// Tool offset from the tool reference point for the geometric stage, mm: `x,y,z`.
    #[arg(
        long,
        value_name = "X,Y,Z",
        requires = "geometry",
        allow_hyphen_values = true
    )]
    pub tool_offset_mm: Option<String>,
    /// Touch-probe settings for the latch (section kind 4): `recommended` (the seed's 2 ms filter,
    /// no latency, 20 ms lockout, 3 mm/min "moving"), or `KEY=V,..` over those with keys
    /// `min_pulse_us`, `latency_us`, `lockout_ms`, `moving_mm_min` (e.g. `latency_us=850`).
    #[arg(long, value_name = "SETTINGS")]
    pub probe: Option<String>,
    /// Geometric components to leave out of the image, comma-separated ISO 230-1 names (e.g.
    /// `EXX,EC0Y`): stored as zero, listed by `image inspect` as excluded. The way to build an image
    /// whose axis positioning table (EXX, EYY, EZZ) or rotary model squareness (EC0Y, EB0Z, EA0Z)
    /// corrects an error the geometric model also carries: without it `image group` refuses such a
    /// group, naming both sources, since the error would be corrected twice.
    #[arg(
        long,
        value_name = "NAMES",
        value_delimiter = ',',
        requires = "geometry"
    )]
    pub exclude_geometric: Vec<String>,
    /// Output group image file.
    #[arg(long, value_name = "IMAGE")]
    pub out: PathBuf,
}

fn parse_axis_arg(arg: &str) -> anyhow::Result<(AxisName, u32, PathBuf)> {
    let (head, path) = arg
        .split_once('=')
        .with_context(|| format!("--axis {arg}: expected NAME[:CPR]=IMAGE"))?;
    let (name, cpr) = match head.split_once(':') {
        Some((n, c)) => (
            n,
            c.parse::<u32>()
                .with_context(|| format!("--axis {arg}: counts per revolution `{c}`"))?,
        ),
        None => (head, 0),
    };
    let mut chars = name.chars();
    let letter = match (chars.next(), chars.next()) {
        (Some(c), None) => AxisName::from_letter(c),
        _ => None,
    }
    .with_context(|| format!("--axis {arg}: axis name must be one of X, Y, Z, A, B, C"))?;
    if letter.is_rotary() && cpr == 0 {
        anyhow::bail!("--axis {arg}: a rotary axis needs NAME:COUNTS_PER_REV=IMAGE");
    }
    if !letter.is_rotary() && cpr != 0 {
        anyhow::bail!("--axis {arg}: a linear axis has no counts per revolution");
    }
    Ok((letter, cpr, PathBuf::from(path)))
}

/// The rotary section from `--rotary` (a `fit rtest` model or the hand-written form) and the
/// placement arguments.
fn rotary_from_args(args: &GroupArgs) -> anyhow::Result<Option<RotaryLocationSpec>> {
    let Some(path) = args.rotary.as_deref() else {
        anyhow::ensure!(
            args.pivot_counts.is_none() && args.tool_length_mm.is_none(),
            "--pivot-counts and --tool-length-mm go with --rotary"
        );
        return Ok(None);
    };
    let bytes =
        std::fs::read(path).with_context(|| format!("--rotary {}: cannot read", path.display()))?;
    let text = axcomp_files::model_text(&bytes)
        .map_err(|why| anyhow::anyhow!("--rotary {} {why}", path.display()))?;
    let v: serde_json::Value = serde_json::from_str(text)
        .with_context(|| format!("--rotary {}: not JSON", path.display()))?;
    if let Some(kind) = v
        .get("format")
        .and_then(|f| f.as_str())
        .and_then(axcomp_files::model_kind)
    {
        anyhow::bail!(
            "--rotary {}: {kind}, not a rotary-axis model (give the model of `fit rtest --out`, or the \
             hand-written AC-trunnion form)",
            path.display()
        );
    }
    if v.get("kind").and_then(|k| k.as_str()) == Some("rtest") {
        let model = RtestModel::from_json(text, &format!("--rotary {}", path.display()))?;
        let pivot = args.pivot_counts.as_deref().with_context(|| {
            format!(
                "--rotary {}: a `fit rtest` model needs --pivot-counts X,Y,Z (the counts of the R-test frame's origin)",
                path.display()
            )
        })?;
        let pivot = parse_pivot_counts(pivot)?;
        let spec = rotary_from_rtest_model(&model, pivot, args.tool_length_mm)
            .with_context(|| format!("--rotary {}", path.display()))?;
        // The group image's rotary stage carries the 11 location errors only: an effect of `fit rtest
        // --effects` is said, with the correction it leaves out, never dropped silently.
        for e in &model.effects {
            eprintln!(
                "axcomp: warning: --rotary {}: the model's effect `{}` ({} parameters) is not carried by the image: the firmware's rotary stage applies the 11 location errors only, so its correction (RMS {:.3} µm over the fitted poses) is left out",
                path.display(),
                e.kind,
                e.parameters.len(),
                e.rms_over_fit_um
            );
        }
        return Ok(Some(spec));
    }
    anyhow::ensure!(
        args.pivot_counts.is_none() && args.tool_length_mm.is_none(),
        "--rotary {}: the hand-written form carries pivot_counts and tool_length_um itself; \
         --pivot-counts and --tool-length-mm are for a `fit rtest` model",
        path.display()
    );
    rotary_from_json(path, &v).map(Some)
}

fn parse_pivot_counts(arg: &str) -> anyhow::Result<[i64; 3]> {
    let parts: Vec<&str> = arg.split(',').map(str::trim).collect();
    anyhow::ensure!(
        parts.len() == 3,
        "--pivot-counts {arg}: expected three integers X,Y,Z"
    );
    let mut out = [0i64; 3];
    for (o, p) in out.iter_mut().zip(&parts) {
        *o = p
            .parse()
            .with_context(|| format!("--pivot-counts {arg}: `{p}` is not an integer"))?;
    }
    Ok(out)
}

/// The core's rotary section from a `fit rtest` model: every identified location error and
/// squareness term goes in (f32); a parameter marked `identified: false` goes in as its fixed prior
/// 0 and is flagged in `not_identified`. Refused: a model whose parameter list is not the 11 names
/// of its machine kind, in order (the stage could not represent the rest), a non-finite value, a
/// value beyond the stage's first-order range, a tool length out of range.
pub fn rotary_from_rtest_model(
    model: &RtestModel,
    pivot_counts: [i64; 3],
    tool_length_mm: Option<f64>,
) -> anyhow::Result<RotaryLocationSpec> {
    let machine = match model.machine {
        MachineKind::AcTrunnion => RotaryMachine::AcTrunnion,
        MachineKind::BcTrunnion => RotaryMachine::BcTrunnion,
        MachineKind::BcHead => RotaryMachine::BcHead,
    };
    let names = machine.constant_names();
    let got: Vec<&str> = model
        .location_errors
        .iter()
        .map(|(n, _)| n.as_str())
        .collect();
    anyhow::ensure!(
        got == names,
        "the model's location errors {got:?} are not the {} parameters the firmware's rotary stage represents ({names:?}); refusing rather than dropping any",
        model.machine.name()
    );
    let mut values = [0.0f32; 11];
    let mut not_identified = 0u16;
    for (k, (name, p)) in model.location_errors.iter().enumerate() {
        let unit = if matches!(k, 0 | 1 | 4 | 5) {
            "um"
        } else {
            "urad"
        };
        anyhow::ensure!(
            p.unit == unit,
            "{name}: unit `{}`, expected `{unit}`",
            p.unit
        );
        if !p.identified {
            not_identified |= 1 << k;
            continue;
        }
        anyhow::ensure!(
            p.value.is_finite(),
            "{name}: value {} is not a number",
            p.value
        );
        anyhow::ensure!(
            p.value.abs() <= 1.0e4,
            "{name}: {} {unit} is beyond the rotary stage's first-order range (10 mm / 10 mrad)",
            p.value
        );
        values[k] = p.value as f32;
    }
    let tool_mm = match (machine, tool_length_mm) {
        (RotaryMachine::BcHead, None) => model.pivot_mm,
        (_, Some(l)) => l,
        (_, None) => anyhow::bail!(
            "a {} model needs --tool-length-mm L (spindle gauge line to tool tip)",
            model.machine.name()
        ),
    };
    anyhow::ensure!(
        tool_mm.is_finite() && (0.0..=1.0e4).contains(&tool_mm),
        "tool length {tool_mm} mm: need 0..=10000 mm"
    );
    let spec = RotaryLocationSpec {
        machine,
        ex0c_um: values[0],
        ey0c_um: values[1],
        ea0c_urad: values[2],
        eb0c_urad: values[3],
        ey0a_um: values[4],
        ez0a_um: values[5],
        eb0a_urad: values[6],
        ec0a_urad: values[7],
        squareness_urad: [values[8], values[9], values[10]],
        pivot_counts,
        tool_length_um: (tool_mm * 1000.0) as f32,
        not_identified,
    };
    spec.validate()
        .map_err(|e| anyhow::anyhow!("the rotary section is not valid: {e}"))?;
    Ok(spec)
}

fn rotary_from_json(
    path: &std::path::Path,
    v: &serde_json::Value,
) -> anyhow::Result<RotaryLocationSpec> {
    let f = |k: &str| -> anyhow::Result<f32> {
        v.get(k)
            .and_then(|x| x.as_f64())
            .map(|x| x as f32)
            .with_context(|| format!("--rotary {}: missing number `{k}`", path.display()))
    };
    let pivot = v
        .get("pivot_counts")
        .and_then(|p| p.as_array())
        .filter(|a| a.len() == 3)
        .and_then(|a| {
            let mut out = [0i64; 3];
            for (o, x) in out.iter_mut().zip(a) {
                *o = x.as_i64()?;
            }
            Some(out)
        })
        .with_context(|| {
            format!(
                "--rotary {}: `pivot_counts` must be three integers",
                path.display()
            )
        })?;
    Ok(RotaryLocationSpec {
        ex0c_um: f("ex0c_um")?,
        ey0c_um: f("ey0c_um")?,
        ea0c_urad: f("ea0c_urad")?,
        eb0c_urad: f("eb0c_urad")?,
        ey0a_um: f("ey0a_um")?,
        ez0a_um: f("ez0a_um")?,
        eb0a_urad: f("eb0a_urad")?,
        ec0a_urad: f("ec0a_urad")?,
        pivot_counts: pivot,
        tool_length_um: f("tool_length_um")?,
        ..RotaryLocationSpec::ZERO_AC
    })
}

/// `--geometry MODEL.json [--tool-offset-mm x,y,z]` for the group's axes: the model converted
/// with the X, Y, Z images' scales; each axis table must span the model's grid of its axis.
fn geometric_for_group(
    path: &std::path::Path,
    tool_offset: Option<&str>,
    axes: &[(AxisName, u32, Vec<u8>)],
) -> anyhow::Result<GeometricSection> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("--geometry {}: cannot read", path.display()))?;
    let model = GeometryModel::from_json(&text, &path.display().to_string())?;
    let tool = tool_offset
        .map(parse_tool_offset)
        .transpose()?
        .unwrap_or([0.0; 3]);
    let mut upc = [0.0f64; 3];
    let mut tables = [None; 3];
    for (k, name) in [AxisName::X, AxisName::Y, AxisName::Z]
        .into_iter()
        .enumerate()
    {
        let (_, _, bytes) = axes.iter().find(|(n, _, _)| *n == name).with_context(|| {
            format!(
                "--geometry {}: the geometric stage needs axis {} in the group (--axis {}=IMAGE)",
                path.display(),
                name.letter(),
                name.letter()
            )
        })?;
        let mut comp = Box::new(Compensator::IDENTITY);
        comp.load(bytes)
            .with_context(|| format!("axis {}: image does not load", name.letter()))?;
        // The image stores f32: its shortest decimal (0.1, not 0.10000000149) is the scale meant.
        upc[k] = comp
            .um_per_count()
            .to_string()
            .parse::<f64>()
            .unwrap_or(comp.um_per_count() as f64);
        if comp.has_table() {
            let n = comp.forward_segments().len() as i64;
            let start = comp.table_start_counts();
            tables[k] = Some((start, start + n * comp.segment_counts() as i64));
        }
    }
    let g = geometric_from_model(&model, upc, tool)
        .with_context(|| format!("--geometry {}", path.display()))?;
    for (k, t) in tables.iter().enumerate() {
        if let Some((lo, hi)) = t {
            let (glo, ghi) = g.strokes()[k];
            anyhow::ensure!(
                (*lo, *hi) == (glo, ghi),
                "--geometry {}: axis {}'s positioning table spans {lo} .. {hi} counts, the \
                 geometry model's {} grid {glo} .. {ghi} counts; the group's tables of an axis \
                 must span one stroke",
                path.display(),
                "XYZ".as_bytes()[k] as char,
                "XYZ".as_bytes()[k] as char
            );
        }
    }
    Ok(g)
}

/// Leaves the named components out of `g` (`--exclude-geometric`): their functions (or squareness
/// constant) are stored as zero and their identified bit is kept, which is how `image inspect` tells an
/// excluded component from one the fit did not identify. A name that is not one of the 21, or a
/// component the model did not identify (nothing to leave out), is an error naming it.
pub fn exclude_geometric_components(
    g: &mut GeometricSection,
    names: &[String],
) -> anyhow::Result<()> {
    for name in names {
        let name = name.trim();
        let i = COMPONENT_NAMES
            .iter()
            .position(|n| n.eq_ignore_ascii_case(name))
            .with_context(|| {
                format!(
                    "--exclude-geometric {name}: not an ISO 230-1 component name ({})",
                    COMPONENT_NAMES.join(", ")
                )
            })?;
        anyhow::ensure!(
            g.identified >> i & 1 == 1,
            "--exclude-geometric {name}: the geometry model did not identify {} (it is stored as \
             zero already): nothing to leave out",
            COMPONENT_NAMES[i]
        );
        if i >= 18 {
            g.squareness_urad[i - 18] = 0.0;
        } else {
            let (k, f) = (i / 6, i % 6);
            let before: usize = g.grids[..k].iter().map(|gr| gr.n_segments as usize).sum();
            for seg in 0..g.grids[k].n_segments as usize {
                g.coefficients[(before + seg) * FUNCTIONS_PER_AXIS + f] = [0.0; 4];
            }
        }
    }
    Ok(())
}

/// True if component `i` (of [`COMPONENT_NAMES`]) of the geometric section has a non-zero value.
fn geometric_component_nonzero(g: &GeometricSpec, i: usize) -> bool {
    if i >= 18 {
        return g.squareness_urad[i - 18] != 0.0;
    }
    let (k, f) = (i / 6, i % 6);
    (0..g.grids[k].n_segments as usize).any(|seg| g.segment(k, seg, f) != [0.0; 4])
}

/// Refuses a group in which one error would be corrected twice (see the module glossary): an axis's
/// positioning table and the geometric model's positioning component of that axis, or the rotary
/// model's squareness and the geometric model's, both non-zero. The error names both sources of
/// each and the way out (`--exclude-geometric`).
fn refuse_double_correction(
    args: &GroupArgs,
    axes: &[(AxisName, u32, Vec<u8>)],
    geometric: Option<&GeometricSection>,
    rotary: Option<&RotaryLocationSpec>,
) -> anyhow::Result<()> {
    let Some(geo) = geometric else {
        return Ok(());
    };
    let spec = geo.spec();
    let geo_path = args
        .geometry
        .as_deref()
        .map_or(String::new(), |p| p.display().to_string());
    let mut twice: Vec<(&str, String)> = Vec::new();
    for (k, name) in [AxisName::X, AxisName::Y, AxisName::Z]
        .into_iter()
        .enumerate()
    {
        let i = 7 * k; // EXX, EYY, EZZ
        let Some(slot) = axes.iter().position(|(n, _, _)| *n == name) else {
            continue;
        };
        let mut comp = Box::new(Compensator::IDENTITY);
        if comp.load(&axes[slot].2).is_err() || !comp.has_table() {
            continue;
        }
        let table_corrects = comp
            .forward_segments()
            .iter()
            .chain(comp.backward_segments())
            .any(|c| *c != [0.0; 4]);
        if table_corrects && geometric_component_nonzero(&spec, i) {
            twice.push((
                COMPONENT_NAMES[i],
                format!(
                    "axis {l}'s positioning table (--axis {}) and the geometry model's {} \
                     (--geometry {geo_path}) both correct {l}'s positioning error",
                    args.axes[slot],
                    COMPONENT_NAMES[i],
                    l = name.letter()
                ),
            ));
        }
    }
    if let Some(r) = rotary {
        let rotary_path = args
            .rotary
            .as_deref()
            .map_or(String::new(), |p| p.display().to_string());
        for q in 0..3 {
            // The rotary section holds EA0Z, EB0Z, EC0Y; the geometric one EC0Y, EB0Z, EA0Z.
            let i = 18 + q;
            if r.squareness_urad[2 - q] != 0.0 && geometric_component_nonzero(&spec, i) {
                twice.push((
                    COMPONENT_NAMES[i],
                    format!(
                        "the rotary model's squareness {n} (--rotary {rotary_path}) and the \
                         geometry model's {n} (--geometry {geo_path}) both correct it",
                        n = COMPONENT_NAMES[i]
                    ),
                ));
            }
        }
    }
    if twice.is_empty() {
        return Ok(());
    }
    let names: Vec<&str> = twice.iter().map(|(n, _)| *n).collect();
    anyhow::bail!(
        "the group would correct the same error twice (nothing written):\n{}\nkeep one source of \
         each: `--exclude-geometric {}` leaves the geometry model's out (the axis table or the \
         rotary model corrects it; `image inspect` lists it as excluded), or build the group from \
         an axis image without a positioning table / a rotary model without that squareness to \
         keep the geometry model's",
        twice
            .iter()
            .map(|(_, why)| format!("  - {why}"))
            .collect::<Vec<_>>()
            .join("\n"),
        names.join(",")
    )
}

/// The group image bytes from the arguments (validated; nothing is written here).
pub fn group_bytes(args: &GroupArgs) -> anyhow::Result<Vec<u8>> {
    let mut axes = Vec::new();
    for a in &args.axes {
        let (name, cpr, path) = parse_axis_arg(a)?;
        let bytes = std::fs::read(&path)
            .with_context(|| format!("--axis {a}: cannot read {}", path.display()))?;
        check_axis_image(a, &path, &bytes)?;
        axes.push((name, cpr, bytes));
    }
    let mut names: Vec<(AxisName, Vec<String>)> = Vec::new();
    for arg in &args.sensor_names {
        let (n, list) = arg
            .split_once('=')
            .with_context(|| format!("--sensor-names {arg}: expected NAME=N1,N2,..."))?;
        let name = n
            .chars()
            .next()
            .and_then(AxisName::from_letter)
            .filter(|_| n.len() == 1)
            .with_context(|| format!("--sensor-names {arg}: unknown axis `{n}`"))?;
        anyhow::ensure!(
            !names.iter().any(|(m, _)| *m == name),
            "--sensor-names {arg}: axis {} is given names twice",
            name.letter()
        );
        names.push((name, list.split(',').map(str::to_string).collect()));
    }
    let rotary = rotary_from_args(args)?;
    // An axis without --sensor-names keeps the names its image carries (from `image build`).
    let carried: Vec<Vec<String>> = axes
        .iter()
        .map(|(_, _, bytes)| carried_sensor_names(bytes))
        .collect();
    let name_refs: Vec<Vec<&str>> = axes
        .iter()
        .zip(&carried)
        .map(|((name, _, _), own)| {
            names
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, l)| l.iter().map(String::as_str).collect())
                .unwrap_or_else(|| own.iter().map(String::as_str).collect())
        })
        .collect();
    for (n, _) in &names {
        anyhow::ensure!(
            axes.iter().any(|(a, _, _)| a == n),
            "--sensor-names: axis {} is not one of the --axis",
            n.letter()
        );
    }
    // One name per sensor, no name twice: the firmware wires each sensor to the board input of its name.
    for (((name, _, bytes), list), arg) in axes.iter().zip(&name_refs).zip(&args.axes) {
        let sensors = usize::from(inspect_image(bytes)?.n_sensors);
        let given = names.iter().any(|(n, _)| n == name);
        if given {
            anyhow::ensure!(
                list.len() == sensors,
                "--sensor-names {}={}: {} names, but axis {} (--axis {arg}) has {sensors} sensors",
                name.letter(),
                list.join(","),
                list.len(),
                name.letter()
            );
        }
        for (j, n) in list.iter().enumerate() {
            anyhow::ensure!(
                !list[..j].contains(n),
                "axis {} (--axis {arg}{}): two sensors are named `{n}`; the firmware wires sensors by \
                 name, so both would read one input",
                name.letter(),
                if given { ", --sensor-names" } else { "" }
            );
        }
    }
    anyhow::ensure!(
        args.exclude_geometric.is_empty() || args.geometry.is_some(),
        "--exclude-geometric goes with --geometry"
    );
    let mut geometric = match &args.geometry {
        Some(path) => Some(geometric_for_group(
            path,
            args.tool_offset_mm.as_deref(),
            &axes,
        )?),
        None => None,
    };
    if let Some(g) = geometric.as_mut() {
        exclude_geometric_components(g, &args.exclude_geometric)?;
    }
    refuse_double_correction(args, &axes, geometric.as_ref(), rotary.as_ref())?;
    let specs: Vec<AxisSectionSpec> = axes
        .iter()
        .zip(&name_refs)
        .map(|((name, cpr, bytes), names)| AxisSectionSpec {
            name: *name,
            counts_per_rev: *cpr,
            stroke_counts: geometric
                .as_ref()
                .filter(|_| !name.is_rotary())
                .map(|g| g.strokes()[name.code() as usize]),
            image: bytes,
            sensor_names: names,
        })
        .collect();
    let geo_spec = geometric.as_ref().map(GeometricSection::spec);
    let probe = args
        .probe
        .as_deref()
        .map(parse_probe_settings)
        .transpose()?;
    let mut buf = vec![
        0u8;
        group_image::group_image_len_with_stages(
            &specs,
            rotary.as_ref(),
            geo_spec.as_ref(),
            probe.as_ref()
        )
    ];
    let n = group_image::write_group_image_with_stages(
        &specs,
        rotary.as_ref(),
        geo_spec.as_ref(),
        probe.as_ref(),
        &mut buf,
    )
    .map_err(|e| anyhow::anyhow!("the group is not valid: {e}"))?;
    buf.truncate(n);
    // What a board refuses of any group (one axis id on two axes, a pivot far outside the strokes), from
    // the firmware's own check.
    group_image::parse(&buf)
        .and_then(|v| v.check_group())
        .map_err(|e| anyhow::anyhow!("the group is not valid: {e}"))?;
    Ok(buf)
}

/// An `--axis` file must be one single-axis image of `image build`: a group image, another file or an
/// image with bytes after its end is refused naming the option and the file (the group writer's own
/// check named neither).
fn check_axis_image(arg: &str, path: &std::path::Path, bytes: &[u8]) -> anyhow::Result<()> {
    let shown = path.display();
    if bytes.starts_with(b"AXCI") && bytes.get(4..6) == Some(&2u16.to_le_bytes()[..]) {
        anyhow::bail!(
            "--axis {arg}: {shown} is a group image (`image group`); an axis takes a single-axis image \
             of `image build`"
        );
    }
    if !bytes.starts_with(b"AXCI") {
        let what = match axcomp_files::model_text(bytes) {
            Err(why) => why,
            Ok(_) => "is not a firmware image (a text file; build one with `image build`)".into(),
        };
        anyhow::bail!("--axis {arg}: {shown} {what}");
    }
    let info = inspect_image(bytes)
        .map_err(|e| anyhow::anyhow!("--axis {arg}: {shown} is not a valid image: {e}"))?;
    anyhow::ensure!(
        bytes.len() == info.len,
        "--axis {arg}: {shown} has {} bytes, its image header says {} (bytes after the image)",
        bytes.len(),
        info.len
    );
    Ok(())
}

/// What `image group` writes: [`group_bytes`] with the provenance section (every axis image's model
/// records, the rotary model file's, the tool, the date).
pub fn group_bytes_with_provenance(args: &GroupArgs) -> anyhow::Result<Vec<u8>> {
    let body = group_bytes(args)?;
    let mut axes = Vec::new();
    for a in &args.axes {
        let (name, cpr, path) = parse_axis_arg(a)?;
        let bytes = std::fs::read(&path)
            .with_context(|| format!("--axis {a}: cannot read {}", path.display()))?;
        axes.push((name, cpr, bytes));
    }
    let records = group_provenance_records(&axes, args.rotary.as_deref())?;
    with_provenance_section(&body, &records)
}

/// The sensor names in a schema-1 image's header extension (empty without them).
fn carried_sensor_names(image: &[u8]) -> Vec<String> {
    let Ok(view) = group_image::parse(image) else {
        return vec![];
    };
    let Some(a) = view.axes().next() else {
        return vec![];
    };
    let n = inspect_image(a.axis.image).map_or(0, |i| i.n_sensors);
    (0..n)
        .map_while(|j| a.sensor_name(j).map(str::to_string))
        .collect()
}

/// Every axis image's provenance records (re-labelled with the group axis) and the rotary model file's.
fn group_provenance_records(
    axes: &[(AxisName, u32, Vec<u8>)],
    rotary: Option<&std::path::Path>,
) -> anyhow::Result<Vec<provenance::ProvenanceRecord>> {
    let mut records = Vec::new();
    for (name, _, bytes) in axes {
        if let Ok(view) = group_image::parse(bytes) {
            for p in view.provenance.iter() {
                for mut r in p.records() {
                    r.axis = name.code();
                    records.push(r);
                }
            }
        }
    }
    if let Some(p) = rotary {
        records.push(crate::provenance::model_record(
            p,
            provenance::ANY_AXIS,
            provenance::role::ROTARY_MODEL,
        )?);
    }
    anyhow::ensure!(
        records.len() <= provenance::MAX_RECORDS,
        "{} model files: an image records at most {}",
        records.len(),
        provenance::MAX_RECORDS
    );
    Ok(records)
}

/// `image` (a group image) with the provenance section (kind 6, optional) appended.
pub fn with_provenance_section(
    image: &[u8],
    records: &[provenance::ProvenanceRecord],
) -> anyhow::Result<Vec<u8>> {
    let block = crate::provenance::image_block(records)?;
    let mut out = vec![0u8; image.len() + group_image::DIR_ENTRY_LEN + block.len()];
    let n = provenance::with_group_section(
        image,
        group_image::SectionKind::Provenance as u16,
        group_image::NO_AXIS,
        0,
        &block,
        &mut out,
    )
    .map_err(|e| anyhow::anyhow!("the image's provenance section: {e}"))?;
    out.truncate(n);
    Ok(out)
}

pub fn group(args: GroupArgs) -> anyhow::Result<()> {
    let mut outputs = OutputSet::new();
    outputs.planned(&args.out);
    for a in &args.axes {
        if let Ok((_, _, path)) = parse_axis_arg(a) {
            outputs.input(path);
        }
    }
    for p in [&args.rotary, &args.geometry].into_iter().flatten() {
        outputs.input(p);
    }
    outputs.check()?;
    let bytes = group_bytes_with_provenance(&args)?;
    outputs.file(&args.out, bytes.as_slice());
    outputs.commit()?;
    let view = group_image::parse(&bytes)?;
    println!(
        "wrote {} ({} bytes, group of {} axes: {}, rotary model: {}, geometric model: {}, CRC-32 {:08x})",
        args.out.display(),
        bytes.len(),
        view.axis_count(),
        view.axes()
            .map(|a| a.axis.name.letter().to_string())
            .collect::<Vec<_>>()
            .join(""),
        if view.rotary.is_some() { "yes" } else { "no" },
        if view.geometric.is_some() {
            "yes"
        } else {
            "no"
        },
        view.crc
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `image group` from per-axis images, then `inspect`: the view lists every axis, the sensor
    /// names and the rotary model; bad axis specs are clear errors.
    #[test]
    fn group_image_build_and_inspect() {
        let dir = std::env::temp_dir().join(format!("axcomp-image-group-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let g = axcomp_scenario::group_image(5, false).unwrap();
        let view = group_image::parse(&g).unwrap();
        let mut axis_args = Vec::new();
        for a in view.axes() {
            let p = dir.join(format!("{}.bin", a.axis.name.letter()));
            std::fs::write(&p, a.axis.image).unwrap();
            axis_args.push(if a.axis.name.is_rotary() {
                format!(
                    "{}:{}={}",
                    a.axis.name.letter(),
                    a.axis.counts_per_rev,
                    p.display()
                )
            } else {
                format!("{}={}", a.axis.name.letter(), p.display())
            });
        }
        let rot = dir.join("rotary.json");
        std::fs::write(
            &rot,
            r#"{"ex0c_um": 12, "ey0c_um": -7, "ea0c_urad": 25, "eb0c_urad": -15, "ey0a_um": 9,
                "ez0a_um": -20, "eb0a_urad": 18, "ec0a_urad": -10,
                "pivot_counts": [500000, 500000, 500000], "tool_length_um": 100000}"#,
        )
        .unwrap();
        let args = GroupArgs {
            axes: axis_args.clone(),
            sensor_names: vec!["X=spindle,column".into()],
            rotary: Some(rot.clone()),
            pivot_counts: None,
            tool_length_mm: None,
            geometry: None,
            tool_offset_mm: None,
            probe: None,
            exclude_geometric: vec![],
            out: dir.join("g.bin"),
        };
        // The same group the scenario builds, byte for byte.
        assert_eq!(group_bytes(&args).unwrap(), g);
        group(args).unwrap();
        let text = describe_any(&std::fs::read(dir.join("g.bin")).unwrap()).unwrap();
        assert!(
            text.contains("5 axes")
                && text.contains("--- axis C (rotary, 3600000 counts per revolution) ---"),
            "{text}"
        );
        assert!(
            text.contains("sensor 1 name: column") && text.contains("EB0A 18 µrad"),
            "{text}"
        );
        // With probe settings (section kind 4): parsed back by the core, shown by inspect.
        let probed = group_bytes(&GroupArgs {
            axes: axis_args.clone(),
            sensor_names: vec!["X=spindle,column".into()],
            rotary: Some(rot.clone()),
            pivot_counts: None,
            tool_length_mm: None,
            geometry: None,
            tool_offset_mm: None,
            probe: Some("latency_us=850, lockout_ms=25".into()),
            exclude_geometric: vec![],
            out: dir.join("never.bin"),
        })
        .unwrap();
        let p = group_image::parse(&probed).unwrap().probe.unwrap();
        assert_eq!(
            p,
            ProbeSettings {
                latency_ns: 850_000,
                lockout_us: 25_000,
                ..ProbeSettings::RECOMMENDED
            }
        );
        let text = describe_any(&probed).unwrap();
        assert!(
            text.contains("probe settings: minimum pulse 2000 µs, latency 850 µs, lockout 25 ms"),
            "{text}"
        );
        assert!(describe_any(&g).unwrap().contains("probe settings: none"));
        assert_eq!(
            parse_probe_settings("recommended").unwrap(),
            ProbeSettings::RECOMMENDED
        );
        for (bad, want) in [
            ("latency=3", "unknown key `latency`"),
            ("lockout_ms=-1", "must be a number >= 0"),
            ("min_pulse_us=2000,lockout_ms=1", "--probe"),
            ("fast", "expected KEY=VALUE"),
        ] {
            let e = parse_probe_settings(bad).unwrap_err();
            assert!(format!("{e:#}").contains(want), "{bad}: {e:#}");
        }
        // Errors name what is wrong.
        for (bad, want) in [
            ("Q=x.bin", "axis name must be one of"),
            ("A=x.bin", "rotary axis needs"),
            ("X:100=x.bin", "linear axis has no counts"),
            ("X", "expected NAME[:CPR]=IMAGE"),
        ] {
            let e = group_bytes(&GroupArgs {
                axes: vec![bad.into()],
                sensor_names: vec![],
                rotary: None,
                pivot_counts: None,
                tool_length_mm: None,
                geometry: None,
                tool_offset_mm: None,
                probe: None,
                exclude_geometric: vec![],
                out: dir.join("never.bin"),
            })
            .unwrap_err();
            assert!(format!("{e:#}").contains(want), "{bad}: {e:#}");
        }
        // Trailing bytes after a schema-1 image are refused by inspect.
        let mut long = std::fs::read(dir.join("X.bin")).unwrap();
        long.extend_from_slice(&[0; 100]);
        let e = describe_any(&long).unwrap_err();
        assert!(format!("{e:#}").contains("bytes follow the end"), "{e:#}");
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A rotary model and a geometric model that both carry a non-zero squareness term would correct
    /// it twice: refused, naming both sources and `--exclude-geometric`; a term only one of them
    /// carries is not a conflict. With the geometric EC0Y excluded the group passes and `inspect` lists
    /// EC0Y as excluded.
    #[test]
    fn double_squareness_correction_is_refused_unless_excluded() {
        let grid = GeometricGrid {
            start_counts: 0,
            segment_counts: 1000,
            n_segments: 1,
        };
        let mut geo = GeometricSection {
            chain: [0, 1, 2],
            work_axes: 0,
            identified: (1 << 21) - 1,
            tool_offset_um: [0.0; 3],
            // EC0Y, EB0Z, EA0Z.
            squareness_urad: [5.0, 0.0, -3.0],
            grids: [grid; 3],
            coefficients: vec![[1.0, 0.0, 0.0, 0.0]; 18],
        };
        // EA0Z, EB0Z, EC0Y: only EC0Y is in both.
        let rot = RotaryLocationSpec {
            squareness_urad: [0.0, 2.0, 7.0],
            ..RotaryLocationSpec::ZERO_AC
        };
        let args = GroupArgs {
            axes: vec![],
            sensor_names: vec![],
            rotary: Some("r.json".into()),
            pivot_counts: None,
            tool_length_mm: None,
            geometry: Some("g.json".into()),
            tool_offset_mm: None,
            probe: None,
            exclude_geometric: vec![],
            out: "never.bin".into(),
        };
        let e = format!(
            "{:#}",
            refuse_double_correction(&args, &[], Some(&geo), Some(&rot)).unwrap_err()
        );
        assert!(
            e.contains(
                "the rotary model's squareness EC0Y (--rotary r.json) and the geometry model's \
                 EC0Y (--geometry g.json) both correct it"
            ),
            "{e}"
        );
        assert!(e.contains("`--exclude-geometric EC0Y`"), "{e}");
        assert!(!e.contains("EA0Z") && !e.contains("EB0Z"), "{e}");
        exclude_geometric_components(&mut geo, &["ec0y".into()]).unwrap();
        assert_eq!(geo.squareness_urad, [0.0, 0.0, -3.0]);
        refuse_double_correction(&args, &[], Some(&geo), Some(&rot)).unwrap();
        let text = describe_geometric(&geo.spec());
        assert!(
            text.contains("  EC0Y 0 µrad, identified by the fit, EXCLUDED from this image"),
            "{text}"
        );
        assert!(text.contains("  EA0Z -3 µrad, identified\n"), "{text}");
    }

    /// An image written before provenance and without names on a board's inputs: `inspect` says it has no
    /// provenance and wires by position; the scenario's named group (spindle, column) is refused by the
    /// STM32G474 board's default inputs and wired on a board that names its inputs so; a bad
    /// `--board-inputs` is an error naming it.
    #[test]
    fn inspect_reports_missing_provenance_and_the_wiring() {
        let g = axcomp_scenario::group_image(3, false).unwrap();
        let board =
            parse_board_inputs(&crate::commands::image_board::default_board_inputs()).unwrap();
        let text = describe_trust(&g, &board).unwrap();
        assert!(
            text.contains("provenance: none")
                && text.contains("axis X (id 1) sensors (wired by name): REFUSED by this board")
                && text.contains("sensor 0 spindle -> no board input"),
            "{text}"
        );
        let named = parse_board_inputs("spindle:degC,column:degC").unwrap();
        let text = describe_trust(&g, &named).unwrap();
        assert!(
            text.contains("sensor 1 column -> board input 1 column (°C)"),
            "{text}"
        );
        // A schema-1 image without names: by position.
        let (x, _) = group_image::parse(&g).unwrap().axis_images();
        let text = describe_trust(x[0].image, &board).unwrap();
        assert!(
            text.contains("no names: wired by position")
                && text.contains("sensor 0 (unnamed) -> board input 0 rtd0 (°C)"),
            "{text}"
        );
        let e = parse_board_inputs("rtd0:kelvin").unwrap_err();
        assert!(e.to_string().contains("`kelvin`"), "{e}");
    }
}
