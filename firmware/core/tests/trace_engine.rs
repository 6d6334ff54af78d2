//! Trace records, reader/writer, output records and the A/B replay engine.

mod common;
use axcomp_core::trace::*;
use axcomp_core::*;
use common::*;

fn table_image(value: f32, slew: f32) -> Vec<u8> {
    let fwd = [[value, 0.0, 0.0, 0.0]; 4];
    image(&table_spec(
        TableSpec {
            start_counts: 0,
            segment_counts: 1000,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        },
        LimitSpec {
            max_slew_um_per_cycle: slew,
            ..LOOSE
        },
    ))
}

#[test]
fn trace_round_trip() {
    let img = table_image(1.0, 10.0);
    let records = [
        Record::Image(&img),
        Record::Temperatures(Temperatures::new(100, &[20.5, f32::NAN, -3.0])),
        Record::Process(ProcessParams {
            ap_mm: 1.0,
            fz_mm: 0.05,
            n_rpm: 1000.0,
        }),
        Record::Cycle(CycleInput {
            scale_raw: 0xDEAD_BEEF,
            command_counts: -123_456_789_012,
            forces_n: [1.5, f32::INFINITY, -0.0],
        }),
        Record::Reset { scale_raw: 77 },
        Record::End,
    ];
    let mut buf = vec![0u8; 4096];
    let mut w = Writer::new(&mut buf).unwrap();
    for r in &records {
        w.push(r).unwrap();
    }
    let n = w.finish();
    let expect_len = TRACE_HEADER_LEN + records.iter().map(|r| r.encoded_len()).sum::<usize>();
    assert_eq!(n, expect_len);
    let got: Vec<Record> = Reader::new(&buf[..n])
        .unwrap()
        .map(|r| r.unwrap())
        .collect();
    assert_eq!(got.len(), records.len());
    for (a, b) in got.iter().zip(records.iter()) {
        match (a, b) {
            // NaN != NaN: compare bit patterns of temperatures.
            (Record::Temperatures(x), Record::Temperatures(y)) => {
                assert_eq!(x.now_ms, y.now_ms);
                let bx: Vec<u32> = x.readings().iter().map(|v| v.to_bits()).collect();
                let by: Vec<u32> = y.readings().iter().map(|v| v.to_bits()).collect();
                assert_eq!(bx, by);
            }
            _ => assert_eq!(a, b),
        }
    }
    // The reader stops at End even if bytes follow.
    let mut longer = buf[..n].to_vec();
    longer.extend_from_slice(&[1, 2, 3]);
    assert_eq!(Reader::new(&longer).unwrap().count(), records.len());
    // A full buffer appends nothing.
    let mut small = [0u8; 20];
    let mut w = Writer::new(&mut small).unwrap();
    assert_eq!(w.push(&records[3]), Err(TraceError::BufferFull));
    assert_eq!(w.len(), TRACE_HEADER_LEN);
}

#[test]
fn reader_reports_and_skips_bad_records() {
    let mut buf = vec![0u8; 256];
    let mut w = Writer::new(&mut buf).unwrap();
    w.push(&Record::Reset { scale_raw: 1 }).unwrap();
    let n = w.finish();
    let mut t = buf[..n].to_vec();
    // Unknown tag 9 with 2 payload bytes, then a Process with a wrong length, then a Reset, then
    // a truncated Cycle.
    t.extend_from_slice(&[9, 2, 0, 0, 0, 0xAA, 0xBB]);
    t.extend_from_slice(&[TAG_PROCESS, 1, 0, 0, 0, 0]);
    t.extend_from_slice(&[TAG_RESET, 4, 0, 0, 0, 5, 0, 0, 0]);
    t.extend_from_slice(&[TAG_CYCLE, 24, 0, 0, 0, 1, 2]);
    let items: Vec<_> = Reader::new(&t).unwrap().collect();
    assert_eq!(items.len(), 5);
    assert_eq!(items[0], Ok(Record::Reset { scale_raw: 1 }));
    assert_eq!(items[1], Err(TraceError::UnknownTag { tag: 9, offset: 17 }));
    assert_eq!(
        items[2],
        Err(TraceError::BadRecord {
            tag: TAG_PROCESS,
            offset: 24
        })
    );
    assert_eq!(items[3], Ok(Record::Reset { scale_raw: 5 }));
    assert_eq!(items[4], Err(TraceError::Truncated { offset: 39 }));
    assert_eq!(Reader::new(b"AXT").err(), Some(TraceError::TooShort));
    assert_eq!(
        Reader::new(b"XXXX\x01\x00\x00\x00").err(),
        Some(TraceError::BadMagic)
    );
}

#[test]
fn output_record_layout() {
    let r = OutputRecord {
        cycle: 0x0102_0304,
        position_counts: -2,
        corrected_command_counts: i64::MAX,
        correction_counts: -7,
        correction_um_bits: 1.5f32.to_bits(),
        flags: 0x0180,
        slot: 1,
        status: STATUS_IMAGE_ACCEPTED,
    };
    let b = r.encode();
    assert_eq!(b.len(), OUTPUT_RECORD_LEN);
    assert_eq!(&b[0..4], &[4, 3, 2, 1]);
    assert_eq!(&b[4..12], &(-2i64).to_le_bytes());
    assert_eq!(&b[28..32], &[0x80, 0x01, 1, 1]);
    assert_eq!(OutputRecord::decode(&b), Ok(r));
    assert_eq!(r.correction_um(), 1.5);
    assert_eq!(OutputRecord::decode(&b[..31]), Err(TraceError::TooShort));
}

#[test]
fn engine_ab_swap_keeps_running_image_on_rejection() {
    let mut e = Box::new(Engine::new());
    let cyc = |raw: u32| Record::Cycle(input(raw, 100));
    let o = e.step(&cyc(10)).unwrap();
    assert_eq!(o.status & STATUS_NO_IMAGE, STATUS_NO_IMAGE);
    assert_eq!(o.correction_counts, 0);
    // Image 1: 2 µm (20 counts), slew 0.5 µm/cycle.
    let img1 = table_image(2.0, 0.5);
    assert_eq!(e.step(&Record::Image(&img1)), None);
    assert_eq!(e.active_slot(), 1);
    let o = e.step(&cyc(10)).unwrap();
    assert_eq!(o.status, STATUS_IMAGE_ACCEPTED);
    assert_eq!(o.slot, 1);
    assert_eq!(o.correction_um(), 0.5, "slewed from 0");
    for _ in 0..10 {
        e.step(&cyc(10));
    }
    assert_eq!(e.step(&cyc(10)).unwrap().correction_counts, 20);
    // A corrupted image is rejected; slot and correction unchanged.
    let mut bad = table_image(-5.0, 0.5);
    let k = bad.len() / 2;
    bad[k] ^= 0x10;
    e.step(&Record::Image(&bad));
    let o = e.step(&cyc(10)).unwrap();
    assert_eq!(o.status, STATUS_IMAGE_REJECTED);
    assert_eq!((o.slot, o.correction_counts), (1, 20));
    assert_eq!(e.stats().images_rejected, 1);
    assert_eq!(e.stats().last_image_error, Some(ImageError::BadCrc));
    // Image 2 (−1 µm) goes to slot A; the change is bridged by the slew limit: no jump.
    let img2 = table_image(-1.0, 0.5);
    e.step(&Record::Image(&img2));
    let mut prev = 2.0f32;
    for _ in 0..8 {
        let o = e.step(&cyc(10)).unwrap();
        assert_eq!(o.slot, 0);
        assert!((o.correction_um() - prev).abs() <= 0.5 + 1e-6);
        prev = o.correction_um();
    }
    assert_eq!(prev, -1.0);
    assert_eq!(e.stats().images_accepted, 2);
    assert_eq!(e.stats().cycles, 22);
    // init() resets in place.
    e.init();
    assert_eq!(e.stats().cycles, 0);
    assert!(!e.active().is_loaded());
}

#[test]
fn engine_replays_reference_trace_deterministically() {
    // The same trace through two engines gives identical output bytes (what the QEMU equivalence
    // test relies on), and the reference workload exercises table, thermo and forces.
    let mut img = vec![0u8; bench::reference_image_len()];
    bench::write_reference_image(&mut img).unwrap();
    let mut trace = vec![0u8; 2 * 1024 * 1024];
    let mut w = Writer::new(&mut trace).unwrap();
    w.push(&Record::Image(&img)).unwrap();
    w.push(&Record::Process(bench::PROCESS)).unwrap();
    for i in 0..20_000u32 {
        if i % 10 == 0 {
            let t = bench::reference_temperatures(i / 10);
            w.push(&Record::Temperatures(Temperatures::new(i / 10 * 100, &t)))
                .unwrap();
        }
        w.push(&Record::Cycle(bench::reference_input(i))).unwrap();
    }
    w.push(&Record::End).unwrap();
    let n = w.finish();
    let run = || {
        let mut e = Box::new(Engine::new());
        let mut out = Vec::new();
        for r in Reader::new(&trace[..n]).unwrap() {
            if let Some(o) = e.step(&r.unwrap()) {
                out.extend_from_slice(&o.encode());
            }
        }
        (out, *e.stats())
    };
    let (a, stats) = run();
    let (b, _) = run();
    assert_eq!(a, b);
    assert_eq!(a.len(), 20_000 * OUTPUT_RECORD_LEN);
    assert_eq!(stats.images_accepted, 1);
    let outs: Vec<OutputRecord> = a
        .chunks(OUTPUT_RECORD_LEN)
        .map(|c| OutputRecord::decode(c).unwrap())
        .collect();
    assert!(outs.iter().any(|o| o.flags().contains(Flags::BACKWARD)));
    assert!(
        outs.iter()
            .any(|o| o.flags().contains(Flags::TABLE_OUTSIDE))
    );
    assert!(outs.iter().any(|o| o.correction_counts != 0));
    assert!(outs.iter().all(|o| o.correction_um().abs() <= 50.0));
}

#[cfg(feature = "std")]
#[test]
fn io_writer_matches_buffer_writer() {
    let img = table_image(1.0, 10.0);
    let records = [
        Record::Image(&img),
        Record::Temperatures(Temperatures::new(5, &[20.0; 16])),
        Record::Cycle(input(1, 2)),
        Record::End,
    ];
    let mut buf = vec![0u8; 4096];
    let mut w = Writer::new(&mut buf).unwrap();
    let mut io = Vec::new();
    write_header_io(&mut io).unwrap();
    for r in &records {
        w.push(r).unwrap();
        write_record_io(&mut io, r).unwrap();
    }
    let n = w.finish();
    assert_eq!(&buf[..n], &io[..]);
}
