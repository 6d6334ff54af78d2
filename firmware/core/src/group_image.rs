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
//!   | 4 | u32 | identified mask: bit i = component i (EXX … ECZ, EC0Y, EB0Z, EA0Z) was identified by the fit; the others are stored as the model gives them (a not-separable component at its minimum-norm share, one without data as zero; applied alike) |
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
//!   images). Version 3 (256 bytes): version 2's 80 bytes, then the wobble
//!   ([`crate::rotary::RotaryWobble`]): C's 4 harmonics × 8 coefficients, then the tilt axis's 3
//!   powers × 4 coefficients (f32, in the order of its fields); written only for a model with a
//!   wobble (a reader without the wobble refuses the mandatory section rather than leave it out).
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
    ROTARY_SECTION_LEN, ROTARY_SECTION_V1_LEN, ROTARY_SECTION_VERSION, ROTARY_SECTION_WOBBLE_LEN,
    ROTARY_SECTION_WOBBLE_VERSION, SENSOR_NAME_LEN,
};

pub use crate::group_image_parse::{
    AxisSection, BoardCaps, GroupImageView, SectionKind, geometric_section_len, parse,
};
pub use crate::group_image_write::{
    AxisSectionSpec, group_image_len, group_image_len_with, group_image_len_with_probe,
    group_image_len_with_stages, write_group_image, write_group_image_with,
    write_group_image_with_probe, write_group_image_with_stages,
};
