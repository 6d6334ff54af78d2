//! `axcomp image group`: a group image (schema 2) from the axes' images of `image build` and the
//! group's stages (rotary location errors, geometric model, probe settings).
//!
//! Glossary (the conversions and checks live in `axcomp_image`):
//! - *group image*: one section per axis (each holding that axis's schema-1 image), an optional
//!   rotary location-error model, geometric model and probe settings, sensor names and provenance.
//! - *double correction*: two sources of one group image correcting the same error; refused (naming
//!   both sources, nothing written) unless `--exclude-geometric` leaves the geometric model's out
//!   (`axcomp_image::group::refuse_double_correction`).

use std::path::{Path, PathBuf};

use anyhow::Context;
use axcomp_core::group::AxisName;
use axcomp_core::group_image;
use axcomp_core::probe::ProbeSettings;
use axcomp_core::provenance;
use axcomp_core::rotary::RotaryLocationSpec;
use axcomp_geometry::GeometryModel;
use axcomp_image::GeometricSection;
use axcomp_image::args;
use axcomp_image::group::{self as group_lib, GroupAxis, GroupStages};
use axcomp_image::linear_geometry::{self, LinearGeometry};

use crate::output::OutputSet;

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
    /// `tool_length_um`). The group needs X, Y, Z, the tilt axis (A or B) and C. The model's effects
    /// go in too: `rotary_positioning` as the rotary axes' angle tables, `rotary_wobble` in the rotary
    /// section, `linear_geometry` in the geometric section (added to --geometry's if given).
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
    /// whose strokes become the model's grids (an axis table must span the same grid). Every
    /// component goes in as the model holds it (what `predict` uses): not-separable ones at their
    /// minimum-norm share, those without data as zero; `image inspect` says which.
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

/// The rotary section from `--rotary` and its placement arguments; the model's rotary positioning
/// error put into the rotary axes' images as their angle tables (a note says so), a warning for each
/// part of the model the image does not carry.
fn rotary_from_args(
    args: &GroupArgs,
    axes: &mut [GroupAxis],
) -> anyhow::Result<Option<(RotaryLocationSpec, Option<LinearGeometry>)>> {
    let Some(path) = args.rotary.as_deref() else {
        anyhow::ensure!(
            args.pivot_counts.is_none() && args.tool_length_mm.is_none(),
            "--pivot-counts and --tool-length-mm go with --rotary"
        );
        return Ok(None);
    };
    let label = format!("--rotary {}", path.display());
    let bytes = std::fs::read(path).with_context(|| format!("{label}: cannot read"))?;
    let text = axcomp_files::model_text(&bytes).map_err(|why| anyhow::anyhow!("{label} {why}"))?;
    let section = axcomp_image::rotary::rotary_section(
        &label,
        text,
        args.pivot_counts.as_deref(),
        args.tool_length_mm,
    )?;
    axcomp_image::angle_table::put_angle_tables(axes, &section.effects.angle_errors, &label)?;
    for c in &section.effects.carried {
        eprintln!("axcomp: note: {label}: {c}");
    }
    for w in &section.effects.left_out {
        eprintln!("axcomp: warning: {label}: {w}");
    }
    Ok(Some((section.spec, section.effects.linear)))
}

/// `--geometry MODEL.json [--tool-offset-mm x,y,z]` for the group's axes, with the rotary model's
/// `linear_geometry` added to its translational components (alone on grids of its own without
/// `--geometry`; a note says how).
fn geometric_from_args(
    args: &GroupArgs,
    axes: &[GroupAxis],
    rotary: Option<&(RotaryLocationSpec, Option<LinearGeometry>)>,
) -> anyhow::Result<Option<GeometricSection>> {
    let base = geometry_model_from_args(args, axes)?;
    let Some((spec, Some(lin))) = rotary else {
        return Ok(base);
    };
    let label = format!(
        "--rotary {}",
        args.rotary.as_deref().unwrap_or(Path::new("")).display()
    );
    let combined = base.is_some();
    let place = linear_geometry::Placement::of(spec, axes)?;
    let (g, said) = linear_geometry::with_linear_geometry(lin, &place, axes, base, &label)?;
    eprintln!(
        "axcomp: note: {label}: `linear_geometry` {} the geometric section: {} (the stage holds \
         every function at its grid's ends; `predict` refuses poses outside the measured range)",
        if combined {
            "added to the --geometry model's components on its grid in"
        } else {
            "alone (no --geometry) in"
        },
        said.join("; ")
    );
    if combined {
        eprintln!(
            "axcomp: warning: {label}: the R-test's linear geometry is summed with the --geometry \
             model's: right when the R-test was measured with that model's compensation active \
             (it then saw what the model leaves); otherwise both correct the same errors"
        );
    }
    Ok(Some(g))
}

/// `--geometry MODEL.json [--tool-offset-mm x,y,z]` for the group's axes.
fn geometry_model_from_args(
    args: &GroupArgs,
    axes: &[GroupAxis],
) -> anyhow::Result<Option<GeometricSection>> {
    let Some(path) = &args.geometry else {
        return Ok(None);
    };
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("--geometry {}: cannot read", path.display()))?;
    let model = GeometryModel::from_json(&text, &path.display().to_string())?;
    let tool = args
        .tool_offset_mm
        .as_deref()
        .map(args::parse_tool_offset)
        .transpose()?
        .unwrap_or([0.0; 3]);
    let label = format!("--geometry {}", path.display());
    let mut g = axcomp_image::geometric::geometric_for_group(&model, &label, tool, axes)?;
    axcomp_image::exclude_geometric_components(&mut g, &args.exclude_geometric)?;
    Ok(Some(g))
}

/// The group's axes from `--axis` (each read and checked).
fn axes_from_args(args: &GroupArgs) -> anyhow::Result<Vec<GroupAxis>> {
    let mut axes = Vec::new();
    for a in &args.axes {
        let (name, cpr, path) = args::parse_axis_arg(a)?;
        let bytes = std::fs::read(&path)
            .with_context(|| format!("--axis {a}: cannot read {}", path.display()))?;
        group_lib::check_axis_image(a, &path.display().to_string(), &bytes)?;
        axes.push(GroupAxis {
            name,
            counts_per_rev: cpr,
            image: bytes,
            given_as: a.clone(),
        });
    }
    Ok(axes)
}

/// The group image bytes from the arguments (validated; nothing is written here).
pub fn group_bytes(args: &GroupArgs) -> anyhow::Result<Vec<u8>> {
    let mut axes = axes_from_args(args)?;
    let mut names: Vec<(AxisName, Vec<String>)> = Vec::new();
    for arg in &args.sensor_names {
        let (name, list) = args::parse_sensor_names_arg(arg)?;
        anyhow::ensure!(
            !names.iter().any(|(m, _)| *m == name),
            "--sensor-names {arg}: axis {} is given names twice",
            name.letter()
        );
        names.push((name, list));
    }
    let rotary = rotary_from_args(args, &mut axes)?;
    let names = group_lib::group_sensor_names(&axes, &names)?;
    anyhow::ensure!(
        args.exclude_geometric.is_empty() || args.geometry.is_some(),
        "--exclude-geometric goes with --geometry"
    );
    let geometric = geometric_from_args(args, &axes, rotary.as_ref())?;
    let rotary = rotary.map(|(spec, _)| spec);
    let shown = |p: &Option<PathBuf>| {
        p.as_ref()
            .map_or(String::new(), |p| p.display().to_string())
    };
    let (rotary_path, mut geo_path) = (shown(&args.rotary), shown(&args.geometry));
    if args.geometry.is_none() && geometric.is_some() {
        geo_path = format!("{rotary_path}'s linear_geometry");
    }
    let mut stages = GroupStages {
        rotary: rotary.as_ref().map(|r| (r, rotary_path.as_str())),
        geometric: geometric.as_ref().map(|g| (g, geo_path.as_str())),
        probe: None,
    };
    group_lib::refuse_double_correction(&axes, &stages)?;
    let probe: Option<ProbeSettings> = args
        .probe
        .as_deref()
        .map(args::parse_probe_settings)
        .transpose()?;
    stages.probe = probe.as_ref();
    Ok(group_lib::write_group(&axes, &names, &stages)?)
}

/// What `image group` writes: [`group_bytes`] with the provenance section (every axis image's model
/// records, the rotary and geometry model files', the tool, the date).
pub fn group_bytes_with_provenance(args: &GroupArgs) -> anyhow::Result<Vec<u8>> {
    let body = group_bytes(args)?;
    let axes = axes_from_args(args)?;
    let mut extra = Vec::new();
    for (path, role) in [
        (&args.rotary, provenance::role::ROTARY_MODEL),
        (&args.geometry, provenance::role::GEOMETRY_MODEL),
    ] {
        if let Some(p) = path {
            extra.push(crate::provenance::model_record(
                p,
                provenance::ANY_AXIS,
                role,
            )?);
        }
    }
    let records = group_lib::group_provenance_records(&axes, &extra)?;
    let block = crate::provenance::image_block(&records)?;
    Ok(axcomp_image::with_provenance_section(&body, &block)?)
}

pub fn group(args: GroupArgs) -> anyhow::Result<()> {
    let mut outputs = OutputSet::new();
    outputs.planned(&args.out);
    for a in &args.axes {
        if let Ok((_, _, path)) = args::parse_axis_arg(a) {
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
mod tests;
