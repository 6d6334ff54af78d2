//! A reference workload for benchmarks: the host example `bench_host` and the firmware's QEMU
//! instruction count (`axcomp-qemu-bench`, run by `.ci/bench`) use the same image and inputs.
//!
//! The image: a bidirectional 1024-segment table (a smooth cubic along the stroke, 1.5 µm
//! reversal), 8 lagged sensors with Σ b_i·ΔT_i and a scale-expansion term, 3 force terms (two
//! measured, one predicted), 0.1 µm per count, 32-bit counter.

use crate::spec::{
    ExpansionSpec, ForceLaw, ForceSpec, ImageSpec, LimitSpec, OutsideStroke, SensorSpec, TableSpec,
    ThermoForceSpec,
};
use crate::{CycleInput, ImageError, MAX_SEGMENTS, ProcessParams};

/// Knot spacing of the reference table, counts.
pub const SEGMENT_COUNTS: u32 = 1000;
/// Stroke of the reference table, counts.
pub const STROKE_COUNTS: i64 = SEGMENT_COUNTS as i64 * MAX_SEGMENTS as i64;
/// Number of sensors of the reference image.
pub const N_SENSORS: usize = 8;

/// Exact segment form (Taylor expansion at each knot) of f(u) = off + a1·u + a2·u² + a3·u³.
const fn cubic_table(off: f32, a1: f32, a2: f32, a3: f32) -> [[f32; 4]; MAX_SEGMENTS] {
    let h = 1.0 / MAX_SEGMENTS as f32;
    let mut t = [[0.0f32; 4]; MAX_SEGMENTS];
    let mut s = 0;
    while s < MAX_SEGMENTS {
        let u = s as f32 * h;
        let f = off + u * (a1 + u * (a2 + u * a3));
        let d1 = a1 + u * (2.0 * a2 + 3.0 * a3 * u);
        let d2 = 2.0 * a2 + 6.0 * a3 * u;
        let d3 = 6.0 * a3;
        t[s] = [f, d1 * h, d2 * h * h / 2.0, d3 * h * h * h / 6.0];
        s += 1;
    }
    t
}

/// Forward table of the reference image.
pub static FORWARD: [[f32; 4]; MAX_SEGMENTS] = cubic_table(0.0, 12.0, -18.0, 9.0);
/// Backward table of the reference image.
pub static BACKWARD: [[f32; 4]; MAX_SEGMENTS] = cubic_table(1.5, 12.5, -18.0, 9.0);

const fn sensor(reference_degc: f32, lag_tau_s: f32) -> SensorSpec {
    SensorSpec {
        reference_degc,
        min_degc: -20.0,
        max_degc: 120.0,
        max_rate_degc_per_s: 2.0,
        lag_tau_s,
        stale_timeout_ms: 5000,
    }
}

/// Sensors of the reference image.
pub static SENSORS: [SensorSpec; N_SENSORS] = [
    sensor(20.0, 0.0),
    sensor(20.0, 30.0),
    sensor(21.0, 120.0),
    sensor(20.5, 0.0),
    sensor(22.0, 600.0),
    sensor(20.0, 10.0),
    sensor(19.5, 0.0),
    sensor(20.0, 300.0),
];
/// b_i of the reference image, µm/K.
pub static B_UM_PER_K: [f32; N_SENSORS] = [1.2, -0.4, 0.8, 0.1, -0.3, 0.5, 0.05, -0.2];
/// Force terms of the reference image.
pub static FORCES: [ForceSpec; 3] = [
    ForceSpec {
        chi_um_per_n: 0.002,
        law: None,
    },
    ForceSpec {
        chi_um_per_n: -0.001,
        law: None,
    },
    ForceSpec {
        chi_um_per_n: 0.0015,
        law: Some(ForceLaw {
            k: 900.0,
            x_ap: 0.9,
            y_fz: 0.75,
            z_n: -0.1,
        }),
    },
];

/// The reference image spec.
pub fn reference_spec() -> ImageSpec<'static> {
    ImageSpec {
        axis_id: 1,
        um_per_count: 0.1,
        counter_bits: 32,
        table: Some(TableSpec {
            start_counts: 0,
            segment_counts: SEGMENT_COUNTS,
            forward: &FORWARD,
            backward: &BACKWARD,
            outside: OutsideStroke::Taper {
                length_counts: 20_000,
            },
        }),
        thermo: Some(ThermoForceSpec {
            sensor_period_ms: 100,
            sensors: &SENSORS,
            b0_um: 0.3,
            b_um_per_k: &B_UM_PER_K,
            expansion: Some(ExpansionSpec {
                sensor: 0,
                x_ref_counts: 0,
                c_um_per_mm_k: 0.0115,
            }),
            forces: &FORCES,
        }),
        limits: LimitSpec {
            max_correction_um: 50.0,
            max_slew_um_per_cycle: 0.5,
            direction_hysteresis_counts: 20,
        },
    }
}

/// Length of the reference image.
pub fn reference_image_len() -> usize {
    crate::image_len(&reference_spec())
}

/// Write the reference image into `out` (needs [`reference_image_len`] bytes, about 33 KiB).
pub fn write_reference_image(out: &mut [u8]) -> Result<usize, ImageError> {
    crate::write_image(&reference_spec(), out)
}

/// Reference process parameters (predicted force of term 2).
pub const PROCESS: ProcessParams = ProcessParams {
    ap_mm: 0.8,
    fz_mm: 0.06,
    n_rpm: 900.0,
};

/// Cycle input `i`: a triangle motion over the stroke and a little beyond (157 counts per cycle),
/// command = position + 3, small forces.
pub fn reference_input(i: u32) -> CycleInput {
    let period = 2 * (STROKE_COUNTS as u32 + 40_000);
    let p = (i.wrapping_mul(157)) % period;
    let x = if p < period / 2 { p } else { period - p } as i64 - 20_000;
    let k = (i % 64) as f32;
    CycleInput {
        scale_raw: x as u32,
        command_counts: x + 3,
        forces_n: [40.0 + k, -25.0 + 0.5 * k, 0.0],
    }
}

/// Temperature readings `i` (one per sensor period): slow warm-up.
pub fn reference_temperatures(i: u32) -> [f32; N_SENSORS] {
    let w = (i % 10_000) as f32 * 0.001;
    let mut t = [0.0f32; N_SENSORS];
    for (k, v) in t.iter_mut().enumerate() {
        *v = SENSORS[k].reference_degc + w * (1.0 + 0.1 * k as f32);
    }
    t
}
