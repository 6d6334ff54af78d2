//! Identification time for 2 × 72 K4 poses plus two 36-pose C circles (216 poses, 648 readings) on an AC
//! trunnion twin: prints `bench rtest_fit_ms VALUE ms` (median of 21 fits, the first excluded as warm-up).
//! Run: `cargo run --release -p axcomp-rtest --example bench_rtest_fit`.
use std::time::Instant;

use axcomp_data::{Dataset, LoadOptions};
use axcomp_kinematics::rotary::{FiveAxis, MachineKind};
use axcomp_rtest::{RtestData, fit};
use axcomp_twin::five_axis::{FiveAxisTwin, standard_paths};

fn main() {
    let m = FiveAxis::new(MachineKind::AcTrunnion, 0.0);
    let twin = FiveAxisTwin::random(m, 1);
    let paths = standard_paths(&m, [150.0, 0.0, 100.0], -60.0, 72, &[0.0, -60.0], 36, None);
    let csv = twin.measure(&paths, 1).to_csv_string();
    let ds = Dataset::from_csv_str("twin", &csv, &LoadOptions::default()).unwrap();
    let data = RtestData::from_dataset(&ds, m, true).unwrap();
    let rows: Vec<usize> = (0..data.poses.len()).collect();
    assert_eq!(rows.len(), 216);
    let mut times = Vec::new();
    for _ in 0..22 {
        let t = Instant::now();
        let f = fit(&data, &rows).unwrap();
        times.push(t.elapsed().as_secs_f64() * 1e3);
        assert!(f.fit_rms_um < 1.0);
    }
    times.remove(0);
    times.sort_by(f64::total_cmp);
    println!("bench rtest_fit_ms {:.2} ms", times[times.len() / 2]);
}
