//! The serial setpoint link between the motion controller (CNC) and the compensation drive, version 2.
//!
//! Every cycle the CNC sends one **setpoint frame** with the commanded positions of all axes of the
//! group (1–5), and the drive answers with one **reply frame** with the corrected commands and its
//! **status word** (see [`crate::status`]). A drive corrects its own axes from the group's frame, so the
//! other axes' commands (which the multi-axis correction needs) arrive on the same link in the same cycle.
//!
//! Glossary:
//! - **Command**: a position in scale counts. On the wire only its low 32 bits travel (`i32`, little
//!   endian); the receiver extends them against the previous command of the same axis
//!   ([`extend_command`]), exact while an axis moves less than 2^31 counts between two received frames
//!   (at 1 nm per count that is 2.1 m per frame).
//! - **Sequence**: a `u8` counter the sender increments by one per frame (wrapping). The receiver compares
//!   it with the last accepted one: +1 is in order, 0 is a **repeated** frame (never applied), +k (k ≥ 2) a
//!   frame after k − 1 **lost** frames (applied, the loss counted). A gap of exactly a multiple of 256 frames
//!   aliases; an outage that long (25.6 ms at 10 kHz) is caught by the late-frame supervision anyway.
//! - **Corrupt frame**: a candidate frame (sync byte and a valid header) whose CRC does not match. It is
//!   never applied; the decoder resynchronises on the next sync byte *inside* the rejected bytes, so a
//!   frame that starts within a corrupt one is still found. (A corrupt frame whose payload holds further
//!   sync bytes followed by a valid-looking header may therefore count more than once.)
//! - **Skipped bytes**: bytes outside any candidate frame (line noise, a partial frame after a restart).
//!
//! Layout (all integers little endian; the CRC covers every byte after the sync byte up to the CRC):
//!
//! | frame | bytes | content | length (n axes) |
//! |---|---|---|---|
//! | setpoint (CNC → drive) | `0xA5`, `0x20 \| n`, `seq`, n × `i32` command, `u16` CRC | version 2 in the high nibble, axis count 1–5 in the low nibble | 5 + 4n: 9 (n = 1), 17 (n = 3), 25 (n = 5) |
//! | reply (drive → CNC) | `0x5A`, `0x20 \| n`, `seq`, n × `i32` corrected command, `u32` status, `u8` echo, `u8` counter id, `u16` counter value, `u16` CRC | `seq` = the drive's own reply counter (checked like the setpoints'), `echo` = sequence of the setpoint frame the corrected commands answer; one [`CounterId`] per frame, round robin, low 16 bits (the receiver extends them) | 13 + 4n: 17 (n = 1), 25 (n = 3) |
//!
//! **Version 3: the touch probe**. Versioned and backwards compatible: the high nibble of
//! the second byte is 3 instead of 2, the CRC still covers every byte after the sync byte, and one block
//! is appended before the CRC. A drive decodes setpoint frames of both versions (a v2 frame is a frame
//! whose probe byte is 0: not armed), and sends v3 replies only while its image has probe settings
//! (section kind 4), so a CNC that speaks only v2 keeps working with every image without a probe. The
//! reply decoder takes both versions.
//!
//! | frame | v3 block (before the CRC) | length (n axes) |
//! |---|---|---|
//! | setpoint | `u8` probe command: bit 0 = a probing move is armed (G31 / SKIP); other bits 0 | 6 + 4n: 18 (n = 3) |
//! | reply | `u16` probe flags ([`axcomp_core::probe::ProbeFlags`]: phase, this cycle's events, latch quality), `u8` latch sequence (+1 per latch), `u8` item, `i32` item value | 21 + 4n: 33 (n = 3) |
//!
//! Items, round robin like the counters: `0..n` = the latched point of board input k (nanometres in the
//! corrected coordinates, `i32` saturated: ±2.1 m; a rotary axis's in milli-arc-seconds), `0x10 + e` = the
//! counter of probe event `e` ([`axcomp_core::probe::ProbeEvent`] code: latched, glitch, bounce, unarmed
//! trigger, trigger during a move, edges lost; low 32 bits). With n inputs a full report takes n + 6
//! cycles (0.9 ms for three axes at 10 kHz); the latch sequence tells the CNC which latch the points
//! belong to. A probing three-axis group needs ≥ 3.3 Mbaud at 10 kHz (33 reply bytes per cycle), or a
//! 6 kHz cycle at 2 Mbaud.
//!
//! **Link budget.** At 2 Mbaud, 8N1, a byte takes 5 µs, so a 100 µs cycle carries 20 bytes in each
//! direction: a setpoint frame for up to 3 axes (17 bytes, 85 µs) and a one-axis reply (17 bytes, 85 µs)
//! fit at 10 kHz. A five-axis setpoint frame (25 bytes, 125 µs) or a three-axis reply (25 bytes, 125 µs)
//! needs ≥ 2.5 Mbaud at 10 kHz, or an 8 kHz cycle at 2 Mbaud; the format does not change with the rate. The STM32G474 board runs the link at
//! `LINK_BAUD` (`board::stm32g474`) and, with today's one-axis engine, sends one-axis replies.
//!
//! **Why CRC-16/CCITT-FALSE** (poly 0x1021, init 0xFFFF, no reflection, no final XOR). Frames are at most
//! 25 bytes (200 bits); for data up to 32 751 bits this CRC has Hamming distance 4 (every 1-, 2- and 3-bit
//! error is detected), and since its polynomial has the factor (x + 1) every odd number of bit errors
//! and every burst up to 16 bits is detected; a random frame passes with probability 2^−16. A CRC-32
//! (Hamming distance 6 at this length) would add 2 bytes per frame = 10 µs at 2 Mbaud, 10 % of the cycle in
//! each direction, which the link budget above does not have. The UART's own start/stop-bit framing
//! errors come on top. The table-driven CRC takes two bytes per step (two lookups in 1 KiB of tables).

/// First byte of a setpoint frame (CNC → drive).
pub const SETPOINT_SYNC: u8 = 0xA5;
/// First byte of a reply frame (drive → CNC); differs from [`SETPOINT_SYNC`] so a looped-back line is
/// never mistaken for setpoints.
pub const REPLY_SYNC: u8 = 0x5A;
/// Frame format version (high nibble of the second byte).
pub const VERSION: u8 = 2;
/// Frame format version with the touch-probe block (see the module doc).
pub const VERSION_PROBE: u8 = 3;
/// Probe block of a v3 setpoint frame: the probe command byte.
pub const SETPOINT_PROBE_LEN: usize = 1;
/// Probe block of a v3 reply frame: flags, latch sequence, item, value.
pub const REPLY_PROBE_LEN: usize = 2 + 1 + 1 + 4;
/// Probe command bit: a probing move is armed.
pub const PROBE_ARM: u8 = 1;
/// First reply probe item carrying a counter (item `PROBE_ITEM_COUNTER + event code`).
pub const PROBE_ITEM_COUNTER: u8 = 0x10;
/// Most axes a frame carries.
pub const MAX_AXES: usize = 5;
/// Sync, version/axis count, sequence.
pub const HEADER_LEN: usize = 3;
/// CRC-16 at the end of every frame.
pub const CRC_LEN: usize = 2;
/// Status word, echoed setpoint sequence, counter id and counter value of a reply frame.
pub const REPLY_TAIL_LEN: usize = 4 + 1 + 1 + 2;

/// Bytes of a setpoint frame for `n_axes` axes.
pub const fn setpoint_frame_len(n_axes: usize) -> usize {
    HEADER_LEN + 4 * n_axes + CRC_LEN
}

/// Bytes of a reply frame for `n_axes` axes.
pub const fn reply_frame_len(n_axes: usize) -> usize {
    HEADER_LEN + 4 * n_axes + REPLY_TAIL_LEN + CRC_LEN
}

/// Bytes of a v3 (probe) setpoint frame for `n_axes` axes.
pub const fn setpoint_probe_frame_len(n_axes: usize) -> usize {
    setpoint_frame_len(n_axes) + SETPOINT_PROBE_LEN
}

/// Bytes of a v3 (probe) reply frame for `n_axes` axes.
pub const fn reply_probe_frame_len(n_axes: usize) -> usize {
    reply_frame_len(n_axes) + REPLY_PROBE_LEN
}

/// Longest setpoint frame (5 axes, v3).
pub const MAX_SETPOINT_FRAME_LEN: usize = setpoint_probe_frame_len(MAX_AXES);
/// Longest reply frame (5 axes, v3).
pub const MAX_REPLY_FRAME_LEN: usize = reply_probe_frame_len(MAX_AXES);
/// Longest v2 reply frame (5 axes, no probe block).
pub const MAX_REPLY_V2_FRAME_LEN: usize = reply_frame_len(MAX_AXES);

/// CRC-16/CCITT-FALSE tables, two bytes at a time ("slice by 2"): `CRC_TABLES[0][v]` is the CRC
/// contribution of byte value `v` in the register's high byte, `CRC_TABLES[1][v]` the same followed by
/// one more (zero) byte. 1 KiB of flash.
const CRC_TABLES: [[u16; 256]; 2] = {
    let mut t = [[0u16; 256]; 2];
    let mut i = 0;
    while i < 256 {
        let mut c = (i as u16) << 8;
        let mut k = 0;
        while k < 8 {
            c = if c & 0x8000 != 0 {
                (c << 1) ^ 0x1021
            } else {
                c << 1
            };
            k += 1;
        }
        t[0][i] = c;
        i += 1;
    }
    let mut i = 0;
    while i < 256 {
        let c = t[0][i];
        t[1][i] = (c << 8) ^ t[0][(c >> 8) as usize];
        i += 1;
    }
    t
};

/// CRC-16/CCITT-FALSE of `bytes` (check value of `b"123456789"`: 0x29B1): two bytes per step, the
/// register's high byte with the first and its low byte with the second looked up at once (by
/// linearity the same as byte by byte), an odd last byte alone.
#[inline(never)]
pub fn crc16(bytes: &[u8]) -> u16 {
    let [t0, t1] = &CRC_TABLES;
    let mut pairs = bytes.chunks_exact(2);
    let mut crc = 0xFFFFu16;
    for p in &mut pairs {
        let x = crc ^ u16::from_be_bytes([p[0], p[1]]);
        crc = t1[usize::from(x >> 8)] ^ t0[usize::from(x & 0xFF)];
    }
    if let Some(&b) = pairs.remainder().first() {
        crc = (crc << 8) ^ t0[usize::from((crc >> 8) as u8 ^ b)];
    }
    crc
}

/// Extends a command's low 32 bits (as sent) against the previous full command of that axis.
pub fn extend_command(previous: i64, low: i32) -> i64 {
    previous.wrapping_add(i64::from(low.wrapping_sub(previous as i32)))
}

/// Invalid frame contents given to an encoder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// Axis count outside 1..=[`MAX_AXES`].
    AxisCount(usize),
}

impl core::fmt::Display for FrameError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            FrameError::AxisCount(n) => write!(f, "axis count {n} outside 1..={MAX_AXES}"),
        }
    }
}

impl core::error::Error for FrameError {}

/// One setpoint frame: the group's commands (low 32 bits) of one cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SetpointFrame {
    pub seq: u8,
    n_axes: u8,
    commands: [i32; MAX_AXES],
    /// The probe command byte of a v3 frame (`None`: a v2 frame).
    pub probe: Option<u8>,
}

impl SetpointFrame {
    /// A frame for `commands.len()` axes (1..=5).
    pub fn new(seq: u8, commands: &[i32]) -> Result<Self, FrameError> {
        if commands.is_empty() || commands.len() > MAX_AXES {
            return Err(FrameError::AxisCount(commands.len()));
        }
        let mut c = [0; MAX_AXES];
        c[..commands.len()].copy_from_slice(commands);
        Ok(SetpointFrame {
            seq,
            n_axes: commands.len() as u8,
            commands: c,
            probe: None,
        })
    }

    /// The same frame as v3 with the probe command byte `probe` (bit 0 [`PROBE_ARM`]).
    pub fn with_probe(mut self, probe: u8) -> Self {
        self.probe = Some(probe);
        self
    }

    /// True if the frame arms a probing move.
    pub fn probe_armed(&self) -> bool {
        self.probe.is_some_and(|p| p & PROBE_ARM != 0)
    }

    /// Commands (low 32 bits), one per axis in group order.
    pub fn commands(&self) -> &[i32] {
        &self.commands[..usize::from(self.n_axes)]
    }

    pub fn n_axes(&self) -> usize {
        usize::from(self.n_axes)
    }

    /// Writes the frame into `out` (at least [`MAX_SETPOINT_FRAME_LEN`] bytes); returns its length.
    pub fn encode_into(&self, out: &mut [u8; MAX_SETPOINT_FRAME_LEN]) -> usize {
        let n = self.n_axes();
        out[0] = SETPOINT_SYNC;
        let version = if self.probe.is_some() {
            VERSION_PROBE
        } else {
            VERSION
        };
        out[1] = (version << 4) | self.n_axes;
        out[2] = self.seq;
        for (i, c) in self.commands().iter().enumerate() {
            out[HEADER_LEN + 4 * i..HEADER_LEN + 4 * i + 4].copy_from_slice(&c.to_le_bytes());
        }
        let mut body = HEADER_LEN + 4 * n;
        if let Some(p) = self.probe {
            out[body] = p;
            body += SETPOINT_PROBE_LEN;
        }
        let crc = crc16(&out[1..body]);
        out[body..body + CRC_LEN].copy_from_slice(&crc.to_le_bytes());
        body + CRC_LEN
    }

    /// The frame in `bytes` (a checked frame: header, length and CRC valid).
    #[inline(never)]
    fn decode(bytes: &[u8]) -> SetpointFrame {
        let head = bytes.get(1).copied().unwrap_or(0);
        let n = usize::from(head & 0x0F).min(MAX_AXES);
        let mut commands = [0; MAX_AXES];
        let (body, tail) = bytes
            .get(HEADER_LEN..)
            .unwrap_or(&[])
            .split_at_checked(4 * n)
            .unwrap_or((&[], &[]));
        // One 4-byte load per command, every slot's test unrolled (a loop over the commands would
        // become a library `memcpy` call: dozens of instructions for a few bytes).
        for (i, c) in commands.iter_mut().enumerate() {
            if let Some(b) = body.get(4 * i..4 * i + 4) {
                *c = i32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            }
        }
        let probe = if head >> 4 == VERSION_PROBE {
            tail.first().copied()
        } else {
            None
        };
        SetpointFrame {
            seq: bytes.get(2).copied().unwrap_or(0),
            n_axes: n as u8,
            commands,
            probe,
        }
    }
}

/// Status-word counters carried one per reply frame, round robin (low 16 bits; see [`crate::status`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u8)]
pub enum CounterId {
    Cycles = 0,
    FramesApplied = 1,
    FramesCorrupt = 2,
    FramesLost = 3,
    FramesRepeated = 4,
    CyclesWithoutFrame = 5,
    LateCycles = 6,
    Overruns = 7,
    ImagesRefused = 8,
    SensorRejected = 9,
    MaxLatenessTicks = 10,
    SkippedBytes = 11,
}

impl CounterId {
    /// Every counter, in the round-robin order.
    pub const ALL: [CounterId; 12] = [
        CounterId::Cycles,
        CounterId::FramesApplied,
        CounterId::FramesCorrupt,
        CounterId::FramesLost,
        CounterId::FramesRepeated,
        CounterId::CyclesWithoutFrame,
        CounterId::LateCycles,
        CounterId::Overruns,
        CounterId::ImagesRefused,
        CounterId::SensorRejected,
        CounterId::MaxLatenessTicks,
        CounterId::SkippedBytes,
    ];

    pub fn from_u8(v: u8) -> Option<CounterId> {
        Self::ALL.get(usize::from(v)).copied()
    }
}

/// The probe block of a v3 reply frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ProbeReply {
    /// [`axcomp_core::probe::ProbeFlags`] bits of this cycle.
    pub flags: u16,
    /// Latches since start (wrapping).
    pub latch_seq: u8,
    /// What `value` is: `0..n` the latched point of board input k (nm), `0x10 + e` the counter of
    /// probe event `e`.
    pub item: u8,
    /// The item's value.
    pub value: i32,
}

/// One reply frame: the corrected commands (low 32 bits), the status word and one counter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ReplyFrame {
    /// The drive's reply counter (+1 per reply, wrapping).
    pub seq: u8,
    /// Sequence of the setpoint frame these corrected commands answer.
    pub echo: u8,
    n_axes: u8,
    corrected: [i32; MAX_AXES],
    /// Status word ([`crate::status::Status`] bits).
    pub status: u32,
    /// Which counter `counter_value` is (an unknown id decodes as `None`).
    pub counter_id: Option<CounterId>,
    /// Low 16 bits of that counter.
    pub counter_value: u16,
    /// The probe block (a v3 frame), `None` for a v2 frame.
    pub probe: Option<ProbeReply>,
}

impl ReplyFrame {
    pub fn new(
        seq: u8,
        echo: u8,
        corrected: &[i32],
        status: u32,
        counter_id: CounterId,
        counter_value: u16,
    ) -> Result<Self, FrameError> {
        if corrected.is_empty() || corrected.len() > MAX_AXES {
            return Err(FrameError::AxisCount(corrected.len()));
        }
        let mut c = [0; MAX_AXES];
        // An element loop, not `copy_from_slice`: no library call for a few words.
        for (d, &v) in c.iter_mut().zip(corrected) {
            *d = v;
        }
        Ok(ReplyFrame {
            seq,
            echo,
            n_axes: corrected.len() as u8,
            corrected: c,
            status,
            counter_id: Some(counter_id),
            counter_value,
            probe: None,
        })
    }

    /// The same frame as v3 with the probe block `probe`.
    pub fn with_probe(mut self, probe: ProbeReply) -> Self {
        self.probe = Some(probe);
        self
    }

    pub fn corrected(&self) -> &[i32] {
        &self.corrected[..usize::from(self.n_axes)]
    }

    pub fn n_axes(&self) -> usize {
        usize::from(self.n_axes)
    }

    /// Writes the frame into `out`; returns its length.
    pub fn encode_into(&self, out: &mut [u8; MAX_REPLY_FRAME_LEN]) -> usize {
        let fields = ReplyFields {
            seq: self.seq,
            echo: self.echo,
            status: self.status,
            counter_id: self.counter_id.map_or(0xFF, |c| c as u8),
            counter_value: self.counter_value,
        };
        encode_reply(out, &fields, self.corrected(), self.probe.as_ref())
    }

    fn decode(bytes: &[u8]) -> ReplyFrame {
        let n = usize::from(bytes[1] & 0x0F);
        let mut corrected = [0; MAX_AXES];
        for (i, c) in corrected.iter_mut().enumerate().take(n) {
            *c = i32_at(bytes, HEADER_LEN + 4 * i);
        }
        let t = HEADER_LEN + 4 * n;
        let p = t + REPLY_TAIL_LEN;
        let probe = (bytes[1] >> 4 == VERSION_PROBE).then(|| ProbeReply {
            flags: u16::from_le_bytes([bytes[p], bytes[p + 1]]),
            latch_seq: bytes[p + 2],
            item: bytes[p + 3],
            value: i32_at(bytes, p + 4),
        });
        ReplyFrame {
            seq: bytes[2],
            n_axes: n as u8,
            corrected,
            status: u32::from_le_bytes([bytes[t], bytes[t + 1], bytes[t + 2], bytes[t + 3]]),
            echo: bytes[t + 4],
            counter_id: CounterId::from_u8(bytes[t + 5]),
            counter_value: u16::from_le_bytes([bytes[t + 6], bytes[t + 7]]),
            probe,
        }
    }
}

/// The fields of a reply frame besides its corrected commands and probe block (see [`ReplyFrame`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ReplyFields {
    pub seq: u8,
    pub echo: u8,
    pub status: u32,
    /// The [`CounterId`] code (0xFF: none).
    pub counter_id: u8,
    pub counter_value: u16,
}

/// Writes a reply frame with `corrected.len()` corrected commands (1..=[`MAX_AXES`]) and, if given,
/// the probe block (a v3 frame) into `out`; returns its length, 0 (nothing written) for an axis count
/// outside 1..=[`MAX_AXES`]. The one encoder of the reply layout ([`ReplyFrame::encode_into`], the
/// drive's cycle): the frame is written where it is sent from, without a [`ReplyFrame`] in between.
pub fn encode_reply(
    out: &mut [u8; MAX_REPLY_FRAME_LEN],
    fields: &ReplyFields,
    corrected: &[i32],
    probe: Option<&ProbeReply>,
) -> usize {
    let n = corrected.len();
    if n == 0 || n > MAX_AXES {
        return 0;
    }
    out[0] = REPLY_SYNC;
    let version = if probe.is_some() {
        VERSION_PROBE
    } else {
        VERSION
    };
    out[1] = (version << 4) | n as u8;
    out[2] = fields.seq;
    // One 4-byte store per command, every slot's test unrolled (a loop over `corrected` would
    // become a library `memcpy` call: dozens of instructions for a few bytes).
    for i in 0..MAX_AXES {
        if let Some(c) = corrected.get(i) {
            out[HEADER_LEN + 4 * i..HEADER_LEN + 4 * i + 4].copy_from_slice(&c.to_le_bytes());
        }
    }
    let t = HEADER_LEN + 4 * n;
    let tail = &mut out[t..t + REPLY_TAIL_LEN];
    tail[..4].copy_from_slice(&fields.status.to_le_bytes());
    tail[4] = fields.echo;
    tail[5] = fields.counter_id;
    tail[6..].copy_from_slice(&fields.counter_value.to_le_bytes());
    let mut body = t + REPLY_TAIL_LEN;
    if let Some(p) = probe {
        let block = &mut out[body..body + REPLY_PROBE_LEN];
        block[..2].copy_from_slice(&p.flags.to_le_bytes());
        block[2] = p.latch_seq;
        block[3] = p.item;
        block[4..].copy_from_slice(&p.value.to_le_bytes());
        body += REPLY_PROBE_LEN;
    }
    let crc = crc16(&out[1..body]);
    out[body..body + CRC_LEN].copy_from_slice(&crc.to_le_bytes());
    body + CRC_LEN
}

fn i32_at(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

/// Link counters of a decoder (wrapping `u32`s, since construction).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkCounters {
    /// Frames returned to the caller (in order or after a gap).
    pub frames_ok: u32,
    /// Candidate frames rejected for a CRC mismatch.
    pub corrupt: u32,
    /// Frames missing according to the sequence counter.
    pub lost: u32,
    /// Frames with the sequence of the last accepted frame (dropped, never returned).
    pub repeated: u32,
    /// Bytes outside any candidate frame.
    pub skipped_bytes: u32,
}

/// What happened on the link since the last [`FrameDecoder::take_events`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LinkEvents {
    pub corrupt: bool,
    pub lost: bool,
    pub repeated: bool,
}

/// Which frame a [`FrameDecoder`] reads.
pub trait FrameKind {
    type Frame: Copy;
    const SYNC: u8;
    /// Bytes after the commands and before the CRC of a frame of `version` (2 or 3).
    fn tail_len(version: u8) -> usize;
    fn seq(frame: &Self::Frame) -> u8;
    fn decode(bytes: &[u8]) -> Self::Frame;
}

/// Setpoint frames (drive side).
#[derive(Clone, Copy, Debug, Default)]
pub struct Setpoints;
/// Reply frames (CNC side, host tools, tests).
#[derive(Clone, Copy, Debug, Default)]
pub struct Replies;

impl FrameKind for Setpoints {
    type Frame = SetpointFrame;
    const SYNC: u8 = SETPOINT_SYNC;
    fn tail_len(version: u8) -> usize {
        if version == VERSION_PROBE {
            SETPOINT_PROBE_LEN
        } else {
            0
        }
    }
    fn seq(f: &SetpointFrame) -> u8 {
        f.seq
    }
    fn decode(bytes: &[u8]) -> SetpointFrame {
        SetpointFrame::decode(bytes)
    }
}

impl FrameKind for Replies {
    type Frame = ReplyFrame;
    const SYNC: u8 = REPLY_SYNC;
    fn tail_len(version: u8) -> usize {
        if version == VERSION_PROBE {
            REPLY_TAIL_LEN + REPLY_PROBE_LEN
        } else {
            REPLY_TAIL_LEN
        }
    }
    fn seq(f: &ReplyFrame) -> u8 {
        f.seq
    }
    fn decode(bytes: &[u8]) -> ReplyFrame {
        ReplyFrame::decode(bytes)
    }
}

/// Byte-at-a-time resynchronising decoder with sequence checking.
#[derive(Clone, Debug)]
pub struct FrameDecoder<K: FrameKind, const N: usize> {
    /// The candidate frame being collected (`N`: the longest frame of the kind).
    buf: [u8; N],
    len: usize,
    /// Length of the candidate frame in `buf` once its header was checked (0: not yet).
    need: usize,
    last_seq: Option<u8>,
    counters: LinkCounters,
    events: LinkEvents,
    kind: core::marker::PhantomData<K>,
}

/// The drive's decoder of setpoint frames.
pub type SetpointDecoder = FrameDecoder<Setpoints, MAX_SETPOINT_FRAME_LEN>;
/// The CNC's (or a test's) decoder of reply frames.
pub type ReplyDecoder = FrameDecoder<Replies, MAX_REPLY_FRAME_LEN>;

enum Parse {
    NeedMore,
    /// Drop `n` leading bytes and look again (`corrupt`: a CRC mismatch).
    Drop {
        corrupt: bool,
    },
    Frame(usize),
}

impl<K: FrameKind, const N: usize> Default for FrameDecoder<K, N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<K: FrameKind, const N: usize> FrameDecoder<K, N> {
    pub const fn new() -> Self {
        FrameDecoder {
            buf: [0; N],
            len: 0,
            need: 0,
            last_seq: None,
            counters: LinkCounters {
                frames_ok: 0,
                corrupt: 0,
                lost: 0,
                repeated: 0,
                skipped_bytes: 0,
            },
            events: LinkEvents {
                corrupt: false,
                lost: false,
                repeated: false,
            },
            kind: core::marker::PhantomData,
        }
    }

    pub fn counters(&self) -> &LinkCounters {
        &self.counters
    }

    /// Events since the previous call (then cleared).
    pub fn take_events(&mut self) -> LinkEvents {
        core::mem::take(&mut self.events)
    }

    /// Forget the last sequence (e.g. after the sender restarted on purpose): the next frame is in order.
    pub fn reset_sequence(&mut self) {
        self.last_seq = None;
    }

    fn parse(&self) -> Parse {
        Self::parse_bytes(&self.buf[..self.len])
    }

    /// What the candidate frame at the start of `b` is: incomplete, to be dropped, or a valid frame
    /// of the returned length (the bytes after it are not looked at).
    #[inline(always)]
    fn parse_bytes(b: &[u8]) -> Parse {
        let (&sync, rest) = match b.split_first() {
            Some(x) => x,
            None => return Parse::NeedMore,
        };
        if sync != K::SYNC {
            return Parse::Drop { corrupt: false };
        }
        let Some(&head) = rest.first() else {
            return Parse::NeedMore;
        };
        let n = usize::from(head & 0x0F);
        let version = head >> 4;
        if (version != VERSION && version != VERSION_PROBE) || n == 0 || n > MAX_AXES {
            return Parse::Drop { corrupt: false };
        }
        let body = HEADER_LEN + 4 * n + K::tail_len(version);
        let flen = body + CRC_LEN;
        let Some(frame) = b.get(..flen) else {
            return Parse::NeedMore;
        };
        let crc = u16::from_le_bytes([frame[body], frame[body + 1]]);
        if crc16(&frame[1..body]) != crc {
            return Parse::Drop { corrupt: true };
        }
        Parse::Frame(flen)
    }

    /// The sequence check of a valid frame with sequence `seq` (byte 2 of every frame): false for a
    /// repeat (counted, never returned), else true (a gap counted as lost frames).
    #[inline(always)]
    fn accept(&mut self, seq: u8) -> bool {
        if let Some(last) = self.last_seq {
            let step = seq.wrapping_sub(last);
            if step == 0 {
                self.counters.repeated = self.counters.repeated.wrapping_add(1);
                self.events.repeated = true;
                return false;
            }
            if step > 1 {
                self.counters.lost = self.counters.lost.wrapping_add(u32::from(step - 1));
                self.events.lost = true;
            }
        }
        self.last_seq = Some(seq);
        self.counters.frames_ok = self.counters.frames_ok.wrapping_add(1);
        true
    }

    /// Feeds every byte of `bytes`; returns the newest valid, not repeated frame they complete.
    pub fn push_bytes(&mut self, bytes: &[u8]) -> Option<K::Frame> {
        let mut newest = None;
        self.push_bytes_into(bytes, &mut newest);
        newest
    }

    /// [`FrameDecoder::push_bytes`] into `newest`: each valid, not repeated frame the bytes complete
    /// is decoded into it (the last one stays); untouched when they complete none.
    pub fn push_bytes_into(&mut self, bytes: &[u8], newest: &mut Option<K::Frame>) {
        let mut rest = bytes;
        // Nothing pending and a whole valid frame at the start of the bytes (the common case: one
        // frame per cycle): checked and decoded where it lies, not collected into `buf` first. Byte
        // by byte the same frame would be collected, checked and returned with the same counters,
        // leaving the decoder empty again (`len` and `need` 0), as here.
        while self.len == 0 {
            let Parse::Frame(flen) = Self::parse_bytes(rest) else {
                break;
            };
            let (frame, after) = rest.split_at(flen);
            if self.accept(frame[2]) {
                *newest = Some(K::decode(frame));
            }
            rest = after;
        }
        while let Some((&b, after)) = rest.split_first() {
            // `push`'s fast path for a run of bytes at once: inside a candidate frame whose header
            // was checked, collect every byte before the frame's last one in one copy (the same
            // bytes, the same state as byte by byte).
            let run = self
                .need
                .saturating_sub(1)
                .saturating_sub(self.len)
                .min(rest.len());
            if let (true, Some(dst)) = (run > 0, self.buf.get_mut(self.len..self.len + run)) {
                if run >= 8 {
                    dst.copy_from_slice(&rest[..run]);
                } else {
                    // A few bytes: cheaper than a library call.
                    for (d, &v) in dst.iter_mut().zip(rest) {
                        *d = v;
                    }
                }
                self.len += run;
                rest = &rest[run..];
                continue;
            }
            if let Some(f) = self.push(b) {
                *newest = Some(f);
            }
            rest = after;
        }
    }

    /// Feeds one byte; returns a frame when the byte completes a valid, not repeated one.
    #[inline]
    pub fn push(&mut self, byte: u8) -> Option<K::Frame> {
        // Fast path: inside a candidate frame whose header was checked, just collect.
        if self.len < self.need.saturating_sub(1) {
            self.buf[self.len] = byte;
            self.len += 1;
            return None;
        }
        self.push_slow(byte)
    }

    fn push_slow(&mut self, byte: u8) -> Option<K::Frame> {
        if self.len >= self.buf.len() {
            // Unreachable (a candidate never outgrows the longest frame); start over rather than panic.
            self.len = 0;
            self.need = 0;
        }
        self.buf[self.len] = byte;
        self.len += 1;
        loop {
            self.need = 0;
            match self.parse() {
                Parse::NeedMore => {
                    if self.len >= 2 {
                        self.need = HEADER_LEN
                            + 4 * usize::from(self.buf[1] & 0x0F)
                            + K::tail_len(self.buf[1] >> 4)
                            + CRC_LEN;
                    }
                    return None;
                }
                Parse::Drop { corrupt } => {
                    if corrupt {
                        self.counters.corrupt = self.counters.corrupt.wrapping_add(1);
                        self.events.corrupt = true;
                    } else {
                        self.counters.skipped_bytes = self.counters.skipped_bytes.wrapping_add(1);
                    }
                    // Resynchronise: continue at the next sync byte after the first one (skipping
                    // the bytes before it), so a frame starting inside the dropped bytes is found.
                    let next = self.buf[1..self.len]
                        .iter()
                        .position(|&b| b == K::SYNC)
                        .map_or(self.len, |p| p + 1);
                    if corrupt {
                        // The sync byte of the corrupt frame is accounted for by `corrupt`; the bytes
                        // up to the next sync are part of it, not skipped noise.
                    } else {
                        self.counters.skipped_bytes = self
                            .counters
                            .skipped_bytes
                            .wrapping_add(next.saturating_sub(1) as u32);
                    }
                    self.buf.copy_within(next..self.len, 0);
                    self.len -= next;
                }
                Parse::Frame(flen) => {
                    let fresh = self.accept(self.buf[2]);
                    let frame = fresh.then(|| K::decode(&self.buf[..flen]));
                    self.buf.copy_within(flen..self.len, 0);
                    self.len -= flen;
                    if frame.is_some() {
                        return frame;
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
