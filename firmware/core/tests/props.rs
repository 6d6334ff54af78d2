//! Property tests: limits always hold, nothing panics, NaN/inf never reach an output, images
//! round-trip, corrupted images are never accepted, trace readers survive garbage.

mod common;
use axcomp_core::trace::{Reader, Record, Temperatures, Writer};
use axcomp_core::*;
use common::*;
use proptest::prelude::*;

/// Any f32 including NaN, ±inf, subnormals and extremes.
fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        4 => -200.0f32..200.0,
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::NEG_INFINITY),
        1 => Just(f32::MAX),
        1 => Just(f32::MIN),
        1 => any::<u32>().prop_map(f32::from_bits),
    ]
}

#[derive(Debug, Clone)]
enum Op {
    Cycle(u32, i64, [f32; 3]),
    Temps(u32, Vec<f32>),
    Process(f32, f32, f32),
    /// Homing to an arbitrary (also extreme) extended position.
    Home(u32, i64),
}

fn any_op() -> impl Strategy<Value = Op> {
    prop_oneof![
        6 => (
            prop_oneof![any::<u32>(), 0u32..2000, Just(0u32), Just(u32::MAX)],
            prop_oneof![any::<i64>(), Just(i64::MIN), Just(i64::MAX), -10_000i64..10_000],
            [any_f32(), any_f32(), any_f32()],
        )
            .prop_map(|(r, c, f)| Op::Cycle(r, c, f)),
        2 => (any::<u32>(), prop::collection::vec(any_f32(), 0..20))
            .prop_map(|(t, v)| Op::Temps(t, v)),
        1 => (any_f32(), any_f32(), any_f32()).prop_map(|(a, b, c)| Op::Process(a, b, c)),
        1 => (
            any::<u32>(),
            prop_oneof![any::<i64>(), Just(i64::MIN), Just(i64::MAX), Just(i64::MIN + 1)],
        )
            .prop_map(|(r, p)| Op::Home(r, p)),
    ]
}

/// A valid image spec drawn from the allowed ranges, owning its slices.
#[derive(Debug, Clone)]
struct Owned {
    um_per_count: f32,
    counter_bits: u8,
    start: i64,
    seg: u32,
    fwd: Vec<[f32; 4]>,
    bwd: Vec<[f32; 4]>,
    taper: Option<u32>,
    sensors: Vec<SensorSpec>,
    b: Vec<f32>,
    b0: f32,
    expansion: Option<(u8, i64, f32)>,
    forces: Vec<ForceSpec>,
    limits: LimitSpec,
}

impl Owned {
    fn spec(&self) -> ImageSpec<'_> {
        ImageSpec {
            axis_id: 9,
            um_per_count: self.um_per_count,
            counter_bits: self.counter_bits,
            table: Some(TableSpec {
                start_counts: self.start,
                segment_counts: self.seg,
                forward: &self.fwd,
                backward: &self.bwd,
                outside: match self.taper {
                    Some(l) => OutsideStroke::Taper { length_counts: l },
                    None => OutsideStroke::Hold,
                },
            }),
            thermo: Some(ThermoForceSpec {
                sensor_period_ms: 100,
                sensors: &self.sensors,
                b0_um: self.b0,
                b_um_per_k: &self.b,
                expansion: self.expansion.map(|(s, x, c)| ExpansionSpec {
                    sensor: s,
                    x_ref_counts: x,
                    c_um_per_mm_k: c,
                }),
                forces: &self.forces,
                reference: ThermoReference::Fixed,
                rise_bounds_k: &[],
            }),
            limits: self.limits,
        }
    }
}

fn coef() -> impl Strategy<Value = [f32; 4]> {
    [
        -2000.0f32..2000.0,
        -500.0f32..500.0,
        -500.0f32..500.0,
        -500.0f32..500.0,
    ]
}

fn any_spec() -> impl Strategy<Value = Owned> {
    (1usize..40, any::<bool>(), 0usize..=4, 0usize..=MAX_FORCES).prop_flat_map(
        |(n, bidir, ns, nf)| {
            let sensors = prop::collection::vec(
                (0.0f32..40.0, 0.0f32..600.0, 0.1f32..50.0, 1u32..100_000).prop_map(
                    |(r, tau, rate, stale)| SensorSpec {
                        reference_degc: r,
                        min_degc: -40.0,
                        max_degc: 150.0,
                        max_rate_degc_per_s: rate,
                        lag_tau_s: tau,
                        stale_timeout_ms: stale,
                    },
                ),
                ns,
            );
            let forces = prop::collection::vec(
                (
                    -1.0f32..1.0,
                    prop::option::of((1.0f32..5000.0, -2.0f32..2.0)),
                )
                    .prop_map(|(chi, law)| ForceSpec {
                        chi_um_per_n: chi,
                        law: law.map(|(k, e)| ForceLaw {
                            k,
                            x_ap: e,
                            y_fz: 0.5 * e,
                            z_n: -0.1,
                        }),
                    }),
                nf,
            );
            (
                (
                    prop_oneof![Just(0.1f32), 0.001f32..10.0],
                    16u8..=32,
                    -(1i64 << 40)..(1i64 << 40),
                    1u32..100_000,
                    prop::collection::vec(coef(), n),
                    prop::collection::vec(coef(), if bidir { n } else { 0 }),
                    prop::option::of(1u32..1_000_000),
                ),
                (
                    sensors,
                    prop::collection::vec(-10.0f32..10.0, ns),
                    -100.0f32..100.0,
                    prop::option::of((0u8..8, -(1i64 << 40)..(1i64 << 40), -0.1f32..0.1)),
                    forces,
                    (0.001f32..500.0, 0.0001f32..20.0, 0u32..1000),
                ),
            )
                .prop_map(
                    move |(
                        (upc, bits, start, seg, fwd, bwd, taper),
                        (sensors, b, b0, exp, forces, (maxc, slew, hyst)),
                    )| Owned {
                        um_per_count: upc,
                        counter_bits: bits,
                        start,
                        seg,
                        fwd,
                        bwd,
                        taper,
                        expansion: exp.and_then(|(s, x, c)| {
                            (!sensors.is_empty()).then(|| (s % sensors.len() as u8, x, c))
                        }),
                        sensors,
                        b,
                        b0,
                        forces,
                        limits: LimitSpec {
                            max_correction_um: maxc,
                            max_slew_um_per_cycle: slew,
                            direction_hysteresis_counts: hyst,
                        },
                    },
                )
        },
    )
}

fn run_ops(
    comp: &Compensator,
    ops: &[Op],
    limits: LimitSpec,
    upc: f32,
) -> Result<(), TestCaseError> {
    let mut st = State::new();
    let mut last_um = 0.0f32;
    let mut last_counts = 0i32;
    for op in ops {
        match op {
            Op::Cycle(r, c, f) => {
                let o = comp.cycle(
                    &mut st,
                    &CycleInput {
                        scale_raw: *r,
                        command_counts: *c,
                        forces_n: *f,
                    },
                );
                prop_assert!(o.correction_um.is_finite());
                prop_assert!(
                    o.correction_um.abs() <= limits.max_correction_um,
                    "|{}| > clamp {}",
                    o.correction_um,
                    limits.max_correction_um
                );
                // Slew: f32 rounding of last ± slew allows one ulp of the larger operand.
                let tol = limits.max_slew_um_per_cycle
                    + f32::EPSILON * (limits.max_correction_um + limits.max_slew_um_per_cycle);
                prop_assert!(
                    (o.correction_um - last_um).abs() <= tol,
                    "slew {} -> {} (limit {})",
                    last_um,
                    o.correction_um,
                    limits.max_slew_um_per_cycle
                );
                // In counts: slew/um_per_count plus one count for the two roundings (half each).
                let max_dc = (limits.max_slew_um_per_cycle / upc) as f64 * (1.0 + 1e-6) + 1.0;
                prop_assert!(
                    ((o.correction_counts as i64 - last_counts as i64).abs() as f64) <= max_dc
                );
                prop_assert_eq!(
                    o.corrected_command_counts,
                    c.saturating_sub(o.correction_counts as i64)
                );
                last_um = o.correction_um;
                last_counts = o.correction_counts;
            }
            Op::Temps(t, v) => comp.update_temperatures(&mut st, *t, v),
            Op::Process(a, b, c) => comp.set_process(
                &mut st,
                &ProcessParams {
                    ap_mm: *a,
                    fz_mm: *b,
                    n_rpm: *c,
                },
            ),
            Op::Home(r, p) => st.home(*r, *p),
        }
        prop_assert!(st.sensor_term_um().is_finite());
        prop_assert!(st.expansion_um_per_count().is_finite());
        for j in 0..MAX_FORCES {
            prop_assert!(st.predicted_force_n(j).is_finite());
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn limits_hold_and_nothing_leaks(o in any_spec(), ops in prop::collection::vec(any_op(), 1..200)) {
        let spec = o.spec();
        let comp = load(&spec);
        run_ops(&comp, &ops, spec.limits, spec.um_per_count)?;
    }

    #[test]
    fn slow_motion_through_the_stroke(o in any_spec(), steps in prop::collection::vec(-3000i32..3000, 1..300)) {
        // Realistic motion (small steps) around the table start, temperatures changing.
        let spec = o.spec();
        let comp = load(&spec);
        let mut ops = Vec::new();
        let mut pos = spec.table.unwrap().start_counts;
        for (k, s) in steps.iter().enumerate() {
            pos += *s as i64 * 10;
            ops.push(Op::Cycle(pos as u32, pos, [10.0, -5.0, 1.0]));
            if k % 5 == 0 {
                ops.push(Op::Temps(k as u32 * 100, vec![20.0 + k as f32 * 0.01; 4]));
            }
        }
        run_ops(&comp, &ops, spec.limits, spec.um_per_count)?;
    }

    #[test]
    fn image_round_trip(o in any_spec()) {
        let spec = o.spec();
        let comp = load(&spec);
        let t = spec.table.unwrap();
        prop_assert_eq!(comp.um_per_count(), spec.um_per_count);
        prop_assert_eq!(comp.counter_bits(), spec.counter_bits);
        prop_assert_eq!(comp.table_start_counts(), t.start_counts);
        prop_assert_eq!(comp.segment_counts(), t.segment_counts);
        // Held as the cycle evaluates them: converted to the remainder in counts.
        let held = |tab: &[[f32; 4]]| -> Vec<[f32; 4]> {
            tab.iter().map(|&c| axcomp_core::segment_per_count(c, t.segment_counts)).collect()
        };
        prop_assert_eq!(comp.forward_segments(), &held(t.forward)[..]);
        prop_assert_eq!(comp.backward_segments(), &held(t.backward)[..]);
        prop_assert_eq!(comp.outside(), t.outside);
        let h = spec.thermo.unwrap();
        prop_assert_eq!(comp.sensor_count(), h.sensors.len());
        for (i, s) in h.sensors.iter().enumerate() {
            prop_assert_eq!(comp.sensor(i), Some(*s));
            prop_assert_eq!(comp.b_um_per_k(i), Some(h.b_um_per_k[i]));
        }
        prop_assert_eq!(comp.b0_um(), h.b0_um);
        prop_assert_eq!(comp.expansion(), h.expansion);
        prop_assert_eq!(comp.force_count(), h.forces.len());
        for (j, f) in h.forces.iter().enumerate() {
            prop_assert_eq!(comp.force(j), Some(*f));
        }
        prop_assert_eq!(comp.limits(), spec.limits);
    }

    #[test]
    fn corrupted_images_are_never_accepted(o in any_spec(), at in any::<prop::sample::Index>(),
                                           bit in 0u8..8, byte in 1u8..=255, cut in any::<prop::sample::Index>()) {
        let bytes = image(&o.spec());
        let mut c = Box::new(Compensator::IDENTITY);
        // Single-bit flip anywhere (CRC-32 detects every single-bit error).
        let k = at.index(bytes.len());
        let mut b = bytes.clone();
        b[k] ^= 1 << bit;
        prop_assert!(c.load(&b).is_err());
        // Single-byte change anywhere (burst ≤ 8 bits: always detected).
        let mut b = bytes.clone();
        b[k] ^= byte;
        prop_assert!(c.load(&b).is_err());
        prop_assert!(inspect_image(&b).is_err());
        // Truncation.
        let n = cut.index(bytes.len());
        prop_assert!(c.load(&bytes[..n]).is_err());
        prop_assert!(!c.is_loaded());
        prop_assert!(c.load(&bytes).is_ok());
    }

    #[test]
    fn random_bytes_never_parse(bytes in prop::collection::vec(any::<u8>(), 0..2048), magic in any::<bool>()) {
        let mut b = bytes;
        if magic && b.len() >= 16 {
            // Give the parser a plausible header so the deeper checks run.
            b[..4].copy_from_slice(b"AXCI");
            b[4..6].copy_from_slice(&1u16.to_le_bytes());
            b[6..8].copy_from_slice(&48u16.to_le_bytes());
            let n = b.len() as u32;
            b[8..12].copy_from_slice(&n.to_le_bytes());
        }
        let mut c = Box::new(Compensator::IDENTITY);
        prop_assert!(c.load(&b).is_err());
    }

    #[test]
    fn trace_reader_survives_garbage(bytes in prop::collection::vec(any::<u8>(), 0..1024)) {
        let _ = Reader::new(&bytes).map(|r| r.count());
        let mut with_header = b"AXTR\x01\x00\x00\x00".to_vec();
        with_header.extend_from_slice(&bytes);
        let mut engine = Box::new(Engine::new());
        let mut n = 0;
        for r in Reader::new(&with_header).unwrap() {
            n += 1;
            prop_assert!(n <= bytes.len() + 1, "reader must make progress");
            if let Ok(rec) = r {
                let _ = engine.step(&rec);
            }
        }
    }

    #[test]
    fn engine_survives_any_record_sequence(o in any_spec(), ops in prop::collection::vec(any_op(), 1..100)) {
        let img = image(&o.spec());
        let mut buf = vec![0u8; img.len() + 64 * 200];
        let mut w = Writer::new(&mut buf).unwrap();
        w.push(&Record::Image(&img)).unwrap();
        for op in &ops {
            let rec = match op {
                Op::Cycle(r, c, f) => Record::Cycle(CycleInput { scale_raw: *r, command_counts: *c, forces_n: *f }),
                Op::Temps(t, v) => Record::Temperatures(Temperatures::new(*t, v)),
                Op::Process(a, b, c) => Record::Process(ProcessParams { ap_mm: *a, fz_mm: *b, n_rpm: *c }),
                Op::Home(r, _) => Record::Reset { scale_raw: *r },
            };
            w.push(&rec).unwrap();
        }
        let n = w.finish();
        let mut e = Box::new(Engine::new());
        for r in Reader::new(&buf[..n]).unwrap() {
            if let Some(out) = e.step(&r.unwrap()) {
                prop_assert!(out.correction_um().is_finite());
                prop_assert!(out.correction_um().abs() <= o.limits.max_correction_um);
            }
        }
        prop_assert_eq!(e.stats().images_accepted, 1);
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 20_000, ..ProptestConfig::default() })]

    /// Reference: `libm::roundf(x) as i32`, bit for bit, for every kind of f32 (half-integers,
    /// neighbours of .5, huge, NaN, ±inf).
    #[test]
    fn round_to_counts_equals_libm_roundf(bits in any::<u32>(), k in -5_000_000i32..5_000_000, d in -2i32..=2) {
        let x = f32::from_bits(bits);
        prop_assert_eq!(round_to_counts(x), libm::roundf(x) as i32, "x = {:e}", x);
        // Half-integers and their f32 neighbours.
        let h = k as f32 + 0.5;
        let y = f32::from_bits((h.to_bits() as i32 + d) as u32);
        prop_assert_eq!(round_to_counts(y), libm::roundf(y) as i32, "y = {:e}", y);
        prop_assert_eq!(round_to_counts(-y), libm::roundf(-y) as i32, "y = {:e}", -y);
    }
}

#[test]
fn round_to_counts_edges() {
    for x in [
        0.0f32,
        -0.0,
        0.5,
        -0.5,
        0.49999997,
        -0.49999997,
        1.5,
        -1.5,
        2.5,
        8388607.5,
        8388608.0,
        16777217.0,
        2147483520.0,
        2147483648.0,
        -2147483648.0,
        3.0e9,
        -3.0e9,
        f32::MAX,
        f32::MIN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::NAN,
        1.0e-45,
    ] {
        assert_eq!(round_to_counts(x), libm::roundf(x) as i32, "x = {x:e}");
    }
}
