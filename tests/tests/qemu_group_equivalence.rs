//! The group firmware in QEMU (`axcomp-qemu-group`) and the host replay give byte-identical output
//! records for the three- and five-axis group traces (all axes moving at once, rotary C through
//! 360° several times, 16-bit counters wrapping, a group image refused by a section CRC, an A/B
//! swap of every axis at once, a group reset).
//!
//! Reference: `axcomp_firmware::replay::replay_group` over `axcomp_core::group::GroupEngine` on the
//! host. Tolerance: none — every 32-byte output record must match bit for bit (one ULP in one
//! record's `correction_um`, or one dropped record, fails), and the record count must be the
//! number of group cycles times the axes.

use axcomp_core::trace::{OUTPUT_RECORD_LEN, OutputRecord};
use axcomp_firmware::scenario;
use axcomp_system_tests::{build_qemu_firmware, host_group_replay, qemu_replay, require_tool};

const CYCLES: u32 = 20_000;

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

fn check(n_axes: usize) {
    if !require_tool("qemu-system-arm") {
        return;
    }
    let elf = build_qemu_firmware("axcomp-qemu-group");
    let trace_bytes = scenario::group(n_axes, CYCLES).expect("scenario");
    let (want, cycles, errors) = host_group_replay(&trace_bytes);
    assert_eq!((cycles, errors), (CYCLES, 0));
    assert_eq!(want.len(), CYCLES as usize * n_axes * OUTPUT_RECORD_LEN);
    let (status, stdout, got) = qemu_replay(&elf, &format!("qemu-group{n_axes}"), &trace_bytes);
    assert!(
        status.success(),
        "QEMU firmware failed ({status})\n{stdout}"
    );
    assert_same_records(&got, &want);
    let outputs = CYCLES as usize * n_axes;
    assert!(
        stdout.contains(&format!(
            "cycles={CYCLES} outputs={outputs} errors=0 images_accepted=2 images_rejected=1"
        )),
        "summary line: {stdout}"
    );
}

#[test]
fn three_axis_group_matches_host_bit_for_bit() {
    check(3);
}

#[test]
fn five_axis_group_matches_host_bit_for_bit() {
    check(5);
}

/// The comparison is strict: one ULP in one record, or one dropped record, fails it.
#[test]
fn comparison_fails_on_one_ulp_and_on_a_dropped_record() {
    let trace_bytes = scenario::group(5, 6_000).expect("scenario");
    let (want, _, _) = host_group_replay(&trace_bytes);
    assert_same_records(&want, &want);
    let k = want.len() / OUTPUT_RECORD_LEN / 2;
    let mut rec = OutputRecord::decode(&want[k * OUTPUT_RECORD_LEN..]).unwrap();
    rec.correction_um_bits = rec.correction_um_bits.wrapping_add(1);
    let mut one_ulp = want.clone();
    one_ulp[k * OUTPUT_RECORD_LEN..(k + 1) * OUTPUT_RECORD_LEN].copy_from_slice(&rec.encode());
    assert!(std::panic::catch_unwind(|| assert_same_records(&one_ulp, &want)).is_err());
    let dropped = &want[..want.len() - OUTPUT_RECORD_LEN];
    assert!(std::panic::catch_unwind(|| assert_same_records(dropped, &want)).is_err());
}
