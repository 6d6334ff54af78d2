//! The group image (schema version 2): a section directory, one CRC-32 per section and one over
//! the whole image, parsed and validated in one place ([`parse`]) into a typed view
//! ([`GroupImageView`]) that [`crate::group::Group::load`] takes. Schema-1 images (one axis) still
//! load: [`parse`] presents one as a single-axis group (axis X).
//!
//! # Glossary
//! - **section**: a typed, versioned, CRC-protected byte range; the directory lists them.
//! - **mandatory**: a section flag; a reader that does not know (or does not support) a
//!   mandatory section's type refuses the image ([`ImageError::UnknownSection`],
//!   [`ImageError::UnsupportedSection`]); an optional one it does not know is skipped.
//! - **requirements**: what the image needs from the board — counter width, axis ids and sensor
//!   count (from the axis sections), sensor names — checked by [`GroupImageView::check_against`]
//!   against a [`BoardCaps`].
//!
//! # Layout (schema version 2, little endian)
//! | off | type | field |
//! |---|---|---|
//! | 0 | `[u8; 4]` | magic `AXCI` |
//! | 4 | u16 | schema version (2) |
//! | 6 | u16 | header length (24) |
//! | 8 | u32 | total length, trailing CRC included |
//! | 12 | u16 | number of sections (1..=[`MAX_SECTIONS`]) |
//! | 14 | u16, u32, u32 | reserved, 0 |
//! | 24 | 20 × n | directory: `kind` u16, `version` u16, `axis` u8 (axis code, 0xFF = none), `flags` u8 (bit 0 mandatory; others 0), reserved u16, `offset` u32, `length` u32, `crc` u32 (CRC-32 of the section's bytes) |
//! | … | | sections, in directory order, after the directory, without overlap |
//! | total − 4 | u32 | CRC-32 of every byte before it |
//!
//! Nothing may follow the trailer ([`ImageError::TrailingBytes`]); offsets and lengths are
//! file-supplied u32 and added with checked arithmetic.
//!
//! Section kinds ([`SectionKind`]):
//! - **axis** (1, version 1, mandatory, one per axis; `axis` = its code): `counts_per_rev` u32
//!   (rotary; 0 linear), `stroke_start`, `stroke_end` i64 (linear: the table grid must span
//!   exactly this stroke; both 0 = not stated), reserved u32 ×2 = 0, then the axis's pipeline as
//!   a schema-1 image (table, thermo-force term, limits) filling the rest of the section.
//! - **geometric model** (2, version 1, axis 0xFF, at most one; [`GeometricSpec`], see
//!   [`crate::geometric`]): the group must have X, Y and Z, and each axis's grid must span exactly
//!   its axis's stroke (the stated stroke of its axis section, else its table's grid; an axis with
//!   neither is refused, [`ImageError::GridMismatch`]). Layout:
//!
//!   | off | type | field |
//!   |---|---|---|
//!   | 0 | `[u8; 3]` | chain: axis codes (0 = X, 1 = Y, 2 = Z) from the workpiece to the tool (work axes outermost first, then tool axes from the bed outward), each once |
//!   | 3 | u8 | work axes: how many of the chain's first entries carry the workpiece (0..=3) |
//!   | 4 | u32 | identified mask: bit i = component i (EXX … ECZ, EC0Y, EB0Z, EA0Z) was identified by the fit; the others are stored as the model gives them (zero) |
//!   | 8 | f32 × 3 | tool offset from the tool reference point, µm (x, y, z) |
//!   | 20 | f32 × 3 | squareness EC0Y, EB0Z, EA0Z, µrad |
//!   | 32 | 3 × (i64, u32, u32) | grids of X, Y, Z: `start_counts`, `segment_counts`, `n_segments` (1..=1024) |
//!   | 80 | u32 × 4 | reserved, 0 |
//!   | 96 | f32 × 4 × 6 × Σn | coefficients: X's segments, then Y's, then Z's; per segment the axis's 6 functions (EX?, EY?, EZ?: µm; EA?, EB?, EC?: µrad) as `[c0, c1, c2, c3]` in t ∈ [0, 1) |
//!
//!   The section's length is exactly 96 + 96·Σn bytes.
//! - **probe settings** (4, version 1, axis 0xFF, 20 bytes, at most one; [`crate::probe`]):
//!   `min_pulse_us` u32, `latency_ns` u32, `lockout_us` u32, `moving_um_per_s` f32, reserved
//!   u32 = 0 (ranges: [`ProbeSettings::validate`]). Image data rather than drive configuration:
//!   the latency and the filter belong to the probe and its receiver, calibrated with the
//!   machine (`axcomp fit probe`) like the tables, and the latched point is corrected with this
//!   image's tables, so they are swapped together (A/B) or not at all.
//! - **rotary model** (3, axis 0xFF): version 2 (80 bytes): `machine` u8 (1 ac-trunnion,
//!   2 bc-trunnion, 3 bc-head), reserved u8 = 0, `not_identified` u16 (bit k: constant k was not
//!   identified and holds 0; provenance only), the 8 location errors of
//!   [`RotaryLocationSpec`] (f32, in its field order), the squareness EA0Z, EB0Z, EC0Y (3 × f32),
//!   `pivot_counts` 3 × i64, `tool_length_um` f32, reserved u32 = 0. Version 1 (64 bytes: the
//!   same without the machine and the squareness) loads as an AC trunnion without squareness;
//!   the writer uses it whenever it holds the model exactly (so older readers keep loading such
//!   images).
//! - **sensor names** (5, version 1, one per axis with sensors; `axis` = its code): one 16-byte
//!   UTF-8 name per sensor of that axis, zero padded, non-empty.
//! - **provenance** (6, version 1, axis 0xFF, optional: written without the mandatory flag, so
//!   readers that do not know it skip it; at most one): the provenance block of
//!   [`crate::provenance`] (tool, build date, per model file its axis, role, SHA-256 and the
//!   SHA-256 of its measurement data). Its framing (length, version, reserved bytes, text fields)
//!   and CRC are validated; its content is never acted on.
//!
//! A schema-1 image presented as a group takes its sensor names and provenance from its header
//! extension (`SNAM`, `PROV` blocks, [`crate::provenance`]) when it has one.

pub use crate::format::{
    AXIS_SECTION_HEADER_LEN, DIR_ENTRY_LEN, FLAG_MANDATORY, GEOMETRIC_HEADER_LEN,
    GEOMETRIC_SEGMENT_LEN, GROUP_HEADER_LEN, GROUP_SCHEMA_VERSION, MAX_SECTIONS, NO_AXIS,
    ROTARY_SECTION_LEN, ROTARY_SECTION_V1_LEN, ROTARY_SECTION_VERSION, SENSOR_NAME_LEN,
};

use crate::axis::{AxisName, GroupAxisImage, MAX_AXES};
use crate::error::ImageError;
use crate::format::{CRC_LEN, crc32};
use crate::geometric::{GeometricCoefficients, GeometricGrid, GeometricSpec};
use crate::image;
use crate::le::{Put, f32_at, i64_at, rd, u8_at, u16_at, u32_at};
use crate::probe_settings::{PROBE_SECTION_LEN, ProbeSettings};
use crate::rotary::{RotaryLocationSpec, RotaryMachine};
use crate::{MAX_IMAGE_LEN, MAX_SENSORS};

/// Section types.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u16)]
pub enum SectionKind {
    /// One axis's pipeline.
    Axis = 1,
    /// Volumetric (21-error) geometric model.
    Geometric = 2,
    /// Rotary location-error model.
    Rotary = 3,
    /// Touch-probe settings ([`ProbeSettings`]).
    Probe = 4,
    /// Sensor names of an axis.
    SensorNames = 5,
    /// Provenance of the image (optional).
    Provenance = 6,
}

impl SectionKind {
    const fn from_u16(v: u16) -> Option<SectionKind> {
        match v {
            1 => Some(SectionKind::Axis),
            2 => Some(SectionKind::Geometric),
            3 => Some(SectionKind::Rotary),
            4 => Some(SectionKind::Probe),
            5 => Some(SectionKind::SensorNames),
            6 => Some(SectionKind::Provenance),
            _ => None,
        }
    }
}

/// One axis of a group image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisSection<'a> {
    /// Name, counts per revolution and the schema-1 image of the pipeline.
    pub axis: GroupAxisImage<'a>,
    /// Linear: the stroke the table grid spans (start, end), if stated.
    pub stroke_counts: Option<(i64, i64)>,
    /// Sensor names (16 bytes each, zero padded), if the image has them.
    pub sensor_names: &'a [u8],
}

impl AxisSection<'_> {
    /// Name of sensor `i` (without padding).
    pub fn sensor_name(&self, i: usize) -> Option<&str> {
        let raw = self
            .sensor_names
            .get(i * SENSOR_NAME_LEN..(i + 1) * SENSOR_NAME_LEN)?;
        let end = raw.iter().position(|&b| b == 0).unwrap_or(raw.len());
        core::str::from_utf8(raw.get(..end)?).ok()
    }
}

/// The validated, typed view of a group image (borrowing its bytes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroupImageView<'a> {
    /// Schema version (1 for a single-axis image, 2 for a group image).
    pub version: u16,
    axes: [Option<AxisSection<'a>>; MAX_AXES],
    n_axes: usize,
    /// The rotary location-error model, if any.
    pub rotary: Option<RotaryLocationSpec>,
    /// The touch-probe settings, if any (section kind 4).
    pub probe: Option<ProbeSettings>,
    /// The provenance block, if the image has one (validated, never acted on).
    pub provenance: Option<crate::provenance_block::ProvenanceView<'a>>,
    /// The volumetric geometric model, if any (its coefficients borrow the image).
    pub geometric: Option<GeometricSpec<'a>>,
    /// The stored whole-image CRC-32.
    pub crc: u32,
}

impl<'a> GroupImageView<'a> {
    /// The axes, in section order.
    pub fn axes(&self) -> impl Iterator<Item = &AxisSection<'a>> {
        self.axes.iter().take(self.n_axes).flatten()
    }
    /// Number of axes.
    pub fn axis_count(&self) -> usize {
        self.n_axes
    }
    /// The axes as [`GroupAxisImage`]s for [`crate::group::Group::load`] (first `n` entries).
    pub fn axis_images(&self) -> ([GroupAxisImage<'a>; MAX_AXES], usize) {
        let mut out = [GroupAxisImage {
            name: AxisName::X,
            counts_per_rev: 0,
            image: &[],
        }; MAX_AXES];
        for (o, a) in out.iter_mut().zip(self.axes()) {
            *o = a.axis;
        }
        (out, self.n_axes)
    }

    /// Refuse a group whose axes do not carry distinct axis ids: a board feeds each id from one
    /// scale input, so two axes with one id would both follow that input.
    pub fn check_axis_ids(&self) -> Result<(), ImageError> {
        let mut seen = [0u16; MAX_AXES];
        for (i, a) in self.axes().enumerate() {
            let id = image::inspect_image(a.axis.image)?.axis_id;
            if seen[..i.min(MAX_AXES)].contains(&id) {
                return Err(ImageError::AxisIdTwice { axis_id: id });
            }
            if let Some(s) = seen.get_mut(i) {
                *s = id;
            }
        }
        Ok(())
    }

    /// Refuse a rotary pivot far outside the strokes: on each linear axis with a stated stroke
    /// (else the span of its table), the pivot's coordinate must lie within the stroke widened by the stroke's length on each
    /// side (a head's gauge origin just off the travel is accepted; a pivot kilometres away, mm
    /// taken for counts or a sign error, is not).
    pub fn check_pivot(&self) -> Result<(), ImageError> {
        let Some(r) = &self.rotary else {
            return Ok(());
        };
        for a in self.axes() {
            let k = a.axis.name as usize;
            // The stated stroke, else the span of the axis's own table.
            let stroke = a.stroke_counts.or_else(|| {
                let (start, seg, n) = image::table_grid_of(a.axis.image)?;
                Some((start, start.saturating_add(seg as i64 * n as i64)))
            });
            let (Some(&p), Some((lo, hi))) = (r.pivot_counts.get(k), stroke) else {
                continue;
            };
            let w = hi.saturating_sub(lo).max(0);
            if k <= 2 && (p < lo.saturating_sub(w) || p > hi.saturating_add(w)) {
                return Err(ImageError::PivotOutsideStroke { axis: k as u8 });
            }
        }
        Ok(())
    }

    /// What a group must hold beyond each section's own validation: distinct axis ids
    /// ([`Self::check_axis_ids`], also checked by the board's drive) and a pivot near the strokes
    /// ([`Self::check_pivot`], checked by the host's `image group` and `inspect`).
    pub fn check_group(&self) -> Result<(), ImageError> {
        self.check_axis_ids()?;
        self.check_pivot()
    }

    /// Refuse the image if the board cannot run it: every axis's counter width must be the
    /// board's, every axis id one the board drives, and no axis may need more temperature inputs
    /// than the board has wired.
    pub fn check_against(&self, caps: &BoardCaps) -> Result<(), ImageError> {
        self.check_group()?;
        for a in self.axes() {
            let info = image::inspect_image(a.axis.image)?;
            caps.check(info.counter_bits, info.axis_id, info.n_sensors)?;
        }
        Ok(())
    }
}

/// What a board has: the counter width of its scale inputs, the axis ids it drives and the
/// temperature inputs it has wired.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BoardCaps {
    /// Width of the hardware counters (e.g. 16 for the STM32G474's encoder timers).
    pub counter_bits: u8,
    /// Axis ids the board drives (first `n_axes` entries).
    pub axis_ids: [u16; MAX_AXES],
    /// Number of valid entries in `axis_ids`.
    pub n_axes: u8,
    /// Temperature inputs wired.
    pub sensor_inputs: u8,
}

impl BoardCaps {
    /// One axis's needs against the board.
    pub fn check(
        &self,
        counter_bits: u8,
        axis_id: u16,
        n_sensors: usize,
    ) -> Result<(), ImageError> {
        if counter_bits != self.counter_bits {
            return Err(ImageError::CounterWidthMismatch {
                image: counter_bits,
                board: self.counter_bits,
            });
        }
        let ids = self
            .axis_ids
            .get(..(self.n_axes as usize).min(MAX_AXES))
            .unwrap_or(&[]);
        if !ids.contains(&axis_id) {
            return Err(ImageError::AxisIdMismatch { image: axis_id });
        }
        if n_sensors > self.sensor_inputs as usize {
            return Err(ImageError::TooFewSensorInputs {
                needed: n_sensors as u8,
                wired: self.sensor_inputs,
            });
        }
        Ok(())
    }
}

/// A directory entry.
#[derive(Debug, Clone, Copy)]
struct Entry {
    kind: u16,
    version: u16,
    axis: u8,
    flags: u8,
    offset: usize,
    len: usize,
}

/// Validate `b` completely (a schema-2 group image, or a schema-1 single-axis image taken as
/// axis X) and return its typed view. Exactly the image's bytes: trailing bytes are refused.
pub fn parse(b: &[u8]) -> Result<GroupImageView<'_>, ImageError> {
    if b.len() < 6 {
        return Err(ImageError::TooShort);
    }
    if rd::<4>(b, 0) != image::MAGIC {
        return Err(ImageError::BadMagic);
    }
    match u16_at(b, 4) {
        image::SCHEMA_VERSION => parse_v1(b),
        GROUP_SCHEMA_VERSION => parse_v2(b),
        found => Err(ImageError::UnsupportedVersion { found }),
    }
}

fn parse_v1(b: &[u8]) -> Result<GroupImageView<'_>, ImageError> {
    let info = image::inspect_image(b)?;
    if b.len() != info.len {
        return Err(ImageError::TrailingBytes);
    }
    // The header extension (older writers have none): sensor names and provenance.
    let ext = crate::provenance_block::header_extension(b);
    let sensor_names = match crate::provenance_block::find_block(
        ext,
        crate::provenance_block::SENSOR_NAMES_TAG,
    )? {
        Some(s) => {
            check_sensor_names(s, info.n_sensors, AxisName::X.code())?;
            s
        }
        None => &[],
    };
    let provenance =
        crate::provenance_block::find_block(ext, crate::provenance_block::PROVENANCE_TAG)?
            .map(crate::provenance_block::ProvenanceView::parse)
            .transpose()?;
    let mut axes = [None; MAX_AXES];
    axes[0] = Some(AxisSection {
        axis: GroupAxisImage {
            name: AxisName::X,
            counts_per_rev: 0,
            image: b,
        },
        stroke_counts: None,
        sensor_names,
    });
    Ok(GroupImageView {
        version: image::SCHEMA_VERSION,
        axes,
        n_axes: 1,
        rotary: None,
        probe: None,
        provenance,
        geometric: None,
        crc: info.crc,
    })
}

fn parse_v2(b: &[u8]) -> Result<GroupImageView<'_>, ImageError> {
    // ---- header, whole-image CRC, exact length ----
    if b.len() < GROUP_HEADER_LEN + CRC_LEN {
        return Err(ImageError::TooShort);
    }
    let header_len = u16_at(b, 6) as usize;
    let total = u32_at(b, 8) as usize;
    let n_sections = u16_at(b, 12) as usize;
    if header_len != GROUP_HEADER_LEN || total > MAX_IMAGE_LEN {
        return Err(ImageError::BadLength);
    }
    if b.len() < total {
        return Err(ImageError::TooShort);
    }
    if b.len() > total {
        return Err(ImageError::TrailingBytes);
    }
    if u16_at(b, 14) != 0 || u32_at(b, 16) != 0 || u32_at(b, 20) != 0 {
        return Err(reserved());
    }
    if n_sections == 0 || n_sections > MAX_SECTIONS {
        return Err(ImageError::BadLength);
    }
    let dir_end = n_sections
        .checked_mul(DIR_ENTRY_LEN)
        .and_then(|d| d.checked_add(GROUP_HEADER_LEN))
        .ok_or(ImageError::BadLength)?;
    let body_end = total.checked_sub(CRC_LEN).ok_or(ImageError::BadLength)?;
    if dir_end > body_end {
        return Err(ImageError::BadLength);
    }
    if crc32(b.get(..body_end).unwrap_or(&[])) != u32_at(b, body_end) {
        return Err(ImageError::BadCrc);
    }

    // ---- directory: bounds (checked), order, per-section CRC ----
    let mut entries = [None::<Entry>; MAX_SECTIONS];
    let mut cursor = dir_end;
    for (i, slot) in entries.iter_mut().enumerate().take(n_sections) {
        let at = GROUP_HEADER_LEN + DIR_ENTRY_LEN * i;
        let e = Entry {
            kind: u16_at(b, at),
            version: u16_at(b, at + 2),
            axis: u8_at(b, at + 4),
            flags: u8_at(b, at + 5),
            offset: u32_at(b, at + 8) as usize,
            len: u32_at(b, at + 12) as usize,
        };
        if u16_at(b, at + 6) != 0 || e.flags & !FLAG_MANDATORY != 0 {
            return Err(reserved());
        }
        let end = e
            .offset
            .checked_add(e.len)
            .ok_or(ImageError::SectionBounds { index: i as u16 })?;
        if e.offset < cursor || end > body_end {
            return Err(ImageError::SectionBounds { index: i as u16 });
        }
        let bytes = b.get(e.offset..end).unwrap_or(&[]);
        if crc32(bytes) != u32_at(b, at + 16) {
            return Err(ImageError::SectionCrc { index: i as u16 });
        }
        cursor = end;
        *slot = Some(e);
    }

    // ---- sections into typed views ----
    let mut view = GroupImageView {
        version: GROUP_SCHEMA_VERSION,
        axes: [None; MAX_AXES],
        n_axes: 0,
        rotary: None,
        probe: None,
        provenance: None,
        geometric: None,
        crc: u32_at(b, body_end),
    };
    let mut names: [Option<(u8, &[u8])>; MAX_AXES] = [None; MAX_AXES];
    let mut n_names = 0;
    for (i, e) in entries.iter().take(n_sections).flatten().enumerate() {
        let s = b.get(e.offset..e.offset + e.len).unwrap_or(&[]);
        let mandatory = e.flags & FLAG_MANDATORY != 0;
        let kind = match SectionKind::from_u16(e.kind) {
            Some(k) => k,
            None if mandatory => return Err(ImageError::UnknownSection { kind: e.kind }),
            None => continue,
        };
        let supported = match kind {
            SectionKind::Rotary => matches!(e.version, 1 | ROTARY_SECTION_VERSION),
            _ => e.version == 1,
        };
        if !supported {
            if mandatory {
                return Err(ImageError::UnsupportedSection { kind: e.kind });
            }
            continue;
        }
        match kind {
            SectionKind::Probe => {
                if e.axis != NO_AXIS || s.len() != PROBE_SECTION_LEN || view.probe.is_some() {
                    return Err(ImageError::SectionBounds { index: i as u16 });
                }
                view.probe = Some(ProbeSettings::from_bytes(s)?);
            }
            SectionKind::Geometric => {
                if e.axis != NO_AXIS || view.geometric.is_some() {
                    return Err(ImageError::SectionBounds { index: i as u16 });
                }
                view.geometric = Some(parse_geometric(s, i)?);
            }
            SectionKind::Axis => {
                if view.n_axes == MAX_AXES {
                    return Err(ImageError::AxisCount);
                }
                view.axes[view.n_axes] = Some(parse_axis(e, s, i)?);
                view.n_axes += 1;
            }
            SectionKind::Rotary => {
                if e.axis != NO_AXIS || view.rotary.is_some() {
                    return Err(ImageError::SectionBounds { index: i as u16 });
                }
                let spec = parse_rotary(e.version, s, i)?;
                spec.validate()?;
                view.rotary = Some(spec);
            }
            SectionKind::SensorNames => {
                if n_names == MAX_AXES
                    || s.len() % SENSOR_NAME_LEN != 0
                    || s.len() / SENSOR_NAME_LEN > MAX_SENSORS
                {
                    return Err(ImageError::SectionBounds { index: i as u16 });
                }
                names[n_names] = Some((e.axis, s));
                n_names += 1;
            }
            SectionKind::Provenance => {
                if e.axis != NO_AXIS || view.provenance.is_some() {
                    return Err(ImageError::SectionBounds { index: i as u16 });
                }
                view.provenance = Some(crate::provenance_block::ProvenanceView::parse(s)?);
            }
        }
    }
    if view.n_axes == 0 {
        return Err(ImageError::AxisCount);
    }
    // Each axis once; sensor names only for an axis the group has, one per sensor.
    let axes = view.axes;
    for (i, a) in axes.iter().flatten().enumerate() {
        if axes[..i]
            .iter()
            .flatten()
            .any(|b| b.axis.name == a.axis.name)
        {
            return Err(ImageError::DuplicateAxis {
                axis: a.axis.name.code(),
            });
        }
    }
    for (code, s) in names.iter().flatten() {
        let Some(k) = axes
            .iter()
            .position(|a| a.is_some_and(|a| a.axis.name.code() == *code))
        else {
            return Err(ImageError::AxisNotInGroup { axis: *code });
        };
        let n_sensors = image::inspect_image(axes[k].map_or(&[][..], |a| a.axis.image))?.n_sensors;
        check_sensor_names(s, n_sensors, *code)?;
        if let Some(a) = view.axes[k].as_mut() {
            a.sensor_names = s;
        }
    }
    // The geometric grids span their axes' strokes (stated, else the table's grid).
    if let Some(g) = &view.geometric {
        for (k, grid) in g.grids.iter().enumerate() {
            let Some(a) = view.axes().find(|a| a.axis.name.code() as usize == k) else {
                return Err(ImageError::AxisNotInGroup { axis: k as u8 });
            };
            let stroke = a.stroke_counts.or_else(|| {
                image::table_grid_of(a.axis.image)
                    .map(|(t0, seg, n)| (t0, (t0 as i128 + seg as i128 * n as i128) as i64))
            });
            match stroke {
                Some((lo, hi)) if lo == grid.start_counts && hi as i128 == grid.end_counts() => {}
                _ => return Err(ImageError::GridMismatch { axis: k as u8 }),
            }
        }
    }
    // The group's own rules (counts per revolution, rotary grids, the stages' axes), as
    // `Group::load` applies them (the pool size is the loading build's business).
    let (images, n) = view.axis_images();
    crate::group_check::validate_group_stages::<{ usize::MAX }>(
        &images[..n],
        view.rotary.as_ref(),
        view.geometric.as_ref(),
    )
    .map_err(|g| g.error)?;
    Ok(view)
}

/// One non-empty, zero-padded UTF-8 name per sensor.
fn check_sensor_names(s: &[u8], n_sensors: usize, code: u8) -> Result<(), ImageError> {
    if s.len() != n_sensors * SENSOR_NAME_LEN {
        return Err(ImageError::SensorNames { axis: code });
    }
    for name in s.chunks(SENSOR_NAME_LEN) {
        let end = name.iter().position(|&c| c == 0).unwrap_or(name.len());
        let (text, pad) = name.split_at(end);
        if end == 0 || core::str::from_utf8(text).is_err() || pad.iter().any(|&c| c != 0) {
            return Err(ImageError::SensorNames { axis: code });
        }
    }
    Ok(())
}

/// A rotary-model section of `version` 1 (AC trunnion, no squareness) or 2.
fn parse_rotary(version: u16, s: &[u8], index: usize) -> Result<RotaryLocationSpec, ImageError> {
    let bounds = ImageError::SectionBounds {
        index: index as u16,
    };
    let (machine, at) = if version == 1 {
        if s.len() != ROTARY_SECTION_V1_LEN {
            return Err(bounds);
        }
        (RotaryMachine::AcTrunnion, 0)
    } else {
        if s.len() != ROTARY_SECTION_LEN {
            return Err(bounds);
        }
        if u8_at(s, 1) != 0 {
            return Err(reserved());
        }
        let Some(m) = RotaryMachine::from_code(u8_at(s, 0)) else {
            return Err(ImageError::OutOfRange {
                field: crate::error::Field::RotaryMachine,
                index: 0,
            });
        };
        (m, 4)
    };
    let f = |k: usize| f32_at(s, at + 4 * k);
    let squareness_urad = if version == 1 {
        [0.0; 3]
    } else {
        [f(8), f(9), f(10)]
    };
    let tail = if version == 1 { at + 32 } else { at + 44 };
    if u32_at(s, tail + 28) != 0 {
        return Err(reserved());
    }
    Ok(RotaryLocationSpec {
        machine,
        ex0c_um: f(0),
        ey0c_um: f(1),
        ea0c_urad: f(2),
        eb0c_urad: f(3),
        ey0a_um: f(4),
        ez0a_um: f(5),
        eb0a_urad: f(6),
        ec0a_urad: f(7),
        squareness_urad,
        pivot_counts: [i64_at(s, tail), i64_at(s, tail + 8), i64_at(s, tail + 16)],
        tool_length_um: f32_at(s, tail + 24),
        not_identified: if version == 1 { 0 } else { u16_at(s, 2) },
    })
}

/// Length of the rotary section [`write_group_image`] writes for `r` (version 1 when it fits).
fn rotary_section_len(r: &RotaryLocationSpec) -> usize {
    if r.fits_version_1() {
        ROTARY_SECTION_V1_LEN
    } else {
        ROTARY_SECTION_LEN
    }
}

fn parse_geometric(s: &[u8], index: usize) -> Result<GeometricSpec<'_>, ImageError> {
    if s.len() < GEOMETRIC_HEADER_LEN {
        return Err(ImageError::SectionBounds {
            index: index as u16,
        });
    }
    if (80..GEOMETRIC_HEADER_LEN)
        .step_by(4)
        .any(|off| u32_at(s, off) != 0)
    {
        return Err(reserved());
    }
    let grid = |k: usize| GeometricGrid {
        start_counts: i64_at(s, 32 + 16 * k),
        segment_counts: u32_at(s, 40 + 16 * k),
        n_segments: u32_at(s, 44 + 16 * k),
    };
    let spec = GeometricSpec {
        chain: [u8_at(s, 0), u8_at(s, 1), u8_at(s, 2)],
        work_axes: u8_at(s, 3),
        identified: u32_at(s, 4),
        tool_offset_um: [f32_at(s, 8), f32_at(s, 12), f32_at(s, 16)],
        squareness_urad: [f32_at(s, 20), f32_at(s, 24), f32_at(s, 28)],
        grids: [grid(0), grid(1), grid(2)],
        coefficients: GeometricCoefficients::Bytes(s.get(GEOMETRIC_HEADER_LEN..).unwrap_or(&[])),
    };
    spec.validate()?;
    Ok(spec)
}

/// Length of a geometric-model section for `spec`.
pub fn geometric_section_len(spec: &GeometricSpec) -> usize {
    GEOMETRIC_HEADER_LEN
        + GEOMETRIC_SEGMENT_LEN
            * spec
                .grids
                .iter()
                .map(|g| g.n_segments as usize)
                .sum::<usize>()
}

fn reserved() -> ImageError {
    ImageError::OutOfRange {
        field: crate::error::Field::Reserved,
        index: 0,
    }
}

fn parse_axis<'a>(e: &Entry, s: &'a [u8], index: usize) -> Result<AxisSection<'a>, ImageError> {
    let Some(name) = AxisName::from_code(e.axis) else {
        return Err(ImageError::SectionBounds {
            index: index as u16,
        });
    };
    if s.len() < AXIS_SECTION_HEADER_LEN {
        return Err(ImageError::SectionBounds {
            index: index as u16,
        });
    }
    if u32_at(s, 24) != 0 || u32_at(s, 28) != 0 {
        return Err(reserved());
    }
    let cpr = u32_at(s, 0);
    let (start, end) = (i64_at(s, 8), i64_at(s, 16));
    let img = s.get(AXIS_SECTION_HEADER_LEN..).unwrap_or(&[]);
    let info = image::inspect_image(img)?;
    if info.len != img.len() {
        return Err(ImageError::TrailingBytes);
    }
    // An embedded image's header extension (from `image build`) is validated like a schema-1
    // image's; the group's own sensor-names and provenance sections are what it uses.
    let ext = crate::provenance_block::header_extension(img);
    if let Some(p) =
        crate::provenance_block::find_block(ext, crate::provenance_block::PROVENANCE_TAG)?
    {
        crate::provenance_block::ProvenanceView::parse(p)?;
    }
    if let Some(n) =
        crate::provenance_block::find_block(ext, crate::provenance_block::SENSOR_NAMES_TAG)?
    {
        check_sensor_names(n, info.n_sensors, e.axis)?;
    }
    let stroke_counts = ((start, end) != (0, 0)).then_some((start, end));
    if let Some((lo, hi)) = stroke_counts {
        if name.is_rotary() || lo >= hi {
            return Err(ImageError::GridMismatch { axis: e.axis });
        }
        if let Some((t0, seg, n)) = image::table_grid_of(img) {
            let span = seg as i128 * n as i128;
            if t0 != lo || t0 as i128 + span != hi as i128 {
                return Err(ImageError::GridMismatch { axis: e.axis });
            }
        }
    }
    Ok(AxisSection {
        axis: GroupAxisImage {
            name,
            counts_per_rev: cpr,
            image: img,
        },
        stroke_counts,
        sensor_names: &[],
    })
}

/// One axis of a group image to write.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisSectionSpec<'a> {
    /// Which axis.
    pub name: AxisName,
    /// Rotary: counts per revolution; linear: 0.
    pub counts_per_rev: u32,
    /// Linear: the stroke the table grid must span, if stated.
    pub stroke_counts: Option<(i64, i64)>,
    /// The axis's schema-1 image (from [`crate::write_image`]).
    pub image: &'a [u8],
    /// One name per sensor of the axis (≤ 15 bytes of UTF-8 each), or empty.
    pub sensor_names: &'a [&'a str],
}

/// Length of the group image [`write_group_image`] writes.
pub fn group_image_len(axes: &[AxisSectionSpec], rotary: Option<&RotaryLocationSpec>) -> usize {
    group_image_len_with_stages(axes, rotary, None, None)
}

/// Length of the group image [`write_group_image_with_probe`] writes.
pub fn group_image_len_with_probe(
    axes: &[AxisSectionSpec],
    rotary: Option<&RotaryLocationSpec>,
    probe: Option<&ProbeSettings>,
) -> usize {
    group_image_len_with_stages(axes, rotary, None, probe)
}

/// Length of the group image [`write_group_image_with`] writes.
pub fn group_image_len_with(
    axes: &[AxisSectionSpec],
    rotary: Option<&RotaryLocationSpec>,
    geometric: Option<&GeometricSpec>,
) -> usize {
    group_image_len_with_stages(axes, rotary, geometric, None)
}

/// Length of the group image [`write_group_image_with_stages`] writes.
pub fn group_image_len_with_stages(
    axes: &[AxisSectionSpec],
    rotary: Option<&RotaryLocationSpec>,
    geometric: Option<&GeometricSpec>,
    probe: Option<&ProbeSettings>,
) -> usize {
    let n = section_count(axes, rotary) + geometric.is_some() as usize + probe.is_some() as usize;
    let mut len = GROUP_HEADER_LEN + DIR_ENTRY_LEN * n + CRC_LEN;
    for a in axes {
        len += AXIS_SECTION_HEADER_LEN + a.image.len() + SENSOR_NAME_LEN * a.sensor_names.len();
    }
    if let Some(r) = rotary {
        len += rotary_section_len(r);
    }
    if probe.is_some() {
        len += PROBE_SECTION_LEN;
    }
    if let Some(g) = geometric {
        len += geometric_section_len(g);
    }
    len
}

fn section_count(axes: &[AxisSectionSpec], rotary: Option<&RotaryLocationSpec>) -> usize {
    axes.len()
        + axes.iter().filter(|a| !a.sensor_names.is_empty()).count()
        + rotary.is_some() as usize
}

/// Write a group image into `out`; returns its length. The written image must pass [`parse`]
/// (and [`crate::group::Group::load`]'s group checks); on `Err` the written bytes are zeroed.
pub fn write_group_image(
    axes: &[AxisSectionSpec],
    rotary: Option<&RotaryLocationSpec>,
    out: &mut [u8],
) -> Result<usize, ImageError> {
    write_group_image_with_stages(axes, rotary, None, None, out)
}

/// [`write_group_image`] with a touch-probe settings section (kind 4) after the others.
pub fn write_group_image_with_probe(
    axes: &[AxisSectionSpec],
    rotary: Option<&RotaryLocationSpec>,
    probe: Option<&ProbeSettings>,
    out: &mut [u8],
) -> Result<usize, ImageError> {
    write_group_image_with_stages(axes, rotary, None, probe, out)
}

/// [`write_group_image`] with a geometric-model section (after the rotary one, if any).
pub fn write_group_image_with(
    axes: &[AxisSectionSpec],
    rotary: Option<&RotaryLocationSpec>,
    geometric: Option<&GeometricSpec>,
    out: &mut [u8],
) -> Result<usize, ImageError> {
    write_group_image_with_stages(axes, rotary, geometric, None, out)
}

/// [`write_group_image`] with the optional sections after the others: the touch-probe settings,
/// then the geometric model.
pub fn write_group_image_with_stages(
    axes: &[AxisSectionSpec],
    rotary: Option<&RotaryLocationSpec>,
    geometric: Option<&GeometricSpec>,
    probe: Option<&ProbeSettings>,
    out: &mut [u8],
) -> Result<usize, ImageError> {
    if let Some(g) = geometric {
        g.validate()?;
    }
    if let Some(p) = probe {
        p.validate()?;
    }
    if axes.is_empty() || axes.len() > MAX_AXES {
        return Err(ImageError::AxisCount);
    }
    for a in axes {
        for name in a.sensor_names {
            if name.is_empty() || name.len() >= SENSOR_NAME_LEN || name.contains('\0') {
                return Err(ImageError::SensorNames {
                    axis: a.name.code(),
                });
            }
        }
    }
    let len = group_image_len_with_stages(axes, rotary, geometric, probe);
    let n = section_count(axes, rotary) + geometric.is_some() as usize + probe.is_some() as usize;
    if len > MAX_IMAGE_LEN {
        return Err(ImageError::BadLength);
    }
    let Some(out) = out.get_mut(..len) else {
        return Err(ImageError::BufferTooSmall { needed: len as u32 });
    };
    out.fill(0);
    // Sections first (after the directory), then the directory with their CRCs.
    let mut at = GROUP_HEADER_LEN + DIR_ENTRY_LEN * n;
    let mut dir = [(0u16, 1u16, 0u8, 0usize, 0usize); MAX_SECTIONS];
    let mut k = 0;
    for a in axes {
        let start = at;
        let mut w = Put::new(out.get_mut(at..).unwrap_or(&mut []));
        w.u32(a.counts_per_rev);
        w.u32(0);
        let (lo, hi) = a.stroke_counts.unwrap_or((0, 0));
        w.i64(lo);
        w.i64(hi);
        w.u32(0);
        w.u32(0);
        w.bytes(a.image);
        at += w.pos;
        dir[k] = (
            SectionKind::Axis as u16,
            1,
            a.name.code(),
            start,
            at - start,
        );
        k += 1;
        if !a.sensor_names.is_empty() {
            let start = at;
            let mut w = Put::new(out.get_mut(at..).unwrap_or(&mut []));
            for name in a.sensor_names {
                let mut field = [0u8; SENSOR_NAME_LEN];
                field[..name.len()].copy_from_slice(name.as_bytes());
                w.bytes(&field);
            }
            at += w.pos;
            dir[k] = (
                SectionKind::SensorNames as u16,
                1,
                a.name.code(),
                start,
                at - start,
            );
            k += 1;
        }
    }
    if let Some(r) = rotary {
        let start = at;
        let mut w = Put::new(out.get_mut(at..).unwrap_or(&mut []));
        let version = if r.fits_version_1() {
            1
        } else {
            w.u8(r.machine.code());
            w.u8(0);
            w.u16(r.not_identified);
            ROTARY_SECTION_VERSION
        };
        for v in r.constants() {
            w.f32(v);
        }
        if version != 1 {
            for v in r.squareness_urad {
                w.f32(v);
            }
        }
        for p in r.pivot_counts {
            w.i64(p);
        }
        w.f32(r.tool_length_um);
        w.u32(0);
        at += w.pos;
        dir[k] = (
            SectionKind::Rotary as u16,
            version,
            NO_AXIS,
            start,
            at - start,
        );
        k += 1;
    }
    if let Some(p) = probe {
        let start = at;
        let mut w = Put::new(out.get_mut(at..).unwrap_or(&mut []));
        w.bytes(&p.to_bytes());
        at += w.pos;
        dir[k] = (SectionKind::Probe as u16, 1, NO_AXIS, start, at - start);
        k += 1;
    }
    if let Some(g) = geometric {
        let start = at;
        let mut w = Put::new(out.get_mut(at..).unwrap_or(&mut []));
        w.bytes(&g.chain);
        w.u8(g.work_axes);
        w.u32(g.identified);
        for v in g.tool_offset_um.iter().chain(g.squareness_urad.iter()) {
            w.f32(*v);
        }
        for grid in &g.grids {
            w.i64(grid.start_counts);
            w.u32(grid.segment_counts);
            w.u32(grid.n_segments);
        }
        for _ in 0..4 {
            w.u32(0);
        }
        for i in 0..g.coefficients.len() {
            for c in g.coefficients.get(i) {
                w.f32(c);
            }
        }
        at += w.pos;
        dir[k] = (SectionKind::Geometric as u16, 1, NO_AXIS, start, at - start);
        k += 1;
    }
    let mut w = Put::new(out);
    w.bytes(&image::MAGIC);
    w.u16(GROUP_SCHEMA_VERSION);
    w.u16(GROUP_HEADER_LEN as u16);
    w.u32(len as u32);
    w.u16(n as u16);
    w.u16(0);
    w.u32(0);
    w.u32(0);
    for &(kind, version, axis, off, slen) in dir.iter().take(k) {
        let crc = crc32(w.buf.get(off..off + slen).unwrap_or(&[]));
        w.u16(kind);
        w.u16(version);
        w.u8(axis);
        w.u8(FLAG_MANDATORY);
        w.u16(0);
        w.u32(off as u32);
        w.u32(slen as u32);
        w.u32(crc);
    }
    let body = len - CRC_LEN;
    let crc = crc32(w.buf.get(..body).unwrap_or(&[]));
    w.pos = body;
    w.u32(crc);
    match parse(out) {
        Ok(_) => Ok(len),
        Err(e) => {
            out.fill(0);
            Err(e)
        }
    }
}
