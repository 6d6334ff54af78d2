//! Setpoint frames on the serial link between the motion controller and the compensation firmware.
//!
//! Glossary:
//! - **Setpoint**: a position command in scale counts (`i64`).
//! - **Frame**: `SYNC (0xA5)`, the setpoint as 8 bytes little endian, then a checksum byte
//!   (XOR of the 8 payload bytes with 0x5A). 10 bytes; at 2 Mbaud (8N1) one frame takes 50 µs, so a frame
//!   per 100 µs cycle in each direction fits.
//! - **Decoder**: byte-at-a-time state machine that resynchronises on the next SYNC after a bad checksum.

/// First byte of every frame.
pub const SYNC: u8 = 0xA5;
/// Bytes per frame.
pub const FRAME_LEN: usize = 10;

fn checksum(payload: &[u8]) -> u8 {
    payload.iter().fold(0x5A, |acc, b| acc ^ b)
}

/// Encodes one setpoint frame.
pub fn encode(counts: i64) -> [u8; FRAME_LEN] {
    let mut f = [0u8; FRAME_LEN];
    f[0] = SYNC;
    f[1..9].copy_from_slice(&counts.to_le_bytes());
    f[9] = checksum(&f[1..9]);
    f
}

/// Byte-wise frame decoder.
#[derive(Clone, Debug, Default)]
pub struct Decoder {
    buf: [u8; FRAME_LEN],
    len: usize,
    /// Frames dropped for a bad checksum since construction.
    pub bad_frames: u32,
}

impl Decoder {
    pub const fn new() -> Self {
        Decoder {
            buf: [0; FRAME_LEN],
            len: 0,
            bad_frames: 0,
        }
    }

    /// Feeds one byte; returns a setpoint when it completes a valid frame.
    pub fn push(&mut self, byte: u8) -> Option<i64> {
        if self.len == 0 && byte != SYNC {
            return None;
        }
        self.buf[self.len] = byte;
        self.len += 1;
        if self.len < FRAME_LEN {
            return None;
        }
        self.len = 0;
        if checksum(&self.buf[1..9]) != self.buf[9] {
            self.bad_frames = self.bad_frames.wrapping_add(1);
            // Resynchronise: restart at the next SYNC inside the rejected frame, if any.
            if let Some(p) = self.buf[1..].iter().position(|&b| b == SYNC) {
                let rest = self.buf;
                let start = p + 1;
                for &b in &rest[start..] {
                    if let Some(v) = self.push(b) {
                        return Some(v);
                    }
                }
            }
            return None;
        }
        let mut p = [0u8; 8];
        p.copy_from_slice(&self.buf[1..9]);
        Some(i64::from_le_bytes(p))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn roundtrip_and_noise() {
        let mut d = Decoder::new();
        let mut got = [None; 3];
        let mut n = 0;
        let mut stream = [0u8; 3 * FRAME_LEN + 3];
        stream[0] = 0x00; // noise before the first frame
        stream[1] = 0x13;
        stream[2..12].copy_from_slice(&encode(-123_456_789_012));
        stream[12..22].copy_from_slice(&encode(0));
        stream[22..32].copy_from_slice(&encode(i64::MAX));
        stream[32] = 0xFF;
        for &b in &stream {
            if let Some(v) = d.push(b) {
                got[n] = Some(v);
                n += 1;
            }
        }
        assert_eq!(got, [Some(-123_456_789_012), Some(0), Some(i64::MAX)]);
        assert_eq!(d.bad_frames, 0);
    }

    #[test]
    fn bad_checksum_is_dropped_and_resyncs() {
        let mut d = Decoder::new();
        let mut bad = encode(42);
        bad[9] ^= 1;
        for &b in &bad {
            assert_eq!(d.push(b), None);
        }
        assert_eq!(d.bad_frames, 1);
        let good = encode(7);
        let mut out = None;
        for &b in &good {
            out = out.or(d.push(b));
        }
        assert_eq!(out, Some(7));
    }
}
