//! Set-up shared by the R-test twin examples (included with `#[path = "common/mod.rs"] mod common;`):
//! positional arguments, the three machine kinds with their sphere positions and standard plan, and one
//! campaign measured on a twin and loaded as R-test data.
#![allow(dead_code)]

use axcomp_data::{Dataset, LoadOptions};
use axcomp_kinematics::rotary::{FiveAxis, MachineKind};
use axcomp_rtest::{Fit, RtestData, fit};
use axcomp_twin::five_axis::{FiveAxisTwin, RtestPathSpec, standard_paths};

/// Positional argument `index` (1 = first after the program name), or `default` when absent or unparsable.
pub fn arg<T: std::str::FromStr>(index: usize, default: T) -> T {
    std::env::args()
        .nth(index)
        .and_then(|s| s.parse().ok())
        .unwrap_or(default)
}

/// The machine kinds every example runs through, in print order.
pub const KINDS: [MachineKind; 3] = [
    MachineKind::AcTrunnion,
    MachineKind::BcTrunnion,
    MachineKind::BcHead,
];

/// The machine (250 mm pivot) and the standard plan of `kind`: K4 run 1 (72 poses, tilt to −60°), C circles
/// at 0° and −60° (36 poses each), K4 run 2 last; the sphere at the table origin on the head machine, at
/// (150, 0, 100) mm on the trunnions.
pub fn machine_and_paths(kind: MachineKind) -> (FiveAxis, Vec<RtestPathSpec>) {
    let m = FiveAxis::new(kind, 250.0);
    let sphere = if kind == MachineKind::BcHead {
        [0.0; 3]
    } else {
        [150.0, 0.0, 100.0]
    };
    let paths = standard_paths(&m, sphere, -60.0, 72, &[0.0, -60.0], 36, None);
    (m, paths)
}

/// The twin's readings of `paths` (noise seed `seed`) loaded as a dataset and as R-test data.
pub fn measure(twin: &FiveAxisTwin, paths: &[RtestPathSpec], seed: u64) -> (Dataset, RtestData) {
    let csv = twin.measure(paths, seed).to_csv_string();
    let ds = Dataset::from_csv_str("twin", &csv, &LoadOptions::default()).unwrap();
    let data = RtestData::from_dataset(&ds, twin.machine, true).unwrap();
    (ds, data)
}

/// The full 11-parameter fit on every row of the twin's readings of `paths` (noise seed `seed`).
pub fn measure_and_fit(twin: &FiveAxisTwin, paths: &[RtestPathSpec], seed: u64) -> Fit {
    let (_, data) = measure(twin, paths, seed);
    let rows: Vec<usize> = (0..data.poses.len()).collect();
    fit(&data, &rows).unwrap()
}
