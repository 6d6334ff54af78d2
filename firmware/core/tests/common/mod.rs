//! Shared helpers of the axcomp-core tests.
#![allow(dead_code)]

use axcomp_core::*;

/// Limits that never interfere (large clamp and slew).
pub const LOOSE: LimitSpec = LimitSpec {
    max_correction_um: 1.0e4,
    max_slew_um_per_cycle: 1.0e4,
    direction_hysteresis_counts: 0,
};

/// A spec with only a table.
pub fn table_spec<'a>(table: TableSpec<'a>, limits: LimitSpec) -> ImageSpec<'a> {
    ImageSpec {
        axis_id: 7,
        um_per_count: 0.1,
        counter_bits: 32,
        table: Some(table),
        thermo: None,
        limits,
    }
}

/// Write `spec` and load it into a fresh (boxed) compensator.
pub fn load(spec: &ImageSpec) -> Box<Compensator> {
    let mut buf = vec![0u8; image_len(spec)];
    let n = write_image(spec, &mut buf).expect("valid spec");
    assert_eq!(n, buf.len());
    let mut c = Box::new(Compensator::IDENTITY);
    c.load(&buf).expect("image loads");
    c
}

/// Write `spec` into a new vector.
pub fn image(spec: &ImageSpec) -> Vec<u8> {
    let mut buf = vec![0u8; image_len(spec)];
    write_image(spec, &mut buf).expect("valid spec");
    buf
}

pub fn input(raw: u32, command: i64) -> CycleInput {
    CycleInput {
        scale_raw: raw,
        command_counts: command,
        forces_n: [0.0; MAX_FORCES],
    }
}

/// Natural cubic spline through `y` at uniform knots, in per-segment Horner form with t in [0, 1]
/// (computed in f64: the reference the f32 table is compared with).
pub fn natural_spline(y: &[f64]) -> Vec<[f64; 4]> {
    let n = y.len() - 1; // segments
    // Second derivatives m (in t units): m[i-1] + 4 m[i] + m[i+1] = 6 (y[i+1] - 2 y[i] + y[i-1]).
    let mut m = vec![0.0f64; n + 1];
    if n >= 2 {
        let k = n - 1;
        let mut diag = vec![4.0f64; k];
        let mut rhs: Vec<f64> = (1..n)
            .map(|i| 6.0 * (y[i + 1] - 2.0 * y[i] + y[i - 1]))
            .collect();
        for i in 1..k {
            let w = 1.0 / diag[i - 1];
            diag[i] -= w;
            rhs[i] -= w * rhs[i - 1];
        }
        let mut x = vec![0.0f64; k];
        x[k - 1] = rhs[k - 1] / diag[k - 1];
        for i in (0..k - 1).rev() {
            x[i] = (rhs[i] - x[i + 1]) / diag[i];
        }
        m[1..n].copy_from_slice(&x);
    }
    (0..n)
        .map(|i| {
            [
                y[i],
                y[i + 1] - y[i] - (2.0 * m[i] + m[i + 1]) / 6.0,
                m[i] / 2.0,
                (m[i + 1] - m[i]) / 6.0,
            ]
        })
        .collect()
}

pub fn horner(c: &[f64; 4], t: f64) -> f64 {
    c[0] + t * (c[1] + t * (c[2] + t * c[3]))
}

pub fn to_f32(c: &[[f64; 4]]) -> Vec<[f32; 4]> {
    c.iter()
        .map(|s| [s[0] as f32, s[1] as f32, s[2] as f32, s[3] as f32])
        .collect()
}

pub fn sensor(reference: f32, tau: f32) -> SensorSpec {
    SensorSpec {
        reference_degc: reference,
        min_degc: -50.0,
        max_degc: 150.0,
        max_rate_degc_per_s: 5.0,
        lag_tau_s: tau,
        stale_timeout_ms: 1000,
    }
}

/// Counts per revolution of the group tests' rotary axes.
pub const CPR: u32 = 3_600_000;

/// A linear axis image for group tests: 8 segments from −4000 counts, bidirectional, `sensors`
/// thermal sensors (b0 0.25 µm, 0.5 µm/K each).
pub fn linear_image(axis_id: u16, sensors: usize) -> Vec<u8> {
    let fwd = [[1.0f32, 0.5, 0.0, 0.0]; 8];
    let bwd = [[1.5f32, 0.5, 0.0, 0.0]; 8];
    let sens = vec![sensor(20.0, 0.0); sensors];
    let b = vec![0.5f32; sensors];
    image(&ImageSpec {
        axis_id,
        um_per_count: 0.1,
        counter_bits: 16,
        table: Some(TableSpec {
            start_counts: -4000,
            segment_counts: 1000,
            forward: &fwd,
            backward: &bwd,
            outside: OutsideStroke::Hold,
        }),
        thermo: (sensors > 0).then_some(ThermoForceSpec {
            sensor_period_ms: 100,
            sensors: &sens,
            b0_um: 0.25,
            b_um_per_k: &b,
            expansion: None,
            forces: &[],
            reference: axcomp_core::ThermoReference::Fixed,
            rise_bounds_k: &[],
        }),
        limits: LOOSE,
    })
}

/// A rotary axis image for group tests: 16 segments over the turn.
pub fn rotary_image(axis_id: u16) -> Vec<u8> {
    let fwd = [[2.0f32, 1.0, 0.0, 0.0]; 16];
    image(&ImageSpec {
        axis_id,
        um_per_count: 1_296_000.0 / CPR as f32,
        counter_bits: 16,
        table: Some(TableSpec {
            start_counts: 0,
            segment_counts: CPR / 16,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        }),
        thermo: None,
        limits: LOOSE,
    })
}
