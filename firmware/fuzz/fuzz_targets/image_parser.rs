//! Any bytes: `Compensator::load` and `inspect_image` never panic; a rejected image leaves the
//! compensator untouched; an accepted one runs a few cycles with finite, clamped output.
//! Each input is tried as is and "repaired" (magic, version, lengths and CRC made consistent),
//! so that the fuzzer also reaches the section and value checks behind the CRC.
#![no_main]

use axcomp_core::{Compensator, CycleInput, MAX_IMAGE_LEN, State, crc32, inspect_image};
use libfuzzer_sys::fuzz_target;

fn check(data: &[u8]) {
    let mut comp = Box::new(Compensator::IDENTITY);
    let info = inspect_image(data);
    match comp.load(data) {
        Ok(()) => {
            assert!(info.is_ok());
            let limits = comp.limits();
            let mut st = State::new();
            comp.update_temperatures(&mut st, 0, &[20.0; 16]);
            for k in 0..16u32 {
                let raw = k.wrapping_mul(0x9E37_79B9);
                let out = comp.cycle(
                    &mut st,
                    &CycleInput {
                        scale_raw: raw,
                        command_counts: raw as i64,
                        forces_n: [1.0; 3],
                    },
                );
                assert!(out.correction_um.is_finite());
                assert!(out.correction_um.abs() <= limits.max_correction_um);
            }
        }
        Err(e) => {
            assert_eq!(info.err(), Some(e));
            assert!(!comp.is_loaded());
        }
    }
}

fuzz_target!(|data: &[u8]| {
    check(data);
    // Repaired up to the longest image the parser accepts (a whole flash slot), so that the
    // largest tables are reached too.
    if data.len() >= 48 + 16 + 4 && data.len() <= MAX_IMAGE_LEN {
        let mut b = data.to_vec();
        b[..4].copy_from_slice(b"AXCI");
        b[4..6].copy_from_slice(&1u16.to_le_bytes());
        b[6..8].copy_from_slice(&48u16.to_le_bytes());
        let n = b.len();
        b[8..12].copy_from_slice(&(n as u32).to_le_bytes());
        let crc = crc32(&b[..n - 4]);
        b[n - 4..].copy_from_slice(&crc.to_le_bytes());
        check(&b);
    }
});
