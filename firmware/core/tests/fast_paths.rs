//! The per-cycle fast paths against a plain reference of the documented rules: the measured-force
//! dispatch (every set of measured terms, NaN in the unmeasured inputs), a unidirectional table
//! used in the backward direction, the rounding for coarse and very fine scales, and the
//! saturating corrected command.

mod common;
use axcomp_core::*;
use common::*;

/// Image: a one-segment constant table (1 µm), no sensors, the given force terms.
fn force_image(forces: &[ForceSpec]) -> Box<Compensator> {
    let fwd = [[1.0f32, 0.0, 0.0, 0.0]];
    load(&ImageSpec {
        axis_id: 3,
        um_per_count: 0.1,
        counter_bits: 32,
        table: Some(TableSpec {
            start_counts: 0,
            segment_counts: 1000,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        }),
        thermo: Some(ThermoForceSpec {
            sensor_period_ms: 100,
            sensors: &[],
            b0_um: 0.0,
            b_um_per_k: &[],
            expansion: None,
            forces,
            reference: ThermoReference::Fixed,
            rise_bounds_k: &[],
        }),
        limits: LOOSE,
    })
}

#[test]
fn every_set_of_measured_forces() {
    let chi = [0.002f32, -0.001, 0.0015];
    let f = [40.0f32, -25.0, 12.5];
    for mask in 1u8..8 {
        let forces: Vec<ForceSpec> = (0..3)
            .map(|j| ForceSpec {
                chi_um_per_n: chi[j],
                // Unmeasured terms are predicted; with no set_process they contribute 0 N.
                law: (mask & (1 << j) == 0).then_some(ForceLaw {
                    k: 1.0,
                    x_ap: 0.0,
                    y_fz: 0.0,
                    z_n: 0.0,
                }),
            })
            .collect();
        let comp = force_image(&forces);
        let mut st = State::new();
        comp.update_temperatures(&mut st, 0, &[]);
        // Unmeasured inputs are NaN ("no reading") and must be ignored.
        let mut forces_n = [f32::NAN; 3];
        let mut want = 0.0f32;
        for j in 0..3 {
            if mask & (1 << j) != 0 {
                forces_n[j] = f[j];
                want += chi[j] * f[j];
            }
        }
        let o = comp.cycle(
            &mut st,
            &CycleInput {
                scale_raw: 500,
                command_counts: 500,
                forces_n,
            },
        );
        // Reference: 1 µm table + Σ χ_j·F_j over the measured terms in index order, the same f32
        // operations, so exact (tolerance 0).
        assert_eq!(o.correction_um, 1.0 + want, "mask {mask:03b}");
        assert!(!o.flags.contains(Flags::FORCE_INVALID), "mask {mask:03b}");
        // A NaN in a measured input drops the whole measured term and flags it.
        let j = mask.trailing_zeros() as usize;
        forces_n[j] = f32::NAN;
        let o = comp.cycle(
            &mut st,
            &CycleInput {
                scale_raw: 500,
                command_counts: 500,
                forces_n,
            },
        );
        assert!(o.flags.contains(Flags::FORCE_INVALID), "mask {mask:03b}");
        assert_eq!(o.correction_um, 1.0, "mask {mask:03b}");
    }
}

#[test]
fn unidirectional_table_serves_the_backward_direction() {
    let fwd = [[1.0f32, 2.0, 0.0, 0.0], [3.0, -1.0, 0.5, 0.0]];
    let comp = load(&table_spec(
        TableSpec {
            start_counts: -1000,
            segment_counts: 1000,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Taper { length_counts: 500 },
        },
        LOOSE,
    ));
    assert!(comp.backward_segments().is_empty());
    // Reference: the forward value, exactly, at every position in and around the stroke.
    for x in (-1800..1800).step_by(7) {
        assert_eq!(
            comp.table_um(Direction::Backward, x),
            comp.table_um(Direction::Forward, x),
            "x = {x}"
        );
    }
    // Moving backward through the cycle: BACKWARD is flagged and the forward table applies.
    let mut st = State::new();
    comp.cycle(&mut st, &input(900, 900));
    let o = comp.cycle(&mut st, &input(-700i32 as u32, -700));
    assert!(o.flags.contains(Flags::BACKWARD));
    assert_eq!(o.correction_um, comp.table_um(Direction::Forward, -700).0);
}

/// Image with a constant table value `um` and a given scale resolution.
fn constant(um: f32, um_per_count: f32) -> Box<Compensator> {
    let fwd = [[um, 0.0, 0.0, 0.0]];
    load(&ImageSpec {
        um_per_count,
        ..table_spec(
            TableSpec {
                start_counts: 0,
                segment_counts: 1000,
                forward: &fwd,
                backward: &[],
                outside: OutsideStroke::Hold,
            },
            LimitSpec {
                max_correction_um: 1.0e5,
                max_slew_um_per_cycle: 1.0e5,
                direction_hysteresis_counts: 0,
            },
        )
    })
}

#[test]
fn rounding_for_coarse_and_fine_scales() {
    // Reference: libm::roundf(correction / um_per_count) as i32 (saturating), exact.
    for (um, upc) in [
        (2.45f32, 0.1f32),
        (-2.45, 0.1),
        (0.05, 0.1),
        (-0.05, 0.1),
        (0.15, 0.1),
        (9.0e3, 1.0e-3),
        (-9.0e3, 1.0e-3),
        // Very fine scales: 9e3 µm / 1e-6 µm = 9e9 counts, saturated.
        (9.0e3, 1.0e-6),
        (-9.0e3, 1.0e-6),
        (1.5e-3, 1.0e-6),
        (-2.5e-6, 1.0e-6),
    ] {
        let comp = constant(um, upc);
        let mut st = State::new();
        let o = comp.cycle(&mut st, &input(10, 0));
        assert_eq!(o.correction_um, um);
        let want = libm::roundf(um / upc) as i32;
        assert_eq!(o.correction_counts, want, "{um} µm at {upc} µm/count");
        assert_eq!(
            o.corrected_command_counts,
            -(want as i64),
            "{um} µm at {upc} µm/count"
        );
    }
}

#[test]
fn corrected_command_saturates_at_both_ends() {
    // Reference: i64::saturating_sub, exact, around the fast path's bound 2^62.
    for um in [3.0f32, -3.0] {
        let comp = constant(um, 0.1);
        let counts = if um > 0.0 { 30i64 } else { -30 };
        for command in [
            i64::MIN,
            i64::MIN + 5,
            -(1i64 << 62) - 1,
            -(1i64 << 62),
            0,
            (1i64 << 62) - 1,
            1i64 << 62,
            i64::MAX - 5,
            i64::MAX,
        ] {
            let mut st = State::new();
            let o = comp.cycle(&mut st, &input(10, command));
            assert_eq!(o.correction_counts as i64, counts);
            assert_eq!(
                o.corrected_command_counts,
                command.saturating_sub(counts),
                "command {command}, {um} µm"
            );
        }
    }
}
