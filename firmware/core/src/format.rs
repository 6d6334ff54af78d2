//! The image byte format's constants: magic, schema versions, section and record lengths, flag
//! bits, the ranges the loader accepts, and the CRC-32 that closes every image. A leaf: the writers,
//! the parsers and the loader all read these ([`crate::image`] and [`crate::group_image`]
//! re-export them under their old names).

// ---- single-axis images (schema 1) ----

/// Image magic.
pub const MAGIC: [u8; 4] = *b"AXCI";
/// Schema version written and accepted by this build.
pub const SCHEMA_VERSION: u16 = 1;
/// Header length written by this build.
pub const HEADER_LEN: usize = 48;
/// Table section length without coefficients.
pub const TABLE_HEADER_LEN: usize = 24;
/// Thermo section length without sensors and forces.
pub const THERMO_HEADER_LEN: usize = 32;
/// Bytes per sensor in the thermo section.
pub const SENSOR_LEN: usize = 28;
/// Bytes per force term in the thermo section.
pub const FORCE_LEN: usize = 24;
/// Bytes per sensor of the rise bounds (thermo flag [`THERMO_RISE_GUARD`]).
pub const RISE_BOUNDS_LEN: usize = 8;
/// Thermo flag: ΔT against each sensor's first accepted reading ([`ThermoReference::SwitchOn`]).
pub const THERMO_REFERENCE_AT_SWITCH_ON: u32 = 1 << 0;
/// Thermo flag: per-sensor rise bounds follow the force records (the range guard).
pub const THERMO_RISE_GUARD: u32 = 1 << 1;
pub(crate) const THERMO_KNOWN_FLAGS: u32 = THERMO_REFERENCE_AT_SWITCH_ON | THERMO_RISE_GUARD;
/// Largest |rise bound|, K (the span of the plausible temperatures).
pub(crate) const MAX_RISE_K: f32 = MAX_DEGC - MIN_DEGC;
/// Limits section length.
pub const LIMITS_LEN: usize = 16;
/// CRC length.
pub const CRC_LEN: usize = 4;

/// Largest |table value| a segment may reach, µm.
pub const MAX_TABLE_UM: f32 = 10_000.0;
/// Largest |b0| of a thermo-force model, µm (the intercept is a deviation, not a position).
pub const MAX_B0_UM: f32 = 1.0e5;
pub(crate) const MAX_ABS_POSITION: i64 = 1 << 62;
pub(crate) const MIN_DEGC: f32 = -273.15;
pub(crate) const MAX_DEGC: f32 = 2000.0;

// ---- CRC-32 (IEEE), nibble table: 64 bytes of table, two steps per byte ----

const fn crc_nibble_table() -> [u32; 16] {
    let mut t = [0u32; 16];
    let mut i = 0;
    while i < 16 {
        let mut c = i as u32;
        let mut k = 0;
        while k < 4 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
            k += 1;
        }
        t[i] = c;
        i += 1;
    }
    t
}
const CRC_TABLE: [u32; 16] = crc_nibble_table();

/// CRC-32 (IEEE 802.3, as zlib/PNG): `crc32(b"123456789") == 0xCBF4_3926`.
///
/// Out of line: the loaders call it at several places and it is not on the per-cycle path (inlined,
/// each copy costs the firmware's code flash about 300 bytes).
#[inline(never)]
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in bytes {
        c ^= b as u32;
        c = (c >> 4) ^ CRC_TABLE[(c & 15) as usize];
        c = (c >> 4) ^ CRC_TABLE[(c & 15) as usize];
    }
    !c
}

// ---- group images (schema 2) ----

/// Schema version of group images.
pub const GROUP_SCHEMA_VERSION: u16 = 2;
/// Header length.
pub const GROUP_HEADER_LEN: usize = 24;
/// Directory entry length.
pub const DIR_ENTRY_LEN: usize = 20;
/// Most sections in one image.
pub const MAX_SECTIONS: usize = 16;
/// Fixed part of an axis section (before the embedded schema-1 image).
pub const AXIS_SECTION_HEADER_LEN: usize = 32;
/// Length of a rotary-model section of version 1 (AC trunnion, no squareness).
pub const ROTARY_SECTION_V1_LEN: usize = 64;
/// Version of the rotary-model section with a machine kind and squareness.
pub const ROTARY_SECTION_VERSION: u16 = 2;
/// Length of a rotary-model section of version [`ROTARY_SECTION_VERSION`].
pub const ROTARY_SECTION_LEN: usize = 80;
/// Version of the rotary-model section with a wobble after the version-2 fields.
pub const ROTARY_SECTION_WOBBLE_VERSION: u16 = 3;
/// Length of a rotary-model section of version [`ROTARY_SECTION_WOBBLE_VERSION`]: version 2's
/// 80 bytes and 44 wobble coefficients (f32).
pub const ROTARY_SECTION_WOBBLE_LEN: usize = 256;
/// Fixed part of a geometric-model section (before the coefficients).
pub const GEOMETRIC_HEADER_LEN: usize = 96;
/// Bytes per segment of one axis in a geometric-model section (6 functions × 4 f32).
pub const GEOMETRIC_SEGMENT_LEN: usize = 96;
/// Bytes per sensor name.
pub const SENSOR_NAME_LEN: usize = 16;
/// Directory `axis` value of a section that belongs to no axis.
pub const NO_AXIS: u8 = 0xFF;
/// Directory flag: the section must be understood.
pub const FLAG_MANDATORY: u8 = 1;
