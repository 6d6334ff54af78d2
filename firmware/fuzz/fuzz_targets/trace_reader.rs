//! Any bytes as a trace: the reader and `Engine::step` never panic and always make progress.
#![no_main]

use axcomp_core::Engine;
use axcomp_core::trace::Reader;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut bytes = b"AXTR\x01\x00\x00\x00".to_vec();
    bytes.extend_from_slice(data);
    let mut engine = Box::new(Engine::new());
    let mut n = 0usize;
    for rec in Reader::new(&bytes).expect("valid header") {
        n += 1;
        assert!(n <= data.len() + 1);
        if let Ok(r) = rec {
            if let Some(out) = engine.step(&r) {
                assert!(out.correction_um().is_finite());
            }
        }
    }
});
