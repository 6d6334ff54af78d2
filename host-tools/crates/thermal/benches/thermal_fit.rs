//! Prints how long thermal fits take (median of repeated runs): `cargo bench -p axcomp-thermal`.
//! Figures only; nothing is asserted.

use std::time::{Duration, Instant};

use axcomp_numeric::lsq::lstsq;
use axcomp_thermal::{Selection, ThermalInput, ThermalOptions, fit_thermal};
use axcomp_twin::synth::{SynthConfig, generate};
use nalgebra::DMatrix;

fn median_time(reps: usize, mut f: impl FnMut()) -> Duration {
    let mut v: Vec<Duration> = (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed()
        })
        .collect();
    v.sort();
    v[reps / 2]
}

fn main() {
    // 5 conditions × 3 h at 10 s → 5400 rows (cut to 5000), 16 sensors, 1 force column.
    let d = generate(&SynthConfig::default());
    let n = 5000;
    let input = ThermalInput {
        time_s: d.time_s[..n].to_vec(),
        sensors: d
            .sensor_series()
            .into_iter()
            .map(|mut s| {
                s.values.truncate(n);
                s
            })
            .collect(),
        forces: d
            .force_series()
            .into_iter()
            .map(|mut s| {
                s.values.truncate(n);
                s
            })
            .collect(),
        target: d.error_um[..n].to_vec(),
        conditions: Some(d.condition[..n].iter().map(|c| c.to_string()).collect()),
        holdout: Some(d.condition[..n].iter().map(|&c| c == 2).collect()),
        runs: None,
    };
    for (name, opts) in [
        (
            "full fit, selection (FCM+GRA, forward, nested CV), no lags",
            ThermalOptions::default(),
        ),
        (
            "full fit, selection + lags (9-point grid, golden section)",
            ThermalOptions {
                lags: true,
                ..ThermalOptions::default()
            },
        ),
        (
            "fixed selection (all 16 sensors), no lags",
            ThermalOptions {
                selection: Selection::All,
                max_sensors: 16,
                ..ThermalOptions::default()
            },
        ),
    ] {
        let t = median_time(7, || {
            std::hint::black_box(fit_thermal(&input, &opts).unwrap());
        });
        println!(
            "thermal fit, {n} rows × 16 sensors, {name}: {:.1} ms (median of 7)",
            t.as_secs_f64() * 1e3
        );
    }
    // The bare regression the diagnosis may call in loops: QR least squares, 5000 × (1 + 4).
    let x = DMatrix::from_fn(n, 5, |r, c| {
        if c == 0 {
            1.0
        } else {
            d.sensors_degc[c * 3][r]
        }
    });
    let y = &d.error_um[..n];
    let t = median_time(51, || {
        std::hint::black_box(lstsq(&x, y, 0.0, Some(0)).unwrap());
    });
    println!(
        "QR least squares, {n} rows × 5 columns: {:.3} ms (median of 51)",
        t.as_secs_f64() * 1e3
    );
}
