//! Host benchmark of the per-cycle path on the reference workload (`axcomp_core::bench`).
//!
//! `cargo run -p axcomp-core --release --example bench_host`
//! Prints `bench host_full_correction_ns X ns` (table + 8-sensor thermo-force term + 3 forces,
//! clamp, slew, rounding) and `bench host_table_correction_ns X ns` (table only, same limits),
//! each the mean over many calls measured with `std::time::Instant`, best of 5 runs.

use std::hint::black_box;
use std::time::Instant;

use axcomp_core::{Compensator, CycleInput, ImageSpec, State, bench, image_len, write_image};

const CALLS: u32 = 2_000_000;

fn load(spec: &ImageSpec) -> Box<Compensator> {
    let mut buf = vec![0u8; image_len(spec)];
    write_image(spec, &mut buf).expect("reference image");
    let mut c = Box::new(Compensator::IDENTITY);
    c.load(&buf).expect("reference image loads");
    c
}

fn measure(comp: &Compensator, with_temps: bool) -> f64 {
    // Inputs precomputed so that only `cycle` is timed.
    let inputs: Vec<CycleInput> = (0..4096).map(bench::reference_input).collect();
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let mut st = State::new();
        if with_temps {
            comp.set_process(&mut st, &bench::PROCESS);
            for i in 0..10 {
                comp.update_temperatures(&mut st, i * 100, &bench::reference_temperatures(i));
            }
        }
        let mut acc = 0i64;
        let t0 = Instant::now();
        for i in 0..CALLS {
            let inp = &inputs[(i & 4095) as usize];
            let out = comp.cycle(&mut st, black_box(inp));
            acc = acc.wrapping_add(out.corrected_command_counts);
        }
        let ns = t0.elapsed().as_nanos() as f64 / CALLS as f64;
        black_box(acc);
        best = best.min(ns);
    }
    best
}

fn main() {
    let full = bench::reference_spec();
    let table_only = ImageSpec {
        thermo: None,
        ..full
    };
    let full_c = load(&full);
    let table_c = load(&table_only);
    println!(
        "bench host_full_correction_ns {:.2} ns",
        measure(&full_c, true)
    );
    println!(
        "bench host_table_correction_ns {:.2} ns",
        measure(&table_c, false)
    );
}
