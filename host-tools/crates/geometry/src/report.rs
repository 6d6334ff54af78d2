//! Markdown + SVG report of a geometry fit: each component with its uncertainty band, the volumetric error
//! map (|e| along X on five Y lines, at three Z heights), held-out (or cross-validated) lines measured vs
//! predicted.

use std::path::Path;

use axcomp_kinematics::Component;
use axcomp_plot::{Figure, markdown_table};

use crate::GeometryError;
use crate::analysis::Analysis;
use crate::data::LineData;

/// Measured vs predicted along one judged line. Readings are placed by their position along the line (the
/// axis it moves, or the distance from its start on a diagonal) and split into passes where the motion
/// reverses: forward passes in one colour, backward in another, the prediction drawn per pass in its
/// position order (never joined across passes, never in file order).
fn line_figure(name: &str, rs: &[&crate::data::LineReading], judged: &[Option<f64>]) -> Figure {
    let q0 = rs[0].q;
    let far = rs
        .iter()
        .map(|r| sub3(r.q, q0))
        .max_by(|a, b| norm3(*a).total_cmp(&norm3(*b)))
        .unwrap_or([1.0, 0.0, 0.0]);
    let len = norm3(far).max(1e-12);
    let u = [far[0] / len, far[1] / len, far[2] / len];
    let along: Vec<f64> = rs
        .iter()
        .map(|r| {
            let d = sub3(r.q, q0);
            d[0] * u[0] + d[1] * u[1] + d[2] * u[2]
        })
        .collect();
    // One moving axis: its coordinate; a diagonal: the distance from the line's lowest point.
    let (xs, x_label): (Vec<f64>, String) = match (0..3).find(|&k| u[k].abs() > 0.999) {
        Some(k) => (
            rs.iter().map(|r| r.q[k]).collect(),
            axcomp_plot::label(&format!("{} position", ["X", "Y", "Z"][k]), "mm"),
        ),
        None => {
            let m = along.iter().copied().fold(f64::INFINITY, f64::min);
            (
                along.iter().map(|a| a - m).collect(),
                axcomp_plot::label("distance along the line", "mm"),
            )
        }
    };
    // Passes: maximal runs of readings moving one way along the line.
    let mut passes: Vec<(i8, Vec<usize>)> = Vec::new();
    for i in 0..rs.len() {
        let step = if i == 0 { 0.0 } else { along[i] - along[i - 1] };
        let dir: i8 = if step > 1e-9 {
            1
        } else if step < -1e-9 {
            -1
        } else {
            0
        };
        match passes.last_mut() {
            Some((d, idx)) if dir == 0 || *d == dir || *d == 0 => {
                if *d == 0 {
                    *d = dir;
                }
                idx.push(i);
            }
            _ => passes.push((dir, vec![i])),
        }
    }
    let pred = |i: usize| judged[rs[i].row].unwrap_or(f64::NAN);
    let rms: f64 = axcomp_numeric::stats::rms(
        rs.iter()
            .enumerate()
            .map(|(i, r)| r.deviation_um - pred(i))
            .filter(|v| v.is_finite()),
    );
    let mut f = Figure::new(
        &format!(
            "Line {name} (not fitted): measured deviation vs the model's prediction, residual RMS {rms:.2} µm"
        ),
        &x_label,
        &axcomp_plot::label("deviation along the beam", "µm"),
    );
    for (dir, dir_name) in [(1i8, "forward"), (-1, "backward")] {
        let (mut mx, mut my, mut px, mut py) = (vec![], vec![], vec![], vec![]);
        for (_, idx) in passes
            .iter()
            .filter(|(d, _)| *d == dir || (*d == 0 && dir == 1))
        {
            let mut sorted = idx.clone();
            sorted.sort_by(|&a, &b| xs[a].total_cmp(&xs[b]));
            for &i in &sorted {
                mx.push(xs[i]);
                my.push(rs[i].deviation_um);
                px.push(xs[i]);
                py.push(pred(i));
            }
            px.push(f64::NAN);
            py.push(f64::NAN);
        }
        if mx.is_empty() {
            continue;
        }
        f.points(&format!("measured, {dir_name} passes"), &mx, &my);
        f.dashed(&format!("predicted, {dir_name} passes"), &px, &py)
            .like_previous();
    }
    f.hline(0.0, "");
    f
}

fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn norm3(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn io(what: &Path) -> impl FnOnce(std::io::Error) -> GeometryError + '_ {
    move |cause| GeometryError::Io {
        what: what.display().to_string(),
        cause,
    }
}

/// Writes `report.md` and the SVGs into `dir` (created if missing); the report is written last.
/// A thin wrapper over [`report_files`].
pub fn write_report(dir: &Path, data: &LineData, an: &Analysis) -> Result<(), GeometryError> {
    std::fs::create_dir_all(dir).map_err(io(dir))?;
    for (name, text) in report_files(data, an) {
        let path = dir.join(&name);
        axcomp_files::write_atomic(&path, text.as_bytes()).map_err(io(&path))?;
    }
    Ok(())
}

/// The report's files, `(file name, content)`, computed without writing anything: the SVGs first,
/// `report.md` last (so a writer that goes in order writes the report last).
pub fn report_files(data: &LineData, an: &Analysis) -> Vec<(String, String)> {
    let mut files: Vec<(String, String)> = Vec::new();
    let mut md = summary_section(an);
    components_section(&mut md, &mut files, an);
    volumetric_section(&mut md, &mut files, an);
    unseen_lines_section(&mut md, &mut files, data, an);
    files.push(("report.md".to_string(), md));
    files
}

/// Title, method, conventions, the figures table, the not-separable sets and the ISO 230-6 diagonals.
fn summary_section(an: &Analysis) -> String {
    let model = &an.fit.model;
    let rep = &an.report;

    let mut md = String::from("# Geometric errors (21 ISO 230-1 components)\n\n");
    md.push_str(&format!(
        "Method: {}. Topology (work/tool axes, bed outward): {}. Lines: {}, readings: {} ({} fitted).\n\n",
        model.method,
        model.topology.label(),
        rep.lines,
        rep.rows,
        rep.train_rows
    ));
    md.push_str("Conventions (ISO 230-1 names): errors are the tool point relative to the workpiece, reached − commanded, in µm; angular errors and squareness in µrad, right-handed about +X/+Y/+Z; every function is zero at its axis's zero; straightness has zero least-squares slope (the slope between axes is the squareness: Y along (−EC0Y, 1, 0), Z along (EB0Z, −EA0Z, 1)); angular errors act through the lever arm from their carriage to the tool point (reflector offset included). Bands: ± one standard uncertainty.\n\n");
    let mut figures = vec![
        ("raw RMS (µm)", format!("{:.3}", rep.raw_rms_um)),
        ("fit RMS (µm)", format!("{:.3}", rep.fit_rms_um)),
    ];
    if let Some(h) = rep.holdout_rms_um {
        figures.push(("held-out RMS (µm)", format!("{h:.3}")));
    }
    if let Some(e) = rep.identifiable_floor.expected_holdout_rms_um {
        figures.push((
            "held-out RMS a model right in the lines' span would score (σ̂ and estimation; the floor itself needs the truth) (µm)",
            format!("{e:.3}"),
        ));
    }
    figures.push((
        "noise σ̂, the floor no model beats on unseen readings (µm)",
        format!("{:.3}", rep.identifiable_floor.noise_um),
    ));
    if let Some(c) = rep.cv_rms_um {
        figures.push(("cross-validated RMS (µm)", format!("{c:.3}")));
    }
    figures.push((
        "volumetric max |e| (µm)",
        format!("{:.2}", rep.volumetric.max_um),
    ));
    figures.push((
        "volumetric RMS |e| (µm)",
        format!("{:.2}", rep.volumetric.rms_um),
    ));
    figures.push((
        "rank / parameters",
        format!(
            "{} / {}",
            rep.identifiability.rank, rep.identifiability.parameters
        ),
    ));
    figures.push((
        "condition number",
        format!("{:.1}", rep.identifiability.condition_number),
    ));
    let rows: Vec<Vec<String>> = figures
        .iter()
        .map(|(a, b)| vec![a.to_string(), b.clone()])
        .collect();
    md.push_str(&markdown_table(&["figure", "value"], &rows));
    md.push('\n');
    if !rep.identifiability.not_separable.is_empty() {
        md.push_str(if model.method.contains("evidence") {
            "Not separable by these lines (estimated with the others, shared as the evidence prior's sizes say, not identified): "
        } else if model.method.contains("minimum norm") {
            "Not separable by these lines (estimated at the damped minimum norm, not identified): "
        } else {
            "Not separable by these lines (fixed at 0): "
        });
        let g: Vec<String> = rep
            .identifiability
            .not_separable
            .iter()
            .map(|g| format!("[{}]", g.join(", ")))
            .collect();
        md.push_str(&g.join(", "));
        md.push_str("\n\n");
    }
    if !rep.iso230_6_body_diagonals.is_empty() {
        md.push_str("## ISO 230-6 body diagonals (range of the readings along the diagonal)\n\n");
        let rows: Vec<Vec<String>> = rep
            .iso230_6_body_diagonals
            .iter()
            .map(|d| {
                vec![
                    d.line.clone(),
                    format!("{:.2}", d.before_um),
                    format!("{:.2}", d.after_um),
                    d.basis.clone(),
                ]
            })
            .collect();
        md.push_str(&markdown_table(
            &["line", "before µm", "after µm", "after from"],
            &rows,
        ));
        md.push('\n');
    }
    md
}

/// The components table and each function's figure with its uncertainty band.
fn components_section(md: &mut String, files: &mut Vec<(String, String)>, an: &Analysis) {
    let model = &an.fit.model;
    md.push_str("## Components\n\n");
    let mut rows = Vec::new();
    for c in Component::ALL {
        let m = &model.components[c.index()];
        let umax = m.uncertainty.iter().map(|x| x[1]).fold(0.0, f64::max);
        let peak = match c.axis() {
            Some(_) => m
                .uncertainty
                .iter()
                .map(|[q, _]| model.component_value(c, *q).abs())
                .fold(0.0, f64::max),
            None => m.value.abs(),
        };
        rows.push(vec![
            c.name().to_string(),
            m.unit.clone(),
            format!("{peak:.2}"),
            format!("{umax:.2}"),
            if m.identified {
                "yes".into()
            } else {
                "no".into()
            },
            m.reason.clone(),
        ]);
        if let Some(ax) = c.axis() {
            let xs: Vec<f64> = m.uncertainty.iter().map(|x| x[0]).collect();
            let ys: Vec<f64> = xs.iter().map(|q| model.component_value(c, *q)).collect();
            let lo: Vec<f64> = ys
                .iter()
                .zip(&m.uncertainty)
                .map(|(y, u)| y - u[1])
                .collect();
            let hi: Vec<f64> = ys
                .iter()
                .zip(&m.uncertainty)
                .map(|(y, u)| y + u[1])
                .collect();
            let unit = if m.unit == "um" { "µm" } else { "µrad" };
            let mut f = Figure::new(
                &format!(
                    "{} of the fitted model ({}): peak |value| {peak:.2} {unit}, {}",
                    c.name(),
                    model.method.split(" (").next().unwrap_or(&model.method),
                    if m.identified {
                        "identified"
                    } else {
                        "not identified"
                    }
                ),
                &axcomp_plot::label(&format!("{} position", ax.letter()), "mm"),
                &axcomp_plot::label(c.name(), unit),
            );
            f.band("± standard uncertainty", &xs, &lo, &hi);
            f.line(c.name(), &xs, &ys).like_previous();
            let file = format!("{}.svg", c.name());
            files.push((file.clone(), f.to_svg()));
            md.push_str(&format!("![{}]({file})\n", c.name()));
        }
    }
    md.push('\n');
    md.push_str(&markdown_table(
        &[
            "component",
            "unit",
            "peak |value|",
            "max u",
            "identified",
            "reason",
        ],
        &rows,
    ));
    md.push('\n');
}

/// The volumetric error map at three Z levels, with the judged RMS after compensation.
fn volumetric_section(md: &mut String, files: &mut Vec<(String, String)>, an: &Analysis) {
    let model = &an.fit.model;
    let rep = &an.report;
    md.push_str("## Volumetric error map (|e| at the tool reference point)\n\n");
    let (lo, hi) = (model.volume_min_mm, model.volume_max_mm);
    let (after_rms, after_what) = match (rep.holdout_rms_um, rep.cv_rms_um) {
        (Some(h), _) => (h, "held-out RMS"),
        (None, Some(c)) => (c, "cross-validated RMS"),
        (None, None) => (rep.fit_rms_um, "fit RMS"),
    };
    for (k, zf) in [0.0, 0.5, 1.0].iter().enumerate() {
        let z = lo[2] + zf * (hi[2] - lo[2]);
        let mut profiles = Vec::new();
        for yf in [0.0, 0.25, 0.5, 0.75, 1.0] {
            let y = lo[1] + yf * (hi[1] - lo[1]);
            let xs: Vec<f64> = (0..=40)
                .map(|i| lo[0] + (hi[0] - lo[0]) * i as f64 / 40.0)
                .collect();
            let ys: Vec<f64> = xs
                .iter()
                .map(|x| {
                    model
                        .error_at([*x, y, z], [0.0; 3])
                        .map(|e| (e[0] * e[0] + e[1] * e[1] + e[2] * e[2]).sqrt())
                        .unwrap_or(f64::NAN)
                })
                .collect();
            profiles.push((y, xs, ys));
        }
        let peak = profiles
            .iter()
            .flat_map(|p| p.2.iter().copied())
            .filter(|v| v.is_finite())
            .fold(0.0, f64::max);
        let mut f = Figure::new(
            &format!(
                "Volumetric error |e| of the fitted model ({}) at z = {z:.0} mm, five y profiles: up to {peak:.1} µm before compensation; after: {after_what} {after_rms:.2} µm along the beam",
                model.method.split(" (").next().unwrap_or(&model.method)
            ),
            &axcomp_plot::label("x", "mm"),
            &axcomp_plot::label("|e| at the tool point", "µm"),
        );
        f.magnitude();
        for (y, xs, ys) in &profiles {
            f.line(&format!("before, y = {y:.0} mm"), xs, ys);
        }
        f.hline(
            after_rms,
            &format!("after compensation: {after_what} {after_rms:.2} µm (judged lines)"),
        );
        let file = format!("volumetric_z{}.svg", k + 1);
        files.push((file.clone(), f.to_svg()));
        md.push_str(&format!("![volumetric z{}]({file})\n", k + 1));
    }
    md.push('\n');
}

/// Measured vs predicted along the lines the model never saw (at most 12).
fn unseen_lines_section(
    md: &mut String,
    files: &mut Vec<(String, String)>,
    data: &LineData,
    an: &Analysis,
) {
    let judged: Vec<usize> = (0..data.lines.len())
        .filter(|&li| {
            data.readings
                .iter()
                .any(|r| r.line == li && an.judged_pred[r.row].is_some())
        })
        .collect();
    if !judged.is_empty() {
        md.push_str("## Lines the model never saw: measured vs predicted\n\n");
        for li in judged.iter().take(12) {
            let rs: Vec<_> = data.readings.iter().filter(|r| r.line == *li).collect();
            let name = &data.lines[*li];
            let f = line_figure(name, &rs, &an.judged_pred);
            let safe: String = name
                .chars()
                .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
                .collect();
            let file = format!("line_{safe}.svg");
            files.push((file.clone(), f.to_svg()));
            md.push_str(&format!("![line {name}]({file})\n"));
        }
    }
}
