//! Where an image came from, and the names of its sensors, in fixed-size fields the core
//! validates (framing, lengths, reserved bytes, UTF-8) but never acts on: the provenance block
//! (the group image's provenance section, kind 6, and the `PROV` block of a schema-1 image's
//! header extension) and the schema-1 `SNAM` block (one 16-byte name per sensor, as the group
//! image's sensor-names section).
//!
//! # Glossary
//! - **provenance block**: the tool and its version, the image's build date (UTC) and one
//!   **record** per model file the image was built from: its axis, its **role** (positioning
//!   table, thermal model, …), the SHA-256 of the model file and the SHA-256 of the measurement
//!   file it was fitted on (all zero when the model file did not record one). The filters
//!   (`--where/--rename/--scale/--holdout`) are in the model file, which the model hash names.
//! - **header extension** (schema 1 only): the bytes between the 48-byte header and the first
//!   section (`header length` > 48). Readers before this module ignore them (they were always
//!   allowed and CRC-covered), so an image with an extension loads on every firmware build. Here
//!   the extension is a chain of **blocks**: `tag` `[u8; 4]`, `body length` u32 (a multiple of 4),
//!   the body. Known tags: `PROV`, `SNAM`; unknown tags are skipped; the chain must fill the
//!   extension exactly.
//!
//! # Provenance block (version 1, little endian)
//! | off | type | field |
//! |---|---|---|
//! | 0 | u16 | block version (1) |
//! | 2 | u16 | number of records n (0..=[`MAX_RECORDS`]) |
//! | 4 | `[u8; 24]` | tool and version, UTF-8, zero padded, non-empty (e.g. `axcomp 0.1.0`) |
//! | 28 | `[u8; 20]` | build date, `YYYY-MM-DDTHH:MM:SSZ` |
//! | 48 | 72 × n | records: `axis` u8 (axis code; 0xFF = the image's only axis, or none), `role` u8 ([`role`], ≠ 0), reserved u16 = 0, `model_sha256` `[u8; 32]`, `data_sha256` `[u8; 32]` (zero = not recorded), reserved u32 = 0 |

//!
//! The blocks' format and view live in a module below the image parsers; this module adds the
//! image edits that insert them (which re-check the result with those parsers).

pub use crate::provenance_block::{
    ANY_AXIS, BLOCK_HEADER_LEN, DATE_LEN, MAX_RECORDS, PROVENANCE_HEADER_LEN, PROVENANCE_TAG,
    PROVENANCE_VERSION, ProvenanceRecord, ProvenanceView, RECORD_LEN, SENSOR_NAMES_TAG, TOOL_LEN,
    extension_len, find_block, header_extension, provenance_len, role, write_provenance,
};

use crate::error::ImageError;
use crate::format::{CRC_LEN, HEADER_LEN, MAGIC, SCHEMA_VERSION, crc32};
use crate::le::{Put, rd, u16_at, u32_at};

/// Copy the schema-1 `image` (validated, without an extension) into `out` with a header extension
/// holding `blocks`, moving its sections and re-computing its CRC; returns the new length. The
/// result must pass [`crate::inspect_image`]; on `Err` the written bytes are zeroed.
pub fn with_header_extension(
    image: &[u8],
    blocks: &[([u8; 4], &[u8])],
    out: &mut [u8],
) -> Result<usize, ImageError> {
    let info = crate::inspect_image(image)?;
    if rd::<4>(image, 0) != MAGIC
        || u16_at(image, 4) != SCHEMA_VERSION
        || u16_at(image, 6) as usize != HEADER_LEN
    {
        return Err(ImageError::BadLength);
    }
    let ext = extension_len(blocks);
    let len = info.len + ext;
    if len > crate::MAX_IMAGE_LEN || HEADER_LEN + ext > u16::MAX as usize {
        return Err(ImageError::BadLength);
    }
    let Some(out) = out.get_mut(..len) else {
        return Err(ImageError::BufferTooSmall { needed: len as u32 });
    };
    out.fill(0);
    let body = info.len - CRC_LEN;
    out[..HEADER_LEN].copy_from_slice(&image[..HEADER_LEN]);
    out[HEADER_LEN + ext..len - CRC_LEN].copy_from_slice(&image[HEADER_LEN..body]);
    {
        let mut w = Put::new(&mut out[HEADER_LEN..HEADER_LEN + ext]);
        for (tag, b) in blocks {
            let padded = b.len().div_ceil(4) * 4;
            w.bytes(tag);
            w.u32(padded as u32);
            w.bytes(b);
            w.pos += padded - b.len();
        }
    }
    let mut w = Put::new(out);
    w.pos = 6;
    w.u16((HEADER_LEN + ext) as u16);
    w.u32(len as u32);
    // Section offsets (table, thermo, limits) move by the extension; absent ones stay (0, 0).
    for at in [20usize, 28, 36] {
        let off = u32_at(w.buf, at);
        if off != 0 {
            w.pos = at;
            w.u32(off + ext as u32);
        }
    }
    let crc = crc32(w.buf.get(..len - CRC_LEN).unwrap_or(&[]));
    w.pos = len - CRC_LEN;
    w.u32(crc);
    match crate::inspect_image(out).and_then(|_| crate::group_image::parse(out)) {
        Ok(_) => Ok(len),
        Err(e) => {
            out.fill(0);
            Err(e)
        }
    }
}

// ---- group image: one more section ----

/// Copy the group image `image` (schema 2, valid) into `out` with one more section appended
/// (after the last one, before the trailer): `kind`, version 1, `axis`, `flags`, `payload`. Every
/// existing section keeps its bytes and CRC (their offsets move by one directory entry); the
/// header and the whole-image CRC are re-computed. Returns the new length; the result must pass
/// [`crate::group_image::parse`]; on `Err` the written bytes are zeroed.
pub fn with_group_section(
    image: &[u8],
    kind: u16,
    axis: u8,
    flags: u8,
    payload: &[u8],
    out: &mut [u8],
) -> Result<usize, ImageError> {
    use crate::group_image::{DIR_ENTRY_LEN, GROUP_HEADER_LEN, GROUP_SCHEMA_VERSION, MAX_SECTIONS};
    crate::group_image::parse(image)?;
    if u16_at(image, 4) != GROUP_SCHEMA_VERSION {
        return Err(ImageError::UnsupportedVersion {
            found: u16_at(image, 4),
        });
    }
    let n = u16_at(image, 12) as usize;
    if n + 1 > MAX_SECTIONS {
        return Err(ImageError::BadLength);
    }
    let old_len = image.len();
    let len = old_len + DIR_ENTRY_LEN + payload.len();
    if len > crate::MAX_IMAGE_LEN {
        return Err(ImageError::BadLength);
    }
    let Some(out) = out.get_mut(..len) else {
        return Err(ImageError::BufferTooSmall { needed: len as u32 });
    };
    out.fill(0);
    let dir_end = GROUP_HEADER_LEN + DIR_ENTRY_LEN * n;
    let body = old_len - CRC_LEN;
    out[..dir_end].copy_from_slice(&image[..dir_end]);
    out[dir_end + DIR_ENTRY_LEN..body + DIR_ENTRY_LEN].copy_from_slice(&image[dir_end..body]);
    let new_off = body + DIR_ENTRY_LEN;
    out[new_off..new_off + payload.len()].copy_from_slice(payload);
    let mut w = Put::new(out);
    w.pos = 8;
    w.u32(len as u32);
    w.u16((n + 1) as u16);
    for i in 0..n {
        let at = GROUP_HEADER_LEN + DIR_ENTRY_LEN * i + 8;
        let off = u32_at(w.buf, at);
        w.pos = at;
        w.u32(off + DIR_ENTRY_LEN as u32);
    }
    w.pos = dir_end;
    w.u16(kind);
    w.u16(1);
    w.u8(axis);
    w.u8(flags);
    w.u16(0);
    w.u32(new_off as u32);
    w.u32(payload.len() as u32);
    w.u32(crc32(payload));
    let crc = crc32(w.buf.get(..len - CRC_LEN).unwrap_or(&[]));
    w.pos = len - CRC_LEN;
    w.u32(crc);
    match crate::group_image::parse(out) {
        Ok(_) => Ok(len),
        Err(e) => {
            out.fill(0);
            Err(e)
        }
    }
}
