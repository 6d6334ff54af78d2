//! Writes a few valid table images into a directory (fuzzing seeds, format examples).
//!
//! `cargo run -p axcomp-core --example write_seed_images -- DIR`

use axcomp_core::{
    ForceSpec, ImageSpec, LimitSpec, OutsideStroke, SensorSpec, TableSpec, ThermoForceSpec, bench,
    image_len, write_image,
};

fn write(dir: &std::path::Path, name: &str, spec: &ImageSpec) -> std::io::Result<()> {
    let mut buf = vec![0u8; image_len(spec)];
    write_image(spec, &mut buf).map_err(std::io::Error::other)?;
    // Write to a temporary name, then rename: never a half-written image.
    let tmp = dir.join(format!(".{name}.tmp"));
    std::fs::write(&tmp, &buf)?;
    std::fs::rename(&tmp, dir.join(name))
}

fn main() -> std::io::Result<()> {
    let dir = std::path::PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| ".".into()));
    std::fs::create_dir_all(&dir)?;
    let reference = bench::reference_spec();
    write(&dir, "reference.axci", &reference)?;
    write(
        &dir,
        "reference_table_only.axci",
        &ImageSpec {
            thermo: None,
            ..reference
        },
    )?;
    let fwd = [[1.0f32, 0.5, -0.25, 0.125]];
    let sensors = [SensorSpec {
        reference_degc: 20.0,
        min_degc: 0.0,
        max_degc: 80.0,
        max_rate_degc_per_s: 1.0,
        lag_tau_s: 60.0,
        stale_timeout_ms: 2000,
    }];
    let forces = [ForceSpec {
        chi_um_per_n: 0.01,
        law: None,
    }];
    write(
        &dir,
        "small.axci",
        &ImageSpec {
            axis_id: 2,
            um_per_count: 1.0,
            counter_bits: 16,
            table: Some(TableSpec {
                start_counts: -100,
                segment_counts: 200,
                forward: &fwd,
                backward: &[],
                outside: OutsideStroke::Hold,
            }),
            thermo: Some(ThermoForceSpec {
                sensor_period_ms: 1000,
                sensors: &sensors,
                b0_um: 0.5,
                b_um_per_k: &[1.5],
                expansion: None,
                forces: &forces,
                reference: axcomp_core::ThermoReference::Fixed,
                rise_bounds_k: &[],
            }),
            limits: LimitSpec {
                max_correction_um: 20.0,
                max_slew_um_per_cycle: 1.0,
                direction_hysteresis_counts: 3,
            },
        },
    )?;
    println!("wrote 3 images to {}", dir.display());
    Ok(())
}
