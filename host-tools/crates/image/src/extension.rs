//! What a single-axis image carries besides the correction (the header extension: provenance block
//! and sensor names), a group image's provenance section, and where a value the core's image writer
//! refuses came from, with the firmware's range for it.

use axcomp_core::group_image;
use axcomp_core::provenance;
use axcomp_core::{Field, ImageError};
use axcomp_thermal::model_file::ThermalModelFile;

use crate::{Error, Result};

/// A schema-1 image with its header extension: the provenance block (`provenance_block`, from
/// `axcomp_core::provenance::write_provenance`) and, if any, the sensor names (`PROV`, `SNAM`;
/// CRC-covered, ignored by the correction).
pub fn with_extension(
    image: Vec<u8>,
    provenance_block: &[u8],
    names: &[String],
) -> Result<Vec<u8>> {
    let mut field = vec![0u8; group_image::SENSOR_NAME_LEN * names.len()];
    for (i, n) in names.iter().enumerate() {
        let at = group_image::SENSOR_NAME_LEN * i;
        field[at..at + n.len()].copy_from_slice(n.as_bytes());
    }
    let mut blocks = vec![(provenance::PROVENANCE_TAG, provenance_block)];
    if !names.is_empty() {
        blocks.push((provenance::SENSOR_NAMES_TAG, field.as_slice()));
    }
    let mut out = vec![0u8; image.len() + provenance::extension_len(&blocks)];
    let n = provenance::with_header_extension(&image, &blocks, &mut out)
        .map_err(|e| Error::core("the image's sensor names or provenance", e))?;
    out.truncate(n);
    Ok(out)
}

/// The provenance block of an image (`axcomp_core::provenance::write_provenance`): the tool that built
/// it, the build date (`built_utc`, ISO 8601) and one record per model file it was built from.
pub fn provenance_block(
    tool: &str,
    built_utc: &str,
    records: &[provenance::ProvenanceRecord],
) -> Result<Vec<u8>> {
    let mut block = vec![0u8; provenance::provenance_len(records.len())];
    provenance::write_provenance(tool, built_utc, records, &mut block)
        .map_err(|e| Error::core("provenance block", e))?;
    Ok(block)
}

/// A group image with the provenance section (kind 6, optional) holding `provenance_block` appended.
pub fn with_provenance_section(image: &[u8], provenance_block: &[u8]) -> Result<Vec<u8>> {
    let mut out = vec![0u8; image.len() + group_image::DIR_ENTRY_LEN + provenance_block.len()];
    let n = provenance::with_group_section(
        image,
        group_image::SectionKind::Provenance as u16,
        group_image::NO_AXIS,
        0,
        provenance_block,
        &mut out,
    )
    .map_err(|e| Error::core("the image's provenance section", e))?;
    out.truncate(n);
    Ok(out)
}

/// One name per sensor of the thermal model (its order is the firmware's): the model's name, or the board
/// input `--sensor-input SENSOR=INPUT` gives it; each 1..=15 bytes.
/// (`shown`: the model file, in messages.)
pub fn sensor_names(
    shown: &str,
    model: &ThermalModelFile,
    renames: &[String],
) -> Result<Vec<String>> {
    let mut names: Vec<String> = model.sensors.iter().map(|s| s.name.clone()).collect();
    let mut given: Vec<(&str, &str)> = Vec::new();
    for r in renames {
        let (from, to) = r.split_once('=').ok_or_else(|| {
            Error::Invalid(format!("--sensor-input `{r}`: expected SENSOR=INPUT"))
        })?;
        if let Some((_, before)) = given.iter().find(|(f, t)| *f == from && *t != to) {
            bail!(
                "--sensor-input `{r}`: sensor `{from}` is already given input `{before}` (one input per sensor)"
            );
        }
        given.push((from, to));
        let Some(k) = model.sensors.iter().position(|s| s.name == from) else {
            bail!(
                "--sensor-input `{r}`: `{from}` is not a sensor of {} (have: {})",
                shown,
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
                bail!(
                    "{}: sensors[{i}] and sensors[{j}] are both named `{n}`; the image wires sensors by \
                     name, so both would read one input (rename one in the model, or wire it with \
                     --sensor-input)",
                    shown
                );
            }
            bail!(
                "--sensor-input: sensors `{a}` and `{b}` of {} would both read input `{n}` (one input per \
                 sensor)",
                shown
            );
        }
    }
    for n in &names {
        ensure!(
            !n.is_empty() && n.len() < group_image::SENSOR_NAME_LEN && !n.contains('\0'),
            "sensor `{n}` of {}: an image keeps sensor names of 1 to {} bytes; name it after its board \
             input with --sensor-input {n}=INPUT",
            shown,
            group_image::SENSOR_NAME_LEN - 1
        );
    }
    Ok(names)
}

/// Where a value of an image field comes from in `image build`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldSource {
    /// The positioning table file.
    Table,
    /// A command-line option (its name, e.g. `--um-per-count`).
    Option(&'static str),
    /// The thermo-force model file, at its key (`sensors`, `forces`, or "" for a scalar).
    Thermal(&'static str),
}

/// Where the image field `field` comes from and the firmware's range for it (`axcomp_core` image,
/// "Validation ranges").
pub fn field_range(field: Field) -> (FieldSource, String) {
    use FieldSource::{Option as Opt, Table, Thermal};
    let (source, range): (FieldSource, &str) = match field {
        Field::ForwardCoefficient | Field::BackwardCoefficient => (
            Table,
            "a segment's deviation must stay within ±10 000 µm (f32 in the image)",
        ),
        Field::StartCounts | Field::SegmentCounts | Field::Outside => (
            Table,
            "in counts at this --um-per-count the table must start within ±2^62 counts and span at \
             most 4 294 967 295 counts",
        ),
        Field::UmPerCount => (Opt("--um-per-count"), "µm per count must be in [1e-6, 1e4]"),
        Field::CounterBits => (Opt("--counter-bits"), "the counter has 16 to 32 bits"),
        Field::MaxCorrection => (Opt("--max-correction-um"), "must be in (0, 100000] µm"),
        Field::MaxSlew => (Opt("--max-slew-um"), "must be in (0, 100000] µm"),
        Field::Hysteresis => (Opt("--hysteresis-counts"), "at most 2147483647 counts"),
        Field::ReferenceDegc | Field::SensorRange => (
            Thermal("sensors"),
            "temperatures must be in [−273.15, 2000] °C, min < max",
        ),
        Field::MaxRate => (
            Thermal("sensors"),
            "max_rate_degc_per_s must be in (0, 1e6] K/s",
        ),
        Field::LagTau => (Thermal("sensors"), "tau_s must be in [0, 1e7] s"),
        Field::StaleTimeout => (Thermal("sensors"), "stale_timeout_ms must be ≥ 1 ms"),
        Field::BUmPerK => (Thermal("sensors"), "|coef_um_per_k| must be ≤ 1e4 µm/K"),
        Field::RiseBounds => (
            Thermal("sensors"),
            "rise_min_k < rise_max_k, both within ±2273.15 K",
        ),
        Field::Chi => (Thermal("forces"), "|chi_um_per_n| must be ≤ 1e3 µm/N"),
        Field::ForceLaw => (
            Thermal("forces"),
            "a force law needs |k| ≤ 1e9 and |exponents| ≤ 10",
        ),
        Field::B0 => {
            return (
                Thermal(""),
                format!("|b0_um| must be ≤ {:e} µm", axcomp_core::image::MAX_B0_UM),
            );
        }
        Field::SensorPeriod => (Thermal(""), "sensor_period_ms must be ≥ 1 ms"),
        _ => (Thermal(""), "outside the firmware's range"),
    };
    (source, range.to_string())
}

/// `write_image`'s refusal `e` of an image spec as a message naming where the value came from
/// (`shown(source)`: the file or the option with its value) and the firmware's range; the element
/// of a thermo-force model named by `sensor_names`.
pub fn spec_error(
    e: ImageError,
    shown: impl Fn(FieldSource) -> String,
    sensor_names: &[String],
) -> Error {
    let field = match e {
        ImageError::NonFinite { field, .. } | ImageError::OutOfRange { field, .. } => field,
        _ => return Error::core("the image spec is not valid", e),
    };
    let (source, range) = field_range(field);
    let at = match (source, e) {
        (
            FieldSource::Thermal("sensors"),
            ImageError::NonFinite { index, .. } | ImageError::OutOfRange { index, .. },
        ) => match sensor_names.get(usize::from(index)) {
            Some(n) => format!(" (sensors[{index}], `{n}`)"),
            None => format!(" (sensors[{index}])"),
        },
        (
            FieldSource::Thermal("forces"),
            ImageError::NonFinite { index, .. } | ImageError::OutOfRange { index, .. },
        ) => format!(" (forces[{index}])"),
        _ => String::new(),
    };
    Error::Invalid(format!("{}{at}: {e}: {range}", shown(source)))
}
