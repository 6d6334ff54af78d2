//! The group image writer: axis sections, sensor names and the stages' sections, the directory
//! with each section's CRC, the whole-image CRC; what it wrote is parsed again
//! ([`crate::group_image::parse`]) before it is returned.

use crate::MAX_IMAGE_LEN;
use crate::axis::{AxisName, MAX_AXES};
use crate::error::ImageError;
use crate::format::{
    AXIS_SECTION_HEADER_LEN, CRC_LEN, DIR_ENTRY_LEN, FLAG_MANDATORY, GROUP_HEADER_LEN,
    GROUP_SCHEMA_VERSION, MAGIC, MAX_SECTIONS, NO_AXIS, ROTARY_SECTION_VERSION,
    ROTARY_SECTION_WOBBLE_VERSION, SENSOR_NAME_LEN, crc32,
};
use crate::geometric::GeometricSpec;
use crate::group_image_parse::{SectionKind, geometric_section_len, parse, rotary_section_len};
use crate::le::Put;
use crate::probe_settings::{PROBE_SECTION_LEN, ProbeSettings};
use crate::rotary_spec::RotaryLocationSpec;

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
    check_writable(axes, geometric, probe)?;
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
    let mut s = SectionWriter {
        out,
        at: GROUP_HEADER_LEN + DIR_ENTRY_LEN * n,
        dir: [(0, 1, 0, 0, 0); MAX_SECTIONS],
        k: 0,
    };
    for a in axes {
        s.push(SectionKind::Axis, 1, a.name.code(), |w| {
            w.u32(a.counts_per_rev);
            w.u32(0);
            let (lo, hi) = a.stroke_counts.unwrap_or((0, 0));
            w.i64(lo);
            w.i64(hi);
            w.u32(0);
            w.u32(0);
            w.bytes(a.image);
        });
        if !a.sensor_names.is_empty() {
            s.push(SectionKind::SensorNames, 1, a.name.code(), |w| {
                for name in a.sensor_names {
                    let mut field = [0u8; SENSOR_NAME_LEN];
                    field[..name.len()].copy_from_slice(name.as_bytes());
                    w.bytes(&field);
                }
            });
        }
    }
    if let Some(r) = rotary {
        let version = if r.fits_version_1() {
            1
        } else if r.wobble.is_none() {
            ROTARY_SECTION_VERSION
        } else {
            ROTARY_SECTION_WOBBLE_VERSION
        };
        s.push(SectionKind::Rotary, version, NO_AXIS, |w| {
            put_rotary(w, r, version)
        });
    }
    if let Some(p) = probe {
        s.push(SectionKind::Probe, 1, NO_AXIS, |w| w.bytes(&p.to_bytes()));
    }
    if let Some(g) = geometric {
        s.push(SectionKind::Geometric, 1, NO_AXIS, |w| put_geometric(w, g));
    }
    let SectionWriter { out, dir, k, .. } = s;
    put_header_and_directory(out, len, n, dir.get(..k).unwrap_or(&[]));
    match parse(out) {
        Ok(_) => Ok(len),
        Err(e) => {
            out.fill(0);
            Err(e)
        }
    }
}

/// What [`write_group_image_with_stages`] refuses before writing: invalid stages, no axis or too
/// many, a sensor name that is empty, too long or holds a NUL.
fn check_writable(
    axes: &[AxisSectionSpec],
    geometric: Option<&GeometricSpec>,
    probe: Option<&ProbeSettings>,
) -> Result<(), ImageError> {
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
    Ok(())
}

/// A directory entry as the writer collects it: kind, version, axis, offset, length.
type DirEntry = (u16, u16, u8, usize, usize);

/// The sections of a group image being written, one after the other from `at`, with their
/// directory entries.
struct SectionWriter<'o> {
    out: &'o mut [u8],
    at: usize,
    dir: [DirEntry; MAX_SECTIONS],
    k: usize,
}

impl SectionWriter<'_> {
    /// One section of `kind`, `version` and `axis`, its body written by `put`.
    fn push(&mut self, kind: SectionKind, version: u16, axis: u8, put: impl FnOnce(&mut Put)) {
        let start = self.at;
        let mut w = Put::new(self.out.get_mut(start..).unwrap_or(&mut []));
        put(&mut w);
        self.at += w.pos;
        if let Some(d) = self.dir.get_mut(self.k) {
            *d = (kind as u16, version, axis, start, self.at - start);
        }
        self.k += 1;
    }
}

/// The rotary-model section's body in `version` (1: AC trunnion without squareness; 3: with the
/// wobble).
fn put_rotary(w: &mut Put, r: &RotaryLocationSpec, version: u16) {
    if version != 1 {
        w.u8(r.machine.code());
        w.u8(0);
        w.u16(r.not_identified);
    }
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
    if version == ROTARY_SECTION_WOBBLE_VERSION {
        for v in r.wobble.coefficients() {
            w.f32(v);
        }
    }
}

/// The geometric-model section's body.
fn put_geometric(w: &mut Put, g: &GeometricSpec) {
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
}

/// The group header, the directory of the `n` sections `dir` (with each section's CRC) and the
/// whole-image CRC, into the `len` bytes of `out` whose sections are written.
fn put_header_and_directory(out: &mut [u8], len: usize, n: usize, dir: &[DirEntry]) {
    let mut w = Put::new(out);
    w.bytes(&MAGIC);
    w.u16(GROUP_SCHEMA_VERSION);
    w.u16(GROUP_HEADER_LEN as u16);
    w.u32(len as u32);
    w.u16(n as u16);
    w.u16(0);
    w.u32(0);
    w.u32(0);
    for &(kind, version, axis, off, slen) in dir {
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
}
