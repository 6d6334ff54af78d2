//! Identification time of a 22-line campaign with 40 targets per line and 3 runs (budget < 1 s).
//! Run: `cargo run --release -p axcomp-geometry --example bench_identify`.

use axcomp_data::{Dataset, LoadOptions};
use axcomp_geometry::plan::{PlanOptions, plan};
use axcomp_geometry::{FitOptions, Judge, LineData, analyse};
use axcomp_kinematics::Topology;
use axcomp_twin::geometry::GeometryTwin;

fn main() {
    let stroke = [800.0, 600.0, 500.0];
    let p = plan(&PlanOptions {
        stroke_mm: stroke,
        max_lines: Some(22),
        tool_offsets: vec![
            [0.0; 3],
            [150.0, 0.0, 0.0],
            [0.0, 150.0, 0.0],
            [0.0, 0.0, 150.0],
        ],
        sigma_um: 0.5,
        targets: 40,
        topology: Topology::default(),
    })
    .expect("plan");
    let twin = GeometryTwin::random(stroke, Topology::default(), 1);
    let camp = twin.measure(&p.lines, 3, 2);
    let ds =
        Dataset::from_csv_str("bench", &camp.to_csv_string(), &LoadOptions::default()).unwrap();
    let mut best = f64::INFINITY;
    let mut rows = 0;
    let mut params = 0;
    for _ in 0..3 {
        let t = std::time::Instant::now();
        let data = LineData::from_dataset(&ds, true).unwrap();
        let an = analyse(&data, &Judge::None, &FitOptions::default()).unwrap();
        best = best.min(t.elapsed().as_secs_f64());
        rows = an.report.rows;
        params = an.report.identifiability.parameters;
    }
    println!(
        "bench geometry_identify_22_lines_40_targets_3_runs {best:.3} s ({rows} readings, {params} parameters, smoothing by leave-one-line-out CV included)"
    );
}
