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
const fn cubic_table<const N: usize>(off: f32, a1: f32, a2: f32, a3: f32) -> [[f32; 4]; N] {
    let h = 1.0 / N as f32;
    let mut t = [[0.0f32; 4]; N];
    let mut s = 0;
    while s < N {
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
            reference: crate::spec::ThermoReference::Fixed,
            rise_bounds_k: &[],
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

// ---- axis groups: the `group3` and `group5` workloads ----

use crate::group::{AxisName, GroupAxisImage, GroupInput, MAX_AXES};
use crate::rotary::RotaryLocationSpec;

/// Segments per direction of the group workloads' tables (the lookup's cost does not depend on
/// it; small, so that the QEMU bench's pool fits beside the single-axis engine).
pub const GROUP_SEGMENTS: usize = 64;
/// Knot spacing of the linear group tables, counts (stroke 64 × 15 625 = 1 000 000 counts).
pub const GROUP_SEGMENT_COUNTS: u32 = 15_625;
/// Counts per revolution of the group workload's rotary axes (0.36″ per count).
pub const GROUP_COUNTS_PER_REV: u32 = 3_600_000;
/// Coefficient pool the group workloads need: 3 × 2 × 64 (linear, bidirectional) + 2 × 64.
pub const GROUP_POOL: usize = 512;

/// Forward tables of X, Y, Z.
pub static GROUP_FORWARD: [[[f32; 4]; GROUP_SEGMENTS]; 3] = [
    cubic_table(0.0, 8.0, -12.0, 6.0),
    cubic_table(-1.0, 5.0, 3.0, -4.0),
    cubic_table(0.5, -6.0, 9.0, -2.0),
];
/// Backward tables of X, Y, Z (a reversal error of 1–2 µm).
pub static GROUP_BACKWARD: [[[f32; 4]; GROUP_SEGMENTS]; 3] = [
    cubic_table(1.5, 8.0, -12.0, 6.0),
    cubic_table(0.0, 5.5, 3.0, -4.0),
    cubic_table(2.0, -6.0, 9.0, -2.0),
];
/// Tables of A and C over one turn, arc-seconds.
pub static GROUP_ROTARY: [[[f32; 4]; GROUP_SEGMENTS]; 2] = [
    cubic_table(0.0, 20.0, -30.0, 10.0),
    cubic_table(3.0, -15.0, 25.0, -13.0),
];

/// Image spec of group axis `k` (0..3: X, Y, Z linear, bidirectional, 0.1 µm per count, clamp
/// 50 µm, slew 0.5 µm per cycle; 3, 4: A, C over one turn, 0.36″ per count).
pub fn group_axis_spec(k: usize) -> ImageSpec<'static> {
    let limits = LimitSpec {
        max_correction_um: 50.0,
        max_slew_um_per_cycle: 0.5,
        direction_hysteresis_counts: 20,
    };
    if k < 3 {
        ImageSpec {
            axis_id: k as u16 + 1,
            um_per_count: 0.1,
            counter_bits: 32,
            table: Some(TableSpec {
                start_counts: 0,
                segment_counts: GROUP_SEGMENT_COUNTS,
                forward: &GROUP_FORWARD[k % 3],
                backward: &GROUP_BACKWARD[k % 3],
                outside: OutsideStroke::Hold,
            }),
            thermo: None,
            limits,
        }
    } else {
        ImageSpec {
            axis_id: k as u16 + 1,
            um_per_count: 1_296_000.0 / GROUP_COUNTS_PER_REV as f32,
            counter_bits: 32,
            table: Some(TableSpec {
                start_counts: 0,
                segment_counts: GROUP_COUNTS_PER_REV / GROUP_SEGMENTS as u32,
                forward: &GROUP_ROTARY[(k - 3) % 2],
                backward: &[],
                outside: OutsideStroke::Hold,
            }),
            thermo: None,
            limits,
        }
    }
}

/// Name and counts per revolution of group axis `k` (X, Y, Z, A, C).
pub fn group_axis(k: usize) -> (AxisName, u32) {
    match k {
        0 => (AxisName::X, 0),
        1 => (AxisName::Y, 0),
        2 => (AxisName::Z, 0),
        3 => (AxisName::A, GROUP_COUNTS_PER_REV),
        _ => (AxisName::C, GROUP_COUNTS_PER_REV),
    }
}

/// Write the images of the first `n` group axes into `buf` (consecutively) and return them as
/// [`GroupAxisImage`]s (needs about 2.2 KiB per linear axis, 1.2 KiB per rotary one).
pub fn write_group_images<'b>(
    n: usize,
    buf: &'b mut [u8],
) -> Result<([GroupAxisImage<'b>; MAX_AXES], usize), ImageError> {
    let mut lens = [0usize; MAX_AXES];
    let mut at = 0;
    for (k, len) in lens.iter_mut().enumerate().take(n.min(MAX_AXES)) {
        let rest = buf.get_mut(at..).unwrap_or(&mut []);
        *len = crate::write_image(&group_axis_spec(k), rest)?;
        at += *len;
    }
    let buf: &'b [u8] = buf;
    let mut out = [GroupAxisImage {
        name: AxisName::X,
        counts_per_rev: 0,
        image: &[],
    }; MAX_AXES];
    let mut at = 0;
    for k in 0..n.min(MAX_AXES) {
        let (name, counts_per_rev) = group_axis(k);
        out[k] = GroupAxisImage {
            name,
            counts_per_rev,
            image: buf.get(at..at + lens[k]).unwrap_or(&[]),
        };
        at += lens[k];
    }
    Ok((out, n.min(MAX_AXES)))
}

/// The rotary stage of the `group5` workload: location errors of a few µm / µrad, pivot in the
/// middle of the strokes, 100 mm tool.
pub const GROUP_ROTARY_STAGE: RotaryLocationSpec = RotaryLocationSpec {
    ex0c_um: 12.0,
    ey0c_um: -7.0,
    ea0c_urad: 25.0,
    eb0c_urad: -15.0,
    ey0a_um: 9.0,
    ez0a_um: -20.0,
    eb0a_urad: 18.0,
    ec0a_urad: -10.0,
    pivot_counts: [500_000, 500_000, 500_000],
    tool_length_um: 100_000.0,
    ..RotaryLocationSpec::ZERO_AC
};

/// Group input `i`: X, Y, Z in triangle motions of different speeds over their strokes (and a
/// little beyond), all moving every cycle; A swinging ±30° at 40 counts per cycle, C turning
/// continuously at 300 counts per cycle (through 360° every 12 000 cycles); commands = scale + 3.
pub fn group_input(i: u32) -> GroupInput {
    let tri = |speed: u32, stroke: u32, off: i64| {
        let period = 2 * stroke;
        let p = i.wrapping_mul(speed) % period;
        (if p < period / 2 { p } else { period - p }) as i64 + off
    };
    let stroke = GROUP_SEGMENT_COUNTS * GROUP_SEGMENTS as u32;
    let pos = [
        tri(157, stroke + 20_000, -10_000),
        tri(211, stroke, 0),
        tri(97, stroke, 0),
        tri(40, 600_000, -300_000),
        i as i64 * 300,
    ];
    let mut g = GroupInput::ZERO;
    for (a, p) in g.axes.iter_mut().zip(pos) {
        a.scale_raw = p as u32;
        a.command_counts = p + 3;
    }
    g
}

// ---- the `group3_geometry` workload: group3 plus the volumetric geometric stage ----

use crate::geometric::{GeometricCoefficients, GeometricGrid, GeometricSpec};

/// Segments per axis of the geometric workload's grids (the stage's cost does not depend on it;
/// small, so that its 14 × 8 pool entries fit beside group3's tables in [`GROUP_POOL`]).
pub const GROUP_GEOMETRIC_SEGMENTS: usize = 8;

/// The 18 functions of the geometric workload: per axis and segment, EX?, EY?, EZ? (µm, a few
/// µm) and EA?, EB?, EC? (µrad, tens of µrad), cubic in each segment.
const fn geometric_coefficients() -> [[f32; 4]; 3 * GROUP_GEOMETRIC_SEGMENTS * 6] {
    let mut out = [[0.0f32; 4]; 3 * GROUP_GEOMETRIC_SEGMENTS * 6];
    let mut i = 0;
    while i < out.len() {
        let f = i % 6;
        let scale = if f < 3 { 1.0 } else { 4.0 };
        let k = (i % 11) as f32;
        out[i] = [
            scale * (k - 5.0) * 0.4,
            scale * 0.8,
            scale * -0.3,
            scale * 0.05 * (k - 5.0),
        ];
        i += 1;
    }
    out
}

/// Coefficients of [`group_geometric`].
pub static GROUP_GEOMETRIC_COEFFICIENTS: [[f32; 4]; 3 * GROUP_GEOMETRIC_SEGMENTS * 6] =
    geometric_coefficients();

/// The geometric model of the `group3_geometry` workload: stacking YX/Z (table on X on Y,
/// spindle on Z), every component identified, squareness 20 / −15 / 30 µrad, a 100 mm tool along
/// −Z, grids over the group tables' strokes (8 segments of 125 000 counts).
pub fn group_geometric() -> GeometricSpec<'static> {
    let grid = GeometricGrid {
        start_counts: 0,
        segment_counts: GROUP_SEGMENT_COUNTS * GROUP_SEGMENTS as u32
            / GROUP_GEOMETRIC_SEGMENTS as u32,
        n_segments: GROUP_GEOMETRIC_SEGMENTS as u32,
    };
    GeometricSpec {
        chain: [0, 1, 2],
        work_axes: 2,
        identified: (1 << 21) - 1,
        tool_offset_um: [0.0, 0.0, -100_000.0],
        squareness_urad: [20.0, -15.0, 30.0],
        grids: [grid; 3],
        coefficients: GeometricCoefficients::Values(&GROUP_GEOMETRIC_COEFFICIENTS),
    }
}
