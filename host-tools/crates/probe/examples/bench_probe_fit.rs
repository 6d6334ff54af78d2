//! Calibration time for 500 touches (budget: < 100 ms). Prints `bench probe_fit_500_ms VALUE ms`
//! (median of 7 runs). Run with `cargo run --release -p axcomp-probe --example bench_probe_fit`.
use axcomp_probe::{CalibrationOptions, Touch, calibrate};
use axcomp_twin::probe::{ProbeModel, ProbePlan, simulate_touches};

fn main() {
    let probe = ProbeModel::kinematic_demo();
    let sim = simulate_touches(&probe, &ProbePlan::standard_calibration(), 1);
    let touches: Vec<Touch> = sim
        .iter()
        .take(500)
        .map(|s| Touch {
            position_mm: s.latched_mm,
            approach: s.approach,
            feed_mm_min: s.feed_mm_min,
        })
        .collect();
    assert_eq!(touches.len(), 500);
    let labels: Vec<String> = (0..500).map(|i| format!("touch {i}")).collect();
    let opts = CalibrationOptions::new(25.0);
    let mut ms = Vec::new();
    let mut last = None;
    for _ in 0..7 {
        let t0 = std::time::Instant::now();
        let r = calibrate(&touches, &labels, &opts).expect("calibrates");
        ms.push(t0.elapsed().as_secs_f64() * 1000.0);
        last = Some(r);
    }
    ms.sort_by(f64::total_cmp);
    let r = last.unwrap();
    println!(
        "model {} with {} candidates cross-validated; fit RMS {:.3} µm",
        r.calibration.structure.name(),
        r.candidates.len(),
        r.calibration.fit_rms_um
    );
    println!("bench probe_fit_500_ms {:.1} ms", ms[ms.len() / 2]);
}
