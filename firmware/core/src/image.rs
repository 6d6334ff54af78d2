//! The table image: versioned binary format, little endian, CRC-32 protected.
//!
//! # Layout (schema version 1)
//! All integers and `f32` little endian; offsets are from the start of the image.
//!
//! Header (48 bytes):
//! | off | type | field |
//! |---|---|---|
//! | 0 | `[u8; 4]` | magic `AXCI` |
//! | 4 | u16 | schema version (1) |
//! | 6 | u16 | header length (≥ 48, multiple of 4; extra bytes are ignored but CRC-covered) |
//! | 8 | u32 | total length, CRC included |
//! | 12 | u16 | axis id |
//! | 14 | u8 | counter bits (16..=32) |
//! | 15 | u8 | reserved, 0 |
//! | 16 | f32 | µm per count |
//! | 20, 24 | u32, u32 | table section offset, length (0, 0 = no table) |
//! | 28, 32 | u32, u32 | thermo section offset, length (0, 0 = no thermo-force term) |
//! | 36, 40 | u32, u32 | limits section offset, length (required) |
//! | 44 | u32 | reserved, 0 |
//!
//! Sections follow the header in the order table, thermo, limits, without overlap; the CRC-32
//! (IEEE 802.3, reflected, init and xor-out `0xFFFF_FFFF`) over all bytes before it is the last
//! 4 bytes of the image.
//!
//! Table section (24 + 16·n·(1 + bidirectional) bytes): `start_counts` i64, `segment_counts` u32,
//! `n_segments` u16, `bidirectional` u8 (0/1), `outside` u8 (0 hold, 1 taper), `taper_length_counts`
//! u32 (0 for hold), reserved u32 = 0, then n forward `[c0, c1, c2, c3]` f32, then (bidirectional)
//! n backward ones.
//!
//! Thermo section (32 + 28·n_sensors + 24·n_forces bytes, + 8·n_sensors with RISE_GUARD):
//! `sensor_period_ms` u32, `n_sensors` u8, `n_forces` u8, `has_expansion` u8 (0/1),
//! `expansion_sensor` u8, `b0_um` f32, `c_um_per_mm_k` f32, `x_ref_counts` i64, `thermo_flags` u32,
//! reserved u32 = 0; per sensor `reference_degc`, `min_degc`, `max_degc`, `max_rate_degc_per_s`,
//! `lag_tau_s` (f32), `stale_timeout_ms` u32, `b_um_per_k` f32; per force `chi_um_per_n` f32,
//! `has_law` u32 (0/1), `k`, `x_ap`, `y_fz`, `z_n` f32; with RISE_GUARD, per sensor `rise_min_k`,
//! `rise_max_k` f32.
//!
//! `thermo_flags` (other bits 0; an image with flags 0 is read exactly as before the flags existed):
//! - bit 0 REFERENCE_AT_SWITCH_ON ([`crate::ThermoReference::SwitchOn`]): each sensor's ΔT is taken
//!   against its first accepted reading after the image was loaded or the state reset, so its lag
//!   starts at 0 (a model fitted on runs that each start at switch-on); `reference_degc` is then
//!   only the nominal temperature the model was fitted around and is not used.
//! - bit 1 RISE_GUARD: while a sensor's unlagged rise (last accepted reading − its reference) is
//!   outside `[rise_min_k, rise_max_k]`, its term b_i·ΔT_i is left out of Σ b_i·ΔT_i (flag
//!   [`crate::Flags::THERMAL_GUARDED`]); the sensor stays healthy and the other terms stay.
//!
//! Limits section (16 bytes): `max_correction_um` f32, `max_slew_um_per_cycle` f32,
//! `direction_hysteresis_counts` u32, reserved u32 = 0.
//!
//! # Validation ranges
//! Every `f32` must be finite. µm per count in [1e-6, 1e4]; |start_counts| ≤ 2^62; the stroke
//! (n·segment_counts) ≤ u32::MAX counts; per segment Σ|c_k| ≤ 10 000 µm (so |value| ≤ 10 mm);
//! temperatures in [−273.15, 2000] °C with min < max; max rate in (0, 1e6] K/s; τ in [0, 1e7] s;
//! stale timeout ≥ 1 ms; sensor period ≥ 1 ms; rise bounds in [−2273.15, 2273.15] K with lo < hi; |b_i| ≤ 1e4 µm/K; |b0| ≤ 1e5 µm; |c| ≤ 1e3 µm/(mm·K);
//! |x_ref| ≤ 2^62; |χ| ≤ 1e3 µm/N; |k| ≤ 1e9, |exponents| ≤ 10; max correction and max slew in
//! (0, 1e5] µm; direction hysteresis ≤ 2^31 − 1 counts.

pub use crate::format::{
    CRC_LEN, FORCE_LEN, HEADER_LEN, LIMITS_LEN, MAGIC, MAX_B0_UM, MAX_TABLE_UM, RISE_BOUNDS_LEN,
    SCHEMA_VERSION, SENSOR_LEN, TABLE_HEADER_LEN, THERMO_HEADER_LEN, THERMO_REFERENCE_AT_SWITCH_ON,
    THERMO_RISE_GUARD, crc32,
};

use crate::counts::CounterShift;
use crate::error::{Field, ImageError};
use crate::format::{MAX_ABS_POSITION, MAX_DEGC, MAX_RISE_K, MIN_DEGC, THERMO_KNOWN_FLAGS};
use crate::limits::MAX_LIMIT_UM;
use crate::runtime::{AxisCompensator, Compensator, TableStore};
use crate::sensor::SensorRt;
use crate::spec::{ForceLaw, ImageSpec, OutsideStroke, ThermoReference};
use crate::{MAX_FORCES, MAX_IMAGE_LEN, MAX_SEGMENTS, MAX_SENSORS};

use crate::le::{Put, f32_at, i64_at, rd, u8_at, u16_at, u32_at};

/// Section offsets and counts of a validated image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Layout {
    pub(crate) len: usize,
    pub(crate) table: Option<usize>,
    pub(crate) n_segments: usize,
    pub(crate) bidirectional: bool,
    pub(crate) thermo: Option<usize>,
    pub(crate) n_sensors: usize,
    pub(crate) n_forces: usize,
    /// The thermo section's `thermo_flags` (0 without one).
    pub(crate) thermo_flags: u32,
    pub(crate) limits: usize,
}

/// Summary of a valid image (see [`inspect_image`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageInfo {
    /// Total length in bytes (CRC included).
    pub len: usize,
    /// Schema version.
    pub version: u16,
    /// Axis id.
    pub axis_id: u16,
    /// Counter width.
    pub counter_bits: u8,
    /// Segments per direction (0 without a table).
    pub n_segments: usize,
    /// True if the table has a backward direction.
    pub bidirectional: bool,
    /// True if the image has a thermo-force term.
    pub has_thermo: bool,
    /// Number of sensors.
    pub n_sensors: usize,
    /// Number of force terms.
    pub n_forces: usize,
    /// The stored CRC-32.
    pub crc: u32,
}

/// The length an image (schema 1 or 2) declares in its header (bytes 8..12: the total length,
/// trailing CRC included), for cutting an image out of a flash slot (the image, then erased
/// flash) before loading it. Reads the header only (magic, schema version, length): the CRC and
/// the content are checked by the loader. Errors: fewer than 12 bytes or fewer than declared
/// ([`ImageError::TooShort`]), [`ImageError::BadMagic`], [`ImageError::UnsupportedVersion`], a
/// declared length below a header and a CRC or above [`MAX_IMAGE_LEN`]
/// ([`ImageError::BadLength`]).
pub fn declared_image_len(b: &[u8]) -> Result<usize, ImageError> {
    if b.len() < 12 {
        return Err(ImageError::TooShort);
    }
    if rd::<4>(b, 0) != MAGIC {
        return Err(ImageError::BadMagic);
    }
    let version = u16_at(b, 4);
    if version != SCHEMA_VERSION && version != crate::format::GROUP_SCHEMA_VERSION {
        return Err(ImageError::UnsupportedVersion { found: version });
    }
    let total = u32_at(b, 8) as usize;
    if !(12 + CRC_LEN..=MAX_IMAGE_LEN).contains(&total) {
        return Err(ImageError::BadLength);
    }
    if b.len() < total {
        return Err(ImageError::TooShort);
    }
    Ok(total)
}

/// Validate `image` fully (structure, CRC, every value) and summarise it. Like
/// [`crate::Compensator::load`], it refuses bytes after the declared length
/// ([`ImageError::TrailingBytes`]).
pub fn inspect_image(image: &[u8]) -> Result<ImageInfo, ImageError> {
    let l = validate(image)?;
    if image.len() > l.len {
        return Err(ImageError::TrailingBytes);
    }
    Ok(ImageInfo {
        len: l.len,
        version: u16_at(image, 4),
        axis_id: u16_at(image, 12),
        counter_bits: u8_at(image, 14),
        n_segments: l.n_segments,
        bidirectional: l.bidirectional,
        has_thermo: l.thermo.is_some(),
        n_sensors: l.n_sensors,
        n_forces: l.n_forces,
        crc: u32_at(image, l.len - CRC_LEN),
    })
}

fn finite(v: f32, field: Field, index: usize) -> Result<f32, ImageError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ImageError::NonFinite {
            field,
            index: index as u16,
        })
    }
}

/// Finite and in `[lo, hi]`.
fn ranged(v: f32, lo: f32, hi: f32, field: Field, index: usize) -> Result<f32, ImageError> {
    finite(v, field, index)?;
    if v >= lo && v <= hi {
        Ok(v)
    } else {
        Err(ImageError::OutOfRange {
            field,
            index: index as u16,
        })
    }
}

/// Finite and in `(0, hi]`.
fn positive(v: f32, hi: f32, field: Field, index: usize) -> Result<f32, ImageError> {
    finite(v, field, index)?;
    if v > 0.0 && v <= hi {
        Ok(v)
    } else {
        Err(ImageError::OutOfRange {
            field,
            index: index as u16,
        })
    }
}

fn check(ok: bool, field: Field, index: usize) -> Result<(), ImageError> {
    if ok {
        Ok(())
    } else {
        Err(ImageError::OutOfRange {
            field,
            index: index as u16,
        })
    }
}

/// Section `(offset, len)` from the header; `(0, 0)` = absent.
fn section(b: &[u8], at: usize) -> (usize, usize) {
    (u32_at(b, at) as usize, u32_at(b, at + 4) as usize)
}

/// Length of a thermo section with `ns` sensors, `nf` forces and (if `guard`) rise bounds.
fn thermo_section_len(ns: usize, nf: usize, guard: bool) -> usize {
    THERMO_HEADER_LEN
        + SENSOR_LEN.saturating_mul(ns)
        + FORCE_LEN.saturating_mul(nf)
        + if guard {
            RISE_BOUNDS_LEN.saturating_mul(ns)
        } else {
            0
        }
}

/// Offset of sensor `i`'s rise bounds in a thermo section at `o` (None without RISE_GUARD).
fn rise_bounds_at(l: &Layout, o: usize, i: usize) -> Option<usize> {
    (l.thermo_flags & THERMO_RISE_GUARD != 0).then_some(
        o + THERMO_HEADER_LEN
            + SENSOR_LEN * l.n_sensors
            + FORCE_LEN * l.n_forces
            + RISE_BOUNDS_LEN * i,
    )
}

/// Validate everything; nothing is copied.
pub(crate) fn validate(b: &[u8]) -> Result<Layout, ImageError> {
    // ---- structure ----
    if b.len() < HEADER_LEN {
        return Err(ImageError::TooShort);
    }
    if rd::<4>(b, 0) != MAGIC {
        return Err(ImageError::BadMagic);
    }
    let version = u16_at(b, 4);
    if version != SCHEMA_VERSION {
        return Err(ImageError::UnsupportedVersion { found: version });
    }
    let header_len = u16_at(b, 6) as usize;
    let total = u32_at(b, 8) as usize;
    if header_len < HEADER_LEN || header_len % 4 != 0 || total > MAX_IMAGE_LEN {
        return Err(ImageError::BadLength);
    }
    if total < header_len + LIMITS_LEN + CRC_LEN {
        return Err(ImageError::BadLength);
    }
    if b.len() < total {
        return Err(ImageError::TooShort);
    }
    let body_end = total - CRC_LEN;
    if crc32(b.get(..body_end).unwrap_or(&[])) != u32_at(b, body_end) {
        return Err(ImageError::BadCrc);
    }

    // ---- sections: in order, in bounds, lengths consistent with their counts ----
    let mut cursor = header_len;
    let (t_off, t_len) = section(b, 20);
    let (h_off, h_len) = section(b, 28);
    let (l_off, l_len) = section(b, 36);
    let mut layout = Layout {
        len: total,
        table: None,
        n_segments: 0,
        bidirectional: false,
        thermo: None,
        n_sensors: 0,
        n_forces: 0,
        thermo_flags: 0,
        limits: 0,
    };
    if (t_off, t_len) != (0, 0) {
        if t_off < cursor || t_len < TABLE_HEADER_LEN || t_off + t_len > body_end {
            return Err(ImageError::BadLength);
        }
        let n = u16_at(b, t_off + 12) as usize;
        let bidir = u8_at(b, t_off + 14);
        if n == 0 || n > MAX_SEGMENTS {
            return Err(ImageError::TooManySegments);
        }
        check(bidir <= 1, Field::Reserved, 0)?;
        let dirs = 1 + bidir as usize;
        if t_len != TABLE_HEADER_LEN + 16 * n * dirs {
            return Err(ImageError::BadLength);
        }
        layout.table = Some(t_off);
        layout.n_segments = n;
        layout.bidirectional = bidir == 1;
        cursor = t_off + t_len;
    }
    if (h_off, h_len) != (0, 0) {
        if h_off < cursor || h_len < THERMO_HEADER_LEN || h_off + h_len > body_end {
            return Err(ImageError::BadLength);
        }
        let ns = u8_at(b, h_off + 4) as usize;
        let nf = u8_at(b, h_off + 5) as usize;
        if ns > MAX_SENSORS {
            return Err(ImageError::TooManySensors);
        }
        if nf > MAX_FORCES {
            return Err(ImageError::TooManyForces);
        }
        let flags = u32_at(b, h_off + 24);
        check(flags & !THERMO_KNOWN_FLAGS == 0, Field::ThermoFlags, 0)?;
        if h_len != thermo_section_len(ns, nf, flags & THERMO_RISE_GUARD != 0) {
            return Err(ImageError::BadLength);
        }
        layout.thermo = Some(h_off);
        layout.thermo_flags = flags;
        layout.n_sensors = ns;
        layout.n_forces = nf;
        cursor = h_off + h_len;
    }
    if l_off < cursor || l_len != LIMITS_LEN || l_off + l_len > body_end {
        return Err(ImageError::BadLength);
    }
    layout.limits = l_off;

    // ---- header values ----
    check(u8_at(b, 15) == 0 && u32_at(b, 44) == 0, Field::Reserved, 0)?;
    let bits = u8_at(b, 14);
    check((16..=32).contains(&bits), Field::CounterBits, 0)?;
    let upc = ranged(f32_at(b, 16), 1.0e-6, 1.0e4, Field::UmPerCount, 0)?;
    let _ = upc;

    // ---- table ----
    if let Some(o) = layout.table {
        validate_table(b, &layout, o)?;
    }

    // ---- thermo-force ----
    if let Some(o) = layout.thermo {
        validate_thermo(b, &layout, o)?;
    }

    // ---- limits ----
    let o = layout.limits;
    positive(f32_at(b, o), MAX_LIMIT_UM, Field::MaxCorrection, 0)?;
    positive(f32_at(b, o + 4), MAX_LIMIT_UM, Field::MaxSlew, 0)?;
    check(u32_at(b, o + 8) <= i32::MAX as u32, Field::Hysteresis, 0)?;
    check(u32_at(b, o + 12) == 0, Field::Reserved, 0)?;
    Ok(layout)
}

/// The values of a table section at `o` whose structure `l` has been checked: start, segment
/// length, outside rule, and each segment's coefficients finite with |c0|+|c1|+|c2|+|c3| within
/// [`MAX_TABLE_UM`].
fn validate_table(b: &[u8], l: &Layout, o: usize) -> Result<(), ImageError> {
    let start = i64_at(b, o);
    check(
        (-MAX_ABS_POSITION..=MAX_ABS_POSITION).contains(&start),
        Field::StartCounts,
        0,
    )?;
    let seg = u32_at(b, o + 8) as u64;
    check(
        seg >= 1 && seg * l.n_segments as u64 <= u32::MAX as u64,
        Field::SegmentCounts,
        0,
    )?;
    let outside = u8_at(b, o + 15);
    let taper = u32_at(b, o + 16);
    check(
        (outside == 0 && taper == 0) || (outside == 1 && taper >= 1),
        Field::Outside,
        0,
    )?;
    check(u32_at(b, o + 20) == 0, Field::Reserved, 0)?;
    let dirs = 1 + l.bidirectional as usize;
    for d in 0..dirs {
        let field = if d == 0 {
            Field::ForwardCoefficient
        } else {
            Field::BackwardCoefficient
        };
        for s in 0..l.n_segments {
            let at = o + TABLE_HEADER_LEN + 16 * (d * l.n_segments + s);
            let mut sum = 0.0f32;
            for k in 0..4 {
                sum += libm::fabsf(finite(f32_at(b, at + 4 * k), field, s)?);
            }
            check(sum <= MAX_TABLE_UM, field, s)?;
        }
    }
    Ok(())
}

/// The values of a thermo section at `o` whose structure `l` has been checked.
fn validate_thermo(b: &[u8], l: &Layout, o: usize) -> Result<(), ImageError> {
    let period = u32_at(b, o);
    check(period >= 1, Field::SensorPeriod, 0)?;
    let has_exp = u8_at(b, o + 6);
    let exp_sensor = u8_at(b, o + 7) as usize;
    ranged(f32_at(b, o + 8), -MAX_B0_UM, MAX_B0_UM, Field::B0, 0)?;
    let c = ranged(f32_at(b, o + 12), -1.0e3, 1.0e3, Field::Expansion, 0)?;
    let x_ref = i64_at(b, o + 16);
    check(u32_at(b, o + 28) == 0, Field::Reserved, 0)?;
    match has_exp {
        0 => check(
            exp_sensor == 0 && c == 0.0 && x_ref == 0,
            Field::Expansion,
            0,
        )?,
        1 => {
            check(exp_sensor < l.n_sensors, Field::ExpansionSensor, 0)?;
            check(
                (-MAX_ABS_POSITION..=MAX_ABS_POSITION).contains(&x_ref),
                Field::Expansion,
                0,
            )?;
        }
        _ => {
            return Err(ImageError::OutOfRange {
                field: Field::Expansion,
                index: 0,
            });
        }
    }
    for i in 0..l.n_sensors {
        let at = o + THERMO_HEADER_LEN + SENSOR_LEN * i;
        ranged(f32_at(b, at), MIN_DEGC, MAX_DEGC, Field::ReferenceDegc, i)?;
        let lo = ranged(f32_at(b, at + 4), MIN_DEGC, MAX_DEGC, Field::SensorRange, i)?;
        let hi = ranged(f32_at(b, at + 8), MIN_DEGC, MAX_DEGC, Field::SensorRange, i)?;
        check(lo < hi, Field::SensorRange, i)?;
        positive(f32_at(b, at + 12), 1.0e6, Field::MaxRate, i)?;
        ranged(f32_at(b, at + 16), 0.0, 1.0e7, Field::LagTau, i)?;
        check(u32_at(b, at + 20) >= 1, Field::StaleTimeout, i)?;
        ranged(f32_at(b, at + 24), -1.0e4, 1.0e4, Field::BUmPerK, i)?;
        if let Some(r) = rise_bounds_at(l, o, i) {
            let lo = ranged(f32_at(b, r), -MAX_RISE_K, MAX_RISE_K, Field::RiseBounds, i)?;
            let hi = ranged(
                f32_at(b, r + 4),
                -MAX_RISE_K,
                MAX_RISE_K,
                Field::RiseBounds,
                i,
            )?;
            check(lo < hi, Field::RiseBounds, i)?;
        }
    }
    for j in 0..l.n_forces {
        let at = o + THERMO_HEADER_LEN + SENSOR_LEN * l.n_sensors + FORCE_LEN * j;
        ranged(f32_at(b, at), -1.0e3, 1.0e3, Field::Chi, j)?;
        let has_law = u32_at(b, at + 4);
        check(has_law <= 1, Field::ForceLaw, j)?;
        let k = ranged(f32_at(b, at + 8), -1.0e9, 1.0e9, Field::ForceLaw, j)?;
        let mut e = [0.0f32; 3];
        for (m, v) in e.iter_mut().enumerate() {
            *v = ranged(f32_at(b, at + 12 + 4 * m), -10.0, 10.0, Field::ForceLaw, j)?;
        }
        if has_law == 0 {
            check(k == 0.0 && e == [0.0; 3], Field::ForceLaw, j)?;
        }
    }
    Ok(())
}

/// `(start_counts, segment_counts, n_segments)` of a validated image's table.
pub(crate) fn table_grid(l: &Layout, b: &[u8]) -> Option<(i64, u32, usize)> {
    let o = l.table?;
    Some((i64_at(b, o), u32_at(b, o + 8), l.n_segments))
}

/// `(start_counts, segment_counts, n_segments)` of a valid image's table (None without a table
/// or for an invalid image).
pub(crate) fn table_grid_of(b: &[u8]) -> Option<(i64, u32, usize)> {
    let l = validate(b).ok()?;
    table_grid(&l, b)
}

/// Segment `s` (< n) of direction half `d` of a validated image's table (the forward segments
/// for both halves of a unidirectional table).
pub(crate) fn table_segment(l: &Layout, b: &[u8], d: usize, s: usize) -> [f32; 4] {
    let Some(o) = l.table else {
        return [0.0; 4];
    };
    let src = if l.bidirectional { d & 1 } else { 0 };
    let at = o + TABLE_HEADER_LEN + 16 * (src * l.n_segments + s);
    [
        f32_at(b, at),
        f32_at(b, at + 4),
        f32_at(b, at + 8),
        f32_at(b, at + 12),
    ]
}

/// [`table_segment`] converted to the remainder in counts ([`crate::table::per_count`]): what
/// the cycle evaluates.
pub(crate) fn table_segment_per_count(l: &Layout, b: &[u8], d: usize, s: usize) -> [f32; 4] {
    let seg = l.table.map_or(1, |o| u32_at(b, o + 8));
    crate::table::per_count(table_segment(l, b, d, s), seg)
}

/// Copy a validated image into `c` (cannot fail).
pub(crate) fn copy_into(l: &Layout, b: &[u8], c: &mut Compensator) {
    // A unidirectional table is copied into both halves, so that the cycle selects the half by
    // the direction alone.
    for d in 0..2 {
        for s in 0..l.n_segments.min(MAX_SEGMENTS) {
            if let Some(dst) = c.segments.0.get_mut(d * MAX_SEGMENTS + s) {
                *dst = table_segment_per_count(l, b, d, s);
            }
        }
    }
    copy_params_into(l, b, c);
    copy_sensors_into(l, b, &mut c.thermo.sensors);
}

/// Copy the sensors' settings of a validated image into `cfgs` (the axis's own or its group's
/// array; all zero beyond the image's sensors).
pub(crate) fn copy_sensors_into(l: &Layout, b: &[u8], cfgs: &mut [SensorRt; MAX_SENSORS]) {
    *cfgs = [SensorRt::ZERO; MAX_SENSORS];
    let Some(o) = l.thermo else { return };
    let period_s = u32_at(b, o) as f32 * 0.001;
    for (i, s) in cfgs.iter_mut().enumerate().take(l.n_sensors) {
        let at = o + THERMO_HEADER_LEN + SENSOR_LEN * i;
        let tau = f32_at(b, at + 16);
        let (rise_min_k, rise_max_k) = match rise_bounds_at(l, o, i) {
            Some(r) => (f32_at(b, r), f32_at(b, r + 4)),
            None => (f32::NEG_INFINITY, f32::INFINITY),
        };
        *s = SensorRt {
            reference_degc: f32_at(b, at),
            min_degc: f32_at(b, at + 4),
            max_degc: f32_at(b, at + 8),
            max_rate_degc_per_s: f32_at(b, at + 12),
            lag_tau_s: tau,
            stale_timeout_ms: u32_at(b, at + 20),
            b_um_per_k: f32_at(b, at + 24),
            alpha: lag_alpha(period_s, tau),
            rise_min_k,
            rise_max_k,
        };
    }
}

/// Copy everything but the table segments of a validated image into `c` (cannot fail).
pub(crate) fn copy_params_into<S: TableStore>(l: &Layout, b: &[u8], c: &mut AxisCompensator<S>) {
    let bits = u8_at(b, 14);
    let upc = f32_at(b, 16);
    c.axis_id = u16_at(b, 12);
    c.counter.counter_bits = bits;
    c.counter.sext_shift = CounterShift::new(32u32.saturating_sub(bits as u32));
    c.limits.um_per_count = upc;
    c.counts_per_rev = 0;

    c.table.bidirectional = false;
    c.table.taper = false;
    c.table.n_segments = 0;
    c.table.start_counts = 0;
    c.table.segment = None;
    c.table.span_counts = 0;
    c.table.taper_counts = 0;
    c.table.inv_taper = 0.0;
    c.table.edge = [[0.0; 2]; 2];
    if let Some(o) = l.table {
        let n = l.n_segments;
        let seg = u32_at(b, o + 8);
        c.table.bidirectional = l.bidirectional;
        c.table.n_segments = n as u32;
        c.table.start_counts = i64_at(b, o);
        c.table.segment = core::num::NonZeroU32::new(seg);
        c.table.span_counts = seg.wrapping_mul(n as u32);
        c.table.taper = u8_at(b, o + 15) == 1;
        c.table.taper_counts = u32_at(b, o + 16);
        c.table.inv_taper = if c.table.taper {
            1.0 / c.table.taper_counts as f32
        } else {
            0.0
        };
        for d in 0..2 {
            let first = table_segment(l, b, d, 0);
            let last = table_segment(l, b, d, n - 1);
            c.table.edge[d] = [first[0], last[0] + last[1] + last[2] + last[3]];
        }
    }

    c.thermo.reset();
    c.thermo.has_thermo = l.thermo.is_some();
    if let Some(o) = l.thermo {
        let period = u32_at(b, o);
        c.thermo.sensor_period_ms = period;
        c.thermo.n_sensors = l.n_sensors as u8;
        c.thermo.b0_um = f32_at(b, o + 8);
        c.thermo.has_expansion = u8_at(b, o + 6) == 1;
        c.thermo.reference_at_switch_on = l.thermo_flags & THERMO_REFERENCE_AT_SWITCH_ON != 0;
        c.thermo.rise_guard = l.thermo_flags & THERMO_RISE_GUARD != 0;
        c.thermo.expansion_sensor = u8_at(b, o + 7);
        c.thermo.c_um_per_mm_k = f32_at(b, o + 12);
        c.thermo.x_ref_counts = i64_at(b, o + 16);
        c.thermo.expansion_um_per_count_k = c.thermo.c_um_per_mm_k * upc * 0.001;
        c.thermo.n_forces = l.n_forces as u8;
        if l.n_sensors > 0 {
            c.thermo.thermo_flags_xor = crate::Flags::THERMAL_FROZEN.0;
        }
        for j in 0..l.n_forces.min(MAX_FORCES) {
            let at = o + THERMO_HEADER_LEN + SENSOR_LEN * l.n_sensors + FORCE_LEN * j;
            c.thermo.chi_um_per_n[j] = f32_at(b, at);
            c.thermo.force_predicted[j] = u32_at(b, at + 4) == 1;
            if !c.thermo.force_predicted[j] {
                c.thermo.measured_mask |= 1 << j;
                c.thermo.chi_measured[j] = c.thermo.chi_um_per_n[j];
            }
            c.thermo.laws[j] = ForceLaw {
                k: f32_at(b, at + 8),
                x_ap: f32_at(b, at + 12),
                y_fz: f32_at(b, at + 16),
                z_n: f32_at(b, at + 20),
            };
        }
    }

    c.thermo.measured = crate::sensor::MeasuredSet::from_mask(c.thermo.measured_mask);

    let o = l.limits;
    c.limits.max_correction_um = f32_at(b, o);
    c.limits.slew_key = crate::limits::magnitude_key(f32_at(b, o + 4));
    c.counter.hysteresis_counts = u32_at(b, o + 8);
    // 2^29 leaves a factor 2 of margin below the 2^30 that `round_half_away_bounded` needs.
    c.limits.half_um_per_count = 0.5 * upc;
    c.limits.fast_max_key = if MAX_LIMIT_UM / upc < 536_870_912.0 {
        crate::limits::magnitude_key(c.limits.max_correction_um)
    } else {
        0
    };
    c.loaded = true;
}

/// α = 1 − exp(−period/τ) (via `expm1f` for accuracy at small period/τ); 1 for τ = 0.
pub fn lag_alpha(period_s: f32, tau_s: f32) -> f32 {
    if tau_s > 0.0 {
        let a = -libm::expm1f(-(period_s / tau_s));
        if a.is_finite() {
            a.clamp(0.0, 1.0)
        } else {
            1.0
        }
    } else {
        1.0
    }
}

/// Length in bytes of the image [`write_image`] writes for `spec`.
pub fn image_len(spec: &ImageSpec) -> usize {
    let mut n = HEADER_LEN + LIMITS_LEN + CRC_LEN;
    if let Some(t) = &spec.table {
        let dirs = if t.backward.is_empty() { 1 } else { 2 };
        n = n.saturating_add(TABLE_HEADER_LEN + 16usize.saturating_mul(t.forward.len()) * dirs);
    }
    if let Some(h) = &spec.thermo {
        n = n.saturating_add(thermo_section_len(
            h.sensors.len(),
            h.forces.len(),
            !h.rise_bounds_k.is_empty(),
        ));
    }
    n
}

/// The `thermo_flags` word [`write_image`] writes for a thermo-force term.
fn thermo_flags_of(h: &crate::spec::ThermoForceSpec) -> u32 {
    let mut f = 0;
    if h.reference == ThermoReference::SwitchOn {
        f |= THERMO_REFERENCE_AT_SWITCH_ON;
    }
    if !h.rise_bounds_k.is_empty() {
        f |= THERMO_RISE_GUARD;
    }
    f
}

/// Validate `spec` and write its image into `out`; returns the length.
///
/// On `Err` nothing usable is left in `out` (the written bytes are zeroed).
pub fn write_image(spec: &ImageSpec, out: &mut [u8]) -> Result<usize, ImageError> {
    // Counts the format cannot represent.
    if let Some(t) = &spec.table {
        if t.forward.is_empty() || t.forward.len() > MAX_SEGMENTS {
            return Err(ImageError::TooManySegments);
        }
        if !t.backward.is_empty() && t.backward.len() != t.forward.len() {
            return Err(ImageError::DirectionLengthMismatch);
        }
    }
    if let Some(h) = &spec.thermo {
        if h.sensors.len() > MAX_SENSORS {
            return Err(ImageError::TooManySensors);
        }
        if h.forces.len() > MAX_FORCES {
            return Err(ImageError::TooManyForces);
        }
        if h.b_um_per_k.len() != h.sensors.len()
            || !(h.rise_bounds_k.is_empty() || h.rise_bounds_k.len() == h.sensors.len())
        {
            return Err(ImageError::SensorCountMismatch);
        }
        if let Some(e) = &h.expansion {
            if e.sensor as usize >= h.sensors.len() {
                return Err(ImageError::OutOfRange {
                    field: Field::ExpansionSensor,
                    index: 0,
                });
            }
        }
    }
    let len = image_len(spec);
    if len > MAX_IMAGE_LEN {
        return Err(ImageError::BadLength);
    }
    if out.len() < len {
        return Err(ImageError::BufferTooSmall { needed: len as u32 });
    }
    let Some(out) = out.get_mut(..len) else {
        return Err(ImageError::BufferTooSmall { needed: len as u32 });
    };

    let table_len = spec.table.as_ref().map_or(0, |t| {
        TABLE_HEADER_LEN + 16 * t.forward.len() * if t.backward.is_empty() { 1 } else { 2 }
    });
    let thermo_len = spec.thermo.as_ref().map_or(0, |h| {
        thermo_section_len(h.sensors.len(), h.forces.len(), !h.rise_bounds_k.is_empty())
    });
    let table_off = if table_len > 0 { HEADER_LEN } else { 0 };
    let thermo_off = if thermo_len > 0 {
        HEADER_LEN + table_len
    } else {
        0
    };
    let limits_off = HEADER_LEN + table_len + thermo_len;

    let mut w = Put::new(out);
    w.bytes(&MAGIC);
    w.u16(SCHEMA_VERSION);
    w.u16(HEADER_LEN as u16);
    w.u32(len as u32);
    w.u16(spec.axis_id);
    w.u8(spec.counter_bits);
    w.u8(0);
    w.f32(spec.um_per_count);
    for v in [
        table_off, table_len, thermo_off, thermo_len, limits_off, LIMITS_LEN,
    ] {
        w.u32(v as u32);
    }
    w.u32(0);

    if let Some(t) = &spec.table {
        w.i64(t.start_counts);
        w.u32(t.segment_counts);
        w.u16(t.forward.len() as u16);
        w.u8(!t.backward.is_empty() as u8);
        match t.outside {
            OutsideStroke::Hold => {
                w.u8(0);
                w.u32(0);
            }
            OutsideStroke::Taper { length_counts } => {
                w.u8(1);
                w.u32(length_counts);
            }
        }
        w.u32(0);
        for c in t.forward.iter().chain(t.backward.iter()) {
            for &v in c {
                w.f32(v);
            }
        }
    }
    if let Some(h) = &spec.thermo {
        put_thermo(&mut w, h);
    }
    w.f32(spec.limits.max_correction_um);
    w.f32(spec.limits.max_slew_um_per_cycle);
    w.u32(spec.limits.direction_hysteresis_counts);
    w.u32(0);
    let body = w.pos;
    let crc = crc32(w.buf.get(..body).unwrap_or(&[]));
    w.u32(crc);

    // The written image must pass exactly the checks the firmware applies.
    match validate(out) {
        Ok(_) => Ok(len),
        Err(e) => {
            out.fill(0);
            Err(e)
        }
    }
}

/// The thermo section of `h` (validated counts) at `w`'s position.
fn put_thermo(w: &mut Put, h: &crate::spec::ThermoForceSpec) {
    w.u32(h.sensor_period_ms);
    w.u8(h.sensors.len() as u8);
    w.u8(h.forces.len() as u8);
    match &h.expansion {
        Some(e) => {
            w.u8(1);
            w.u8(e.sensor);
            w.f32(h.b0_um);
            w.f32(e.c_um_per_mm_k);
            w.i64(e.x_ref_counts);
        }
        None => {
            w.u8(0);
            w.u8(0);
            w.f32(h.b0_um);
            w.f32(0.0);
            w.i64(0);
        }
    }
    w.u32(thermo_flags_of(h));
    w.u32(0);
    for (s, &b) in h.sensors.iter().zip(h.b_um_per_k.iter()) {
        w.f32(s.reference_degc);
        w.f32(s.min_degc);
        w.f32(s.max_degc);
        w.f32(s.max_rate_degc_per_s);
        w.f32(s.lag_tau_s);
        w.u32(s.stale_timeout_ms);
        w.f32(b);
    }
    for f in h.forces {
        w.f32(f.chi_um_per_n);
        match &f.law {
            Some(l) => {
                w.u32(1);
                w.f32(l.k);
                w.f32(l.x_ap);
                w.f32(l.y_fz);
                w.f32(l.z_n);
            }
            None => {
                w.u32(0);
                for _ in 0..4 {
                    w.f32(0.0);
                }
            }
        }
    }
    for &(lo, hi) in h.rise_bounds_k {
        w.f32(lo);
        w.f32(hi);
    }
}
