//! The firmware in QEMU and the host replay give byte-identical output records for the same trace.
//!
//! Reference: `axcomp_core::trace::Reader` + `axcomp_core::Engine` on the host. Tolerance: none — every
//! 32-byte output record must match bit for bit (a one-ULP difference in `correction_um` or a dropped cycle
//! fails), and the record count must equal the number of cycle records.

use axcomp_core::Engine;
use axcomp_core::trace::{self, OUTPUT_RECORD_LEN, OutputRecord, Record};
use axcomp_firmware::scenario;
use axcomp_system_tests::{build_qemu_firmware, qemu_replay, require_tool};

const CYCLES: u32 = 30_000;

/// Host replay: output records, cycle records seen, malformed records reported.
fn host_replay(trace_bytes: &[u8]) -> (Vec<u8>, u32, u32) {
    let mut engine = Box::new(Engine::new());
    let mut out = Vec::new();
    let (mut cycles, mut errors) = (0, 0);
    for r in trace::Reader::new(trace_bytes).expect("trace header") {
        match r {
            Ok(rec) => {
                if matches!(rec, Record::Cycle(_)) {
                    cycles += 1;
                }
                if let Some(o) = engine.step(&rec) {
                    out.extend_from_slice(&o.encode());
                }
            }
            Err(_) => errors += 1,
        }
    }
    (out, cycles, errors)
}

/// Panics with the first differing record, then compares the counts.
fn assert_same_records(got: &[u8], want: &[u8]) {
    assert_eq!(
        got.len() % OUTPUT_RECORD_LEN,
        0,
        "QEMU output is whole records"
    );
    let first_diff = got
        .chunks(OUTPUT_RECORD_LEN)
        .zip(want.chunks(OUTPUT_RECORD_LEN))
        .position(|(a, b)| a != b);
    if let Some(k) = first_diff {
        let a = OutputRecord::decode(&got[k * OUTPUT_RECORD_LEN..]).unwrap();
        let b = OutputRecord::decode(&want[k * OUTPUT_RECORD_LEN..]).unwrap();
        panic!("first differing output record #{k}:\n  qemu: {a:?}\n  host: {b:?}");
    }
    assert_eq!(
        got.len() / OUTPUT_RECORD_LEN,
        want.len() / OUTPUT_RECORD_LEN,
        "record count (QEMU vs host)"
    );
}

#[test]
fn qemu_firmware_matches_host_replay_bit_for_bit() {
    if !require_tool("qemu-system-arm") {
        return;
    }
    let elf = build_qemu_firmware("axcomp-qemu");
    let trace_bytes = scenario::equivalence(CYCLES, None).expect("scenario");
    let (want, cycles, errors) = host_replay(&trace_bytes);
    assert_eq!((cycles, errors), (CYCLES, 0));

    let (status, stdout, got) = qemu_replay(&elf, "qemu-equivalence", &trace_bytes);
    assert!(
        status.success(),
        "QEMU firmware failed ({status})\n{stdout}"
    );
    assert_same_records(&got, &want);
    assert_eq!(got.len() / OUTPUT_RECORD_LEN, CYCLES as usize);
    assert!(
        stdout.contains(&format!(
            "cycles={CYCLES} outputs={CYCLES} errors=0 images_accepted=2 images_rejected=1"
        )),
        "summary line: {stdout}"
    );
}

#[test]
fn qemu_firmware_reports_malformed_trace_and_still_matches() {
    if !require_tool("qemu-system-arm") {
        return;
    }
    let elf = build_qemu_firmware("axcomp-qemu");
    let good = scenario::equivalence(12_000, None).expect("scenario");
    // Splice an unknown-tag record (intact framing: skipped) after the 1000th record, and cut the trace in
    // the middle of its last record (truncated: ends the replay).
    let mut reader = trace::Reader::new(&good).unwrap();
    for _ in 0..1000 {
        reader.next().unwrap().unwrap();
    }
    let at = reader.offset();
    let mut bad = good[..at].to_vec();
    bad.extend_from_slice(&[200, 3, 0, 0, 0, 1, 2, 3]);
    bad.extend_from_slice(&good[at..good.len() - 3]);
    let (want, _, errors) = host_replay(&bad);
    assert_eq!(
        errors, 2,
        "host reader sees the unknown tag and the truncation"
    );

    let (status, stdout, got) = qemu_replay(&elf, "qemu-malformed", &bad);
    assert_eq!(
        status.code(),
        Some(3),
        "exit status 3 for malformed records\n{stdout}"
    );
    assert!(stdout.contains("unknown record tag 200"), "{stdout}");
    assert_same_records(&got, &want);
}

/// The comparison itself is strict: one ULP in one record's `correction_um`, or one dropped cycle, fails it.
#[test]
fn comparison_fails_on_one_ulp_and_on_a_dropped_cycle() {
    let trace_bytes = scenario::equivalence(10_000, None).expect("scenario");
    let (want, cycles, _) = host_replay(&trace_bytes);
    assert_eq!(cycles, 10_000);
    assert_same_records(&want, &want);

    // One ULP: the f32 bits of correction_um in the middle record, plus one.
    let k = (cycles / 2) as usize;
    let mut rec = OutputRecord::decode(&want[k * OUTPUT_RECORD_LEN..]).unwrap();
    rec.correction_um_bits = rec.correction_um_bits.wrapping_add(1);
    let mut one_ulp = want.clone();
    one_ulp[k * OUTPUT_RECORD_LEN..(k + 1) * OUTPUT_RECORD_LEN].copy_from_slice(&rec.encode());
    assert_ne!(one_ulp, want);
    assert!(std::panic::catch_unwind(|| assert_same_records(&one_ulp, &want)).is_err());

    // A dropped cycle: the last record missing (every earlier one equal).
    let dropped = &want[..want.len() - OUTPUT_RECORD_LEN];
    assert!(std::panic::catch_unwind(|| assert_same_records(dropped, &want)).is_err());
}

/// The single-axis outputs as they are now, summarised as the CRC-32 of the host replay's 30 000
/// output records of `scenario::equivalence(30 000)` (960 000 bytes); tolerance: none.
///
/// History of the reference: the core split and the single-axis speed-up (instructions per call
/// 126.8 → 119.2) changed no output bit (0xF56AF04B, the engine of commit 7f4875d, kept through
/// e586ee3). The table's coefficients converted to the remainder in counts at load
/// (`segment_per_count`: no multiply by 1/segment per cycle) changed the last bits of
/// `correction_um` in 1 210 of the 30 000 records, by at most 4.8e-7 µm, and no corrected command
/// and no correction in counts (compared record by record with e586ee3's replay) → 0x45D6A834.
#[test]
fn single_axis_outputs_unchanged_by_the_core_split() {
    let trace_bytes = scenario::equivalence(30_000, None).expect("scenario");
    let (got, cycles, errors) = host_replay(&trace_bytes);
    assert_eq!((cycles, errors, got.len()), (30_000, 0, 960_000));
    assert_eq!(axcomp_core::crc32(&got), 0x45D6_A834);
}
