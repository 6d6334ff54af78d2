//! Table image: format, validation errors, size budget, load-in-place semantics.

mod common;
use axcomp_core::*;
use common::*;

#[test]
fn crc32_check_value() {
    // Reference: the CRC-32/ISO-HDLC check value from the CRC catalogue (same as zlib.crc32).
    assert_eq!(crc32(b"123456789"), 0xCBF4_3926);
    assert_eq!(crc32(b""), 0);
}

/// Forward and backward segments, sensors, b_i.
type Parts = (Vec<[f32; 4]>, Vec<[f32; 4]>, Vec<SensorSpec>, Vec<f32>);

fn full_spec_parts() -> Parts {
    let fwd: Vec<[f32; 4]> = (0..MAX_SEGMENTS)
        .map(|s| [s as f32 * 0.001, 0.5, -0.25, 0.125])
        .collect();
    let bwd: Vec<[f32; 4]> = fwd.iter().map(|c| [c[0] + 1.0, c[1], c[2], c[3]]).collect();
    let sensors: Vec<SensorSpec> = (0..MAX_SENSORS)
        .map(|i| sensor(20.0 + i as f32 * 0.1, i as f32 * 5.0))
        .collect();
    let b: Vec<f32> = (0..MAX_SENSORS).map(|i| 0.1 * i as f32 - 0.5).collect();
    (fwd, bwd, sensors, b)
}

const FORCES: [ForceSpec; 3] = [
    ForceSpec {
        chi_um_per_n: 0.01,
        law: None,
    },
    ForceSpec {
        chi_um_per_n: 0.02,
        law: Some(ForceLaw {
            k: 1000.0,
            x_ap: 0.9,
            y_fz: 0.8,
            z_n: -0.1,
        }),
    },
    ForceSpec {
        chi_um_per_n: -0.03,
        law: None,
    },
];

fn full_spec<'a>(
    fwd: &'a [[f32; 4]],
    bwd: &'a [[f32; 4]],
    sensors: &'a [SensorSpec],
    b: &'a [f32],
) -> ImageSpec<'a> {
    ImageSpec {
        axis_id: 0xA5,
        um_per_count: 0.05,
        counter_bits: 24,
        table: Some(TableSpec {
            start_counts: -5_000_000,
            segment_counts: 4000,
            forward: fwd,
            backward: bwd,
            outside: OutsideStroke::Taper {
                length_counts: 12_345,
            },
        }),
        thermo: Some(ThermoForceSpec {
            sensor_period_ms: 250,
            sensors,
            b0_um: -1.25,
            b_um_per_k: b,
            expansion: Some(ExpansionSpec {
                sensor: 3,
                x_ref_counts: -42,
                c_um_per_mm_k: 0.0115,
            }),
            forces: &FORCES,
            reference: ThermoReference::Fixed,
            rise_bounds_k: &[],
        }),
        limits: LimitSpec {
            max_correction_um: 80.0,
            max_slew_um_per_cycle: 0.25,
            direction_hysteresis_counts: 17,
        },
    }
}

#[test]
fn largest_image_fits_one_slot_and_round_trips() {
    let (fwd, bwd, sensors, b) = full_spec_parts();
    let spec = full_spec(&fwd, &bwd, &sensors, &b);
    let len = image_len(&spec);
    assert!(
        len <= MAX_IMAGE_LEN,
        "2×1024 segments + 16 sensors: {len} bytes > 64 KiB"
    );
    let bytes = image(&spec);
    let info = inspect_image(&bytes).unwrap();
    assert_eq!(info.len, len);
    assert_eq!((info.n_segments, info.bidirectional), (MAX_SEGMENTS, true));
    assert_eq!((info.n_sensors, info.n_forces), (MAX_SENSORS, 3));
    let mut c = Box::new(Compensator::IDENTITY);
    c.load(&bytes).unwrap();
    assert_eq!(c.axis_id(), 0xA5);
    assert_eq!(c.um_per_count(), 0.05);
    assert_eq!(c.counter_bits(), 24);
    // Reference: the image's coefficients in t = r/L converted to the remainder r (counts),
    // c_k / L^k by f32 divisions (tolerance 0: the same operations as the load's).
    let per_count = |c: &[f32; 4]| {
        let l = 4000.0f32;
        [c[0], c[1] / l, c[2] / l / l, c[3] / l / l / l]
    };
    let expect = |t: &[[f32; 4]]| t.iter().map(per_count).collect::<Vec<_>>();
    assert_eq!(c.forward_segments(), &expect(&fwd)[..]);
    assert_eq!(c.backward_segments(), &expect(&bwd)[..]);
    assert_eq!(c.table_start_counts(), -5_000_000);
    assert_eq!(c.segment_counts(), 4000);
    assert_eq!(
        c.outside(),
        OutsideStroke::Taper {
            length_counts: 12_345
        }
    );
    for (i, s) in sensors.iter().enumerate() {
        assert_eq!(c.sensor(i), Some(*s));
        assert_eq!(c.b_um_per_k(i), Some(b[i]));
    }
    assert_eq!(c.sensor(MAX_SENSORS), None);
    assert_eq!(c.b0_um(), -1.25);
    assert_eq!(c.sensor_period_ms(), 250);
    assert_eq!(c.expansion(), spec.thermo.unwrap().expansion);
    for (j, f) in FORCES.iter().enumerate() {
        assert_eq!(c.force(j), Some(*f));
    }
    assert_eq!(c.limits(), spec.limits);
}

#[test]
fn spec_errors_name_the_field() {
    let fwd = [[0.0f32, 1.0, 0.0, 0.0]; 4];
    let base = table_spec(
        TableSpec {
            start_counts: 0,
            segment_counts: 100,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        },
        LOOSE,
    );
    let mut buf = vec![0u8; 4096];
    let check = |spec: &ImageSpec, want: ImageError| {
        let mut buf = vec![0u8; 4096];
        assert_eq!(write_image(spec, &mut buf), Err(want));
        assert!(buf.iter().all(|&b| b == 0), "nothing half-written");
    };
    // Non-finite coefficient in segment 2.
    let mut bad = fwd;
    bad[2][3] = f32::NAN;
    let mut s = base;
    s.table = Some(TableSpec {
        forward: &bad,
        ..base.table.unwrap()
    });
    check(
        &s,
        ImageError::NonFinite {
            field: Field::ForwardCoefficient,
            index: 2,
        },
    );
    // Value beyond 10 mm.
    let mut big = fwd;
    big[1][0] = 20_000.0;
    s.table = Some(TableSpec {
        forward: &big,
        ..base.table.unwrap()
    });
    check(
        &s,
        ImageError::OutOfRange {
            field: Field::ForwardCoefficient,
            index: 1,
        },
    );
    // Backward length mismatch, too many segments, no segments.
    let short = [[0.0f32; 4]; 3];
    s.table = Some(TableSpec {
        backward: &short,
        ..base.table.unwrap()
    });
    check(&s, ImageError::DirectionLengthMismatch);
    let many = vec![[0.0f32; 4]; MAX_SEGMENTS + 1];
    s.table = Some(TableSpec {
        forward: &many,
        ..base.table.unwrap()
    });
    check(&s, ImageError::TooManySegments);
    s.table = Some(TableSpec {
        forward: &[],
        ..base.table.unwrap()
    });
    check(&s, ImageError::TooManySegments);
    // Zero segment length, stroke beyond u32.
    s.table = Some(TableSpec {
        segment_counts: 0,
        ..base.table.unwrap()
    });
    check(
        &s,
        ImageError::OutOfRange {
            field: Field::SegmentCounts,
            index: 0,
        },
    );
    s.table = Some(TableSpec {
        segment_counts: u32::MAX / 2,
        ..base.table.unwrap()
    });
    check(
        &s,
        ImageError::OutOfRange {
            field: Field::SegmentCounts,
            index: 0,
        },
    );
    // Header values.
    let mut s = base;
    s.um_per_count = 0.0;
    check(
        &s,
        ImageError::OutOfRange {
            field: Field::UmPerCount,
            index: 0,
        },
    );
    s.um_per_count = f32::INFINITY;
    check(
        &s,
        ImageError::NonFinite {
            field: Field::UmPerCount,
            index: 0,
        },
    );
    let mut s = base;
    s.counter_bits = 12;
    check(
        &s,
        ImageError::OutOfRange {
            field: Field::CounterBits,
            index: 0,
        },
    );
    let mut s = base;
    s.limits.max_slew_um_per_cycle = -1.0;
    check(
        &s,
        ImageError::OutOfRange {
            field: Field::MaxSlew,
            index: 0,
        },
    );
    let mut s = base;
    s.limits.direction_hysteresis_counts = u32::MAX;
    check(
        &s,
        ImageError::OutOfRange {
            field: Field::Hysteresis,
            index: 0,
        },
    );
    // Thermo: counts and sensor values.
    let sensors = [sensor(20.0, 0.0), sensor(20.0, 0.0)];
    let thermo = ThermoForceSpec {
        sensor_period_ms: 100,
        sensors: &sensors,
        b0_um: 0.0,
        b_um_per_k: &[1.0, 2.0],
        expansion: None,
        forces: &[],
        reference: ThermoReference::Fixed,
        rise_bounds_k: &[],
    };
    let mut s = base;
    s.thermo = Some(ThermoForceSpec {
        b_um_per_k: &[1.0],
        ..thermo
    });
    check(&s, ImageError::SensorCountMismatch);
    let bad_sensor = [
        sensor(20.0, 0.0),
        SensorSpec {
            min_degc: 50.0,
            max_degc: 40.0,
            ..sensor(20.0, 0.0)
        },
    ];
    s.thermo = Some(ThermoForceSpec {
        sensors: &bad_sensor,
        ..thermo
    });
    check(
        &s,
        ImageError::OutOfRange {
            field: Field::SensorRange,
            index: 1,
        },
    );
    let many = [sensor(20.0, 0.0); MAX_SENSORS + 1];
    s.thermo = Some(ThermoForceSpec {
        sensors: &many,
        b_um_per_k: &[0.0; MAX_SENSORS + 1],
        ..thermo
    });
    check(&s, ImageError::TooManySensors);
    s.thermo = Some(ThermoForceSpec {
        expansion: Some(ExpansionSpec {
            sensor: 2,
            x_ref_counts: 0,
            c_um_per_mm_k: 0.01,
        }),
        ..thermo
    });
    check(
        &s,
        ImageError::OutOfRange {
            field: Field::ExpansionSensor,
            index: 0,
        },
    );
    s.thermo = Some(ThermoForceSpec {
        forces: &[ForceSpec {
            chi_um_per_n: f32::NAN,
            law: None,
        }],
        ..thermo
    });
    check(
        &s,
        ImageError::NonFinite {
            field: Field::Chi,
            index: 0,
        },
    );
    // Buffer too small.
    let n = image_len(&base);
    assert_eq!(
        write_image(&base, &mut buf[..n - 1]),
        Err(ImageError::BufferTooSmall { needed: n as u32 })
    );
    // Messages name the field.
    let msg = format!(
        "{}",
        ImageError::NonFinite {
            field: Field::ForwardCoefficient,
            index: 2
        }
    );
    assert_eq!(msg, "table.forward[2] is not finite");
}

/// Recompute the CRC after patching an image (to reach the checks behind the CRC).
fn patch(bytes: &mut [u8], at: usize, v: &[u8]) {
    bytes[at..at + v.len()].copy_from_slice(v);
    let n = bytes.len() - 4;
    let crc = crc32(&bytes[..n]);
    bytes[n..].copy_from_slice(&crc.to_le_bytes());
}

#[test]
fn parse_errors_and_load_leaves_running_object_untouched() {
    let fwd = [[3.0f32, 0.0, 0.0, 0.0]; 4];
    let good = image(&table_spec(
        TableSpec {
            start_counts: 0,
            segment_counts: 100,
            forward: &fwd,
            backward: &[],
            outside: OutsideStroke::Hold,
        },
        LOOSE,
    ));
    let mut c = Box::new(Compensator::IDENTITY);
    c.load(&good).unwrap();
    let before = c.clone();
    let try_load = |c: &mut Compensator, bytes: &[u8], want: ImageError| {
        assert_eq!(c.load(bytes), Err(want));
    };
    try_load(&mut c, &good[..20], ImageError::TooShort);
    try_load(&mut c, &good[..good.len() - 1], ImageError::TooShort);
    let mut b = good.clone();
    b[0] = b'X';
    try_load(&mut c, &b, ImageError::BadMagic);
    let mut b = good.clone();
    b[100] ^= 1;
    try_load(&mut c, &b, ImageError::BadCrc);
    let mut b = good.clone();
    patch(&mut b, 4, &2u16.to_le_bytes());
    try_load(&mut c, &b, ImageError::UnsupportedVersion { found: 2 });
    let mut b = good.clone();
    patch(&mut b, 36, &9999u32.to_le_bytes()); // limits offset beyond the image
    try_load(&mut c, &b, ImageError::BadLength);
    let mut b = good.clone();
    patch(&mut b, 48 + 24 + 16 + 4, &f32::NAN.to_le_bytes()); // segment 1, c1
    try_load(
        &mut c,
        &b,
        ImageError::NonFinite {
            field: Field::ForwardCoefficient,
            index: 1,
        },
    );
    // Nothing changed in the running object.
    assert_eq!(format!("{c:?}"), format!("{before:?}"));
    let mut st = State::new();
    assert_eq!(c.cycle(&mut st, &input(50, 0)).correction_um, 3.0);
    // Trailing bytes after the declared length are refused, never accepted without
    // comment; a flash slot is cut to the image with `declared_image_len` first.
    let mut padded = good.clone();
    padded.extend_from_slice(&[0xFF; 100]);
    assert_eq!(c.load(&padded), Err(ImageError::TrailingBytes));
    let n = declared_image_len(&padded).unwrap();
    assert_eq!(c.load(&padded[..n]), Ok(()));
}

#[test]
fn identity_is_unloaded() {
    // The identity must not depend on an image; a fresh State too.
    let c = Compensator::IDENTITY;
    assert!(!c.is_loaded());
    assert_eq!(c.forward_segments().len(), 0);
    assert_eq!(State::new(), State::default());
}

/// Two sensors, one force, with the given reference mode and rise bounds.
fn flagged_spec<'a>(
    sensors: &'a [SensorSpec],
    reference: ThermoReference,
    rise_bounds_k: &'a [(f32, f32)],
) -> ImageSpec<'a> {
    ImageSpec {
        axis_id: 7,
        um_per_count: 0.1,
        counter_bits: 32,
        table: None,
        thermo: Some(ThermoForceSpec {
            sensor_period_ms: 500,
            sensors,
            b0_um: 0.5,
            b_um_per_k: &[1.0, -2.0],
            expansion: None,
            forces: &FORCES[..1],
            reference,
            rise_bounds_k,
        }),
        limits: LOOSE,
    }
}

/// Offset of the thermo section (header field at 28).
fn thermo_off(img: &[u8]) -> usize {
    u32::from_le_bytes(img[28..32].try_into().unwrap()) as usize
}

#[test]
fn thermo_flags_and_rise_bounds_round_trip() {
    let s = [sensor(20.0, 30.0), sensor(21.0, 0.0)];
    let bounds = [(-1.5f32, 6.25), (-2273.15, 2273.15)];
    // Flags 0: the thermo section and its flags word are as without flags.
    let plain = image(&flagged_spec(&s, ThermoReference::Fixed, &[]));
    let o = thermo_off(&plain);
    assert_eq!(&plain[o + 24..o + 32], &[0u8; 8]);
    assert_eq!(
        u32::from_le_bytes(plain[32..36].try_into().unwrap()),
        (32 + 28 * 2 + 24) as u32
    );
    for (reference, b, flags) in [
        (ThermoReference::SwitchOn, &[][..], 1u32),
        (ThermoReference::Fixed, &bounds[..], 2),
        (ThermoReference::SwitchOn, &bounds[..], 3),
    ] {
        let spec = flagged_spec(&s, reference, b);
        let img = image(&spec);
        assert_eq!(img.len(), image_len(&spec));
        let o = thermo_off(&img);
        assert_eq!(
            u32::from_le_bytes(img[o + 24..o + 28].try_into().unwrap()),
            flags
        );
        let len = u32::from_le_bytes(img[32..36].try_into().unwrap()) as usize;
        assert_eq!(len, 32 + 28 * 2 + 24 + if b.is_empty() { 0 } else { 16 });
        assert_eq!(img.len(), plain.len() + len - (32 + 28 * 2 + 24));
        let c = load(&spec);
        assert_eq!(c.thermo_reference(), reference);
        assert_eq!(c.has_rise_guard(), !b.is_empty());
        for (i, si) in s.iter().enumerate() {
            assert_eq!(c.rise_bounds_k(i), b.get(i).copied());
            assert_eq!(c.sensor(i), Some(*si));
        }
        assert_eq!(c.rise_bounds_k(2), None);
        assert_eq!(inspect_image(&img).unwrap().n_sensors, 2);
    }
}

#[test]
fn invalid_thermo_flags_and_rise_bounds_are_refused() {
    let s = [sensor(20.0, 30.0), sensor(21.0, 0.0)];
    let write = |b: &[(f32, f32)]| {
        let spec = flagged_spec(&s, ThermoReference::Fixed, b);
        let mut buf = vec![0u8; image_len(&spec)];
        write_image(&spec, &mut buf).map(|_| ())
    };
    let range = |index| ImageError::OutOfRange {
        field: Field::RiseBounds,
        index,
    };
    assert_eq!(write(&[(0.0, 1.0), (2.0, 2.0)]), Err(range(1)), "lo == hi");
    assert_eq!(write(&[(3.0, 1.0), (0.0, 1.0)]), Err(range(0)), "lo > hi");
    assert_eq!(write(&[(0.0, 1.0), (0.0, 2274.0)]), Err(range(1)));
    assert_eq!(write(&[(-2274.0, 1.0), (0.0, 1.0)]), Err(range(0)));
    assert_eq!(
        write(&[(0.0, f32::NAN), (0.0, 1.0)]),
        Err(ImageError::NonFinite {
            field: Field::RiseBounds,
            index: 0
        })
    );
    assert_eq!(write(&[(0.0, 1.0)]), Err(ImageError::SensorCountMismatch));

    let good = image(&flagged_spec(&s, ThermoReference::Fixed, &[]));
    let o = thermo_off(&good);
    let mut c = Box::new(Compensator::IDENTITY);
    // An unknown flag bit.
    for bit in [2u32, 31] {
        let mut b = good.clone();
        patch(&mut b, o + 24, &(1u32 << bit).to_le_bytes());
        assert_eq!(
            c.load(&b),
            Err(ImageError::OutOfRange {
                field: Field::ThermoFlags,
                index: 0
            })
        );
    }
    // The second reserved word stays 0.
    let mut b = good.clone();
    patch(&mut b, o + 28, &1u32.to_le_bytes());
    assert_eq!(
        c.load(&b),
        Err(ImageError::OutOfRange {
            field: Field::Reserved,
            index: 0
        })
    );
    // RISE_GUARD without the bounds' bytes: the section length no longer matches.
    let mut b = good.clone();
    patch(&mut b, o + 24, &2u32.to_le_bytes());
    assert_eq!(c.load(&b), Err(ImageError::BadLength));
    // SwitchOn needs no extra bytes.
    let mut b = good.clone();
    patch(&mut b, o + 24, &1u32.to_le_bytes());
    assert_eq!(c.load(&b), Ok(()));
    assert_eq!(c.thermo_reference(), ThermoReference::SwitchOn);
    // A bound patched beyond the range in a guarded image.
    let guarded = image(&flagged_spec(&s, ThermoReference::Fixed, &[(0.0, 1.0); 2]));
    let at = thermo_off(&guarded) + 32 + 28 * 2 + 24 + 8 + 4; // sensor 1's rise_max_k
    let mut b = guarded.clone();
    patch(&mut b, at, &(-0.5f32).to_le_bytes());
    assert_eq!(c.load(&b), Err(range(1)));
    assert_eq!(Field::RiseBounds.name(), "thermo.rise_bounds_k");
}
