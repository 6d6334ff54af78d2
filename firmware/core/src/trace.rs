//! Binary traces (inputs) and output records for replay on the host and on the target.
//!
//! # Trace layout (version 1, little endian)
//! A trace is an 8-byte header — magic `AXTR`, version u16 (1), reserved u16 (0) — followed by
//! records. Every record is `tag: u8`, `len: u32` (payload bytes), then the payload, so a reader
//! can skip or validate any record:
//!
//! | tag | record | payload |
//! |---|---|---|
//! | 1 | `Cycle` | `scale_raw` u32, `command_counts` i64, `forces_n` 3×f32 (24 bytes) |
//! | 2 | `Temperatures` | `now_ms` u32, `n` u8 (≤ 16), 3 reserved bytes (0), n×f32 (8 + 4n bytes) |
//! | 3 | `Process` | `ap_mm`, `fz_mm`, `n_rpm` f32 (12 bytes) |
//! | 4 | `Image` | a table image (≤ 128 KiB, `MAX_IMAGE_LEN`), loaded into the spare slot |
//! | 5 | `Reset` | `scale_raw` u32 (4 bytes): [`crate::State::reset`] |
//! | 6 | `GroupCycle` | `n` u8 (1..=5), 3 reserved bytes (0), then per axis slot the `Cycle` payload (4 + 24n bytes) |
//! | 7 | `AxisTemperatures` | `slot` u8 (< 5), 3 reserved bytes (0), then the `Temperatures` payload |
//! | 8 | `GroupReset` | `n` u8 (1..=5), 3 reserved bytes (0), `scale_raw` u32 per slot (4 + 4n bytes) |
//! | 254 | `Crc` | CRC-32 (u32) of every trace byte before this record; written just before `End` |
//! | 255 | `End` | empty; the reader stops after it |
//!
//! [`verify`] checks a whole trace before use: every record well formed, `End` last with nothing
//! after it, and, if the trace has a `Crc` record (every trace `axcomp trace` writes does), the
//! CRC — so a truncated trace is always refused and a bit flip in a trace with a `Crc` record too.
//!
//! A group trace uses `GroupCycle`, `AxisTemperatures`, `GroupReset`, `Process` and `Image` (a
//! group image of schema 2, or a schema-1 image as a single-axis group); the single-axis
//! [`crate::Engine`] ignores the group records and [`crate::group::GroupEngine::step`] the
//! single-axis `Cycle`, `Temperatures` and `Reset`. A group cycle has one output record per
//! axis of the trace's cycle, in slot order.
//!
//! # Output record (32 bytes, little endian)
//! | off | type | field |
//! |---|---|---|
//! | 0 | u32 | cycle index (0-based, counts Cycle records) |
//! | 4 | i64 | extended position, counts |
//! | 12 | i64 | corrected command, counts |
//! | 20 | i32 | correction, counts |
//! | 24 | u32 | correction, µm, as `f32::to_bits` |
//! | 28 | u16 | [`crate::Flags`] bits |
//! | 30 | u8 | active slot (0 = A, 1 = B) |
//! | 31 | u8 | status bits: [`STATUS_IMAGE_ACCEPTED`], [`STATUS_IMAGE_REJECTED`], [`STATUS_NO_IMAGE`] |

use core::fmt;

use crate::le::{Put, f32_at, i32_at, i64_at, rd, u16_at, u32_at};
use crate::{CycleInput, MAX_FORCES, MAX_IMAGE_LEN, MAX_SENSORS, ProcessParams};

/// Trace magic.
pub const TRACE_MAGIC: [u8; 4] = *b"AXTR";
/// Trace version written and read by this build.
pub const TRACE_VERSION: u16 = 1;
/// Length of the trace header.
pub const TRACE_HEADER_LEN: usize = 8;
/// Length of a record header (tag + length).
pub const RECORD_HEADER_LEN: usize = 5;
/// Tag of [`Record::Cycle`].
pub const TAG_CYCLE: u8 = 1;
/// Tag of [`Record::Temperatures`].
pub const TAG_TEMPERATURES: u8 = 2;
/// Tag of [`Record::Process`].
pub const TAG_PROCESS: u8 = 3;
/// Tag of [`Record::Image`].
pub const TAG_IMAGE: u8 = 4;
/// Tag of [`Record::Reset`].
pub const TAG_RESET: u8 = 5;
/// Tag of [`Record::GroupCycle`].
pub const TAG_GROUP_CYCLE: u8 = 6;
/// Tag of [`Record::AxisTemperatures`].
pub const TAG_AXIS_TEMPERATURES: u8 = 7;
/// Tag of [`Record::GroupReset`].
pub const TAG_GROUP_RESET: u8 = 8;
/// Tag of [`Record::Crc`].
pub const TAG_CRC: u8 = 254;
/// Tag of [`Record::End`].
pub const TAG_END: u8 = 255;
/// Length of an encoded [`OutputRecord`].
pub const OUTPUT_RECORD_LEN: usize = 32;
/// Status bit: an image was accepted since the previous output record.
pub const STATUS_IMAGE_ACCEPTED: u8 = 1;
/// Status bit: an image was rejected since the previous output record.
pub const STATUS_IMAGE_REJECTED: u8 = 2;
/// Status bit: no image loaded, the identity is running.
pub const STATUS_NO_IMAGE: u8 = 4;

const CYCLE_LEN: usize = 24;
const PROCESS_LEN: usize = 12;
const RESET_LEN: usize = 4;

/// Trace framing or decoding error.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TraceError {
    /// Shorter than the trace header.
    TooShort,
    /// Magic is not `AXTR`.
    BadMagic,
    /// Trace version not supported.
    UnsupportedVersion {
        /// Version found.
        found: u16,
    },
    /// A record header or payload runs past the end of the trace.
    Truncated {
        /// Byte offset of the record.
        offset: u32,
    },
    /// Unknown record tag (the record is skipped).
    UnknownTag {
        /// The tag.
        tag: u8,
        /// Byte offset of the record.
        offset: u32,
    },
    /// A known record with a payload length or content that does not fit its tag (skipped).
    BadRecord {
        /// The tag.
        tag: u8,
        /// Byte offset of the record.
        offset: u32,
    },
    /// The output buffer is too small.
    BufferFull,
    /// The trace does not end with an `End` record (truncated), or bytes follow it.
    NoEnd,
    /// The trace's `Crc` record does not match its bytes (or is not just before `End`).
    BadChecksum,
}

impl fmt::Display for TraceError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            TraceError::TooShort => f.write_str("trace shorter than its header"),
            TraceError::BadMagic => f.write_str("bad trace magic (not an axcomp trace)"),
            TraceError::UnsupportedVersion { found } => {
                write!(f, "unsupported trace version {found}")
            }
            TraceError::Truncated { offset } => {
                write!(f, "record at byte {offset} runs past the end of the trace")
            }
            TraceError::UnknownTag { tag, offset } => {
                write!(f, "unknown record tag {tag} at byte {offset}")
            }
            TraceError::BadRecord { tag, offset } => {
                write!(f, "malformed record (tag {tag}) at byte {offset}")
            }
            TraceError::BufferFull => f.write_str("output buffer full"),
            TraceError::NoEnd => f.write_str(
                "the trace does not end with an End record (truncated or trailing bytes)",
            ),
            TraceError::BadChecksum => f.write_str("trace CRC-32 mismatch (damaged trace)"),
        }
    }
}

impl core::error::Error for TraceError {}

/// A set of temperature readings (°C, NaN = no reading) at `now_ms`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Temperatures {
    /// Time of the readings, ms (wraps).
    pub now_ms: u32,
    /// Number of valid entries in `values`.
    pub n: u8,
    /// Readings; entries at `n..` are unused.
    pub values: [f32; MAX_SENSORS],
}

impl Temperatures {
    /// From a slice (at most [`MAX_SENSORS`] entries are kept).
    pub fn new(now_ms: u32, readings: &[f32]) -> Temperatures {
        let mut values = [f32::NAN; MAX_SENSORS];
        let n = readings.len().min(MAX_SENSORS);
        values[..n].copy_from_slice(&readings[..n]);
        Temperatures {
            now_ms,
            n: n as u8,
            values,
        }
    }
    /// The valid readings.
    pub fn readings(&self) -> &[f32] {
        &self.values[..(self.n as usize).min(MAX_SENSORS)]
    }
}

/// One trace record.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Record<'a> {
    /// A control cycle.
    Cycle(CycleInput),
    /// A sensor-rate temperature update.
    Temperatures(Temperatures),
    /// New process parameters (predicted forces).
    Process(ProcessParams),
    /// A new table image for the spare slot.
    Image(&'a [u8]),
    /// Reset the axis state with the counter value at reset.
    Reset {
        /// Counter value at reset.
        scale_raw: u32,
    },
    /// A group cycle: the inputs of the first `n` axis slots.
    GroupCycle {
        /// Axes in the cycle (1..=5).
        n: u8,
        /// Inputs by slot (entries from `n` on are zero).
        input: crate::io::GroupInput,
    },
    /// A sensor-rate update of one axis slot of a group.
    AxisTemperatures {
        /// The axis slot.
        slot: u8,
        /// The readings.
        t: Temperatures,
    },
    /// Reset of a group's first `n` axes with their counter values at reset.
    GroupReset {
        /// Axes reset (1..=5).
        n: u8,
        /// Counter values by slot.
        scale_raw: [u32; crate::axis::MAX_AXES],
    },
    /// CRC-32 of every trace byte before this record.
    Crc(u32),
    /// End of the trace.
    End,
}

impl Record<'_> {
    /// The record's tag.
    pub fn tag(&self) -> u8 {
        match self {
            Record::Cycle(_) => TAG_CYCLE,
            Record::Temperatures(_) => TAG_TEMPERATURES,
            Record::Process(_) => TAG_PROCESS,
            Record::Image(_) => TAG_IMAGE,
            Record::Reset { .. } => TAG_RESET,
            Record::GroupCycle { .. } => TAG_GROUP_CYCLE,
            Record::AxisTemperatures { .. } => TAG_AXIS_TEMPERATURES,
            Record::GroupReset { .. } => TAG_GROUP_RESET,
            Record::Crc(_) => TAG_CRC,
            Record::End => TAG_END,
        }
    }
    /// Payload length in bytes.
    pub fn payload_len(&self) -> usize {
        match self {
            Record::Cycle(_) => CYCLE_LEN,
            Record::Temperatures(t) => 8 + 4 * t.readings().len(),
            Record::Process(_) => PROCESS_LEN,
            Record::Image(b) => b.len(),
            Record::Reset { .. } => RESET_LEN,
            Record::GroupCycle { n, .. } => 4 + CYCLE_LEN * group_n(*n),
            Record::AxisTemperatures { t, .. } => 4 + 8 + 4 * t.readings().len(),
            Record::GroupReset { n, .. } => 4 + RESET_LEN * group_n(*n),
            Record::Crc(_) => 4,
            Record::End => 0,
        }
    }
    /// Encoded length (header + payload).
    pub fn encoded_len(&self) -> usize {
        RECORD_HEADER_LEN + self.payload_len()
    }
}

/// `n` limited to 1..=5 (what an encoder writes for a group record).
fn group_n(n: u8) -> usize {
    (n as usize).clamp(1, crate::axis::MAX_AXES)
}

fn put_cycle(w: &mut Put, c: &CycleInput) {
    w.u32(c.scale_raw);
    w.i64(c.command_counts);
    for &f in &c.forces_n {
        w.f32(f);
    }
}

fn put_temperatures(w: &mut Put, t: &Temperatures) {
    let r = t.readings();
    w.u32(t.now_ms);
    w.u8(r.len() as u8);
    w.bytes(&[0; 3]);
    for &v in r {
        w.f32(v);
    }
}

fn cycle_at(p: &[u8], at: usize) -> CycleInput {
    let mut forces_n = [0.0f32; MAX_FORCES];
    for (k, f) in forces_n.iter_mut().enumerate() {
        *f = f32_at(p, at + 12 + 4 * k);
    }
    CycleInput {
        scale_raw: u32_at(p, at),
        command_counts: i64_at(p, at + 4),
        forces_n,
    }
}

/// The `Temperatures` payload `p`, if well formed.
fn temperatures_of(p: &[u8]) -> Option<Temperatures> {
    let n = p.get(4).copied().unwrap_or(0) as usize;
    if n > MAX_SENSORS || p.len() != 8 + 4 * n || rd::<3>(p, 5) != [0; 3] {
        return None;
    }
    let mut values = [f32::NAN; MAX_SENSORS];
    for (k, v) in values.iter_mut().enumerate().take(n) {
        *v = f32_at(p, 8 + 4 * k);
    }
    Some(Temperatures {
        now_ms: u32_at(p, 0),
        n: n as u8,
        values,
    })
}

/// Write the trace header into `out`; returns its length.
pub fn write_header(out: &mut [u8]) -> Result<usize, TraceError> {
    let dst = out
        .get_mut(..TRACE_HEADER_LEN)
        .ok_or(TraceError::BufferFull)?;
    let mut w = Put::new(dst);
    w.bytes(&TRACE_MAGIC);
    w.u16(TRACE_VERSION);
    w.u16(0);
    Ok(TRACE_HEADER_LEN)
}

/// Check the trace header; returns the offset of the first record.
pub fn check_header(bytes: &[u8]) -> Result<usize, TraceError> {
    if bytes.len() < TRACE_HEADER_LEN {
        return Err(TraceError::TooShort);
    }
    if rd::<4>(bytes, 0) != TRACE_MAGIC {
        return Err(TraceError::BadMagic);
    }
    let v = u16_at(bytes, 4);
    if v != TRACE_VERSION {
        return Err(TraceError::UnsupportedVersion { found: v });
    }
    Ok(TRACE_HEADER_LEN)
}

/// Encode one record (header + payload) into `out`; returns the bytes written.
pub fn encode_record(rec: &Record, out: &mut [u8]) -> Result<usize, TraceError> {
    let len = rec.encoded_len();
    if rec.payload_len() > u32::MAX as usize {
        return Err(TraceError::BufferFull);
    }
    let dst = out.get_mut(..len).ok_or(TraceError::BufferFull)?;
    let mut w = Put::new(dst);
    w.u8(rec.tag());
    w.u32(rec.payload_len() as u32);
    match rec {
        Record::Cycle(c) => put_cycle(&mut w, c),
        Record::Temperatures(t) => put_temperatures(&mut w, t),
        Record::GroupCycle { n, input } => {
            w.u8(group_n(*n) as u8);
            w.bytes(&[0; 3]);
            for c in input.axes.iter().take(group_n(*n)) {
                put_cycle(&mut w, c);
            }
        }
        Record::AxisTemperatures { slot, t } => {
            w.u8(*slot);
            w.bytes(&[0; 3]);
            put_temperatures(&mut w, t);
        }
        Record::GroupReset { n, scale_raw } => {
            w.u8(group_n(*n) as u8);
            w.bytes(&[0; 3]);
            for &r in scale_raw.iter().take(group_n(*n)) {
                w.u32(r);
            }
        }
        Record::Process(q) => {
            w.f32(q.ap_mm);
            w.f32(q.fz_mm);
            w.f32(q.n_rpm);
        }
        Record::Image(b) => w.bytes(b),
        Record::Reset { scale_raw } => w.u32(*scale_raw),
        Record::Crc(c) => w.u32(*c),
        Record::End => {}
    }
    Ok(len)
}

/// Decode the record at the start of `bytes`; returns it and its encoded length.
///
/// `offset` is only used in error values. On `UnknownTag` and `BadRecord` the record's framing is
/// intact, and [`record_extent`] tells how far to skip.
pub fn decode_record(bytes: &[u8], offset: usize) -> Result<(Record<'_>, usize), TraceError> {
    let off32 = offset.min(u32::MAX as usize) as u32;
    let total = record_extent(bytes).ok_or(TraceError::Truncated { offset: off32 })?;
    let tag = crate::le::u8_at(bytes, 0);
    let p = bytes.get(RECORD_HEADER_LEN..total).unwrap_or(&[]);
    let bad = TraceError::BadRecord { tag, offset: off32 };
    let rec = match tag {
        TAG_CYCLE => {
            if p.len() != CYCLE_LEN {
                return Err(bad);
            }
            Record::Cycle(cycle_at(p, 0))
        }
        TAG_TEMPERATURES => Record::Temperatures(temperatures_of(p).ok_or(bad)?),
        TAG_GROUP_CYCLE | TAG_GROUP_RESET => {
            let n = p.first().copied().unwrap_or(0) as usize;
            let each = if tag == TAG_GROUP_CYCLE {
                CYCLE_LEN
            } else {
                RESET_LEN
            };
            if !(1..=crate::axis::MAX_AXES).contains(&n)
                || p.len() != 4 + each * n
                || rd::<3>(p, 1) != [0; 3]
            {
                return Err(bad);
            }
            if tag == TAG_GROUP_CYCLE {
                let mut input = crate::io::GroupInput::ZERO;
                for (k, c) in input.axes.iter_mut().enumerate().take(n) {
                    *c = cycle_at(p, 4 + CYCLE_LEN * k);
                }
                Record::GroupCycle { n: n as u8, input }
            } else {
                let mut scale_raw = [0u32; crate::axis::MAX_AXES];
                for (k, r) in scale_raw.iter_mut().enumerate().take(n) {
                    *r = u32_at(p, 4 + RESET_LEN * k);
                }
                Record::GroupReset {
                    n: n as u8,
                    scale_raw,
                }
            }
        }
        TAG_AXIS_TEMPERATURES => {
            let slot = p.first().copied().unwrap_or(0);
            if slot as usize >= crate::axis::MAX_AXES || rd::<3>(p, 1) != [0; 3] {
                return Err(bad);
            }
            let t = temperatures_of(p.get(4..).unwrap_or(&[])).ok_or(bad)?;
            Record::AxisTemperatures { slot, t }
        }
        TAG_PROCESS => {
            if p.len() != PROCESS_LEN {
                return Err(bad);
            }
            Record::Process(ProcessParams {
                ap_mm: f32_at(p, 0),
                fz_mm: f32_at(p, 4),
                n_rpm: f32_at(p, 8),
            })
        }
        TAG_IMAGE => {
            if p.len() > MAX_IMAGE_LEN {
                return Err(bad);
            }
            Record::Image(p)
        }
        TAG_RESET => {
            if p.len() != RESET_LEN {
                return Err(bad);
            }
            Record::Reset {
                scale_raw: u32_at(p, 0),
            }
        }
        TAG_CRC => {
            if p.len() != 4 {
                return Err(bad);
            }
            Record::Crc(u32_at(p, 0))
        }
        TAG_END => {
            if !p.is_empty() {
                return Err(bad);
            }
            Record::End
        }
        _ => {
            return Err(TraceError::UnknownTag { tag, offset: off32 });
        }
    };
    Ok((rec, total))
}

/// What [`verify`] found in a sound trace.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TraceCheck {
    /// Records, `End` included.
    pub records: u32,
    /// True if the trace carries a (matching) `Crc` record.
    pub has_crc: bool,
    /// True if the trace has group records.
    pub is_group: bool,
}

/// Check a whole trace: header, every record well formed, `End` last and nothing after it, and
/// the `Crc` record (if any) just before `End` and matching. The first problem is the error.
pub fn verify(bytes: &[u8]) -> Result<TraceCheck, TraceError> {
    let mut at = check_header(bytes)?;
    let mut check = TraceCheck {
        records: 0,
        has_crc: false,
        is_group: false,
    };
    let mut crc_at = None;
    loop {
        let rest = bytes.get(at..).unwrap_or(&[]);
        if rest.is_empty() {
            return Err(TraceError::NoEnd);
        }
        let (rec, len) = decode_record(rest, at)?;
        check.records += 1;
        match rec {
            Record::End => {
                if at + len != bytes.len() {
                    return Err(TraceError::NoEnd);
                }
                if let Some((off, value)) = crc_at {
                    // The Crc record must be the one just before End.
                    if off + RECORD_HEADER_LEN + 4 != at
                        || crate::crc32(bytes.get(..off).unwrap_or(&[])) != value
                    {
                        return Err(TraceError::BadChecksum);
                    }
                    check.has_crc = true;
                }
                return Ok(check);
            }
            Record::Crc(v) => crc_at = Some((at, v)),
            Record::GroupCycle { .. }
            | Record::AxisTemperatures { .. }
            | Record::GroupReset { .. } => check.is_group = true,
            _ => {}
        }
        at += len;
    }
}

/// Encoded length of the record at the start of `bytes`, if its header and payload are complete.
pub fn record_extent(bytes: &[u8]) -> Option<usize> {
    if bytes.len() < RECORD_HEADER_LEN {
        return None;
    }
    let len = u32_at(bytes, 1) as usize;
    let total = RECORD_HEADER_LEN.checked_add(len)?;
    (total <= bytes.len()).then_some(total)
}

/// Reader over a whole trace in memory; yields records and errors, never panics.
///
/// Malformed records with intact framing (unknown tag, wrong payload) are reported and skipped; a
/// truncated record is reported and ends the iteration; so does `End`.
#[derive(Debug, Clone)]
pub struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    done: bool,
}

impl<'a> Reader<'a> {
    /// Check the header and start at the first record.
    pub fn new(bytes: &'a [u8]) -> Result<Reader<'a>, TraceError> {
        let pos = check_header(bytes)?;
        Ok(Reader {
            bytes,
            pos,
            done: false,
        })
    }
    /// Byte offset of the next record.
    pub fn offset(&self) -> usize {
        self.pos
    }
}

impl<'a> Iterator for Reader<'a> {
    type Item = Result<Record<'a>, TraceError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.done || self.pos >= self.bytes.len() {
            return None;
        }
        let rest = self.bytes.get(self.pos..).unwrap_or(&[]);
        let at = self.pos;
        match decode_record(rest, at) {
            Ok((rec, n)) => {
                self.pos += n;
                if rec == Record::End {
                    self.done = true;
                }
                Some(Ok(rec))
            }
            Err(e) => {
                match record_extent(rest) {
                    Some(n) => self.pos += n,
                    None => self.done = true,
                }
                Some(Err(e))
            }
        }
    }
}

/// Writes a trace (header + records) into a caller buffer.
#[derive(Debug)]
pub struct Writer<'b> {
    buf: &'b mut [u8],
    len: usize,
}

impl<'b> Writer<'b> {
    /// Start a trace: writes the header.
    pub fn new(buf: &'b mut [u8]) -> Result<Writer<'b>, TraceError> {
        let len = write_header(buf)?;
        Ok(Writer { buf, len })
    }
    /// Append one record; on `BufferFull` nothing is appended.
    pub fn push(&mut self, rec: &Record) -> Result<(), TraceError> {
        let dst = self.buf.get_mut(self.len..).ok_or(TraceError::BufferFull)?;
        self.len += encode_record(rec, dst)?;
        Ok(())
    }
    /// Bytes written so far.
    pub fn len(&self) -> usize {
        self.len
    }
    /// True if only the header has been written.
    pub fn is_empty(&self) -> bool {
        self.len <= TRACE_HEADER_LEN
    }
    /// The trace written so far.
    pub fn as_bytes(&self) -> &[u8] {
        self.buf.get(..self.len).unwrap_or(&[])
    }
    /// Finish; returns the trace length.
    pub fn finish(self) -> usize {
        self.len
    }
}

/// Write the trace header to an `std::io::Write`.
#[cfg(feature = "std")]
pub fn write_header_io<W: std::io::Write>(w: &mut W) -> std::io::Result<()> {
    let mut h = [0u8; TRACE_HEADER_LEN];
    let _ = write_header(&mut h);
    w.write_all(&h)
}

/// Write one record to an `std::io::Write`.
#[cfg(feature = "std")]
pub fn write_record_io<W: std::io::Write>(w: &mut W, rec: &Record) -> std::io::Result<()> {
    if let Record::Image(b) = rec {
        w.write_all(&[TAG_IMAGE])?;
        w.write_all(&(b.len() as u32).to_le_bytes())?;
        return w.write_all(b);
    }
    let mut buf = [0u8; RECORD_HEADER_LEN + 8 + 4 * MAX_SENSORS];
    let n = encode_record(rec, &mut buf)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidInput, e))?;
    w.write_all(&buf[..n])
}

/// One output of [`crate::Engine::step`], fixed size ([`OUTPUT_RECORD_LEN`] bytes encoded).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct OutputRecord {
    /// Cycle index (0-based).
    pub cycle: u32,
    /// Extended scale position, counts.
    pub position_counts: i64,
    /// Corrected command, counts.
    pub corrected_command_counts: i64,
    /// Correction, counts.
    pub correction_counts: i32,
    /// Correction in µm as `f32::to_bits` (bit-exact comparison).
    pub correction_um_bits: u32,
    /// [`crate::Flags`] bits.
    pub flags: u16,
    /// Active slot (0 = A, 1 = B).
    pub slot: u8,
    /// Status bits (`STATUS_*`).
    pub status: u8,
}

impl OutputRecord {
    /// All fields zero.
    pub const ZERO: OutputRecord = OutputRecord {
        cycle: 0,
        position_counts: 0,
        corrected_command_counts: 0,
        correction_counts: 0,
        correction_um_bits: 0,
        flags: 0,
        slot: 0,
        status: 0,
    };

    /// Correction in µm.
    pub fn correction_um(&self) -> f32 {
        f32::from_bits(self.correction_um_bits)
    }
    /// Flags.
    pub fn flags(&self) -> crate::Flags {
        crate::Flags(self.flags)
    }
    /// Little-endian encoding.
    pub fn encode(&self) -> [u8; OUTPUT_RECORD_LEN] {
        let mut b = [0u8; OUTPUT_RECORD_LEN];
        let mut w = Put::new(&mut b);
        w.u32(self.cycle);
        w.i64(self.position_counts);
        w.i64(self.corrected_command_counts);
        w.i32(self.correction_counts);
        w.u32(self.correction_um_bits);
        w.u16(self.flags);
        w.u8(self.slot);
        w.u8(self.status);
        b
    }
    /// Decode the first [`OUTPUT_RECORD_LEN`] bytes of `bytes`.
    pub fn decode(bytes: &[u8]) -> Result<OutputRecord, TraceError> {
        if bytes.len() < OUTPUT_RECORD_LEN {
            return Err(TraceError::TooShort);
        }
        Ok(OutputRecord {
            cycle: u32_at(bytes, 0),
            position_counts: i64_at(bytes, 4),
            corrected_command_counts: i64_at(bytes, 12),
            correction_counts: i32_at(bytes, 20),
            correction_um_bits: u32_at(bytes, 24),
            flags: u16_at(bytes, 28),
            slot: crate::le::u8_at(bytes, 30),
            status: crate::le::u8_at(bytes, 31),
        })
    }
}
