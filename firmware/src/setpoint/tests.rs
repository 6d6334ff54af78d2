extern crate std;
use super::*;
use std::vec::Vec;

fn setpoint_bytes(seq: u8, cmds: &[i32]) -> Vec<u8> {
    let mut b = [0u8; MAX_SETPOINT_FRAME_LEN];
    let n = SetpointFrame::new(seq, cmds).unwrap().encode_into(&mut b);
    b[..n].to_vec()
}

fn feed(d: &mut SetpointDecoder, bytes: &[u8]) -> Vec<SetpointFrame> {
    bytes.iter().filter_map(|&b| d.push(b)).collect()
}

#[test]
fn crc16_check_value() {
    // Reference: the CRC catalogue's check value of CRC-16/CCITT-FALSE for "123456789".
    assert_eq!(crc16(b"123456789"), 0x29B1);
}

/// Reference: the bitwise definition of CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, MSB
/// first, no final XOR); tolerance: exact, for every length 0..=48 (even and odd) of
/// pseudo-random bytes.
#[test]
fn crc16_two_bytes_per_step_equals_the_bitwise_definition() {
    fn bitwise(bytes: &[u8]) -> u16 {
        let mut crc = 0xFFFFu16;
        for &b in bytes {
            crc ^= u16::from(b) << 8;
            for _ in 0..8 {
                crc = if crc & 0x8000 != 0 {
                    (crc << 1) ^ 0x1021
                } else {
                    crc << 1
                };
            }
        }
        crc
    }
    let mut x = 0x9E37_79B9u32;
    let bytes: Vec<u8> = (0..48)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x as u8
        })
        .collect();
    for len in 0..=bytes.len() {
        assert_eq!(crc16(&bytes[..len]), bitwise(&bytes[..len]), "length {len}");
    }
    assert_eq!(bitwise(b"123456789"), 0x29B1);
}

#[test]
fn frame_lengths_match_the_link_budget() {
    assert_eq!(setpoint_frame_len(1), 9);
    assert_eq!(setpoint_frame_len(3), 17);
    assert_eq!(setpoint_frame_len(5), 25);
    assert_eq!(reply_frame_len(1), 17);
    assert_eq!(reply_frame_len(3), 25);
    assert_eq!(setpoint_bytes(0, &[1, 2, 3]).len(), 17);
}

#[test]
fn setpoint_roundtrip_every_axis_count() {
    let mut d = SetpointDecoder::new();
    let cmds = [-123_456_789, 0, i32::MAX, i32::MIN, 42];
    for n in 1..=MAX_AXES {
        let got = feed(&mut d, &setpoint_bytes(n as u8, &cmds[..n]));
        assert_eq!(got.len(), 1, "n = {n}");
        assert_eq!(got[0].commands(), &cmds[..n]);
        assert_eq!(got[0].seq, n as u8);
    }
    assert_eq!(d.counters().frames_ok, 5);
    assert_eq!(
        *d.counters(),
        LinkCounters {
            frames_ok: 5,
            ..LinkCounters::default()
        }
    );
    assert_eq!(
        SetpointFrame::new(0, &[]).unwrap_err(),
        FrameError::AxisCount(0)
    );
    assert_eq!(
        SetpointFrame::new(0, &[0; 6]).unwrap_err(),
        FrameError::AxisCount(6)
    );
}

#[test]
fn reply_roundtrip() {
    let f = ReplyFrame::new(
        7,
        200,
        &[1, -2, 300_000],
        0x8000_0421,
        CounterId::FramesLost,
        65_535,
    )
    .unwrap();
    let mut b = [0u8; MAX_REPLY_FRAME_LEN];
    let n = f.encode_into(&mut b);
    assert_eq!(n, reply_frame_len(3));
    let mut d = ReplyDecoder::new();
    let got: Vec<_> = b[..n].iter().filter_map(|&x| d.push(x)).collect();
    assert_eq!(got, [f]);
    // A setpoint decoder never takes a reply (different sync byte): all bytes skipped.
    let mut s = SetpointDecoder::new();
    assert!(feed(&mut s, &b[..n]).is_empty());
    assert_eq!(s.counters().frames_ok, 0);
}

/// Version 3 (probe block): both decoders take v2 and v3 frames; a v2 frame's probe command is
/// absent (not armed); every single-bit flip of a v3 frame is detected like a v2 frame's.
#[test]
fn probe_frames_v3_roundtrip_beside_v2() {
    let mut d = SetpointDecoder::new();
    let mut b = [0u8; MAX_SETPOINT_FRAME_LEN];
    let v3 = SetpointFrame::new(1, &[10, -20, 30])
        .unwrap()
        .with_probe(PROBE_ARM);
    let n = v3.encode_into(&mut b);
    assert_eq!(n, setpoint_probe_frame_len(3));
    assert_eq!(n, 18);
    let mut stream = b[..n].to_vec();
    stream.extend_from_slice(&setpoint_bytes(2, &[11, -21, 31]));
    let got = feed(&mut d, &stream);
    assert_eq!(got.len(), 2);
    assert!(got[0].probe_armed() && got[0].probe == Some(PROBE_ARM));
    assert_eq!(got[0].commands(), &[10, -20, 30]);
    assert!(!got[1].probe_armed() && got[1].probe.is_none());
    let r = ReplyFrame::new(3, 1, &[1, 2, 3], 0x0020_0000, CounterId::Cycles, 9)
        .unwrap()
        .with_probe(ProbeReply {
            flags: 0x0012,
            latch_seq: 4,
            item: 1,
            value: -123_456_789,
        });
    let mut rb = [0u8; MAX_REPLY_FRAME_LEN];
    let rn = r.encode_into(&mut rb);
    assert_eq!(rn, reply_probe_frame_len(3));
    assert_eq!(rn, 33);
    let mut rd = ReplyDecoder::new();
    let got: Vec<_> = rb[..rn].iter().filter_map(|&x| rd.push(x)).collect();
    assert_eq!(got, [r]);
    let good = b[..n].to_vec();
    for bit in 0..good.len() * 8 {
        let mut bad = good.clone();
        bad[bit / 8] ^= 1 << (bit % 8);
        let mut d = SetpointDecoder::new();
        let got = feed(&mut d, &bad);
        assert!(got.is_empty(), "bit {bit} accepted");
    }
}

#[test]
fn every_single_bit_flip_is_detected() {
    // Every one-bit corruption of a three-axis frame (17 bytes × 8 bits) must be rejected; the
    // following good frame must still be decoded (resynchronisation).
    let good = setpoint_bytes(10, &[100, -200, 300]);
    let next = setpoint_bytes(11, &[101, -201, 301]);
    for bit in 0..good.len() * 8 {
        let mut bad = good.clone();
        bad[bit / 8] ^= 1 << (bit % 8);
        let mut d = SetpointDecoder::new();
        let mut stream = bad.clone();
        stream.extend_from_slice(&next);
        let got = feed(&mut d, &stream);
        assert_eq!(got.len(), 1, "bit {bit}: only the good frame");
        assert_eq!(got[0].seq, 11, "bit {bit}");
        assert_eq!(got[0].commands(), &[101, -201, 301]);
        let c = d.counters();
        if bit / 8 >= 2 {
            // Header intact (sync and version/count): the flip is in sequence, payload or CRC.
            assert!(c.corrupt >= 1, "bit {bit}: counted corrupt");
        } else {
            // A flipped sync or header byte makes no candidate frame: its bytes are skipped or
            // fail the CRC as a longer/shorter candidate.
            assert!(c.corrupt + c.skipped_bytes >= 1, "bit {bit}");
        }
    }
}

#[test]
fn lost_and_repeated_frames_are_detected() {
    let mut d = SetpointDecoder::new();
    let mut stream = Vec::new();
    for seq in [250u8, 251, 251, 254, 255, 0, 0, 0, 3] {
        stream.extend_from_slice(&setpoint_bytes(seq, &[i32::from(seq)]));
    }
    let got: Vec<u8> = feed(&mut d, &stream).iter().map(|f| f.seq).collect();
    // Repeated frames are never returned.
    assert_eq!(got, [250, 251, 254, 255, 0, 3]);
    let c = d.counters();
    assert_eq!(c.repeated, 3, "251 once, 0 twice");
    assert_eq!(c.lost, 2 + 2, "252-253 and 1-2 (through the wrap)");
    assert_eq!(c.frames_ok, 6);
    assert_eq!(c.corrupt, 0);
    let e = d.take_events();
    assert!(e.lost && e.repeated && !e.corrupt);
    assert_eq!(d.take_events(), LinkEvents::default(), "events are cleared");
}

#[test]
fn resyncs_after_garbage_and_truncated_frames() {
    let mut d = SetpointDecoder::new();
    let mut stream = vec![0x00, 0xA5, 0xA5, 0x13, 0xFF];
    // A truncated frame (the sender restarted mid-frame), then good frames.
    stream.extend_from_slice(&setpoint_bytes(1, &[5, 6])[..7]);
    stream.extend_from_slice(&setpoint_bytes(2, &[7, 8]));
    stream.extend_from_slice(&[0xA5, 0x25]); // a sync and a valid header, then noise
    stream.extend_from_slice(&[0x11; 30]);
    stream.extend_from_slice(&setpoint_bytes(3, &[9, 10]));
    let got = feed(&mut d, &stream);
    let seqs: Vec<u8> = got.iter().map(|f| f.seq).collect();
    assert_eq!(seqs, [2, 3]);
    assert_eq!(got[1].commands(), &[9, 10]);
    assert!(d.counters().skipped_bytes > 0);
    assert!(d.counters().corrupt >= 1);
}

#[test]
fn command_extension_is_exact_through_the_32_bit_wrap() {
    // Reference: the true i64 positions; the wire carries `as i32`.
    let mut prev = 0i64;
    let mut truth = (1i64 << 31) - 5_000;
    for _ in 0..10 {
        truth += 1_000;
        prev = extend_command(prev, truth as i32);
        assert_eq!(prev, truth);
    }
    let mut truth = -(1i64 << 33);
    let mut prev = truth + 17;
    for step in [-1_000_000i64, 2_000_000_000, -2_000_000_000, 1] {
        truth += step;
        prev = extend_command(prev, truth as i32);
        assert_eq!(prev, truth);
    }
}

/// Reference: `push`, byte by byte (the decoder's definition); tolerance: exact — the newest
/// frame of every chunk, the events after it and the counters at the end must be the same when
/// the same stream (frames of 1–5 axes, garbage, truncated, corrupt and repeated frames) is fed
/// to `push_bytes` in chunks of 1–40 bytes.
#[test]
fn push_bytes_in_chunks_equals_byte_by_byte() {
    let mut x = 0x2545_F491_4F6C_DD1Du64;
    let mut next = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let mut stream = Vec::new();
    for k in 0..400u32 {
        let n = 1 + (next() % 5) as usize;
        let cmds: Vec<i32> = (0..n).map(|_| next() as i32).collect();
        let seq = if k % 37 == 0 { k.wrapping_sub(1) } else { k } as u8;
        let mut f = setpoint_bytes(seq, &cmds);
        match next() % 10 {
            0 => f.truncate(1 + (next() as usize % f.len())),
            1 => {
                let at = next() as usize % f.len();
                f[at] ^= 1 << (next() % 8);
            }
            2 => stream.extend((0..next() % 6).map(|_| next() as u8)),
            _ => {}
        }
        stream.extend_from_slice(&f);
    }
    let mut bytewise = SetpointDecoder::new();
    let mut chunked = SetpointDecoder::new();
    let (mut at, mut chunks, mut frames) = (0, 0, 0);
    while at < stream.len() {
        let len = (1 + next() as usize % 40).min(stream.len() - at);
        let chunk = &stream[at..at + len];
        let want = chunk.iter().filter_map(|&b| bytewise.push(b)).last();
        let got = chunked.push_bytes(chunk);
        assert_eq!(got, want, "chunk at byte {at}");
        assert_eq!(
            chunked.take_events(),
            bytewise.take_events(),
            "events, chunk at {at}"
        );
        frames += usize::from(got.is_some());
        chunks += 1;
        at += len;
    }
    assert_eq!(chunked.counters(), bytewise.counters());
    assert!(
        chunks > 200 && frames > 150,
        "{chunks} chunks, {frames} with a frame"
    );
    assert!(bytewise.counters().corrupt > 0 && bytewise.counters().repeated > 0);
}
