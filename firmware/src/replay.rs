//! Trace replay through the control loop, streaming from a byte source into a fixed buffer.
//!
//! Glossary:
//! - **Byte source** ([`ByteSource`]): where trace bytes come from (a semihosting host file under QEMU, a
//!   slice on the host).
//! - **Stream buffer**: the fixed RAM window the trace is read through; a record must fit in it whole (image
//!   records are the largest). Bytes are shifted down and refilled as records are consumed.
//! - **Output record**: `axcomp_core::trace::OutputRecord`, 32 bytes per cycle record, identical on QEMU and
//!   on the host because both run `Engine::step` on the same records.
//!
//! Error semantics follow `axcomp_core::trace::Reader`: a record with intact framing but bad content is
//! reported and skipped; a truncated record is reported and ends the stream; `End` ends it.

use axcomp_core::trace::{self, OutputRecord, Record, TRACE_HEADER_LEN, TraceError};

use crate::control::{AxisIo, ControlLoop, CycleClock};

// The window's framing is the core trace's.
const _: () = assert!(FRAME_HEADER_LEN == trace::RECORD_HEADER_LEN);

/// Where trace bytes come from.
pub trait ByteSource {
    type Error;
    /// Reads up to `buf.len()` bytes; 0 means end of input.
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error>;
}

impl ByteSource for &[u8] {
    type Error = core::convert::Infallible;
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, Self::Error> {
        let n = buf.len().min(self.len());
        buf[..n].copy_from_slice(&self[..n]);
        *self = &self[n..];
        Ok(n)
    }
}

/// Replay stream error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StreamError<E> {
    /// The byte source failed.
    Source(E),
    /// Header or record error from the core's trace decoder (offsets are absolute in the trace).
    Trace(TraceError),
    /// A record larger than the stream buffer; the stream ends.
    RecordTooLarge {
        offset: u32,
        len: u32,
        capacity: u32,
    },
}

impl<E: core::fmt::Debug> core::fmt::Display for StreamError<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            StreamError::Source(e) => write!(f, "reading the trace failed: {e:?}"),
            StreamError::Trace(e) => write!(f, "{e}"),
            StreamError::RecordTooLarge {
                offset,
                len,
                capacity,
            } => write!(
                f,
                "record at byte {offset} is {len} bytes, larger than the {capacity}-byte replay buffer"
            ),
        }
    }
}

impl<E: core::fmt::Debug> core::error::Error for StreamError<E> {}

/// Why [`RecordWindow::next_frame`] could not return a whole record.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FrameError<E> {
    /// The byte source failed.
    Source(E),
    /// The input ends inside the record (its header or its payload).
    Truncated,
    /// The record (`len` bytes with its header) is larger than the buffer.
    TooLarge { len: usize },
}

/// A fixed RAM window over a [`ByteSource`] for records framed as `tag: u8, payload length: u32
/// (little-endian), payload`: the trace ([`TraceStream`]) and the drive trace
/// (`drive::link_trace::LinkStream`) read through it. Bytes are shifted down and refilled as
/// records are consumed; a record must fit in the buffer whole.
pub struct RecordWindow<'b, S> {
    src: S,
    buf: &'b mut [u8],
    start: usize,
    end: usize,
    eof: bool,
    /// Absolute input offset of `buf[start]`.
    offset: usize,
}

/// Bytes before a record's payload: tag and payload length.
pub const FRAME_HEADER_LEN: usize = 5;

impl<'b, S: ByteSource> RecordWindow<'b, S> {
    pub fn new(src: S, buf: &'b mut [u8]) -> Self {
        RecordWindow {
            src,
            buf,
            start: 0,
            end: 0,
            eof: false,
            offset: 0,
        }
    }

    /// Absolute input offset of the next unread byte.
    pub fn offset(&self) -> usize {
        self.offset
    }

    /// Capacity of the window (the largest record it can hold).
    pub fn capacity(&self) -> usize {
        self.buf.len()
    }

    /// Makes at least `n` bytes available (fewer only at end of input) and returns what is.
    pub fn peek(&mut self, n: usize) -> Result<&[u8], S::Error> {
        if self.end - self.start < n {
            if self.start > 0 {
                self.buf.copy_within(self.start..self.end, 0);
                self.end -= self.start;
                self.start = 0;
            }
            while self.end < n && !self.eof {
                let got = self.src.read(&mut self.buf[self.end..])?;
                if got == 0 {
                    self.eof = true;
                }
                self.end += got;
            }
        }
        Ok(&self.buf[self.start..self.end])
    }

    /// Consumes `n` available bytes (e.g. a file header after [`RecordWindow::peek`]).
    pub fn consume(&mut self, n: usize) {
        let n = n.min(self.end - self.start);
        self.start += n;
        self.offset += n;
    }

    /// The next whole record (header and payload) and its absolute offset; `Ok(None)` at the end
    /// of input.
    #[allow(clippy::type_complexity)]
    pub fn next_frame(&mut self) -> Result<Option<(usize, &[u8])>, FrameError<S::Error>> {
        let at = self.offset;
        let h = self.peek(FRAME_HEADER_LEN).map_err(FrameError::Source)?;
        if h.is_empty() {
            return Ok(None);
        }
        if h.len() < FRAME_HEADER_LEN {
            return Err(FrameError::Truncated);
        }
        let payload = u32::from_le_bytes([h[1], h[2], h[3], h[4]]) as usize;
        let total = FRAME_HEADER_LEN.saturating_add(payload);
        if total > self.buf.len() {
            return Err(FrameError::TooLarge { len: total });
        }
        if self.peek(total).map_err(FrameError::Source)?.len() < total {
            return Err(FrameError::Truncated);
        }
        let s = self.start;
        self.consume(total);
        Ok(Some((at, &self.buf[s..s + total])))
    }
}

/// Reads trace records from a [`ByteSource`] through a fixed buffer.
pub struct TraceStream<'b, S> {
    window: RecordWindow<'b, S>,
    done: bool,
}

impl<'b, S: ByteSource> TraceStream<'b, S> {
    /// Reads and checks the trace header.
    pub fn new(src: S, buf: &'b mut [u8]) -> Result<Self, StreamError<S::Error>> {
        let mut window = RecordWindow::new(src, buf);
        let head = window.peek(TRACE_HEADER_LEN).map_err(StreamError::Source)?;
        let first = trace::check_header(head).map_err(StreamError::Trace)?;
        window.consume(first);
        Ok(TraceStream {
            window,
            done: false,
        })
    }

    /// Absolute trace offset of the next record.
    pub fn offset(&self) -> usize {
        self.window.offset()
    }

    /// The next record, `None` at the end of the trace (end of input or an `End` record).
    pub fn next_record(&mut self) -> Option<Result<Record<'_>, StreamError<S::Error>>> {
        if self.done {
            return None;
        }
        let at32 = self.window.offset().min(u32::MAX as usize) as u32;
        let capacity = self.window.capacity() as u32;
        let (at, frame) = match self.window.next_frame() {
            Ok(Some(f)) => f,
            Ok(None) => {
                self.done = true;
                return None;
            }
            Err(e) => {
                self.done = true;
                return Some(Err(match e {
                    FrameError::Source(e) => StreamError::Source(e),
                    FrameError::Truncated => {
                        StreamError::Trace(TraceError::Truncated { offset: at32 })
                    }
                    FrameError::TooLarge { len } => StreamError::RecordTooLarge {
                        offset: at32,
                        len: len.min(u32::MAX as usize) as u32,
                        capacity,
                    },
                }));
            }
        };
        match trace::decode_record(frame, at) {
            Ok((rec, _)) => {
                if rec == Record::End {
                    self.done = true;
                }
                Some(Ok(rec))
            }
            Err(e) => Some(Err(StreamError::Trace(e))),
        }
    }
}

/// Replay totals.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReplaySummary {
    pub records: u32,
    pub cycles: u32,
    pub outputs: u32,
    /// Records reported as malformed and skipped (or the one that ended the stream).
    pub errors: u32,
}

/// The axis as seen from a trace: each cycle record becomes the board inputs of one cycle.
#[derive(Clone, Copy, Debug)]
pub struct TraceAxis {
    pub input: axcomp_core::CycleInput,
    pub written: i64,
}

impl TraceAxis {
    pub const fn new() -> Self {
        TraceAxis {
            input: axcomp_core::CycleInput {
                scale_raw: 0,
                command_counts: 0,
                forces_n: [0.0; axcomp_core::MAX_FORCES],
            },
            written: 0,
        }
    }
}

impl Default for TraceAxis {
    fn default() -> Self {
        Self::new()
    }
}

impl AxisIo for TraceAxis {
    fn read_scale(&mut self) -> u32 {
        self.input.scale_raw
    }
    fn read_command(&mut self) -> i64 {
        self.input.command_counts
    }
    fn read_forces(&mut self) -> [f32; axcomp_core::MAX_FORCES] {
        self.input.forces_n
    }
    fn write_command(&mut self, counts: i64) {
        self.written = counts;
    }
}

/// Replays a trace through the control loop: cycle records run [`ControlLoop::cycle`] on a [`TraceAxis`];
/// other records are applied between cycles. Every output record is passed to `emit`; every stream error
/// to `on_error` (replay continues after skippable errors).
pub fn replay<S, C>(
    ctl: &mut ControlLoop<'_>,
    stream: &mut TraceStream<'_, S>,
    clock: &C,
    mut emit: impl FnMut(&OutputRecord),
    mut on_error: impl FnMut(&StreamError<S::Error>),
) -> ReplaySummary
where
    S: ByteSource,
    C: CycleClock,
{
    let mut sum = ReplaySummary::default();
    let mut axis = TraceAxis::default();
    while let Some(item) = stream.next_record() {
        sum.records += 1;
        let out = match item {
            Ok(Record::Cycle(input)) => {
                sum.cycles += 1;
                axis.input = input;
                ctl.cycle(&mut axis, clock)
            }
            Ok(rec) => ctl.apply(&rec),
            Err(e) => {
                sum.errors += 1;
                on_error(&e);
                None
            }
        };
        if let Some(o) = out {
            sum.outputs += 1;
            emit(&o);
        }
    }
    sum
}

/// Replays a group trace through a [`axcomp_core::group::GroupEngine`] (no control loop: the
/// group is driven directly): each `GroupCycle` record gives one output record per axis, in slot
/// order, passed to `emit`; every stream error to `on_error` (replay continues after skippable
/// errors). The QEMU group firmware and the host replay both run this, so their outputs are
/// bit-identical.
pub fn replay_group<S, const POOL: usize>(
    engine: &mut axcomp_core::group::GroupEngine<POOL>,
    stream: &mut TraceStream<'_, S>,
    mut emit: impl FnMut(&OutputRecord),
    mut on_error: impl FnMut(&StreamError<S::Error>),
) -> ReplaySummary
where
    S: ByteSource,
{
    let mut sum = ReplaySummary::default();
    let mut out = [OutputRecord::ZERO; axcomp_core::group::MAX_AXES];
    while let Some(item) = stream.next_record() {
        sum.records += 1;
        match item {
            Ok(rec) => {
                if matches!(rec, Record::GroupCycle { .. }) {
                    sum.cycles += 1;
                }
                let n = engine.step(&rec, &mut out);
                for o in out.iter().take(n) {
                    sum.outputs += 1;
                    emit(o);
                }
            }
            Err(e) => {
                sum.errors += 1;
                on_error(&e);
            }
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use crate::control::LoopSettings;
    use crate::control::fake::SteppingClock;
    use axcomp_core::trace::{Temperatures, Writer};
    use axcomp_core::{Engine, bench};
    use std::boxed::Box;
    use std::vec;
    use std::vec::Vec;

    fn reference_trace() -> Vec<u8> {
        let mut image = vec![0u8; bench::reference_image_len()];
        let n = bench::write_reference_image(&mut image).unwrap();
        let mut buf = vec![0u8; 200_000];
        let mut w = Writer::new(&mut buf).unwrap();
        w.push(&Record::Image(&image[..n])).unwrap();
        w.push(&Record::Process(bench::PROCESS)).unwrap();
        for i in 0..2000u32 {
            if i % 100 == 0 {
                let t = Temperatures::new(i / 10, &bench::reference_temperatures(i / 100));
                w.push(&Record::Temperatures(t)).unwrap();
            }
            w.push(&Record::Cycle(bench::reference_input(i))).unwrap();
        }
        // An unknown tag with intact framing: reported and skipped.
        let len = w.finish();
        buf.truncate(len);
        buf.extend_from_slice(&[77, 2, 0, 0, 0, 0xAA, 0xBB]);
        let mut tail = vec![0u8; 64];
        let m =
            trace::encode_record(&Record::Cycle(bench::reference_input(2000)), &mut tail).unwrap();
        buf.extend_from_slice(&tail[..m]);
        buf
    }

    #[test]
    fn streamed_replay_matches_engine_over_reader() {
        // Reference: the core's Reader + Engine over the whole trace in memory (what the host replay does).
        // The streamed replay through a buffer just larger than the image must give the same bytes.
        let trace_bytes = reference_trace();
        let mut want = Vec::new();
        let mut want_errors = 0;
        let mut reference = Box::new(Engine::new());
        for r in trace::Reader::new(&trace_bytes).unwrap() {
            match r {
                Ok(rec) => {
                    if let Some(o) = reference.step(&rec) {
                        want.extend_from_slice(&o.encode());
                    }
                }
                Err(_) => want_errors += 1,
            }
        }
        assert_eq!(want.len(), 2001 * 32);
        assert_eq!(want_errors, 1);

        let mut engine = Box::new(Engine::new());
        let mut ctl =
            ControlLoop::new(&mut engine, LoopSettings::new(100_000_000).build().unwrap());
        let mut buf = vec![0u8; bench::reference_image_len() + 5];
        let mut stream = TraceStream::new(&trace_bytes[..], &mut buf).unwrap();
        let mut got = Vec::new();
        let mut errors = Vec::new();
        let clock = SteppingClock::default();
        let sum = replay(
            &mut ctl,
            &mut stream,
            &clock,
            |o| got.extend_from_slice(&o.encode()),
            |e| errors.push(*e),
        );
        assert_eq!(sum.outputs, 2001);
        assert_eq!(sum.errors, 1);
        assert!(matches!(
            errors[0],
            StreamError::Trace(TraceError::UnknownTag { tag: 77, .. })
        ));
        assert!(
            got == want,
            "streamed replay differs from Engine over Reader"
        );
    }

    #[test]
    fn oversized_and_truncated_records_end_the_stream() {
        let trace_bytes = reference_trace();
        let mut small = vec![0u8; 1024];
        let mut s = TraceStream::new(&trace_bytes[..], &mut small).unwrap();
        match s.next_record() {
            Some(Err(StreamError::RecordTooLarge {
                offset: 8,
                capacity: 1024,
                ..
            })) => {}
            other => panic!("expected RecordTooLarge at byte 8, got {other:?}"),
        }
        assert!(s.next_record().is_none());

        // Cut in the middle of the last cycle record.
        let cut = &trace_bytes[..trace_bytes.len() - 3];
        let mut buf = vec![0u8; 40_000];
        let mut s = TraceStream::new(cut, &mut buf).unwrap();
        let mut last = None;
        while let Some(r) = s.next_record() {
            last = Some(r.map(|_| ()));
        }
        assert!(matches!(
            last,
            Some(Err(StreamError::Trace(TraceError::Truncated { .. })))
        ));

        let mut buf = vec![0u8; 64];
        assert!(matches!(
            TraceStream::new(&b"NOPE\x01\x00\x00\x00"[..], &mut buf),
            Err(StreamError::Trace(TraceError::BadMagic))
        ));
    }
}
