//! How fast the twin simulates: a 5,000-row campaign of every plan, open loop and compensated through
//! the core (ideal table + thermo-force term), and the spindle campaign. Prints figures; run with `cargo bench -p axcomp-twin --bench simulate`.

use std::hint::black_box;
use std::time::Instant;

use axcomp_core::Compensator;
use axcomp_twin::{Axis, EffectKind, Plan, ideal_image, simulate};

fn time_it(repeats: u32, mut f: impl FnMut()) -> f64 {
    f(); // warm-up
    let t0 = Instant::now();
    for _ in 0..repeats {
        f();
    }
    t0.elapsed().as_secs_f64() / f64::from(repeats)
}

fn main() {
    let axis = Axis::typical("bench", 0.0, 200.0, &EffectKind::ALL);
    let mut comp = Compensator::IDENTITY;
    comp.load(&ideal_image(&axis, 2.0).expect("image"))
        .expect("load");
    println!(
        "{:<8} {:>6} {:>14} {:>14} {:>16}",
        "plan", "rows", "open loop ms", "compensated ms", "campaign span h"
    );
    for name in Plan::NAMES {
        let plan = Plan::by_name(name, axis.start_mm, axis.end_mm, Some(5000)).expect("plan");
        let rows = plan.samples().len();
        let span_h = plan.samples().last().map_or(0.0, |s| s.time_s / 3600.0);
        let open = time_it(5, || {
            black_box(simulate(&axis, &plan, None, 1).expect("simulate"));
        });
        let closed = time_it(3, || {
            black_box(simulate(&axis, &plan, Some(&comp), 1).expect("simulate"));
        });
        println!(
            "{name:<8} {rows:>6} {:>14.2} {:>14.2} {span_h:>16.2}",
            open * 1e3,
            closed * 1e3
        );
    }
    // The spindle campaign (axcomp-thermal's generator, 16 sensors), open loop only.
    let cfg = axcomp_twin::spindle_config(&axis, 1, Some(5000));
    let rows = axcomp_twin::simulate_spindle(&axis, 100.0, &cfg)
        .expect("spindle")
        .campaign
        .rows
        .len();
    let t = time_it(5, || {
        black_box(axcomp_twin::simulate_spindle(&axis, 100.0, &cfg).expect("spindle"));
    });
    println!(
        "{:<8} {rows:>6} {:>14.2} {:>14} {:>16.2}",
        "spindle",
        t * 1e3,
        "-",
        rows as f64 * cfg.dt_s / 3600.0
    );
}
