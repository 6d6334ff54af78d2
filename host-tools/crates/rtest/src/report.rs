//! `fit rtest --report DIR`: report.md and SVG figures (measured vs predicted along the judged path, the
//! identified location errors' displacement over the rotary range).

use std::path::Path;

use axcomp_kinematics::rotary::{N_LOCATION, N_SETUP};
use axcomp_plot::{Figure, markdown_table};

use crate::analysis::Analysis;
use crate::{RtestData, SIGN_CONVENTION};

/// Report files: name and contents. Nothing is written here; the caller writes them all or none.
pub fn report_files(a: &Analysis, data: &RtestData) -> Vec<(String, String)> {
    let mut files = Vec::new();
    path_figures(a, data, &mut files);
    files.push(("rotary_range.svg".into(), rotary_range_figure(a, data)));
    files.push(("report.md".into(), report_md(a, data)));
    files
}

/// The measured-vs-model figures along the judged paths, one per component (`path_dx.svg`, …).
fn path_figures(a: &Analysis, data: &RtestData, files: &mut Vec<(String, String)>) {
    // The judged rows grouped by run and path (file order kept within each), each drawn over its C angle.
    let mut groups: Vec<(String, Vec<usize>)> = Vec::new();
    for (k, &r) in a.judged_rows.iter().enumerate() {
        let key = data.path[r].clone();
        match groups.iter_mut().find(|g| g.0 == key) {
            Some(g) => g.1.push(k),
            None => groups.push((key, vec![k])),
        }
    }
    let c_label = axcomp_plot::label("C angle", "°");
    let cs = a.judged_rows.iter().map(|&r| data.poses[r].c_deg);
    let c_lo = (cs.clone().fold(0.0, f64::min) / 45.0).floor() * 45.0;
    let c_hi = (cs.fold(c_lo + 45.0, f64::max) / 45.0).ceil() * 45.0;
    for (c, comp) in ["dx", "dy", "dz"].iter().enumerate() {
        let axis = ["X", "Y", "Z"][c];
        let meas = |k: usize| data.d_um[a.judged_rows[k]][c];
        let pred = |k: usize| a.judged_pred[k][c];
        let rms = axcomp_numeric::stats::rms((0..a.judged_rows.len()).map(|k| meas(k) - pred(k)));
        let mut f = Figure::new(
            &format!(
                "R-test {axis} deviation {comp} on {}: measured vs the location-error model, residual RMS {rms:.2} µm ({})",
                data.machine.kind.name(),
                a.judged_by
            ),
            &c_label,
            &axcomp_plot::label(&format!("{axis} deviation {comp}"), "µm"),
        );
        f.x_axis(c_lo, c_hi, Some(45.0));
        let (mut rx, mut ry) = (Vec::new(), Vec::new());
        for (path, ks) in &groups {
            // File order; a pass that starts again (C going back) is not joined to the one before.
            let (mut xs, mut ms, mut ps) = (Vec::new(), Vec::new(), Vec::new());
            for &k in ks {
                let cdeg = data.poses[a.judged_rows[k]].c_deg;
                if xs.last().is_some_and(|&l: &f64| cdeg < l) {
                    for v in [&mut xs, &mut ms, &mut ps, &mut rx, &mut ry] {
                        v.push(f64::NAN);
                    }
                }
                xs.push(cdeg);
                ms.push(meas(k));
                ps.push(pred(k));
                rx.push(cdeg);
                ry.push(meas(k) - pred(k));
            }
            rx.push(f64::NAN);
            ry.push(f64::NAN);
            f.points(&format!("measured, path {path}"), &xs, &ms);
            f.dashed(&format!("model, path {path}"), &xs, &ps)
                .like_previous();
        }
        f.line("measured − model", &rx, &ry).with_colour("#555555");
        f.hline(0.0, "");
        files.push((format!("path_{comp}.svg"), f.to_svg()));
    }
}

/// `rotary_range.svg`: the displacement the identified location errors alone cause over the rotary range.
fn rotary_range_figure(a: &Analysis, data: &RtestData) -> String {
    // The location errors alone (no set-up offsets) over the rotary range, for the campaign's first sphere.
    let sphere = data.machine.nominal_sphere(&data.poses[0]);
    let le = a.model.location();
    let tilts: Vec<f64> = {
        let lo = data
            .poses
            .iter()
            .map(|p| p.tilt_deg)
            .fold(f64::INFINITY, f64::min);
        let hi = data
            .poses
            .iter()
            .map(|p| p.tilt_deg)
            .fold(f64::NEG_INFINITY, f64::max);
        let mut v = vec![lo, (lo + hi) / 2.0, hi];
        v.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
        v
    };
    let cs: Vec<f64> = (0..=72).map(|k| k as f64 * 5.0).collect();
    let tilt = data.machine.kind.tilt_letter().to_ascii_uppercase();
    let peak = std::cell::Cell::new(0.0f64); // the largest |d| drawn, for the title
    let mut f = Figure::new(
        "",
        &axcomp_plot::label("C angle", "°"),
        &axcomp_plot::label("|d| from the location errors", "µm"),
    );
    f.magnitude().x_axis(0.0, 360.0, Some(45.0));
    for t in &tilts {
        let mag: Vec<f64> = cs
            .iter()
            .map(|&c| {
                let pose = axcomp_kinematics::rotary::pose_on_sphere(&data.machine, sphere, *t, c);
                let d = data.machine.displacement(&pose, &le, [0.0; N_SETUP]);
                let m = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                peak.set(peak.get().max(m));
                m
            })
            .collect();
        f.line(
            &format!("{tilt} = {}°", axcomp_plot::style::fmt_fixed(*t, 1)),
            &cs,
            &mag,
        );
    }
    f.set_title(&format!(
        "Displacement |d| over the rotary range from the identified location errors ({}): up to {:.2} µm uncompensated",
        data.machine.kind.name(),
        peak.get()
    ));
    f.to_svg()
}

/// report.md: the fitted parameters, set-up offsets, identifiability, RMS figures and the sections after.
fn report_md(a: &Analysis, data: &RtestData) -> String {
    let names = crate::param_names_with(data, &a.fit.effects);
    let judged = match a.judged_by {
        "holdout" => "held-out rows (prediction from the fit on the other rows)",
        "cv" => "every row (cross-validated prediction)",
        _ => "the fitted rows (in-sample)",
    };
    let mut md = String::new();
    md.push_str(&format!(
        "# R-test location errors ({})\n\nData: `{}`; {} rows fitted; judged on {}.\n\n",
        data.machine.kind.name(),
        data.source,
        a.fit_rows.len(),
        judged
    ));
    md.push_str(&format!("**Sign convention.** {SIGN_CONVENTION}\n\n"));
    md.push_str(&parameter_table("name", &a.model.location_errors));
    md.push('\n');
    setup_offsets_section(&mut md, a, data);
    md.push_str(&format!(
        "\nIdentifiability: rank {} of {} parameters, condition number {:.3e} (column-scaled).\n",
        a.fit.ident.rank,
        names.len(),
        a.fit.ident.condition_number
    ));
    for &(i, j, r) in &a.fit.correlations {
        md.push_str(&format!(
            "- correlation {} / {}: {r:.3}\n",
            names[i], names[j]
        ));
    }
    md.push_str(&format!(
        "\nRMS over dx, dy, dz: raw {:.3} µm, fit {:.3} µm, {} {:.3} µm (σ̂ = {:.3} µm).\n",
        a.raw_rms_um, a.fit.fit_rms_um, a.judged_by, a.judged_rms_um, a.fit.sigma_um
    ));
    k4_section(&mut md, a);
    effects_section(&mut md, a);
    closure_section(&mut md, a, data);
    md.push_str("\n![dx](path_dx.svg)\n![dy](path_dy.svg)\n![dz](path_dz.svg)\n![rotary range](rotary_range.svg)\n");
    md
}

/// The set-up offsets (nuisance parameters) table, with its heading.
fn setup_offsets_section(md: &mut String, a: &Analysis, data: &RtestData) {
    let mut setup_rows = Vec::new();
    for s in 0..data.setup_names.len() {
        let b = N_LOCATION + N_SETUP * s;
        for (o, what) in [(0, "sphere"), (3, "R-test head")] {
            let cell = |k: usize| match (a.fit.std[b + o + k], &a.fit.ident.reasons[b + o + k]) {
                (Some(sd), _) => format!("{:.3} ± {sd:.3}", a.fit.theta[b + o + k]),
                (None, Some(r)) if r.starts_with("taken as known") => "0 (known)".into(),
                (None, _) => "not identified".into(),
            };
            setup_rows.push(vec![
                data.setup_names[s].clone(),
                what.to_string(),
                cell(0),
                cell(1),
                cell(2),
            ]);
        }
    }
    md.push_str("\nSet-up offsets (nuisance), µm:\n\n");
    md.push_str(&markdown_table(
        &["set-up", "of", "dx", "dy", "dz"],
        &setup_rows,
    ));
}

/// The ISO 10791-6 K4 figures, when the data have K4 poses.
fn k4_section(md: &mut String, a: &Analysis) {
    let Some(k) = &a.k4 else {
        return;
    };
    md.push_str(&format!(
        "\nISO 10791-6 K4 figures (range of each component over {} K4 poses, {}):\n\n",
        k.rows,
        if k.in_sample { "fit" } else { a.judged_by }
    ));
    let r = |i: usize| {
        vec![
            ["dx", "dy", "dz"][i].to_string(),
            format!("{:.3}", k.before_um[i]),
            format!("{:.3}", k.after_um[i]),
            format!("{:.1}", 100.0 * (1.0 - k.after_um[i] / k.before_um[i])),
        ]
    };
    md.push_str(&markdown_table(
        &["component", "before µm", "after µm", "reduction %"],
        &[r(0), r(1), r(2)],
    ));
}

/// The effect terms of `--effects`, when there are any.
fn effects_section(md: &mut String, a: &Analysis) {
    for e in &a.model.effects {
        md.push_str(&format!(
            "\nEffect `{}` ({:?}): correction RMS {:.3} µm over the fitted poses; {} RMS with the location errors alone {:.3} µm, with the effect {:.3} µm.\n\n",
            e.kind, e.basis, e.rms_over_fit_um, a.judged_by, a.full_rms_um, a.judged_rms_um
        ));
        md.push_str(&parameter_table("parameter", &e.parameters));
    }
}

/// The closure drift of revisited poses ([`crate::revisit`]), when there are any.
fn closure_section(md: &mut String, a: &Analysis, data: &RtestData) {
    if a.closure.is_empty() {
        return;
    }
    let tilt = data.machine.kind.tilt_letter().to_ascii_uppercase();
    md.push_str(&format!(
        "\nClosure (poses revisited in a later run; last visit − first visit, µm; the model cancels at one \
         pose, so this is drift plus noise: about {:.3} µm per component without drift, √2 σ̂; what \
         `setup_drift`, `thermal_drift`, `time_drift` look at):\n\n",
        std::f64::consts::SQRT_2 * a.fit.sigma_um
    ));
    let rows: Vec<Vec<String>> = a
        .closure
        .iter()
        .map(|r| {
            vec![
                format!(
                    "x {} y {} z {} {tilt} {} C {}",
                    r.pose[0], r.pose[1], r.pose[2], r.pose[3], r.pose[4]
                ),
                r.setup.clone(),
                format!(
                    "{} (line {}) → {} (line {})",
                    r.first.run, r.first.line, r.last.run, r.last.line
                ),
                r.elapsed_s.map_or("–".into(), |t| format!("{t:.0}")),
                format!("{:.3}", r.drift_um[0]),
                format!("{:.3}", r.drift_um[1]),
                format!("{:.3}", r.drift_um[2]),
                format!("{:.3}", r.magnitude_um),
            ]
        })
        .collect();
    md.push_str(&markdown_table(
        &[
            "pose",
            "set-up",
            "runs",
            "elapsed s",
            "dx",
            "dy",
            "dz",
            "|d|",
        ],
        &rows,
    ));
}

/// Writes the report files into `dir` (each atomically; the directory is created).
pub fn write_report(dir: &Path, files: &[(String, String)]) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    for (name, text) in files {
        axcomp_files::write_atomic(&dir.join(name), text.as_bytes())?;
    }
    Ok(())
}

/// A Markdown table of named parameters: value, unit, std, identified and why not.
fn parameter_table(first: &str, params: &[(String, crate::ParamValue)]) -> String {
    let rows: Vec<Vec<String>> = params
        .iter()
        .map(|(n, v)| {
            vec![
                n.clone(),
                format!("{:.3}", v.value),
                v.unit.clone(),
                v.std.map_or("–".into(), |s| format!("{s:.3}")),
                if v.identified {
                    "yes".into()
                } else {
                    "**no**".into()
                },
                v.reason.clone().unwrap_or_default(),
            ]
        })
        .collect();
    markdown_table(
        &[first, "value", "unit", "std", "identified", "reason"],
        &rows,
    )
}
