//! Correction pipeline: counter extension, direction hysteresis, rounding, clamp, slew.

mod common;
use axcomp_core::*;
use common::*;

fn flat(value: f32, bits: u8, limits: LimitSpec) -> Box<Compensator> {
    static FWD: [[f32; 4]; 4] = [[0.0; 4]; 4];
    let mut fwd = FWD;
    for s in fwd.iter_mut() {
        s[0] = value;
    }
    let mut spec = table_spec(
        TableSpec {
            start_counts: -1_000_000,
            segment_counts: 500_000,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        },
        limits,
    );
    spec.counter_bits = bits;
    load(&spec)
}

#[test]
fn counter_wrap_16_bits() {
    // Reference: a 16-bit counter counting up through 0xFFFF → 0 and back down; the extended
    // position must follow the true motion exactly.
    let comp = flat(0.0, 16, LOOSE);
    let mut st = State::new();
    let mut true_pos: i64 = 65_000;
    let o = comp.cycle(&mut st, &input(true_pos as u32 & 0xFFFF, 0));
    // The first value is read as a signed 16-bit number: 65000 = −536.
    assert_eq!(o.position_counts, 65_000 - 65_536);
    let offset = 65_000 - 65_536 - true_pos;
    for step in [
        300i64, 300, 300, 30_000, -30_000, -300, -1000, -1000, 32_000, 32_767,
    ] {
        true_pos += step;
        let raw = (true_pos as u32) & 0xFFFF; // the upper bits are not wired
        let o = comp.cycle(&mut st, &input(raw | 0xABCD_0000, 0));
        assert_eq!(o.position_counts, true_pos + offset, "after step {step}");
    }
}

#[test]
fn counter_wrap_32_bits() {
    let comp = flat(0.0, 32, LOOSE);
    let mut st = State::new();
    let mut true_pos: i64 = u32::MAX as i64 - 10;
    comp.cycle(&mut st, &input(true_pos as u32, 0));
    let offset = -11 - true_pos; // u32::MAX − 10 read as i32 = −11
    for step in [
        5i64,
        5,
        5,
        1 << 30,
        1 << 30,
        -(1 << 31) + 1,
        1 << 30,
        3 << 29,
    ] {
        true_pos += step;
        let o = comp.cycle(&mut st, &input(true_pos as u32, 0));
        assert_eq!(o.position_counts, true_pos + offset, "after step {step}");
    }
    // Several full turns upwards: the extended position goes beyond the 32-bit range.
    for _ in 0..20 {
        true_pos += 1 << 30;
        comp.cycle(&mut st, &input(true_pos as u32, 0));
    }
    assert_eq!(st.position_counts(), true_pos + offset);
    assert!(st.position_counts() > u32::MAX as i64 * 4);
}

#[test]
fn reset_and_home() {
    let comp = flat(0.0, 16, LOOSE);
    let mut st = State::new();
    comp.cycle(&mut st, &input(1000, 0));
    st.reset(100);
    // Counter at reset = 100, next cycle reads 150: position 100 + 50.
    assert_eq!(comp.cycle(&mut st, &input(150, 0)).position_counts, 150);
    st.home(0xFFF0, 1_000_000);
    // 0xFFF0 → 0x0010 is +32 counts through the wrap.
    assert_eq!(
        comp.cycle(&mut st, &input(0x0010, 0)).position_counts,
        1_000_032
    );
}

#[test]
fn direction_hysteresis() {
    // Forward table 0 µm, backward 1 µm: the correction tells the direction.
    let fwd = [[0.0f32; 4]; 2];
    let bwd = [[1.0f32, 0.0, 0.0, 0.0]; 2];
    let comp = load(&table_spec(
        TableSpec {
            start_counts: 0,
            segment_counts: 10_000,
            forward: &fwd,
            backward: &bwd,
            outside: OutsideStroke::Hold,
        },
        LimitSpec {
            direction_hysteresis_counts: 10,
            ..LOOSE
        },
    ));
    let mut st = State::new();
    let mut dir_at = |p: u32| {
        comp.cycle(&mut st, &input(p, 0));
        st.direction()
    };
    assert_eq!(dir_at(1000), Direction::Forward);
    assert_eq!(dir_at(1100), Direction::Forward); // extreme 1100
    assert_eq!(dir_at(1090), Direction::Forward); // 10 back: not more than the hysteresis
    assert_eq!(dir_at(1095), Direction::Forward);
    assert_eq!(dir_at(1089), Direction::Backward); // 11 back from the extreme 1100
    assert_eq!(dir_at(1080), Direction::Backward); // extreme 1080
    assert_eq!(dir_at(1090), Direction::Backward); // 10 up
    assert_eq!(dir_at(1091), Direction::Forward); // 11 up
    // Noise of ±10 counts at standstill never toggles.
    for k in 0..100u32 {
        assert_eq!(dir_at(1091 - (k % 11)), Direction::Forward);
    }
}

#[test]
fn rounding_half_away_from_zero_and_sign() {
    // 0.25 µm at 0.5 µm/count = 0.5 counts exactly → 1; −0.25 → −1; 0.2 → 0.4 → 0.
    for (v, want) in [
        (0.25f32, 1i32),
        (-0.25, -1),
        (0.2, 0),
        (-0.2, 0),
        (0.75, 2),
        (-0.75, -2),
    ] {
        let fwd = [[v, 0.0, 0.0, 0.0]];
        let mut spec = table_spec(
            TableSpec {
                start_counts: 0,
                segment_counts: 100,
                forward: &fwd,
                backward: &[],
                outside: OutsideStroke::Hold,
            },
            LOOSE,
        );
        spec.um_per_count = 0.5;
        let comp = load(&spec);
        let mut st = State::new();
        let o = comp.cycle(&mut st, &input(10, 1000));
        assert_eq!(o.correction_counts, want, "{v} µm");
        // Sign convention: the deviation is subtracted from the command.
        assert_eq!(o.corrected_command_counts, 1000 - want as i64);
    }
}

#[test]
fn clamp_and_slew() {
    // Table 30 µm, clamp 20 µm, slew 3 µm/cycle: 3, 6, ..., 18, 20, 20 (exact in f32).
    let comp = flat(
        30.0,
        32,
        LimitSpec {
            max_correction_um: 20.0,
            max_slew_um_per_cycle: 3.0,
            direction_hysteresis_counts: 0,
        },
    );
    let mut st = State::new();
    let mut seen = Vec::new();
    for _ in 0..9 {
        let o = comp.cycle(&mut st, &input(0, 0));
        assert!(o.flags.contains(Flags::CLAMPED));
        seen.push((o.correction_um, o.flags.contains(Flags::SLEWED)));
    }
    let want = [3.0, 6.0, 9.0, 12.0, 15.0, 18.0, 20.0, 20.0, 20.0];
    for (k, (&(v, slewed), &w)) in seen.iter().zip(want.iter()).enumerate() {
        assert_eq!(v, w, "cycle {k}");
        assert_eq!(slewed, k < 6, "cycle {k}");
    }
    assert_eq!(comp.cycle(&mut st, &input(0, 0)).correction_counts, 200);
}

#[test]
fn saturating_command() {
    let comp = flat(-5.0, 32, LOOSE);
    let mut st = State::new();
    let o = comp.cycle(&mut st, &input(0, i64::MAX));
    assert_eq!(o.correction_counts, -50);
    assert_eq!(o.corrected_command_counts, i64::MAX);
}

#[test]
fn identity_is_zero() {
    let comp = Compensator::IDENTITY;
    let mut st = State::new();
    let o = comp.cycle(&mut st, &input(1234, 99));
    assert_eq!(o.correction_counts, 0);
    assert_eq!(o.corrected_command_counts, 99);
    assert_eq!(o.position_counts, 1234);
    assert!(o.flags.contains(Flags::IDENTITY));
}
