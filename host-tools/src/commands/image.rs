//! `axcomp image build|inspect`: the firmware's binary table image.
//!
//! Glossary:
//! - *image*: the versioned, CRC-protected binary the firmware loads (`axcomp_core::write_image`).
//! - *table file*: a fitted positioning table (`fit positioning --out`), JSON, physical units.
//! - *thermal model file*: a fitted thermo-force model (`fit thermal --out`), JSON.
//! - *counts*: scale counts; `um_per_count` is the scale resolution.

use std::path::PathBuf;

use anyhow::Context;
use axcomp_core::{Compensator, ImageSpec, LimitSpec, image_len, inspect_image, write_image};
use axcomp_positioning::TableFile;
use axcomp_thermal::model_file::ThermalModelFile;

use super::common::write_atomic;

#[derive(Debug, clap::Args)]
pub struct BuildArgs {
    /// Positioning table (JSON from `fit positioning --out`).
    #[arg(long, value_name = "TABLE.json")]
    pub table: Option<PathBuf>,
    /// Thermo-force model (JSON from `fit thermal --out`).
    #[arg(long, value_name = "MODEL.json")]
    pub thermal: Option<PathBuf>,
    /// Axis id stored in the image (the firmware refuses an image for another axis).
    #[arg(long, value_name = "N")]
    pub axis_id: u16,
    /// Scale resolution, µm per count.
    #[arg(long, value_name = "U")]
    pub um_per_count: f64,
    /// Width of the hardware position counter (16..=32).
    #[arg(long, default_value_t = 32)]
    pub counter_bits: u8,
    /// Clamp of the total correction, µm.
    #[arg(long, default_value_t = 1000.0)]
    pub max_correction_um: f32,
    /// Largest change of the applied correction per control cycle, µm.
    #[arg(long, default_value_t = 5.0)]
    pub max_slew_um: f32,
    /// Hysteresis (counts) before a reversal switches between forward and backward tables.
    #[arg(long, default_value_t = 2)]
    pub hysteresis_counts: u32,
    /// Output image file.
    #[arg(long, value_name = "IMAGE")]
    pub out: PathBuf,
}

#[derive(Debug, clap::Args)]
pub struct InspectArgs {
    /// The image file.
    #[arg(value_name = "IMAGE")]
    pub image: PathBuf,
}

/// Builds the image bytes from the table/model files (validated; nothing is written here).
pub fn build_bytes(args: &BuildArgs) -> anyhow::Result<Vec<u8>> {
    if args.table.is_none() && args.thermal.is_none() {
        anyhow::bail!("image build: give --table and/or --thermal");
    }
    if !(args.um_per_count.is_finite() && args.um_per_count > 0.0) {
        anyhow::bail!(
            "--um-per-count {}: must be a finite number > 0",
            args.um_per_count
        );
    }
    let table = match &args.table {
        Some(p) => {
            let t = TableFile::load(p).with_context(|| format!("reading table {}", p.display()))?;
            Some(
                t.try_to_core(args.um_per_count)
                    .with_context(|| format!("{}: converting to scale counts", p.display()))?,
            )
        }
        None => None,
    };
    let thermo = match &args.thermal {
        Some(p) => {
            let m = ThermalModelFile::load(p)
                .with_context(|| format!("reading thermal model {}", p.display()))?;
            Some(m.to_core())
        }
        None => None,
    };
    let spec = ImageSpec {
        axis_id: args.axis_id,
        um_per_count: args.um_per_count as f32,
        counter_bits: args.counter_bits,
        table: table.as_ref().map(|t| t.spec()),
        thermo: thermo.as_ref().map(|t| t.spec()),
        limits: LimitSpec {
            max_correction_um: args.max_correction_um,
            max_slew_um_per_cycle: args.max_slew_um,
            direction_hysteresis_counts: args.hysteresis_counts,
        },
    };
    let mut buf = vec![0u8; image_len(&spec)];
    let n = write_image(&spec, &mut buf).context("the image spec is not valid")?;
    buf.truncate(n);
    Ok(buf)
}

pub fn build(args: BuildArgs) -> anyhow::Result<()> {
    let bytes = build_bytes(&args)?;
    // Check what was built loads, before writing it.
    let mut comp = Compensator::IDENTITY;
    comp.load(&bytes)
        .context("the built image does not load (internal error)")?;
    write_atomic(&args.out, &bytes)?;
    let info = inspect_image(&bytes)?;
    println!(
        "wrote {} ({} bytes, axis {}, {} segments{}, thermo: {}, CRC-32 {:08x})",
        args.out.display(),
        info.len,
        info.axis_id,
        info.n_segments,
        if info.bidirectional {
            " per direction"
        } else {
            ""
        },
        if info.has_thermo { "yes" } else { "no" },
        info.crc
    );
    Ok(())
}

/// The text `image inspect` prints for a valid image.
pub fn describe(bytes: &[u8]) -> anyhow::Result<String> {
    use std::fmt::Write;
    let info = inspect_image(bytes)?;
    let mut comp = Compensator::IDENTITY;
    comp.load(bytes)?;
    let mut s = String::new();
    writeln!(
        s,
        "image: {} bytes, schema version {}, CRC-32 {:08x} (ok)",
        info.len, info.version, info.crc
    )?;
    writeln!(s, "axis id: {}", info.axis_id)?;
    writeln!(
        s,
        "scale: {} µm/count, {}-bit counter",
        comp.um_per_count(),
        info.counter_bits
    )?;
    let l = comp.limits();
    writeln!(
        s,
        "limits: |correction| <= {} µm, slew <= {} µm/cycle, reversal hysteresis {} counts",
        l.max_correction_um, l.max_slew_um_per_cycle, l.direction_hysteresis_counts
    )?;
    if comp.has_table() {
        let um = comp.um_per_count() as f64;
        let start = comp.table_start_counts();
        let seg = comp.segment_counts() as i64;
        let n = info.n_segments as i64;
        writeln!(
            s,
            "table: {} segments{} of {} counts ({:.4} mm), {} .. {} counts ({:.4} .. {:.4} mm), outside: {:?}",
            info.n_segments,
            if info.bidirectional {
                " per direction"
            } else {
                " (unidirectional)"
            },
            seg,
            seg as f64 * um / 1000.0,
            start,
            start + seg * n,
            start as f64 * um / 1000.0,
            (start + seg * n) as f64 * um / 1000.0,
            comp.outside()
        )?;
        for (name, tab) in [
            ("forward", comp.forward_segments()),
            ("backward", comp.backward_segments()),
        ] {
            if tab.is_empty() {
                continue;
            }
            // Knot values c0 and the end value of the last segment.
            let mut lo = f32::INFINITY;
            let mut hi = f32::NEG_INFINITY;
            for c in tab {
                lo = lo.min(c[0]);
                hi = hi.max(c[0]);
            }
            let last = tab[tab.len() - 1];
            let end = last[0] + last[1] + last[2] + last[3];
            lo = lo.min(end);
            hi = hi.max(end);
            writeln!(s, "  {name}: deviation at knots {lo:.3} .. {hi:.3} µm")?;
        }
    } else {
        writeln!(s, "table: none")?;
    }
    if info.has_thermo {
        writeln!(
            s,
            "thermo-force: {} sensors (period {} ms), b0 = {} µm, {} force terms, expansion: {}",
            info.n_sensors,
            comp.sensor_period_ms(),
            comp.b0_um(),
            info.n_forces,
            if comp.expansion().is_some() {
                "yes"
            } else {
                "no"
            }
        )?;
        for i in 0..comp.sensor_count() {
            if let (Some(sp), Some(b)) = (comp.sensor(i), comp.b_um_per_k(i)) {
                writeln!(
                    s,
                    "  sensor {i}: ref {} °C, range {} .. {} °C, b = {} µm/K, lag τ = {} s",
                    sp.reference_degc, sp.min_degc, sp.max_degc, b, sp.lag_tau_s
                )?;
            }
        }
    } else {
        writeln!(s, "thermo-force: none")?;
    }
    Ok(s)
}

pub fn inspect(args: InspectArgs) -> anyhow::Result<()> {
    let bytes = std::fs::read(&args.image)
        .with_context(|| format!("cannot read {}", args.image.display()))?;
    let text =
        describe(&bytes).with_context(|| format!("{}: invalid image", args.image.display()))?;
    print!("{text}");
    Ok(())
}
