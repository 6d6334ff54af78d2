//! Thermo-force term: lags, the formula, predicted forces, sensor health.

mod common;
use axcomp_core::*;
use common::*;

fn thermo_spec<'a>(t: ThermoForceSpec<'a>) -> ImageSpec<'a> {
    ImageSpec {
        axis_id: 3,
        um_per_count: 0.1,
        counter_bits: 32,
        table: None,
        thermo: Some(t),
        limits: LOOSE,
    }
}

#[test]
fn lag_step_response_matches_analytic() {
    // Reference: a first-order lag with τ = 10 s sampled every 100 ms answers a unit step with
    // 1 − exp(−t/τ) exactly at the samples; the f32 filter must agree to 1e-5 K for 20 τ.
    let sensors = [SensorSpec {
        max_rate_degc_per_s: 20.0,
        ..sensor(20.0, 10.0)
    }];
    let comp = load(&thermo_spec(ThermoForceSpec {
        sensor_period_ms: 100,
        sensors: &sensors,
        b0_um: 0.0,
        b_um_per_k: &[1.0],
        expansion: None,
        forces: &[],
        reference: ThermoReference::Fixed,
        rise_bounds_k: &[],
    }));
    let mut st = State::new();
    comp.update_temperatures(&mut st, 0, &[20.0]);
    assert_eq!(st.filtered_delta_t(0), Some(0.0));
    let mut max_err = 0.0f64;
    for k in 1..=2000u32 {
        // Rate check: +1 K within 100 ms is allowed (20 K/s).
        comp.update_temperatures(&mut st, k * 100, &[21.0]);
        let want = 1.0 - (-(k as f64) * 0.1 / 10.0).exp();
        let got = st.filtered_delta_t(0).unwrap() as f64;
        max_err = max_err.max((got - want).abs());
        // b = 1 µm/K: the cached thermal term equals the lagged ΔT.
        assert_eq!(st.sensor_term_um(), st.filtered_delta_t(0).unwrap());
    }
    assert!(max_err < 1e-5, "max error {max_err} K (tol 1e-5)");
    // No lag (τ = 0): α = 1.
    assert_eq!(image::lag_alpha(0.1, 0.0), 1.0);
}

#[test]
fn thermo_force_formula() {
    // Reference: E = b0 + Σ b_i ΔT_i + c (x − x_ref)·um_per_count/1000·ΔT_s + Σ χ_j F_j in f64,
    // no lags, tolerance 1e-4 µm (f32 on values ≤ 100 µm).
    let sensors = [sensor(20.0, 0.0), sensor(22.0, 0.0), sensor(18.0, 0.0)];
    let b = [1.5f32, -0.75, 0.25];
    let forces = [
        ForceSpec {
            chi_um_per_n: 0.01,
            law: None,
        },
        ForceSpec {
            chi_um_per_n: -0.02,
            law: None,
        },
    ];
    let comp = load(&thermo_spec(ThermoForceSpec {
        sensor_period_ms: 100,
        sensors: &sensors,
        b0_um: 0.5,
        b_um_per_k: &b,
        expansion: Some(ExpansionSpec {
            sensor: 1,
            x_ref_counts: 100_000,
            c_um_per_mm_k: 0.0115,
        }),
        forces: &forces,
        reference: ThermoReference::Fixed,
        rise_bounds_k: &[],
    }));
    let mut st = State::new();
    let temps = [23.0f32, 25.5, 17.0];
    comp.update_temperatures(&mut st, 0, &temps);
    assert!(st.thermal_live());
    let x: i64 = 900_000; // 80 mm from x_ref at 0.1 µm/count
    let f = [120.0f32, 35.0, 0.0];
    let o = comp.cycle(
        &mut st,
        &CycleInput {
            scale_raw: x as u32,
            command_counts: x,
            forces_n: f,
        },
    );
    let dt = [3.0f64, 3.5, -1.0];
    let want = 0.5 + 1.5 * dt[0] - 0.75 * dt[1]
        + 0.25 * dt[2]
        + 0.0115 * ((x - 100_000) as f64 * 0.1 / 1000.0) * dt[1]
        + 0.01 * 120.0
        - 0.02 * 35.0;
    assert!(
        (o.correction_um as f64 - want).abs() < 1e-4,
        "{} vs {want}",
        o.correction_um
    );
    assert!(o.flags.is_empty(), "{:?}", o.flags);
    // A NaN force drops the measured force term for this cycle (both forces) and is flagged.
    let o2 = comp.cycle(
        &mut st,
        &CycleInput {
            scale_raw: x as u32,
            command_counts: x,
            forces_n: [f32::NAN, 35.0, 0.0],
        },
    );
    assert!(o2.flags.contains(Flags::FORCE_INVALID));
    assert!((o2.correction_um as f64 - (want - 0.01 * 120.0 + 0.02 * 35.0)).abs() < 1e-4);
}

#[test]
fn predicted_force_from_process() {
    // Reference: F = K ap^x fz^y n^z in f64; relative tolerance 1e-5.
    let law = ForceLaw {
        k: 1200.0,
        x_ap: 0.92,
        y_fz: 0.78,
        z_n: -0.12,
    };
    let forces = [ForceSpec {
        chi_um_per_n: 0.004,
        law: Some(law),
    }];
    let comp = load(&thermo_spec(ThermoForceSpec {
        sensor_period_ms: 100,
        sensors: &[],
        b0_um: 0.0,
        b_um_per_k: &[],
        expansion: None,
        forces: &forces,
        reference: ThermoReference::Fixed,
        rise_bounds_k: &[],
    }));
    assert_eq!(comp.force_source(0), Some(ForceSource::Predicted));
    let mut st = State::new();
    // Before any process: 0 N.
    assert_eq!(
        comp.cycle(&mut st, &input(0, 0)).correction_um,
        0.0,
        "no cut, no force"
    );
    let p = ProcessParams {
        ap_mm: 0.8,
        fz_mm: 0.06,
        n_rpm: 900.0,
    };
    comp.set_process(&mut st, &p);
    let want = 1200.0 * 0.8f64.powf(0.92) * 0.06f64.powf(0.78) * 900.0f64.powf(-0.12);
    let got = st.predicted_force_n(0) as f64;
    assert!((got / want - 1.0).abs() < 1e-5, "{got} vs {want}");
    // The measured force input is not used for a predicted term.
    let o = comp.cycle(
        &mut st,
        &CycleInput {
            scale_raw: 0,
            command_counts: 0,
            forces_n: [1.0e6, 0.0, 0.0],
        },
    );
    assert!((o.correction_um as f64 - 0.004 * want).abs() < 1e-5 * want);
    // Negative depth of cut: NaN prediction → 0 N and flagged.
    comp.set_process(&mut st, &ProcessParams { ap_mm: -1.0, ..p });
    assert_eq!(st.predicted_force_n(0), 0.0);
    assert!(
        comp.cycle(&mut st, &input(0, 0))
            .flags
            .contains(Flags::FORCE_INVALID)
    );
}

fn one_sensor() -> Box<Compensator> {
    // b = 2 µm/K, no lag, range −50..150 °C, 5 K/s, stale after 1000 ms, period 100 ms.
    let sensors = [sensor(20.0, 0.0)];
    load(&thermo_spec(ThermoForceSpec {
        sensor_period_ms: 100,
        sensors: &sensors,
        b0_um: 0.0,
        b_um_per_k: &[2.0],
        expansion: None,
        forces: &[],
        reference: ThermoReference::Fixed,
        rise_bounds_k: &[],
    }))
}

#[test]
fn implausible_readings_are_rejected() {
    let comp = one_sensor();
    let mut st = State::new();
    // Before any reading: thermal term frozen (at 0), no fault yet.
    let o = comp.cycle(&mut st, &input(0, 0));
    assert!(o.flags.contains(Flags::THERMAL_FROZEN));
    assert!(!o.flags.contains(Flags::SENSOR_FAULT));
    comp.update_temperatures(&mut st, 0, &[21.0]);
    assert_eq!(st.sensor_term_um(), 2.0);
    // Out of range, infinite, too fast (+2 K in 100 ms > 5 K/s · 0.1 s): rejected, value held.
    for (k, r) in [200.0f32, f32::INFINITY, 23.0, -60.0].iter().enumerate() {
        comp.update_temperatures(&mut st, 100 * (k as u32 + 1), &[*r]);
        assert_eq!(st.sensor_term_um(), 2.0, "reading {r}");
        assert!(st.sensor_fault(), "reading {r}");
        let o = comp.cycle(&mut st, &input(0, 0));
        assert!(o.flags.contains(Flags::SENSOR_FAULT));
        assert_eq!(o.correction_um, 2.0);
    }
    assert_eq!(st.rejected_readings(0), 4);
    // NaN = no reading: not a rejection.
    comp.update_temperatures(&mut st, 500, &[f32::NAN]);
    assert!(!st.sensor_fault());
    // A plausible reading (+1 K in 600 ms ≤ 3 K) is accepted.
    comp.update_temperatures(&mut st, 600, &[22.0]);
    assert_eq!(st.sensor_term_um(), 4.0);
    // A missing entry in the slice also counts as no reading.
    comp.update_temperatures(&mut st, 700, &[]);
    assert_eq!(st.sensor_term_um(), 4.0);
}

#[test]
fn stale_sensor_freezes_and_recovers() {
    let comp = one_sensor();
    let mut st = State::new();
    comp.update_temperatures(&mut st, 0, &[21.0]);
    comp.update_temperatures(&mut st, 100, &[21.5]);
    assert_eq!(st.sensor_term_um(), 3.0);
    // No readings for > 1000 ms: stale, frozen at 3 µm, fault.
    let mut t = 100;
    while t <= 1100 {
        t += 100;
        comp.update_temperatures(&mut st, t, &[f32::NAN]);
    }
    assert!(st.sensor_stale(0));
    let o = comp.cycle(&mut st, &input(0, 0));
    assert!(
        o.flags
            .contains(Flags::SENSOR_FAULT | Flags::THERMAL_FROZEN)
    );
    assert_eq!(o.correction_um, 3.0);
    // Recovery needs RECOVERY_READINGS consecutive accepted readings; the value stays frozen until then.
    for k in 0..RECOVERY_READINGS {
        t += 100;
        comp.update_temperatures(&mut st, t, &[22.0]);
        if k + 1 < RECOVERY_READINGS {
            assert!(st.sensor_stale(0));
            assert_eq!(st.sensor_term_um(), 3.0);
        }
    }
    assert!(!st.sensor_stale(0));
    assert!(!st.sensor_fault());
    assert_eq!(st.sensor_term_um(), 4.0);
    let o = comp.cycle(&mut st, &input(0, 0));
    assert!(!o.flags.contains(Flags::THERMAL_FROZEN));
    assert_eq!(o.correction_um, 4.0);
}

#[test]
fn a_sensor_that_never_reports_goes_stale() {
    let comp = one_sensor();
    let mut st = State::new();
    comp.update_temperatures(&mut st, 5000, &[]);
    assert!(!st.sensor_fault());
    comp.update_temperatures(&mut st, 6001, &[]);
    assert!(st.sensor_fault());
    assert!(st.sensor_stale(0));
    // Clock wrap of now_ms is harmless.
    let mut st = State::new();
    comp.update_temperatures(&mut st, u32::MAX - 50, &[20.0]);
    comp.update_temperatures(&mut st, 49, &[20.2]);
    assert!(!st.sensor_fault());
    assert!((st.sensor_term_um() - 0.4).abs() < 1e-5);
}

/// Two lagged sensors (τ 60 s and none), b = 1.5 and −0.5 µm/K, b0 0.25 µm, period 1 s, with the
/// given reference mode and rise bounds (`nominal` as each sensor's `reference_degc`).
fn two_sensor_spec<'a>(
    sensors: &'a [SensorSpec; 2],
    reference: ThermoReference,
    rise_bounds_k: &'a [(f32, f32)],
) -> ImageSpec<'a> {
    thermo_spec(ThermoForceSpec {
        sensor_period_ms: 1000,
        sensors,
        b0_um: 0.25,
        b_um_per_k: &[1.5, -0.5],
        expansion: None,
        forces: &[],
        reference,
        rise_bounds_k,
    })
}

/// Readings of update `k` of a run starting at `start`: a warm-up of both sensors (sensor 0 by
/// 6 K over 600 s, sensor 1 by 2 K), then a plateau.
fn run_readings(start: [f32; 2], k: u32) -> [f32; 2] {
    let w = (k.min(600) as f32) / 600.0;
    [start[0] + 6.0 * w, start[1] + 2.0 * w]
}

#[test]
fn switch_on_reference_equals_a_fixed_reference_at_the_first_reading() {
    // Reference: a Fixed image whose references are the run's first readings (31 °C and 24.5 °C);
    // tolerance 1e-5 µm on the thermal term and the cycle's correction (the switch-on image stores
    // the same f32 reference, so they agree bit for bit in practice). A second run (a fresh State)
    // starting at 27 °C / 22 °C is compared with a Fixed image referenced there.
    let nominal = [sensor(20.0, 60.0), sensor(20.0, 0.0)];
    let on = load(&two_sensor_spec(&nominal, ThermoReference::SwitchOn, &[]));
    assert_eq!(on.thermo_reference(), ThermoReference::SwitchOn);
    for start in [[31.0f32, 24.5], [27.0, 22.0]] {
        let fixed_sensors = [sensor(start[0], 60.0), sensor(start[1], 0.0)];
        let fixed = load(&two_sensor_spec(
            &fixed_sensors,
            ThermoReference::Fixed,
            &[],
        ));
        let (mut st_on, mut st_fixed) = (State::new(), State::new());
        // A missing first reading of sensor 0 does not take its reference.
        on.update_temperatures(&mut st_on, 0, &[f32::NAN, start[1]]);
        fixed.update_temperatures(&mut st_fixed, 0, &[f32::NAN, start[1]]);
        for k in 1..=1200u32 {
            let r = run_readings(start, k - 1);
            on.update_temperatures(&mut st_on, k * 1000, &r);
            fixed.update_temperatures(&mut st_fixed, k * 1000, &r);
            if k == 1 {
                assert_eq!(st_on.filtered_delta_t(0), Some(0.0), "lag starts at ΔT = 0");
            }
            let d = (st_on.sensor_term_um() - st_fixed.sensor_term_um()).abs();
            assert!(d <= 1e-5, "update {k}: {d} µm (tol 1e-5)");
            let x = input(0, 0);
            let (a, b) = (on.cycle(&mut st_on, &x), fixed.cycle(&mut st_fixed, &x));
            assert!(
                (a.correction_um - b.correction_um).abs() <= 1e-5,
                "update {k}"
            );
            assert_eq!(a.flags, b.flags);
        }
        // After the warm-up: 1.5·6 − 0.5·2 = 8 µm (the 60 s lag's ramp error, 0.6 K, has decayed
        // by exp(−600/60) over the 600 s plateau: < 1e-4 µm; tolerance 1e-3 µm).
        assert!((st_on.sensor_term_um() - 8.0).abs() < 1e-3);
    }
}

#[test]
fn rise_guard_drops_only_the_term_of_the_sensor_beyond_its_bounds() {
    // Reference: hand-computed Σ b_i·ΔT_i without lag (sensor 1's τ = 0; sensor 0 here also 0):
    // b = 1.5, −0.5 µm/K, references 20 °C; bounds sensor 0 [−1, 5] K, sensor 1 [−2, 3] K;
    // tolerance 1e-5 µm.
    let s = [sensor(20.0, 0.0), sensor(20.0, 0.0)];
    let bounds = [(-1.0f32, 5.0), (-2.0, 3.0)];
    let guarded = load(&two_sensor_spec(&s, ThermoReference::Fixed, &bounds));
    let plain = load(&two_sensor_spec(&s, ThermoReference::Fixed, &[]));
    assert!(guarded.has_rise_guard() && !plain.has_rise_guard());
    assert_eq!(guarded.rise_bounds_k(1), Some((-2.0, 3.0)));
    assert_eq!(plain.rise_bounds_k(0), None);
    let (mut st, mut sp) = (State::new(), State::new());
    // (readings, expected sum of the guarded image, a term left out)
    let steps: [([f32; 2], f32, bool); 6] = [
        ([23.0, 21.0], 1.5 * 3.0 - 0.5, false),
        ([25.0, 21.0], 1.5 * 5.0 - 0.5, false), // on the upper bound: kept
        ([26.0, 21.0], -0.5, true),             // sensor 0 beyond: only its term dropped
        ([26.0, 23.5], 0.0, true),              // both beyond
        ([24.0, 23.5], 1.5 * 4.0, true),        // sensor 1 still beyond
        ([24.0, 22.0], 1.5 * 4.0 - 0.5 * 2.0, false),
    ];
    for (k, &(r, want, dropped)) in steps.iter().enumerate() {
        let now = (k as u32 + 1) * 1000;
        guarded.update_temperatures(&mut st, now, &r);
        plain.update_temperatures(&mut sp, now, &r);
        let got = st.sensor_term_um();
        assert!(
            (got - want).abs() <= 1e-5,
            "step {k}: {got} µm, want {want}"
        );
        let f = guarded.cycle(&mut st, &input(0, 0)).flags;
        assert_eq!(f.contains(Flags::THERMAL_GUARDED), dropped, "step {k}");
        assert!(!f.contains(Flags::SENSOR_FAULT) && !f.contains(Flags::THERMAL_FROZEN));
        // The image without the guard keeps every term and never flags.
        let full = 1.5 * (r[0] - 20.0) - 0.5 * (r[1] - 20.0);
        assert!((sp.sensor_term_um() - full).abs() <= 1e-5);
        assert!(
            !plain
                .cycle(&mut sp, &input(0, 0))
                .flags
                .contains(Flags::THERMAL_GUARDED)
        );
    }
}

#[test]
fn rise_guard_with_the_reference_at_switch_on_uses_the_rise_since_the_first_reading() {
    // Reference: a run starting at 40 °C (20 K above the nominal reference): its rise is taken
    // from 40 °C, so +3 K is within [−1, 5] K and kept; +6 K is dropped. Hand-computed, no lag,
    // tolerance 1e-5 µm.
    let s = [sensor(20.0, 0.0), sensor(20.0, 0.0)];
    let bounds = [(-1.0f32, 5.0), (-2.0, 3.0)];
    let comp = load(&two_sensor_spec(&s, ThermoReference::SwitchOn, &bounds));
    let mut st = State::new();
    comp.update_temperatures(&mut st, 1000, &[40.0, 30.0]);
    assert!(st.sensor_term_um().abs() <= 1e-5);
    comp.update_temperatures(&mut st, 2000, &[43.0, 31.0]);
    assert!((st.sensor_term_um() - (4.5 - 0.5)).abs() <= 1e-5);
    comp.update_temperatures(&mut st, 3000, &[46.0, 31.0]);
    assert!((st.sensor_term_um() + 0.5).abs() <= 1e-5);
}

#[test]
fn group_axis_with_switch_on_and_guard_equals_the_compensator_bit_for_bit() {
    // Reference: `Compensator` on the same image and readings (the group passes its own sensor
    // settings array); tolerance: none (every output bit).
    use axcomp_core::group::GroupState;
    use axcomp_core::group::{AxisName, Group, GroupAxisImage, GroupInput, GroupOutput};
    let s = [sensor(20.0, 60.0), sensor(20.0, 0.0)];
    let bounds = [(-1.0f32, 5.0), (-2.0, 1.5)];
    let img = image(&two_sensor_spec(&s, ThermoReference::SwitchOn, &bounds));
    let comp = load(&two_sensor_spec(&s, ThermoReference::SwitchOn, &bounds));
    let mut group: Box<Group<64>> = Box::new(Group::new());
    group
        .load(
            &[GroupAxisImage {
                name: AxisName::X,
                counts_per_rev: 0,
                image: &img,
            }],
            None,
        )
        .unwrap();
    let (mut st, mut gst) = (State::new(), Box::new(GroupState::new()));
    let (gin, mut gout) = (GroupInput::ZERO, GroupOutput::ZERO);
    let mut seen = Flags::NONE;
    for k in 0..900u32 {
        let r = run_readings([33.0, 25.0], k);
        comp.update_temperatures(&mut st, k * 1000, &r);
        group.update_temperatures(&mut gst, 0, k * 1000, &r);
        let want = comp.cycle(&mut st, &gin.axes[0]);
        group.cycle(&mut gst, &gin, &mut gout);
        assert_eq!(
            gout.axes[0].correction_um.to_bits(),
            want.correction_um.to_bits()
        );
        assert_eq!(gout.axes[0].flags, want.flags, "update {k}");
        seen |= want.flags;
    }
    // Sensor 1 rose 2 K > 1.5 K: the guard acted.
    assert!(seen.contains(Flags::THERMAL_GUARDED));
}
