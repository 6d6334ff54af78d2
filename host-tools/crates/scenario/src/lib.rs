//! Trace scenarios for replay on the host and in QEMU (host only, feature `std`).
//!
//! Glossary:
//! - **Scenario**: a named, deterministic generator of a binary trace (`axcomp_core::trace` format).
//! - **`equivalence`**: the scenario of the QEMU equivalence test. It exercises every path of the pipeline:
//!   a bidirectional table with direction reversals and hysteresis, a 16-bit scale counter that wraps, motion
//!   beyond both table ends (taper), temperature ramps through first-order lags, scale expansion, an
//!   implausible temperature jump, a sensor that goes stale long enough to freeze the thermal term and then
//!   recovers, measured force steps (with NaN and implausible samples) and a predicted force from process
//!   parameters, the correction clamp and slew limit, a corrupt table image (rejected, the running one
//!   kept) and later a valid replacement (A/B swap), and a state reset.
//! - **`reference`**: the core's benchmark workload (`axcomp_core::bench`): full 1024-segment bidirectional
//!   table, 8 lagged sensors, 3 force terms.
//!
//! - **`group3`** / **`group5`**: axis groups (trace records `GroupCycle`, `AxisTemperatures`,
//!   `GroupReset`): three linear axes X, Y, Z (bidirectional tables, clamp and slew, X with two
//!   lagged sensors), and for `group5` also rotary A and C (tables over the turn, C turning through
//!   360° several times, A swinging) with the rotary location-error stage; all axes move at once.
//!   Both: a group image of schema 2 at the start, a corrupt one (a flipped bit in a section,
//!   re-sealed whole-image CRC: the section CRC refuses it, nothing changes), a valid replacement
//!   (A/B swap of every axis at once) and a group reset.
//!
//! Cycles run at 10 kHz; temperatures arrive every 100 ms (1000 cycles).

use std::vec;
use std::vec::Vec;

use axcomp_core::trace::{self, Record, Temperatures};
use axcomp_core::{
    ExpansionSpec, ForceLaw, ForceSpec, ImageError, ImageSpec, LimitSpec, OutsideStroke,
    ProcessParams, SensorSpec, TableSpec, ThermoForceSpec, bench, image_len, write_image,
};

/// Scenario names accepted by [`generate`].
pub const NAMES: &[&str] = &["equivalence", "reference", "group3", "group5"];
/// Default cycle count of [`generate`].
pub const DEFAULT_CYCLES: u32 = 20_000;
/// Cycles per temperature update (100 ms at 10 kHz).
pub const CYCLES_PER_TEMPERATURE: u32 = 1000;
/// Cycle rate the scenarios assume.
pub const CYCLE_RATE_HZ: u32 = 10_000;

/// Scenario generation error.
#[derive(Debug, Clone, PartialEq)]
pub enum ScenarioError {
    UnknownScenario(std::string::String),
    TooFewCycles { scenario: &'static str, min: u32 },
    Image(ImageError),
}

impl core::fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            ScenarioError::UnknownScenario(n) => {
                write!(f, "unknown scenario `{n}` (known: {})", NAMES.join(", "))
            }
            ScenarioError::TooFewCycles { scenario, min } => {
                write!(f, "scenario `{scenario}` needs at least {min} cycles")
            }
            ScenarioError::Image(e) => write!(f, "building the scenario's image: {e}"),
        }
    }
}

impl std::error::Error for ScenarioError {}

/// A trace being built in memory.
pub struct TraceBuilder {
    bytes: Vec<u8>,
}

impl Default for TraceBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl TraceBuilder {
    pub fn new() -> Self {
        let mut bytes = vec![0u8; trace::TRACE_HEADER_LEN];
        trace::write_header(&mut bytes).expect("header fits its own length");
        TraceBuilder { bytes }
    }

    pub fn push(&mut self, rec: &Record) {
        let at = self.bytes.len();
        self.bytes.resize(at + rec.encoded_len(), 0);
        trace::encode_record(rec, &mut self.bytes[at..]).expect("record fits its encoded length");
    }

    /// The trace with its `Crc` record (CRC-32 of every byte before it) and `End`.
    pub fn finish(mut self) -> Vec<u8> {
        let crc = axcomp_core::crc32(&self.bytes);
        self.push(&Record::Crc(crc));
        self.push(&Record::End);
        self.bytes
    }
}

fn build_image(spec: &ImageSpec) -> Result<Vec<u8>, ScenarioError> {
    let mut out = vec![0u8; image_len(spec)];
    let n = write_image(spec, &mut out).map_err(ScenarioError::Image)?;
    out.truncate(n);
    Ok(out)
}

/// Counter width of the equivalence images: 16 bits, so the scale counter wraps during the motion.
pub const EQUIVALENCE_COUNTER_BITS: u8 = 16;
const EQ_SEGMENTS: usize = 48;
const EQ_SEGMENT_COUNTS: u32 = 2500;
const EQ_START_COUNTS: i64 = -10_000;

fn eq_table(scale: f32, phase: f32, offset: f32) -> Vec<[f32; 4]> {
    // Segments of a smooth periodic-plus-linear deviation (not a spline fit: any finite cubic pieces will do).
    (0..EQ_SEGMENTS)
        .map(|s| {
            let u = s as f32 + phase;
            let c0 = offset + scale * (0.08 * u + 2.0 * (0.4 * u).sin());
            let c1 = scale * (0.08 + 0.8 * (0.4 * u).cos());
            let c2 = scale * -0.16 * (0.4 * u).sin();
            let c3 = scale * -0.02 * (0.4 * u).cos();
            [c0, c1, c2, c3]
        })
        .collect()
}

fn eq_sensor(reference_degc: f32, lag_tau_s: f32) -> SensorSpec {
    SensorSpec {
        reference_degc,
        min_degc: 0.0,
        max_degc: 80.0,
        max_rate_degc_per_s: 5.0,
        lag_tau_s,
        stale_timeout_ms: 500,
    }
}

/// The two valid tables of the equivalence scenario (`second = false`: initial; `true`: replacement).
pub fn equivalence_image(second: bool) -> Result<Vec<u8>, ScenarioError> {
    let (fw, bw) = if second {
        (eq_table(1.3, 0.5, -0.7), eq_table(1.3, 0.5, 0.9))
    } else {
        (eq_table(1.0, 0.0, 0.0), eq_table(1.0, 0.0, 1.8))
    };
    let sensors = [
        eq_sensor(20.0, 0.0),
        eq_sensor(20.0, 5.0),
        eq_sensor(21.0, 30.0),
        eq_sensor(20.5, 0.0),
    ];
    let b = [1.1f32, -0.6, 0.9, 0.3];
    let forces = [
        ForceSpec {
            chi_um_per_n: 0.004,
            law: None,
        },
        ForceSpec {
            chi_um_per_n: -0.002,
            law: Some(ForceLaw {
                k: 1100.0,
                x_ap: 0.85,
                y_fz: 0.7,
                z_n: -0.15,
            }),
        },
    ];
    let spec = ImageSpec {
        axis_id: 3,
        um_per_count: 0.1,
        counter_bits: EQUIVALENCE_COUNTER_BITS,
        table: Some(TableSpec {
            start_counts: EQ_START_COUNTS,
            segment_counts: EQ_SEGMENT_COUNTS,
            forward: &fw,
            backward: &bw,
            outside: if second {
                OutsideStroke::Hold
            } else {
                OutsideStroke::Taper {
                    length_counts: 8000,
                }
            },
        }),
        thermo: Some(ThermoForceSpec {
            sensor_period_ms: 100,
            sensors: &sensors,
            b0_um: 0.25,
            b_um_per_k: &b,
            expansion: Some(ExpansionSpec {
                sensor: 0,
                x_ref_counts: 0,
                c_um_per_mm_k: 0.0117,
            }),
            forces: &forces,
            reference: axcomp_core::ThermoReference::Fixed,
            rise_bounds_k: &[],
        }),
        limits: LimitSpec {
            max_correction_um: 5.0,
            max_slew_um_per_cycle: 0.05,
            direction_hysteresis_counts: 12,
        },
    };
    build_image(&spec)
}

/// Extended position of the equivalence motion at cycle `i`: a slow triangle from −25 000 to 135 000 counts
/// (beyond both table ends, crossing the 16-bit counter wrap several times) with a fast ±30-count dither that
/// makes small reversals (some inside the hysteresis), and dwells.
fn eq_position(i: u32) -> i64 {
    let span: i64 = 160_000;
    let period: i64 = 12_000; // cycles for one up-and-down
    let p = i64::from(i) % period;
    let half = period / 2;
    let tri = if p < half { p } else { period - p }; // 0..=half
    let base = -25_000 + span * tri / half;
    let dwell = (i / 1700) % 5 == 4; // every fifth block of 1700 cycles, stand still (with dither)
    let base = if dwell {
        let q = i64::from(i - i % 1700) % period;
        -25_000 + span * (if q < half { q } else { period - q }) / half
    } else {
        base
    };
    let dither = match i % 40 {
        0..=9 => 0,
        10..=19 => 8,
        20..=29 => 30,
        _ => -6,
    };
    base + dither
}

fn eq_temperatures(k: u32, n_updates: u32) -> [f32; 4] {
    let t = k as f32 * 0.1; // seconds
    let mut v = [
        20.0 + 0.05 * t, // slow ramp
        20.0 + 0.30 * t, // fast ramp (lagged, 5 s)
        21.0 + 2.0 * (0.2 * t).sin(),
        20.5 - 0.02 * t,
    ];
    // Sensor 1: one implausible jump (rate limit 5 K/s at 100 ms → > 0.5 K step is rejected).
    if k == n_updates / 5 {
        v[1] += 9.0;
    }
    // Sensor 3: no readings from 35 % to 70 % of the run (longer than the 500 ms stale timeout).
    if k >= n_updates * 35 / 100 && k < n_updates * 70 / 100 {
        v[3] = f32::NAN;
    }
    // Sensor 2: out of its range once.
    if k == n_updates / 2 + 1 {
        v[2] = 95.0;
    }
    v
}

/// The equivalence scenario. `first_image` replaces the initial image (e.g. `axcomp trace --image`).
pub fn equivalence(cycles: u32, first_image: Option<&[u8]>) -> Result<Vec<u8>, ScenarioError> {
    let min = 10 * CYCLES_PER_TEMPERATURE;
    if cycles < min {
        return Err(ScenarioError::TooFewCycles {
            scenario: "equivalence",
            min,
        });
    }
    let own_first = equivalence_image(false)?;
    let first = first_image.unwrap_or(&own_first);
    let second = equivalence_image(true)?;
    let mut corrupt = second.clone();
    let mid = corrupt.len() / 2;
    corrupt[mid] ^= 0x10; // one flipped bit: the CRC must reject it

    let n_updates = cycles / CYCLES_PER_TEMPERATURE;
    let mut t = TraceBuilder::new();
    t.push(&Record::Reset {
        scale_raw: (eq_position(0) as u32) & 0xFFFF,
    });
    // A few cycles on the identity before any image (status NO_IMAGE).
    let mut i = 0u32;
    let cycle = |t: &mut TraceBuilder, i: u32| {
        let x = eq_position(i);
        let following = (eq_position(i + 1) - x) * 3; // command leads the position a little
        let force_step = match (i / 2300) % 4 {
            0 => 0.0,
            1 => 180.0,
            2 => -95.5,
            _ => 40.25,
        };
        let input = axcomp_core::CycleInput {
            scale_raw: x as u32, // the hardware counter: low bits of the position
            command_counts: x + following,
            forces_n: [
                match i % 4999 {
                    // A dropped force sample (NaN) and an implausible one: ignored and flagged.
                    1234 => f32::NAN,
                    2345 => 3.0e7,
                    _ => force_step + (i % 7) as f32 * 0.5,
                },
                0.0,
                0.0,
            ],
        };
        t.push(&Record::Cycle(input));
    };
    while i < 5 {
        cycle(&mut t, i);
        i += 1;
    }
    t.push(&Record::Image(first));
    t.push(&Record::Process(ProcessParams {
        ap_mm: 1.2,
        fz_mm: 0.08,
        n_rpm: 2400.0,
    }));
    let corrupt_at = cycles * 2 / 5;
    let replace_at = cycles * 3 / 5;
    let process_at = cycles / 2;
    let reset_at = cycles * 9 / 10;
    while i < cycles {
        if i % CYCLES_PER_TEMPERATURE == 0 {
            let k = i / CYCLES_PER_TEMPERATURE;
            let now_ms = i / (CYCLE_RATE_HZ / 1000);
            t.push(&Record::Temperatures(Temperatures::new(
                now_ms,
                &eq_temperatures(k, n_updates),
            )));
        }
        if i == corrupt_at {
            t.push(&Record::Image(&corrupt));
        }
        if i == replace_at {
            t.push(&Record::Image(&second));
        }
        if i == process_at {
            t.push(&Record::Process(ProcessParams {
                ap_mm: 2.5,
                fz_mm: 0.12,
                n_rpm: 1800.0,
            }));
        }
        if i == reset_at {
            t.push(&Record::Reset {
                scale_raw: (eq_position(i) as u32) & 0xFFFF,
            });
        }
        cycle(&mut t, i);
        i += 1;
    }
    Ok(t.finish())
}

/// The core's benchmark workload as a trace (`first_image` replaces the reference image).
pub fn reference(cycles: u32, first_image: Option<&[u8]>) -> Result<Vec<u8>, ScenarioError> {
    let mut own = vec![0u8; bench::reference_image_len()];
    let n = bench::write_reference_image(&mut own).map_err(ScenarioError::Image)?;
    own.truncate(n);
    let mut t = TraceBuilder::new();
    t.push(&Record::Image(first_image.unwrap_or(&own)));
    t.push(&Record::Process(bench::PROCESS));
    for i in 0..cycles {
        if i % CYCLES_PER_TEMPERATURE == 0 {
            t.push(&Record::Temperatures(Temperatures::new(
                i / (CYCLE_RATE_HZ / 1000),
                &bench::reference_temperatures(i / CYCLES_PER_TEMPERATURE),
            )));
        }
        t.push(&Record::Cycle(bench::reference_input(i)));
    }
    Ok(t.finish())
}

/// The group image of the `group3`/`group5` scenarios: the core's group workload axes
/// (`axcomp_core::bench::group_axis_spec`), X with two lagged sensors, and for five axes the
/// workload's rotary stage; `second` scales the tables (the replacement image).
pub fn group_image(n_axes: usize, second: bool) -> Result<Vec<u8>, ScenarioError> {
    group_image_variant(n_axes, second, GroupImageVariant::Board)
}

/// How a group image of [`group_image_variant`] differs from the `group3`/`group5` one (the drive
/// fault matrix's images that do not fit the board).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GroupImageVariant {
    /// As [`group_image`]: 16-bit counters, axis ids 1…n, X with two sensors.
    Board,
    /// Every axis with this counter width.
    CounterBits(u8),
    /// Axis `slot` with axis id `id`.
    AxisId { slot: usize, id: u16 },
    /// X with this many sensors (1–4).
    Sensors(usize),
    /// X's first sensor named `warmup` (a warm-up drift input; the board has only RTDs).
    WarmupSensor,
}

/// [`group_image`] with a [`GroupImageVariant`].
pub fn group_image_variant(
    n_axes: usize,
    second: bool,
    variant: GroupImageVariant,
) -> Result<Vec<u8>, ScenarioError> {
    use axcomp_core::group_image::{AxisSectionSpec, group_image_len, write_group_image};
    let all_sensors = [
        eq_sensor(20.0, 30.0),
        eq_sensor(21.0, 0.0),
        eq_sensor(22.0, 0.0),
        eq_sensor(23.0, 0.0),
    ];
    let all_b = [0.8f32, -0.3, 0.2, 0.1];
    let n_sensors = match variant {
        GroupImageVariant::Sensors(k) => k.clamp(1, 4),
        _ => 2,
    };
    let sensors = &all_sensors[..n_sensors];
    let b = &all_b[..n_sensors];
    let scale = if second { 1.2f32 } else { 1.0 };
    let scaled: Vec<Vec<[f32; 4]>> = (0..10)
        .map(|k| {
            let t: &[[f32; 4]] = match k {
                0..=2 => &bench::GROUP_FORWARD[k],
                3..=5 => &bench::GROUP_BACKWARD[k - 3],
                _ => &bench::GROUP_ROTARY[(k - 6) % 2],
            };
            t.iter().map(|c| c.map(|v| v * scale)).collect()
        })
        .collect();
    let mut images = Vec::new();
    for k in 0..n_axes {
        let mut spec = bench::group_axis_spec(k);
        if let Some(t) = spec.table.as_mut() {
            if k < 3 {
                t.forward = &scaled[k];
                t.backward = &scaled[3 + k];
            } else {
                t.forward = &scaled[6 + (k - 3)];
            }
        }
        spec.counter_bits = match variant {
            GroupImageVariant::CounterBits(bits) => bits,
            _ => EQUIVALENCE_COUNTER_BITS,
        };
        if let GroupImageVariant::AxisId { slot, id } = variant {
            if slot == k {
                spec.axis_id = id;
            }
        }
        if k == 0 {
            spec.thermo = Some(ThermoForceSpec {
                sensor_period_ms: 100,
                sensors,
                b0_um: 0.4,
                b_um_per_k: b,
                expansion: None,
                forces: &[],
                reference: axcomp_core::ThermoReference::Fixed,
                rise_bounds_k: &[],
            });
        }
        images.push(build_image(&spec)?);
    }
    // The replays' board names its two inputs `spindle`, `column` (the firmware wires sensors by name).
    let mut all_names: [&str; 4] = ["spindle", "column", "bed", "table"];
    if variant == GroupImageVariant::WarmupSensor {
        all_names[0] = "warmup";
    }
    let names = &all_names[..n_sensors];
    let axes: Vec<AxisSectionSpec> = images
        .iter()
        .enumerate()
        .map(|(k, img)| {
            let (name, counts_per_rev) = bench::group_axis(k);
            AxisSectionSpec {
                name,
                counts_per_rev,
                stroke_counts: None,
                image: img,
                sensor_names: if k == 0 { names } else { &[] },
            }
        })
        .collect();
    let stage = (n_axes == 5).then_some(&bench::GROUP_ROTARY_STAGE);
    let mut out = vec![0u8; group_image_len(&axes, stage)];
    let n = write_group_image(&axes, stage, &mut out).map_err(ScenarioError::Image)?;
    out.truncate(n);
    Ok(out)
}

/// The `group3`/`group5` scenario with `n_axes` axes (3 or 5) and `cycles` group cycles.
pub fn group(n_axes: usize, cycles: u32) -> Result<Vec<u8>, ScenarioError> {
    const MIN: u32 = 6000;
    if cycles < MIN {
        return Err(ScenarioError::TooFewCycles {
            scenario: if n_axes == 5 { "group5" } else { "group3" },
            min: MIN,
        });
    }
    let first = group_image(n_axes, false)?;
    let second = group_image(n_axes, true)?;
    // A flipped bit inside the first section, the whole-image CRC re-sealed: only the section
    // CRC can refuse it.
    let mut corrupt = second.clone();
    let at = axcomp_core::group_image::GROUP_HEADER_LEN + 20 * 8 + 40;
    let at = at.min(corrupt.len() - 5);
    corrupt[at] ^= 0x04;
    let body = corrupt.len() - 4;
    let crc = axcomp_core::crc32(&corrupt[..body]);
    corrupt[body..].copy_from_slice(&crc.to_le_bytes());
    let n = n_axes as u8;
    let mut t = TraceBuilder::new();
    // A few cycles before any image: identity.
    for i in 0..5 {
        t.push(&Record::GroupCycle {
            n,
            input: bench::group_input(i),
        });
    }
    t.push(&Record::Image(&first));
    for i in 5..cycles {
        if i % CYCLES_PER_TEMPERATURE == 0 {
            let k = i / CYCLES_PER_TEMPERATURE;
            let w = k as f32 * 0.05;
            t.push(&Record::AxisTemperatures {
                slot: 0,
                t: Temperatures::new(k * 100, &[20.0 + w, 21.0 + 0.5 * w]),
            });
        }
        if i == cycles / 3 {
            t.push(&Record::Image(&corrupt));
        }
        if i == cycles / 2 {
            t.push(&Record::Image(&second));
        }
        if i == 2 * cycles / 3 {
            let input = bench::group_input(i);
            let mut scale_raw = [0u32; axcomp_core::group::MAX_AXES];
            for (r, a) in scale_raw.iter_mut().zip(input.axes.iter()) {
                *r = a.scale_raw;
            }
            t.push(&Record::GroupReset { n, scale_raw });
        }
        let mut input = bench::group_input(i);
        // 16-bit counters: the scale counters wrap as they move.
        for a in input.axes.iter_mut() {
            a.scale_raw &= 0xFFFF;
        }
        t.push(&Record::GroupCycle { n, input });
    }
    Ok(t.finish())
}

/// Generates scenario `name` with `cycles` cycle records.
pub fn generate(
    name: &str,
    cycles: u32,
    first_image: Option<&[u8]>,
) -> Result<Vec<u8>, ScenarioError> {
    match name {
        "equivalence" => equivalence(cycles, first_image),
        "reference" => reference(cycles, first_image),
        "group3" => group(3, cycles),
        "group5" => group(5, cycles),
        other => Err(ScenarioError::UnknownScenario(other.into())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use axcomp_core::{Engine, Flags};
    use std::boxed::Box;

    #[test]
    fn equivalence_scenario_exercises_every_path() {
        let bytes = equivalence(DEFAULT_CYCLES, None).unwrap();
        let mut engine = Box::new(Engine::new());
        let mut seen = 0u16;
        let mut status = 0u8;
        let mut slots = [false; 2];
        let mut outputs = 0;
        let mut wrapped = false;
        let mut last_raw = None;
        for r in trace::Reader::new(&bytes).unwrap() {
            let rec = r.expect("the scenario writes only well-formed records");
            if let Record::Cycle(c) = rec {
                let raw = c.scale_raw & 0xFFFF;
                if let Some(l) = last_raw {
                    let d: u32 = raw.wrapping_sub(l) & 0xFFFF;
                    wrapped |=
                        (raw < 1000 && l > 64_000) || (l < 1000 && raw > 64_000 && d > 32768);
                }
                last_raw = Some(raw);
            }
            if let Some(o) = engine.step(&rec) {
                outputs += 1;
                seen |= o.flags;
                status |= o.status;
                slots[o.slot as usize] = true;
            }
        }
        assert_eq!(outputs, DEFAULT_CYCLES);
        assert!(wrapped, "the 16-bit counter wraps");
        let s = engine.stats();
        assert_eq!((s.images_accepted, s.images_rejected), (2, 1));
        assert_eq!(
            status & 7,
            7,
            "accepted, rejected and no-image statuses all occur"
        );
        assert!(slots[0] && slots[1], "both slots run");
        for (flag, name) in [
            (Flags::TABLE_OUTSIDE, "TABLE_OUTSIDE"),
            (Flags::CLAMPED, "CLAMPED"),
            (Flags::SLEWED, "SLEWED"),
            (Flags::SENSOR_FAULT, "SENSOR_FAULT"),
            (Flags::THERMAL_FROZEN, "THERMAL_FROZEN"),
            (Flags::BACKWARD, "BACKWARD"),
            (Flags::IDENTITY, "IDENTITY"),
            (Flags::FORCE_INVALID, "FORCE_INVALID"),
        ] {
            assert!(
                seen & flag.bits() != 0,
                "flag {name} never set by the scenario"
            );
        }
    }

    #[test]
    fn group_scenarios_exercise_their_paths() {
        use axcomp_core::group::{GroupEngine, MAX_AXES};
        use axcomp_core::trace::OutputRecord;
        for n in [3usize, 5] {
            let bytes = group(n, 30_000).unwrap();
            let mut engine: Box<GroupEngine<512>> = Box::new(GroupEngine::new());
            let mut out = [OutputRecord::decode(&[0; 32]).unwrap(); MAX_AXES];
            let (mut cycles, mut seen, mut status, mut slots) = (0, 0u16, 0u8, [false; 2]);
            for r in trace::Reader::new(&bytes).unwrap() {
                let rec = r.expect("well-formed records");
                let k = engine.step(&rec, &mut out);
                if k > 0 {
                    assert_eq!(k, n);
                    cycles += 1;
                    for o in &out[..k] {
                        seen |= o.flags;
                        status |= o.status;
                        slots[o.slot as usize] = true;
                    }
                }
            }
            assert_eq!(cycles, 30_000);
            let s = engine.stats();
            assert_eq!((s.images_accepted, s.images_rejected), (2, 1), "{n} axes");
            assert_eq!(status & 7, 7);
            assert!(slots[0] && slots[1]);
            for f in [
                Flags::BACKWARD,
                Flags::SLEWED,
                Flags::IDENTITY,
                Flags::TABLE_OUTSIDE,
            ] {
                assert!(seen & f.bits() != 0, "{n} axes: {f:?} never set");
            }
            if n == 5 {
                assert!(engine.state().angle_refreshes() > 1000);
            }
        }
    }

    #[test]
    fn unknown_scenario_and_short_runs_are_errors() {
        assert!(matches!(
            generate("nope", 100, None),
            Err(ScenarioError::UnknownScenario(_))
        ));
        assert!(matches!(
            generate("equivalence", 100, None),
            Err(ScenarioError::TooFewCycles { .. })
        ));
        let r = generate("reference", 3000, None).unwrap();
        assert_eq!(
            trace::Reader::new(&r)
                .unwrap()
                .filter(|x| matches!(x, Ok(Record::Cycle(_))))
                .count(),
            3000
        );
    }
}
