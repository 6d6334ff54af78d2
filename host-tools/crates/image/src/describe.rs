//! What `image inspect` prints of an image: the axis images (table, thermo-force, limits), the group's
//! rotary, probe and geometric sections, provenance and the sensors' wiring onto a board.

use std::fmt::Write;

use axcomp_core::geometric::{COMPONENT_NAMES, GeometricSpec};
use axcomp_core::group::AxisName;
use axcomp_core::group_image;
use axcomp_core::provenance;
use axcomp_core::rotary::{
    RotaryLocationSpec, RotaryMachine, WOBBLE_HARMONICS, WOBBLE_TILT_DEGREE,
};
use axcomp_core::wiring::{BoardInput, InputUnit};
use axcomp_core::{Compensator, inspect_image};

use crate::geometric::geometric_component_nonzero;
use crate::{Error, Result};

/// Lower-case hex of 32 bytes (a SHA-256).
pub fn to_hex(b: &[u8; 32]) -> String {
    b.iter().map(|x| format!("{x:02x}")).collect()
}

/// The text `image inspect` prints for a valid image.
pub fn describe(bytes: &[u8]) -> Result<String> {
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
            // The last segment at its end, r = L (the coefficients are in the remainder r,
            // counts from the knot: c0 + r·(c1 + r·(c2 + r·c3))).
            let last = tab[tab.len() - 1].map(f64::from);
            let l = comp.segment_counts() as f64;
            let end = (last[0] + l * (last[1] + l * (last[2] + l * last[3]))) as f32;
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
        let switch_on = comp.thermo_reference() == axcomp_core::ThermoReference::SwitchOn;
        writeln!(
            s,
            "  reference: {}; range guard: {}",
            if switch_on {
                "each sensor's first reading after load/reset (switch-on); ref = nominal"
            } else {
                "fixed (ref per sensor)"
            },
            if comp.has_rise_guard() {
                "on (a sensor's term is left out while its rise is outside its bounds)"
            } else {
                "off"
            }
        )?;
        for i in 0..comp.sensor_count() {
            if let (Some(sp), Some(b)) = (comp.sensor(i), comp.b_um_per_k(i)) {
                write!(
                    s,
                    "  sensor {i}: ref {} °C, range {} .. {} °C, b = {} µm/K, lag τ = {} s",
                    sp.reference_degc, sp.min_degc, sp.max_degc, b, sp.lag_tau_s
                )?;
                match comp.rise_bounds_k(i) {
                    Some((lo, hi)) => writeln!(s, ", rise {lo} .. {hi} K")?,
                    None => writeln!(s)?,
                }
            }
        }
    } else {
        writeln!(s, "thermo-force: none")?;
    }
    Ok(s)
}

/// Provenance, sensor names and their wiring onto `board` (the part of `image inspect` after the axes).
pub fn describe_trust(bytes: &[u8], board: &[(String, InputUnit)]) -> Result<String> {
    let view = group_image::parse(bytes)?;
    let inputs: Vec<BoardInput> = board
        .iter()
        .map(|(name, unit)| BoardInput { name, unit: *unit })
        .collect();
    let mut s = String::new();
    match view.provenance {
        Some(p) => {
            writeln!(s, "provenance: built {} by {}", p.built_utc(), p.tool())?;
            for r in p.records() {
                let axis = AxisName::from_code(r.axis)
                    .map_or(String::new(), |a| format!("axis {}: ", a.letter()));
                writeln!(
                    s,
                    "  {axis}{} sha256 {}; data sha256 {}",
                    provenance::role::name(r.role),
                    to_hex(&r.model_sha256),
                    if r.data_sha256 == [0; 32] {
                        "not recorded".to_string()
                    } else {
                        to_hex(&r.data_sha256)
                    }
                )?;
            }
        }
        None => writeln!(s, "provenance: none (built before images carried it)")?,
    }
    writeln!(
        s,
        "board inputs: {}",
        board
            .iter()
            .enumerate()
            .map(|(k, (n, u))| format!("{k} {n} ({})", u.name()))
            .collect::<Vec<_>>()
            .join(", ")
    )?;
    for a in view.axes() {
        let n = inspect_image(a.axis.image)?.n_sensors;
        if n == 0 {
            continue;
        }
        let named = !a.sensor_names.is_empty();
        let wiring = axcomp_core::wiring::wire_axis(a, n, &inputs);
        writeln!(
            s,
            "{} sensors ({}): {}",
            crate::board::axis_label(
                view.version == 1,
                a.axis.name,
                inspect_image(a.axis.image)?.axis_id
            ),
            if named {
                "wired by name"
            } else {
                "no names: wired by position"
            },
            match &wiring {
                Ok(_) => "every sensor has its input".to_string(),
                Err(e) => format!("REFUSED by this board: {e}"),
            }
        )?;
        for j in 0..n {
            let name = a.sensor_name(j).unwrap_or("(unnamed)");
            let to = match &wiring {
                Ok(w) => {
                    let k = usize::from(w[j]);
                    format!(
                        "board input {k} {} ({})",
                        inputs[k].name,
                        inputs[k].unit.name()
                    )
                }
                Err(_) => match inputs.iter().position(|i| i.name == name) {
                    Some(k) if named => format!("board input {k} {}", inputs[k].name),
                    _ if !named && j < inputs.len() => {
                        format!("board input {j} {} (by position)", inputs[j].name)
                    }
                    _ => "no board input".to_string(),
                },
            };
            writeln!(s, "  sensor {j} {name} -> {to}")?;
        }
    }
    Ok(s)
}

/// `image inspect` for any image: a group image (schema 2) per axis, a schema-1 image as before;
/// bytes after an image's declared end are an error.
pub fn describe_any(bytes: &[u8]) -> Result<String> {
    let view = group_image::parse(bytes)?;
    if view.version == 1 {
        return describe(bytes);
    }
    view.check_group()
        .map_err(|e| Error::core("the group is not valid (every board refuses it)", e))?;
    let mut s = String::new();
    writeln!(
        s,
        "group image: {} bytes, schema version 2, {} axes, CRC-32 {:08x} (ok, every section's too)",
        bytes.len(),
        view.axis_count(),
        view.crc
    )?;
    for a in view.axes() {
        writeln!(
            s,
            "--- axis {} ({}{}) ---",
            a.axis.name.letter(),
            if a.axis.name.is_rotary() {
                format!("rotary, {} counts per revolution", a.axis.counts_per_rev)
            } else {
                "linear".to_string()
            },
            match a.stroke_counts {
                Some((lo, hi)) => format!(", stroke {lo} .. {hi} counts"),
                None => String::new(),
            }
        )?;
        s.push_str(&describe(a.axis.image)?);
        let n = inspect_image(a.axis.image)?.n_sensors;
        for i in 0..n {
            if let Some(name) = a.sensor_name(i) {
                writeln!(s, "  sensor {i} name: {name}")?;
            }
        }
    }
    match view.rotary {
        Some(r) => s.push_str(&describe_rotary(&r)),
        None => writeln!(s, "rotary location errors: none")?,
    }
    match &view.probe {
        Some(p) => writeln!(
            s,
            "probe settings: minimum pulse {} µs, latency {} µs, lockout {} ms, moving above {} mm/min",
            p.min_pulse_us,
            p.latency_ns as f64 / 1000.0,
            p.lockout_us as f64 / 1000.0,
            p.moving_um_per_s as f64 * 60.0 / 1000.0
        )?,
        None => writeln!(s, "probe settings: none")?,
    }
    match &view.geometric {
        Some(g) => s.push_str(&describe_geometric(g)),
        None => writeln!(s, "geometric model: none")?,
    }
    Ok(s)
}

/// The rotary section's lines of `image inspect`: machine kind, every constant by its ISO 230-7
/// name, which ones were not identified (fixed at 0), pivot and tool length.
fn describe_rotary(r: &RotaryLocationSpec) -> String {
    let names = r.machine.constant_names();
    let values = r.all_constants();
    let list = |range: std::ops::Range<usize>| {
        range
            .map(|k| {
                let unit = if matches!(k, 0 | 1 | 4 | 5) {
                    "µm"
                } else {
                    "µrad"
                };
                let fixed = if r.not_identified >> k & 1 == 1 {
                    " (not identified: fixed at 0)"
                } else {
                    ""
                };
                format!("{} {} {unit}{fixed}", names[k], values[k])
            })
            .collect::<Vec<_>>()
            .join(", ")
    };
    let not: Vec<&str> = (0..11)
        .filter(|k| r.not_identified >> k & 1 == 1)
        .map(|k| names[k])
        .collect();
    let length = if r.machine == RotaryMachine::BcHead {
        "pivot to tool tip"
    } else {
        "tool length"
    };
    format!(
        "rotary location errors ({}): {}\n  squareness: {}\n  not identified (fixed at their prior 0): {}\n  pivot {:?} counts, {length} {} µm\n{}",
        r.machine.name(),
        list(0..8),
        list(8..11),
        if not.is_empty() {
            "none".to_string()
        } else {
            not.join(", ")
        },
        r.pivot_counts,
        r.tool_length_um,
        describe_wobble(r)
    )
}

/// The wobble's line of `image inspect`: its non-zero coefficients by the model's parameter names
/// (`C_tilt_x_cos2`, `A_radial_z_t1`, …), or `none`.
fn describe_wobble(r: &RotaryLocationSpec) -> String {
    let tilt = r.machine.tilt_axis().letter();
    let perpendicular = if tilt == 'A' { ['y', 'z'] } else { ['x', 'z'] };
    let mut names = Vec::new();
    for k in 1..=WOBBLE_HARMONICS {
        for trig in ["cos", "sin"] {
            for ax in ['x', 'y'] {
                names.push((format!("C_tilt_{ax}_{trig}{k}"), "µrad"));
                names.push((format!("C_radial_{ax}_{trig}{k}"), "µm"));
            }
        }
    }
    for d in 1..=WOBBLE_TILT_DEGREE {
        for ax in perpendicular {
            names.push((format!("{tilt}_tilt_{ax}_t{d}"), "µrad"));
            names.push((format!("{tilt}_radial_{ax}_t{d}"), "µm"));
        }
    }
    let terms: Vec<String> = names
        .iter()
        .zip(r.wobble.coefficients())
        .filter(|(_, v)| *v != 0.0)
        .map(|((n, unit), v)| format!("{n} {v} {unit}"))
        .collect();
    if terms.is_empty() {
        "  wobble: none\n".to_string()
    } else {
        format!(
            "  wobble (angles of C at k per turn, of {tilt} as powers of its signed angle in rad): {}\n",
            terms.join(", ")
        )
    }
}

/// The `image inspect` lines of a geometric section: stacking, tool offset, grids, squareness
/// and each component's status and range of values over its grid.
pub fn describe_geometric(g: &GeometricSpec) -> String {
    let mut s = String::new();
    let label = String::from_utf8_lossy(&g.stacking_label()).into_owned();
    let n_id = (0..21).filter(|i| g.identified >> i & 1 == 1).count();
    let n_excluded = (0..21)
        .filter(|&i| g.identified >> i & 1 == 1 && !geometric_component_nonzero(g, i))
        .count();
    let n_shared = (0..21)
        .filter(|&i| g.identified >> i & 1 == 0 && geometric_component_nonzero(g, i))
        .count();
    let _ = writeln!(
        s,
        "geometric model (21 ISO 230-1 components, volumetric stage): stacking {label} \
         (work axes / tool axes), tool offset ({}, {}, {}) µm, {n_id} of 21 components identified{}{}",
        g.tool_offset_um[0],
        g.tool_offset_um[1],
        g.tool_offset_um[2],
        match n_excluded {
            0 => String::new(),
            n => format!(", {n} of them excluded from this image (stored as zero)"),
        },
        match n_shared {
            0 => String::new(),
            n => format!(
                ", {n} not separable stored at their minimum-norm share (only their combination \
                 is measured)"
            ),
        }
    );
    for (k, grid) in g.grids.iter().enumerate() {
        let _ = writeln!(
            s,
            "  grid {}: {} segments of {} counts from {} counts ({} knots)",
            ['X', 'Y', 'Z'][k],
            grid.n_segments,
            grid.segment_counts,
            grid.start_counts,
            grid.n_segments + 1
        );
    }
    let status = |i: usize| {
        if g.identified >> i & 1 == 0 && geometric_component_nonzero(g, i) {
            "NOT separable: only its combination with others is measured; stored at its \
             minimum-norm share (the fit's value, as `axcomp predict` uses it)"
        } else if g.identified >> i & 1 == 0 {
            "NOT identified: stored as zero (the model's prior)"
        } else if geometric_component_nonzero(g, i) {
            "identified"
        } else {
            "identified by the fit, EXCLUDED from this image: stored as zero (`image group \
             --exclude-geometric`: an axis table or the rotary model corrects it)"
        }
    };
    for k in 0..3 {
        for f in 0..6 {
            let i = 6 * k + f;
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for seg in 0..g.grids[k].n_segments as usize {
                let c = g.segment(k, seg, f);
                for t in [0.0f32, 0.25, 0.5, 0.75, 1.0] {
                    let v = c[0] + t * (c[1] + t * (c[2] + t * c[3]));
                    lo = lo.min(v);
                    hi = hi.max(v);
                }
            }
            let unit = if f < 3 { "µm" } else { "µrad" };
            let _ = writeln!(
                s,
                "  {:<4} {:.3} .. {:.3} {unit}, {}",
                COMPONENT_NAMES[i],
                lo,
                hi,
                status(i)
            );
        }
    }
    for q in 0..3 {
        let _ = writeln!(
            s,
            "  {:<4} {} µrad, {}",
            COMPONENT_NAMES[18 + q],
            g.squareness_urad[q],
            status(18 + q)
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::board::parse_board_inputs;

    /// An image written before provenance and without names on a board's inputs: `inspect` says it has no
    /// provenance and wires by position; the scenario's named group (spindle, column) is refused by the
    /// STM32G474 board's default inputs and wired on a board that names its inputs so; a bad
    /// `--board-inputs` is an error naming it.
    #[test]
    fn inspect_reports_missing_provenance_and_the_wiring() {
        let g = axcomp_scenario::group_image(3, false).unwrap();
        let board = parse_board_inputs(&crate::board::default_board_inputs()).unwrap();
        let text = describe_trust(&g, &board).unwrap();
        assert!(
            text.contains("provenance: none")
                && text.contains("axis X (id 1) sensors (wired by name): REFUSED by this board")
                && text.contains("sensor 0 spindle -> no board input"),
            "{text}"
        );
        let named = parse_board_inputs("spindle:degC,column:degC").unwrap();
        let text = describe_trust(&g, &named).unwrap();
        assert!(
            text.contains("sensor 1 column -> board input 1 column (°C)"),
            "{text}"
        );
        // A schema-1 image without names: by position.
        let (x, _) = group_image::parse(&g).unwrap().axis_images();
        let text = describe_trust(x[0].image, &board).unwrap();
        assert!(
            text.contains("no names: wired by position")
                && text.contains("sensor 0 (unnamed) -> board input 0 rtd0 (°C)"),
            "{text}"
        );
        let e = parse_board_inputs("rtd0:kelvin").unwrap_err();
        assert!(e.to_string().contains("`kelvin`"), "{e}");
    }
}
