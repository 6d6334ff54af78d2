//! The text forms of `image group`'s options: an axis (`NAME[:CPR]=IMAGE`), sensor names
//! (`NAME=N1,N2,..`), probe settings, a tool offset and pivot counts. Errors name the option.

use std::path::PathBuf;

use axcomp_core::group::AxisName;
use axcomp_core::probe::ProbeSettings;

use crate::{Context, Error, Result};

/// `--probe recommended` or `KEY=V,..` over [`ProbeSettings::RECOMMENDED`]; validated.
pub fn parse_probe_settings(arg: &str) -> Result<ProbeSettings> {
    let mut p = ProbeSettings::RECOMMENDED;
    if arg.trim() != "recommended" {
        for kv in arg.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let (k, v) = kv
                .split_once('=')
                .with_context(|| format!("--probe `{kv}`: expected KEY=VALUE or `recommended`"))?;
            let v: f64 = v
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite() && *v >= 0.0)
                .with_context(|| format!("--probe `{kv}`: the value must be a number >= 0"))?;
            let whole = |x: f64| -> Result<u32> {
                ensure!(x <= u32::MAX as f64, "--probe `{kv}`: {x} is out of range");
                Ok(x.round() as u32)
            };
            match k.trim() {
                "min_pulse_us" => p.min_pulse_us = whole(v)?,
                "latency_us" => p.latency_ns = whole(v * 1000.0)?,
                "lockout_ms" => p.lockout_us = whole(v * 1000.0)?,
                "moving_mm_min" => p.moving_um_per_s = (v * 1000.0 / 60.0) as f32,
                other => bail!(
                    "--probe `{kv}`: unknown key `{other}` (min_pulse_us, latency_us, lockout_ms, \
                     moving_mm_min)"
                ),
            }
        }
    }
    p.validate()
        .map_err(|e| Error::core(format!("--probe {arg}"), e))?;
    Ok(p)
}

pub fn parse_tool_offset(arg: &str) -> Result<[f64; 3]> {
    let v: Vec<f64> = arg
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<std::result::Result<_, _>>()
        .with_context(|| format!("--tool-offset-mm {arg}: expected three numbers x,y,z"))?;
    ensure!(
        v.len() == 3 && v.iter().all(|x| x.is_finite()),
        "--tool-offset-mm {arg}: expected three finite numbers x,y,z"
    );
    Ok([v[0], v[1], v[2]])
}

pub fn parse_axis_arg(arg: &str) -> Result<(AxisName, u32, PathBuf)> {
    let (head, path) = arg
        .split_once('=')
        .with_context(|| format!("--axis {arg}: expected NAME[:CPR]=IMAGE"))?;
    let (name, cpr) = match head.split_once(':') {
        Some((n, c)) => (
            n,
            c.parse::<u32>()
                .with_context(|| format!("--axis {arg}: counts per revolution `{c}`"))?,
        ),
        None => (head, 0),
    };
    let mut chars = name.chars();
    let letter = match (chars.next(), chars.next()) {
        (Some(c), None) => AxisName::from_letter(c),
        _ => None,
    }
    .with_context(|| format!("--axis {arg}: axis name must be one of X, Y, Z, A, B, C"))?;
    if letter.is_rotary() && cpr == 0 {
        bail!("--axis {arg}: a rotary axis needs NAME:COUNTS_PER_REV=IMAGE");
    }
    if !letter.is_rotary() && cpr != 0 {
        bail!("--axis {arg}: a linear axis has no counts per revolution");
    }
    Ok((letter, cpr, PathBuf::from(path)))
}

pub fn parse_pivot_counts(arg: &str) -> Result<[i64; 3]> {
    let parts: Vec<&str> = arg.split(',').map(str::trim).collect();
    ensure!(
        parts.len() == 3,
        "--pivot-counts {arg}: expected three integers X,Y,Z"
    );
    let mut out = [0i64; 3];
    for (o, p) in out.iter_mut().zip(&parts) {
        *o = p
            .parse()
            .with_context(|| format!("--pivot-counts {arg}: `{p}` is not an integer"))?;
    }
    Ok(out)
}

/// `--sensor-names NAME=N1,N2,...`: the axis and its sensor names.
pub fn parse_sensor_names_arg(arg: &str) -> Result<(AxisName, Vec<String>)> {
    let (n, list) = arg
        .split_once('=')
        .with_context(|| format!("--sensor-names {arg}: expected NAME=N1,N2,..."))?;
    let name = n
        .chars()
        .next()
        .and_then(AxisName::from_letter)
        .filter(|_| n.len() == 1)
        .with_context(|| format!("--sensor-names {arg}: unknown axis `{n}`"))?;
    Ok((name, list.split(',').map(str::to_string).collect()))
}
