//! Spread of the twin figures over seeds (plane height and ring diameter after correction).
use axcomp_probe::{CalibrationOptions, Touch, calibrate};
use axcomp_twin::probe::{ProbeModel, ProbePlan, simulate_touches};
fn main() {
    let probe = ProbeModel::kinematic_demo();
    for seed in 0..10u64 {
        let sim = simulate_touches(&probe, &ProbePlan::standard_calibration(), 100 + seed);
        let t: Vec<Touch> = sim
            .iter()
            .map(|s| Touch {
                position_mm: s.latched_mm,
                approach: s.approach,
                feed_mm_min: s.feed_mm_min,
            })
            .collect();
        let labels: Vec<String> = (0..t.len()).map(|i| format!("touch {i}")).collect();
        let res = calibrate(&t, &labels, &CalibrationOptions::new(25.0)).unwrap();
        let c = res.calibration.sphere_center_mm;
        let meas = simulate_touches(
            &probe.clone().without_glitches(),
            &ProbePlan::measurement(450.0, 1),
            200 + seed,
        );
        let z: Vec<f64> = meas
            .iter()
            .filter(|s| s.artefact == "plane")
            .map(|s| {
                res.calibration.contact_mm(&Touch {
                    position_mm: s.latched_mm,
                    approach: s.approach,
                    feed_mm_min: s.feed_mm_min,
                })[2]
            })
            .collect();
        let zm = z.iter().sum::<f64>() / z.len() as f64;
        println!(
            "seed {seed}: {} centre err z {:+.3} µm, plane {:+.3} µm",
            res.calibration.structure.name(),
            (c[2] - 20.0) * 1000.0,
            (zm - 2.0) * 1000.0
        );
    }
}
