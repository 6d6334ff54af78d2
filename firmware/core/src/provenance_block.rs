//! The provenance and sensor-names blocks as bytes: their constants, the view that validates them,
//! the writer and the header extension's block chain. Below the image parsers, which read them; the
//! public face, with the glossary and the layout, is [`crate::provenance`].

use crate::axis::AxisName;
use crate::error::ImageError;
use crate::format::HEADER_LEN;
use crate::le::{Put, rd, u8_at, u16_at, u32_at};

/// Version of the provenance block.
pub const PROVENANCE_VERSION: u16 = 1;
/// Fixed part of the provenance block.
pub const PROVENANCE_HEADER_LEN: usize = 48;
/// Bytes per record.
pub const RECORD_LEN: usize = 72;
/// Most records in one block.
pub const MAX_RECORDS: usize = 32;
/// Bytes of the tool field.
pub const TOOL_LEN: usize = 24;
/// Bytes of the build-date field.
pub const DATE_LEN: usize = 20;
/// Tag of the provenance block in a schema-1 header extension.
pub const PROVENANCE_TAG: [u8; 4] = *b"PROV";
/// Tag of the sensor-names block in a schema-1 header extension.
pub const SENSOR_NAMES_TAG: [u8; 4] = *b"SNAM";
/// Block header (tag, body length) in a header extension.
pub const BLOCK_HEADER_LEN: usize = 8;
/// Record axis value for "the image's only axis" (schema 1) or "no axis".
pub const ANY_AXIS: u8 = 0xFF;

/// Roles of a record (what the hashed model file is).
pub mod role {
    /// Positioning table (`fit positioning --out`).
    pub const POSITIONING_TABLE: u8 = 1;
    /// Thermo-force model (`fit thermal --out`, or a warm-up drift `fit positioning --drift-model`).
    pub const THERMAL_MODEL: u8 = 2;
    /// Rotary location-error model (`fit rtest --out`).
    pub const ROTARY_MODEL: u8 = 3;
    /// Geometric model (`fit geometry --out`).
    pub const GEOMETRY_MODEL: u8 = 4;
    /// Probe calibration (`fit probe --out`).
    pub const PROBE_CALIBRATION: u8 = 5;
    /// Any other input file.
    pub const OTHER: u8 = 255;

    /// A short name for inspection output.
    pub const fn name(r: u8) -> &'static str {
        match r {
            POSITIONING_TABLE => "positioning table",
            THERMAL_MODEL => "thermal model",
            ROTARY_MODEL => "rotary model",
            GEOMETRY_MODEL => "geometry model",
            PROBE_CALIBRATION => "probe calibration",
            _ => "other",
        }
    }
}

/// One record of a provenance block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProvenanceRecord {
    /// Axis code ([`AxisName::code`]) or [`ANY_AXIS`].
    pub axis: u8,
    /// What the model file is ([`role`]).
    pub role: u8,
    /// SHA-256 of the model file's bytes.
    pub model_sha256: [u8; 32],
    /// SHA-256 of the measurement file the model was fitted on (zero = not recorded).
    pub data_sha256: [u8; 32],
}

/// A validated provenance block (borrowing its bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProvenanceView<'a> {
    bytes: &'a [u8],
}

fn text_field(raw: &[u8]) -> Option<&str> {
    let end = raw.iter().position(|&b| b == 0).unwrap_or(raw.len());
    let (text, pad) = raw.split_at(end);
    if end == 0 || pad.iter().any(|&b| b != 0) {
        return None;
    }
    core::str::from_utf8(text).ok()
}

fn date_ok(d: &[u8]) -> bool {
    d.len() == DATE_LEN
        && d.iter().enumerate().all(|(i, &c)| match i {
            4 | 7 => c == b'-',
            10 => c == b'T',
            13 | 16 => c == b':',
            19 => c == b'Z',
            _ => c.is_ascii_digit(),
        })
}

impl<'a> ProvenanceView<'a> {
    /// Validate a provenance block: version, exact length, text fields, records.
    pub fn parse(b: &'a [u8]) -> Result<ProvenanceView<'a>, ImageError> {
        let bad = Err(ImageError::Provenance);
        if b.len() < PROVENANCE_HEADER_LEN || u16_at(b, 0) != PROVENANCE_VERSION {
            return bad;
        }
        let n = u16_at(b, 2) as usize;
        if n > MAX_RECORDS || b.len() != PROVENANCE_HEADER_LEN + RECORD_LEN * n {
            return bad;
        }
        if text_field(b.get(4..4 + TOOL_LEN).unwrap_or(&[])).is_none()
            || !date_ok(b.get(28..28 + DATE_LEN).unwrap_or(&[]))
        {
            return bad;
        }
        for i in 0..n {
            let at = PROVENANCE_HEADER_LEN + RECORD_LEN * i;
            let axis = u8_at(b, at);
            if (axis != ANY_AXIS && AxisName::from_code(axis).is_none())
                || u8_at(b, at + 1) == 0
                || u16_at(b, at + 2) != 0
                || u32_at(b, at + 68) != 0
            {
                return bad;
            }
        }
        Ok(ProvenanceView { bytes: b })
    }
    /// The tool and its version.
    pub fn tool(&self) -> &'a str {
        text_field(self.bytes.get(4..4 + TOOL_LEN).unwrap_or(&[])).unwrap_or("")
    }
    /// The build date, `YYYY-MM-DDTHH:MM:SSZ`.
    pub fn built_utc(&self) -> &'a str {
        core::str::from_utf8(self.bytes.get(28..28 + DATE_LEN).unwrap_or(&[])).unwrap_or("")
    }
    /// Number of records.
    pub fn len(&self) -> usize {
        u16_at(self.bytes, 2) as usize
    }
    /// True without records.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Record `i`.
    pub fn record(&self, i: usize) -> Option<ProvenanceRecord> {
        if i >= self.len() {
            return None;
        }
        let at = PROVENANCE_HEADER_LEN + RECORD_LEN * i;
        Some(ProvenanceRecord {
            axis: u8_at(self.bytes, at),
            role: u8_at(self.bytes, at + 1),
            model_sha256: rd::<32>(self.bytes, at + 4),
            data_sha256: rd::<32>(self.bytes, at + 36),
        })
    }
    /// Every record.
    pub fn records(&self) -> impl Iterator<Item = ProvenanceRecord> + '_ {
        (0..self.len()).filter_map(|i| self.record(i))
    }
    /// The block's bytes.
    pub fn bytes(&self) -> &'a [u8] {
        self.bytes
    }
}

/// Length of a provenance block with `n` records.
pub const fn provenance_len(n: usize) -> usize {
    PROVENANCE_HEADER_LEN + RECORD_LEN * n
}

/// Write a provenance block into `out`; returns its length. `tool`: 1..=24 bytes of UTF-8 without
/// NUL; `built_utc`: `YYYY-MM-DDTHH:MM:SSZ`.
pub fn write_provenance(
    tool: &str,
    built_utc: &str,
    records: &[ProvenanceRecord],
    out: &mut [u8],
) -> Result<usize, ImageError> {
    if tool.is_empty()
        || tool.len() > TOOL_LEN
        || tool.contains('\0')
        || !date_ok(built_utc.as_bytes())
        || records.len() > MAX_RECORDS
    {
        return Err(ImageError::Provenance);
    }
    let len = provenance_len(records.len());
    let Some(out) = out.get_mut(..len) else {
        return Err(ImageError::BufferTooSmall { needed: len as u32 });
    };
    out.fill(0);
    let mut w = Put::new(out);
    w.u16(PROVENANCE_VERSION);
    w.u16(records.len() as u16);
    let mut tool_field = [0u8; TOOL_LEN];
    tool_field[..tool.len()].copy_from_slice(tool.as_bytes());
    w.bytes(&tool_field);
    w.bytes(built_utc.as_bytes());
    for r in records {
        w.u8(r.axis);
        w.u8(r.role);
        w.u16(0);
        w.bytes(&r.model_sha256);
        w.bytes(&r.data_sha256);
        w.u32(0);
    }
    match ProvenanceView::parse(out) {
        Ok(_) => Ok(len),
        Err(e) => {
            out.fill(0);
            Err(e)
        }
    }
}

// ---- schema-1 header extension ----

/// The header extension of a schema-1 image (bytes 48..header length; empty without one). The
/// image must have been validated ([`crate::inspect_image`]).
pub fn header_extension(image: &[u8]) -> &[u8] {
    let header_len = u16_at(image, 6) as usize;
    image.get(HEADER_LEN..header_len).unwrap_or(&[])
}

/// The body of the block tagged `tag` in a header extension (`None` when absent); the whole chain's
/// framing is checked ([`ImageError::Provenance`] when it does not fill the extension exactly).
pub fn find_block(extension: &[u8], tag: [u8; 4]) -> Result<Option<&[u8]>, ImageError> {
    let mut at = 0;
    let mut found = None;
    while at < extension.len() {
        let len = u32_at(extension, at + 4) as usize;
        let start = at + BLOCK_HEADER_LEN;
        let end = start.checked_add(len).ok_or(ImageError::Provenance)?;
        if len % 4 != 0 || end > extension.len() {
            return Err(ImageError::Provenance);
        }
        if rd::<4>(extension, at) == tag && found.is_none() {
            found = extension.get(start..end);
        }
        at = end;
    }
    Ok(found)
}

/// Length of a header extension holding `bodies` (each padded to a multiple of 4).
pub fn extension_len(bodies: &[([u8; 4], &[u8])]) -> usize {
    bodies
        .iter()
        .map(|(_, b)| BLOCK_HEADER_LEN + b.len().div_ceil(4) * 4)
        .sum()
}
