//! Drive traces: what a group drive receives (setpoint-link bytes, scale counters, cycle start and end
//! times, images, temperature readings), replayed through [`GroupDrive::cycle`] on the host and in QEMU
//! (`axcomp-qemu-group`) alike, one [`DriveOutputRecord`] per cycle.
//!
//! Format (little-endian): the 8-byte header `AXLT`, version `u16` = 1 (or 2: a probe trace), `u16` 0;
//! then records `tag: u8, len: u32, payload[len]`:
//!
//! | tag | record | payload |
//! |---|---|---|
//! | 0 | `End` | – |
//! | 1 | `Link` | bytes the link receives before the next cycle (raw: frames, garbage, repeats) |
//! | 2 | `Cycle` | `start_tick: u32`, `end_tick: u32` (the cycle clock at the cycle's start and end, so that lateness and overruns replay exactly), `scale_raw: [u32; 5]` by board input |
//! | 3 | `Image` | an image offered to the drive ([`GroupDrive::offer_image`]) |
//! | 4 | `Temperatures` | `now_ms: u32`, then `f32` readings by board sensor |
//! | 5 | `ProbeEdge` (version 2) | `time: u32` (cycle-clock ticks), `level: u8`, 3 × `u8` 0, `scale_raw: [u32; 5]` by board input (the counters captured at the edge); read by the next `Cycle` ([`super::probe::ProbeIo`]) |
//!
//! A version-2 (probe) trace's replay writes after each cycle's [`DriveOutputRecord`] a
//! [`ProbeOutputRecord`] (128 bytes: the probe flags, phase, latch sequence, counters, latched point
//! and the whole reply frame).
//!
//! A record that does not fit the replay buffer, a truncated record, an unknown tag or a malformed
//! payload ends the replay with an error (counted in [`LinkReplaySummary::errors`]).

use core::cell::Cell;

use axcomp_core::MAX_SENSORS;
use axcomp_core::group::{GroupEngine, MAX_AXES};

use super::group::{GroupDrive, GroupDriveCycle};
use super::probe::{CapturedEdge, FakeProbe};
use super::{DriveIo, NoWatchdog};
use crate::control::CycleClock;
use crate::replay::{ByteSource, FrameError, RecordWindow};
use crate::setpoint::MAX_REPLY_FRAME_LEN;
use axcomp_core::probe::{Latch, ProbeCounters, ProbePhase};

/// Header magic.
pub const MAGIC: [u8; 4] = *b"AXLT";
/// Format version.
pub const VERSION: u16 = 1;
/// Format version of a probe trace (adds `ProbeEdge` records and [`ProbeOutputRecord`]s).
pub const VERSION_PROBE: u16 = 2;
/// Payload of a `ProbeEdge` record.
pub const PROBE_EDGE_PAYLOAD_LEN: usize = 8 + 4 * MAX_AXES;
/// Bytes of one [`ProbeOutputRecord`].
pub const PROBE_OUTPUT_LEN: usize = 128;
/// Header length.
pub const HEADER_LEN: usize = 8;
/// Record header (tag + length).
pub const RECORD_HEADER_LEN: usize = crate::replay::FRAME_HEADER_LEN;
/// Payload of a `Cycle` record.
pub const CYCLE_PAYLOAD_LEN: usize = 8 + 4 * MAX_AXES;
/// Bytes of one [`DriveOutputRecord`].
pub const DRIVE_OUTPUT_LEN: usize = 128;
/// Most link bytes buffered between two cycles (a record with more is malformed).
pub const MAX_LINK_BYTES: usize = 256;

const TAG_END: u8 = 0;
const TAG_LINK: u8 = 1;
const TAG_CYCLE: u8 = 2;
const TAG_IMAGE: u8 = 3;
const TAG_TEMPERATURES: u8 = 4;
const TAG_PROBE_EDGE: u8 = 5;

/// One record of a drive trace.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LinkRecord<'a> {
    End,
    Link(&'a [u8]),
    Cycle {
        start_tick: u32,
        end_tick: u32,
        scale_raw: [u32; MAX_AXES],
    },
    Image(&'a [u8]),
    Temperatures {
        now_ms: u32,
        readings: [f32; MAX_SENSORS],
        n: usize,
    },
    ProbeEdge(CapturedEdge),
}

/// Why a drive trace could not be read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LinkTraceError<E> {
    Source(E),
    /// Not `AXLT` version 1.
    BadHeader,
    /// The trace ends inside the record at `offset`.
    Truncated {
        offset: u32,
    },
    /// The record at `offset` is larger than the replay buffer.
    TooLarge {
        offset: u32,
        len: u32,
    },
    /// The record at `offset` has an unknown tag or a payload of the wrong length.
    Malformed {
        offset: u32,
        tag: u8,
    },
}

impl<E: core::fmt::Debug> core::fmt::Display for LinkTraceError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            LinkTraceError::Source(e) => write!(f, "reading the drive trace failed: {e:?}"),
            LinkTraceError::BadHeader => write!(f, "not a drive trace (AXLT version 1)"),
            LinkTraceError::Truncated { offset } => {
                write!(f, "drive trace truncated in the record at byte {offset}")
            }
            LinkTraceError::TooLarge { offset, len } => write!(
                f,
                "record at byte {offset} is {len} bytes, larger than the replay buffer"
            ),
            LinkTraceError::Malformed { offset, tag } => {
                write!(f, "malformed record (tag {tag}) at byte {offset}")
            }
        }
    }
}

impl<E: core::fmt::Debug> core::error::Error for LinkTraceError<E> {}

/// True if `head` starts like a drive trace.
pub fn is_link_trace(head: &[u8]) -> bool {
    head.len() >= 4 && head[..4] == MAGIC
}

/// Reads drive-trace records through a fixed buffer ([`RecordWindow`], the trace's framing).
pub struct LinkStream<'b, S> {
    version: u16,
    window: RecordWindow<'b, S>,
}

impl<'b, S: ByteSource> LinkStream<'b, S> {
    pub fn new(src: S, buf: &'b mut [u8]) -> Result<Self, LinkTraceError<S::Error>> {
        let mut window = RecordWindow::new(src, buf);
        let h = window.peek(HEADER_LEN).map_err(LinkTraceError::Source)?;
        let version = if h.len() >= HEADER_LEN {
            u16::from_le_bytes([h[4], h[5]])
        } else {
            0
        };
        if h.len() < HEADER_LEN
            || !is_link_trace(h)
            || !(version == VERSION || version == VERSION_PROBE)
        {
            return Err(LinkTraceError::BadHeader);
        }
        window.consume(HEADER_LEN);
        Ok(LinkStream { version, window })
    }

    /// The trace's format version ([`VERSION`], or [`VERSION_PROBE`]: a probe trace).
    pub fn version(&self) -> u16 {
        self.version
    }

    /// True for a probe trace (its replay writes a [`ProbeOutputRecord`] after each cycle's record).
    pub fn is_probe_trace(&self) -> bool {
        self.version == VERSION_PROBE
    }

    /// The next record; `Ok(None)` at the end of input.
    pub fn next_record(&mut self) -> Result<Option<LinkRecord<'_>>, LinkTraceError<S::Error>> {
        let at = self.window.offset().min(u32::MAX as usize) as u32;
        let version = self.version;
        let frame = match self.window.next_frame() {
            Ok(Some((_, f))) => f,
            Ok(None) => return Ok(None),
            Err(FrameError::Source(e)) => return Err(LinkTraceError::Source(e)),
            Err(FrameError::Truncated) => return Err(LinkTraceError::Truncated { offset: at }),
            Err(FrameError::TooLarge { len }) => {
                return Err(LinkTraceError::TooLarge {
                    offset: at,
                    len: len.min(u32::MAX as usize) as u32,
                });
            }
        };
        let tag = frame[0];
        let p = &frame[RECORD_HEADER_LEN..];
        let malformed = LinkTraceError::Malformed { offset: at, tag };
        let u32_at = |b: &[u8], i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        let rec = match tag {
            TAG_END if p.is_empty() => LinkRecord::End,
            TAG_LINK if p.len() <= MAX_LINK_BYTES => LinkRecord::Link(p),
            TAG_CYCLE if p.len() == CYCLE_PAYLOAD_LEN => {
                let mut scale_raw = [0u32; MAX_AXES];
                for (k, s) in scale_raw.iter_mut().enumerate() {
                    *s = u32_at(p, 8 + 4 * k);
                }
                LinkRecord::Cycle {
                    start_tick: u32_at(p, 0),
                    end_tick: u32_at(p, 4),
                    scale_raw,
                }
            }
            TAG_IMAGE => LinkRecord::Image(p),
            TAG_TEMPERATURES if p.len() >= 4 && (p.len() - 4) % 4 == 0 => {
                let n = (p.len() - 4) / 4;
                if n > MAX_SENSORS {
                    return Err(malformed);
                }
                let mut readings = [0f32; MAX_SENSORS];
                for (k, r) in readings.iter_mut().take(n).enumerate() {
                    *r = f32::from_bits(u32_at(p, 4 + 4 * k));
                }
                LinkRecord::Temperatures {
                    now_ms: u32_at(p, 0),
                    readings,
                    n,
                }
            }
            TAG_PROBE_EDGE if version == VERSION_PROBE && p.len() == PROBE_EDGE_PAYLOAD_LEN => {
                if p[4] > 1 || p[5..8] != [0, 0, 0] {
                    return Err(malformed);
                }
                let mut scale_raw = [0u32; MAX_AXES];
                for (k, s) in scale_raw.iter_mut().enumerate() {
                    *s = u32_at(p, 8 + 4 * k);
                }
                LinkRecord::ProbeEdge(CapturedEdge {
                    time: u32_at(p, 0),
                    level: p[4] == 1,
                    scale_raw,
                })
            }
            _ => return Err(malformed),
        };
        Ok(Some(rec))
    }
}

/// One replayed drive cycle, as written to the output file (128 bytes, little-endian):
/// `cycle: u32`, `status: u32`, `n_axes: u8`, `n_inputs: u8`, `reply_len: u8`, `0: u8`, the reply frame
/// sent (zero-padded to 36 bytes), then per group slot (5): the corrected command `i64`, the applied
/// correction `f32` bits, the engine's correction `f32` bits (entries beyond `n_axes` zero).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DriveOutputRecord {
    pub cycle: u32,
    pub cycle_result: GroupDriveCycle,
    pub reply: [u8; MAX_REPLY_FRAME_LEN],
    pub reply_len: usize,
    /// The probe latch after the cycle.
    pub probe: ProbeSnapshot,
}

/// The probe latch's state after a cycle (what a [`ProbeOutputRecord`] holds).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeSnapshot {
    pub phase: ProbePhase,
    pub latch_seq: u8,
    pub counters: ProbeCounters,
    pub latch: Option<Latch>,
}

impl ProbeSnapshot {
    /// Of a drive after a cycle.
    pub fn of(drive: &GroupDrive) -> Self {
        let st = drive.probe().state();
        ProbeSnapshot {
            phase: st.phase(),
            latch_seq: st.latch_seq(),
            counters: *st.counters(),
            latch: st.latch().copied(),
        }
    }
}

/// One probe trace cycle's probe record (128 bytes, little-endian): `cycle: u32`, probe flags `u16`,
/// phase `u8`, latch sequence `u8`, reply length `u8`, 3 × 0, the reply frame as sent (zero-padded to
/// 44 bytes), the 6 event counters `u32` (by [`axcomp_core::probe::ProbeEvent`] code), the latched
/// point by group slot 5 × `i64` nm, the latch's leading-edge time `u32` (ticks), its quality `u16`
/// ([`axcomp_core::probe::ProbeFlags`]), `u16` 0. No latch yet: point, time and quality zero.
pub struct ProbeOutputRecord;

impl ProbeOutputRecord {
    /// Encodes the probe part of `r`.
    pub fn encode(r: &DriveOutputRecord) -> [u8; PROBE_OUTPUT_LEN] {
        let mut o = [0u8; PROBE_OUTPUT_LEN];
        let p = &r.probe;
        o[0..4].copy_from_slice(&r.cycle.to_le_bytes());
        o[4..6].copy_from_slice(&r.cycle_result.probe.bits().to_le_bytes());
        o[6] = p.phase as u8;
        o[7] = p.latch_seq;
        o[8] = r.reply_len as u8;
        let n = r.reply_len.min(PROBE_REPLY_FIELD_LEN);
        o[12..12 + n].copy_from_slice(&r.reply[..n]);
        let mut at = 12 + PROBE_REPLY_FIELD_LEN;
        for c in p.counters.events {
            o[at..at + 4].copy_from_slice(&c.to_le_bytes());
            at += 4;
        }
        if let Some(l) = &p.latch {
            for v in l.point_nm {
                o[at..at + 8].copy_from_slice(&v.to_le_bytes());
                at += 8;
            }
            o[at..at + 4].copy_from_slice(&l.time.to_le_bytes());
            o[at + 4..at + 6].copy_from_slice(&l.quality.bits().to_le_bytes());
        }
        o
    }
}

/// The fields of an encoded [`ProbeOutputRecord`] a test reads back.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DecodedProbeOutput {
    pub cycle: u32,
    pub flags: u16,
    pub phase: u8,
    pub latch_seq: u8,
    pub reply_len: usize,
    pub reply: [u8; PROBE_REPLY_FIELD_LEN],
    pub counters: [u32; 6],
    pub point_nm: [i64; MAX_AXES],
    pub latch_time: u32,
    pub latch_quality: u16,
}

impl DecodedProbeOutput {
    pub fn decode(o: &[u8; PROBE_OUTPUT_LEN]) -> Self {
        let u32_at = |i: usize| u32::from_le_bytes([o[i], o[i + 1], o[i + 2], o[i + 3]]);
        let mut d = DecodedProbeOutput {
            cycle: u32_at(0),
            flags: u16::from_le_bytes([o[4], o[5]]),
            phase: o[6],
            latch_seq: o[7],
            reply_len: usize::from(o[8]),
            reply: [0; PROBE_REPLY_FIELD_LEN],
            counters: [0; 6],
            point_nm: [0; MAX_AXES],
            latch_time: 0,
            latch_quality: 0,
        };
        d.reply.copy_from_slice(&o[12..12 + PROBE_REPLY_FIELD_LEN]);
        let mut at = 12 + PROBE_REPLY_FIELD_LEN;
        for c in d.counters.iter_mut() {
            *c = u32_at(at);
            at += 4;
        }
        for v in d.point_nm.iter_mut() {
            let mut b = [0u8; 8];
            b.copy_from_slice(&o[at..at + 8]);
            *v = i64::from_le_bytes(b);
            at += 8;
        }
        d.latch_time = u32_at(at);
        d.latch_quality = u16::from_le_bytes([o[at + 4], o[at + 5]]);
        d
    }
}

const PROBE_REPLY_FIELD_LEN: usize = 44;
const _: () = assert!(MAX_REPLY_FRAME_LEN <= PROBE_REPLY_FIELD_LEN);
const _: () = assert!(12 + PROBE_REPLY_FIELD_LEN + 4 * 6 + 8 * MAX_AXES + 8 == PROBE_OUTPUT_LEN);

const REPLY_FIELD_LEN: usize = 36;
const _: () = assert!(crate::setpoint::MAX_REPLY_V2_FRAME_LEN <= REPLY_FIELD_LEN);
const _: () = assert!(12 + REPLY_FIELD_LEN + 16 * MAX_AXES == DRIVE_OUTPUT_LEN);

impl DriveOutputRecord {
    pub fn encode(&self) -> [u8; DRIVE_OUTPUT_LEN] {
        let c = &self.cycle_result;
        let mut o = [0u8; DRIVE_OUTPUT_LEN];
        o[0..4].copy_from_slice(&self.cycle.to_le_bytes());
        o[4..8].copy_from_slice(&c.status.bits().to_le_bytes());
        o[8] = c.n_axes as u8;
        o[9] = c.n_inputs as u8;
        o[10] = self.reply_len as u8;
        // A v3 (probe) reply longer than the field is cut here; the probe record has all of it.
        let shown = self.reply_len.min(REPLY_FIELD_LEN);
        o[12..12 + shown].copy_from_slice(&self.reply[..shown]);
        let mut at = 12 + REPLY_FIELD_LEN;
        for i in 0..MAX_AXES {
            if i < c.n_axes {
                o[at..at + 8].copy_from_slice(&c.corrected_command_counts[i].to_le_bytes());
                o[at + 8..at + 12]
                    .copy_from_slice(&c.applied[i].correction_um.to_bits().to_le_bytes());
                o[at + 12..at + 16]
                    .copy_from_slice(&c.engine.axes[i].correction_um.to_bits().to_le_bytes());
            }
            at += 16;
        }
        o
    }
}

/// The fields of an encoded [`DriveOutputRecord`] a test reads back.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DecodedDriveOutput {
    pub cycle: u32,
    pub status: u32,
    pub n_axes: usize,
    pub corrected_command_counts: [i64; MAX_AXES],
    pub applied_um: [f32; MAX_AXES],
    pub engine_um: [f32; MAX_AXES],
}

impl DecodedDriveOutput {
    pub fn decode(o: &[u8; DRIVE_OUTPUT_LEN]) -> Self {
        let u32_at = |i: usize| u32::from_le_bytes([o[i], o[i + 1], o[i + 2], o[i + 3]]);
        let mut d = DecodedDriveOutput {
            cycle: u32_at(0),
            status: u32_at(4),
            n_axes: usize::from(o[8]),
            corrected_command_counts: [0; MAX_AXES],
            applied_um: [0.0; MAX_AXES],
            engine_um: [0.0; MAX_AXES],
        };
        let mut at = 12 + REPLY_FIELD_LEN;
        for i in 0..MAX_AXES {
            let mut b = [0u8; 8];
            b.copy_from_slice(&o[at..at + 8]);
            d.corrected_command_counts[i] = i64::from_le_bytes(b);
            d.applied_um[i] = f32::from_bits(u32_at(at + 8));
            d.engine_um[i] = f32::from_bits(u32_at(at + 12));
            at += 16;
        }
        d
    }
}

/// The cycle clock of a replay: the `Cycle` record's start tick on the first read, its end tick after.
struct TraceClock {
    ticks: Cell<[u32; 2]>,
    reads: Cell<u8>,
}

impl CycleClock for TraceClock {
    fn now(&self) -> u32 {
        let r = self.reads.get();
        self.reads.set(r.saturating_add(1));
        self.ticks.get()[usize::from(r.min(1))]
    }
}

/// Board I/O of a replay: the `Cycle` record's counters, the `Link` bytes, the reply captured.
struct TraceIo {
    scales: [u32; MAX_AXES],
    rx: [u8; MAX_LINK_BYTES],
    rx_len: usize,
    rx_at: usize,
    reply: [u8; MAX_REPLY_FRAME_LEN],
    reply_len: usize,
}

impl DriveIo for TraceIo {
    fn read_scale(&mut self, input: usize) -> u32 {
        self.scales.get(input).copied().unwrap_or(0)
    }
    fn read_link(&mut self, buf: &mut [u8]) -> usize {
        let n = buf.len().min(self.rx_len - self.rx_at);
        buf[..n].copy_from_slice(&self.rx[self.rx_at..self.rx_at + n]);
        self.rx_at += n;
        n
    }
    fn write_link(&mut self, frame: &[u8]) -> bool {
        let n = frame.len().min(MAX_REPLY_FRAME_LEN);
        self.reply[..n].copy_from_slice(&frame[..n]);
        self.reply_len = n;
        true
    }
}

/// Replay totals.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LinkReplaySummary {
    pub records: u32,
    pub cycles: u32,
    pub images_refused: u32,
    /// 1 when a malformed or truncated record ended the replay.
    pub errors: u32,
}

/// Replays a drive trace through `drive` and `engine`; `on_output` gets each cycle's record, `on_error`
/// the error that ended the replay early.
pub fn replay_link<const POOL: usize, S: ByteSource>(
    drive: &mut GroupDrive,
    engine: &mut GroupEngine<POOL>,
    stream: &mut LinkStream<'_, S>,
    mut on_output: impl FnMut(&DriveOutputRecord),
    mut on_error: impl FnMut(LinkTraceError<S::Error>),
) -> LinkReplaySummary {
    let mut sum = LinkReplaySummary::default();
    let mut io = TraceIo {
        scales: [0; MAX_AXES],
        rx: [0; MAX_LINK_BYTES],
        rx_len: 0,
        rx_at: 0,
        reply: [0; MAX_REPLY_FRAME_LEN],
        reply_len: 0,
    };
    let clock = TraceClock {
        ticks: Cell::new([0, 0]),
        reads: Cell::new(0),
    };
    let mut probe = FakeProbe::new();
    loop {
        let rec = match stream.next_record() {
            Ok(Some(r)) => r,
            Ok(None) => break,
            Err(e) => {
                sum.errors += 1;
                on_error(e);
                break;
            }
        };
        sum.records += 1;
        match rec {
            LinkRecord::End => break,
            LinkRecord::Link(b) => {
                // Bytes not read by a cycle stay queued (the board's receive ring); the oldest are
                // dropped when the ring is full, as the USART's would be.
                if io.rx_at > 0 {
                    io.rx.copy_within(io.rx_at..io.rx_len, 0);
                    io.rx_len -= io.rx_at;
                    io.rx_at = 0;
                }
                let room = MAX_LINK_BYTES - io.rx_len;
                let take = b.len().min(room);
                io.rx[io.rx_len..io.rx_len + take].copy_from_slice(&b[..take]);
                io.rx_len += take;
            }
            LinkRecord::Cycle {
                start_tick,
                end_tick,
                scale_raw,
            } => {
                io.scales = scale_raw;
                clock.ticks.set([start_tick, end_tick]);
                clock.reads.set(0);
                io.reply_len = 0;
                let c =
                    drive.cycle_with_probe(engine, &mut io, &mut probe, &clock, &mut NoWatchdog);
                on_output(&DriveOutputRecord {
                    cycle: sum.cycles,
                    cycle_result: c,
                    reply: io.reply,
                    reply_len: io.reply_len,
                    probe: ProbeSnapshot::of(drive),
                });
                sum.cycles += 1;
            }
            LinkRecord::Image(b) => {
                if drive.offer_image(engine, b).is_err() {
                    sum.images_refused += 1;
                }
            }
            LinkRecord::Temperatures {
                now_ms,
                readings,
                n,
            } => drive.update_temperatures(engine, now_ms, &readings[..n]),
            LinkRecord::ProbeEdge(e) => probe.push(e),
        }
    }
    sum
}

/// Writes drive traces (host only).
#[cfg(any(test, feature = "std"))]
pub mod write {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    /// Builds a drive trace in memory.
    pub struct LinkTraceBuilder {
        bytes: Vec<u8>,
    }

    impl Default for LinkTraceBuilder {
        fn default() -> Self {
            Self::new()
        }
    }

    impl LinkTraceBuilder {
        pub fn new() -> Self {
            Self::with_version(VERSION)
        }
        /// A probe trace (version 2: `ProbeEdge` records allowed, probe output records replayed).
        pub fn new_probe() -> Self {
            Self::with_version(VERSION_PROBE)
        }
        fn with_version(version: u16) -> Self {
            let mut bytes = Vec::new();
            bytes.extend_from_slice(&MAGIC);
            bytes.extend_from_slice(&version.to_le_bytes());
            bytes.extend_from_slice(&0u16.to_le_bytes());
            LinkTraceBuilder { bytes }
        }
        fn record(&mut self, tag: u8, payload: &[u8]) {
            self.bytes.push(tag);
            self.bytes
                .extend_from_slice(&(payload.len() as u32).to_le_bytes());
            self.bytes.extend_from_slice(payload);
        }
        pub fn link(&mut self, bytes: &[u8]) {
            self.record(TAG_LINK, bytes);
        }
        pub fn cycle(&mut self, start_tick: u32, end_tick: u32, scale_raw: &[u32; MAX_AXES]) {
            let mut p = Vec::with_capacity(CYCLE_PAYLOAD_LEN);
            p.extend_from_slice(&start_tick.to_le_bytes());
            p.extend_from_slice(&end_tick.to_le_bytes());
            for s in scale_raw {
                p.extend_from_slice(&s.to_le_bytes());
            }
            self.record(TAG_CYCLE, &p);
        }
        pub fn image(&mut self, image: &[u8]) {
            self.record(TAG_IMAGE, image);
        }
        pub fn temperatures(&mut self, now_ms: u32, readings: &[f32]) {
            let mut p = Vec::new();
            p.extend_from_slice(&now_ms.to_le_bytes());
            for r in readings {
                p.extend_from_slice(&r.to_bits().to_le_bytes());
            }
            self.record(TAG_TEMPERATURES, &p);
        }
        /// An edge of the probe input (read by the next cycle).
        pub fn probe_edge(&mut self, time: u32, level: bool, scale_raw: &[u32; MAX_AXES]) {
            let mut p = Vec::with_capacity(PROBE_EDGE_PAYLOAD_LEN);
            p.extend_from_slice(&time.to_le_bytes());
            p.extend_from_slice(&[u8::from(level), 0, 0, 0]);
            for s in scale_raw {
                p.extend_from_slice(&s.to_le_bytes());
            }
            self.record(TAG_PROBE_EDGE, &p);
        }
        pub fn finish(mut self) -> Vec<u8> {
            self.record(TAG_END, &[]);
            self.bytes
        }
    }
}

/// The board a drive-trace replay models (host and QEMU alike): three 16-bit scale inputs wired to axes
/// 1, 2, 3 (the `group3` scenario's X, Y, Z), two temperature sensors — the STM32G474 board's wiring.
pub const REPLAY_CAPS: super::BoardCaps = super::BoardCaps {
    counter_bits: 16,
    axis_ids: &[1, 2, 3],
    sensors: 2,
};

/// The sensor inputs of the board a replay models: the STM32G474 board's two RTDs (°C), named after the
/// sensors of the scenarios' group image (`spindle`, `column`), as a machine's board names them
/// (`board::stm32g474::SENSOR_INPUTS`, `rtd0`, `rtd1` until set).
pub const REPLAY_SENSOR_INPUTS: [axcomp_core::wiring::BoardInput<'static>; 2] = [
    axcomp_core::wiring::BoardInput {
        name: "spindle",
        unit: axcomp_core::wiring::InputUnit::DegC,
    },
    axcomp_core::wiring::BoardInput {
        name: "column",
        unit: axcomp_core::wiring::InputUnit::DegC,
    },
];

/// Cycle-clock rate of a replay (the STM32G474's core clock): 17 000 ticks per 10 kHz cycle.
pub const REPLAY_CLOCK_HZ: u32 = 170_000_000;

/// The drive of a replay: [`REPLAY_CAPS`], 10 kHz, the default link settings (hold 50 cycles, ramp
/// 0.1 µm per cycle), the default lateness tolerance (1 700 ticks).
pub fn replay_drive() -> GroupDrive {
    let cfg = crate::control::LoopSettings::new(REPLAY_CLOCK_HZ)
        .build()
        .expect("10 kHz at 170 MHz is valid");
    GroupDrive::new(
        REPLAY_CAPS,
        &cfg,
        super::LinkSettings::defaults(cfg.rate_hz),
        super::ResetCause::default(),
    )
    .with_sensor_inputs(&REPLAY_SENSOR_INPUTS)
}
