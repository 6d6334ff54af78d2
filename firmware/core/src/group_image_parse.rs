//! The group image parser: the header, the directory and each section into a typed view
//! ([`GroupImageView`]), every check of [`crate::group_image`]'s layout, and the group's own rules
//! ([`crate::group_check`]). Below the writer, which re-parses what it wrote.

use crate::axis::{AxisName, GroupAxisImage, MAX_AXES};
use crate::error::ImageError;
use crate::format::{
    AXIS_SECTION_HEADER_LEN, DIR_ENTRY_LEN, FLAG_MANDATORY, GEOMETRIC_HEADER_LEN,
    GEOMETRIC_SEGMENT_LEN, GROUP_HEADER_LEN, GROUP_SCHEMA_VERSION, MAX_SECTIONS, NO_AXIS,
    ROTARY_SECTION_LEN, ROTARY_SECTION_V1_LEN, ROTARY_SECTION_VERSION, ROTARY_SECTION_WOBBLE_LEN,
    ROTARY_SECTION_WOBBLE_VERSION, SENSOR_NAME_LEN,
};
use crate::format::{CRC_LEN, crc32};
use crate::geometric::{GeometricCoefficients, GeometricGrid, GeometricSpec};
use crate::image;
use crate::le::{f32_at, i64_at, rd, u8_at, u16_at, u32_at};
use crate::probe_settings::{PROBE_SECTION_LEN, ProbeSettings};
use crate::rotary_spec::{RotaryLocationSpec, RotaryMachine, RotaryWobble};
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
        // Indexed, not zipped: load-time code the zip unrolled over the slots (about 900 B more
        // of firmware code).
        for (k, a) in self.axes().enumerate() {
            if let Some(o) = out.get_mut(k) {
                *o = a.axis;
            }
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
    let (n_sections, dir_end, body_end) = check_header(b)?;
    let entries = read_directory(b, n_sections, dir_end, body_end)?;
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
    let mut names: SensorNameSections = [None; MAX_AXES];
    let mut n_names = 0;
    read_sections(
        b,
        &entries[..n_sections],
        &mut view,
        &mut names,
        &mut n_names,
    )?;
    check_across_sections(&mut view, &names)?;
    Ok(view)
}

/// The group header, the whole-image CRC and the exact length: `(sections, end of the directory,
/// end of the body)`.
fn check_header(b: &[u8]) -> Result<(usize, usize, usize), ImageError> {
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
    Ok((n_sections, dir_end, body_end))
}

/// The directory's entries: bounds (checked), order, each section's CRC.
fn read_directory(
    b: &[u8],
    n_sections: usize,
    dir_end: usize,
    body_end: usize,
) -> Result<[Option<Entry>; MAX_SECTIONS], ImageError> {
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
    Ok(entries)
}

/// Sensor names by axis code, as the sections list them (checked against the axes afterwards).
type SensorNameSections<'a> = [Option<(u8, &'a [u8])>; MAX_AXES];

/// The sections into typed views (`view`) and the sensor-names sections (`names`, `n_names`):
/// unknown optional kinds and versions skipped, each kind's own checks.
fn read_sections<'a>(
    b: &'a [u8],
    entries: &[Option<Entry>],
    view: &mut GroupImageView<'a>,
    names: &mut SensorNameSections<'a>,
    n_names: &mut usize,
) -> Result<(), ImageError> {
    for (i, e) in entries.iter().flatten().enumerate() {
        let s = b.get(e.offset..e.offset + e.len).unwrap_or(&[]);
        let mandatory = e.flags & FLAG_MANDATORY != 0;
        let kind = match SectionKind::from_u16(e.kind) {
            Some(k) => k,
            None if mandatory => return Err(ImageError::UnknownSection { kind: e.kind }),
            None => continue,
        };
        let supported = match kind {
            SectionKind::Rotary => {
                matches!(
                    e.version,
                    1 | ROTARY_SECTION_VERSION | ROTARY_SECTION_WOBBLE_VERSION
                )
            }
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
                if *n_names == MAX_AXES
                    || s.len() % SENSOR_NAME_LEN != 0
                    || s.len() / SENSOR_NAME_LEN > MAX_SENSORS
                {
                    return Err(ImageError::SectionBounds { index: i as u16 });
                }
                names[*n_names] = Some((e.axis, s));
                *n_names += 1;
            }
            SectionKind::Provenance => {
                if e.axis != NO_AXIS || view.provenance.is_some() {
                    return Err(ImageError::SectionBounds { index: i as u16 });
                }
                view.provenance = Some(crate::provenance_block::ProvenanceView::parse(s)?);
            }
        }
    }
    Ok(())
}

/// The rules across sections: at least one axis, each once; sensor names only for an axis the
/// group has, one per sensor; the geometric grids spanning their axes' strokes; the group's own
/// rules.
fn check_across_sections<'a>(
    view: &mut GroupImageView<'a>,
    names: &SensorNameSections<'a>,
) -> Result<(), ImageError> {
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
    crate::group_check::validate_group_stages(
        usize::MAX,
        &images[..n],
        view.rotary.as_ref(),
        view.geometric.as_ref(),
    )
    .map_err(|g| g.error)?;
    Ok(())
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

/// A rotary-model section of `version` 1 (AC trunnion, no squareness), 2 or 3 (with a wobble).
fn parse_rotary(version: u16, s: &[u8], index: usize) -> Result<RotaryLocationSpec, ImageError> {
    let bounds = ImageError::SectionBounds {
        index: index as u16,
    };
    let len = match version {
        1 => ROTARY_SECTION_V1_LEN,
        ROTARY_SECTION_VERSION => ROTARY_SECTION_LEN,
        _ => ROTARY_SECTION_WOBBLE_LEN,
    };
    if s.len() != len {
        return Err(bounds);
    }
    let (machine, at) = if version == 1 {
        (RotaryMachine::AcTrunnion, 0)
    } else {
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
        wobble: parse_wobble(s.get(ROTARY_SECTION_LEN..).unwrap_or(&[])),
    })
}

/// The wobble of a version-3 rotary section from the bytes after version 2's fields (none for
/// fewer bytes: versions 1 and 2).
fn parse_wobble(s: &[u8]) -> RotaryWobble {
    let mut w = RotaryWobble::NONE;
    if s.len() == ROTARY_SECTION_WOBBLE_LEN - ROTARY_SECTION_LEN {
        let (c, tilt) = s.split_at(32 * 4);
        read_f32s(c, w.c.as_flattened_mut());
        read_f32s(tilt, w.tilt.as_flattened_mut());
    }
    w
}

/// The little-endian f32 values of `s` into `out` (as many as both hold).
fn read_f32s(s: &[u8], out: &mut [f32]) {
    for (v, b) in out.iter_mut().zip(s.chunks_exact(4)) {
        *v = f32_at(b, 0);
    }
}

/// Length of the rotary section [`write_group_image`] writes for `r` (version 1 when it fits).
pub(crate) fn rotary_section_len(r: &RotaryLocationSpec) -> usize {
    if r.fits_version_1() {
        ROTARY_SECTION_V1_LEN
    } else if r.wobble.is_none() {
        ROTARY_SECTION_LEN
    } else {
        ROTARY_SECTION_WOBBLE_LEN
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
