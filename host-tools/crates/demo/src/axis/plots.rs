//! The demo's SVG plots: deviation before (with the fitted table and the twin's truth), after, and the
//! ISO 230-2 figures before/after as two panels.

use axcomp_data::Dataset;
use axcomp_plot::Figure;
use axcomp_positioning::fit::FitResult;
use axcomp_positioning::iso230::Iso230Result;
use axcomp_twin::Axis;

use super::evaluated::Evaluated;
use crate::{Result, StepContext};

/// Per direction: (targets, means, −2s, +2s) of an ISO evaluation.
fn per_direction(iso: &Iso230Result, direction: i8) -> [Vec<f64>; 4] {
    let t = &iso.targets;
    let (m, s): (Vec<f64>, Vec<f64>) = t
        .iter()
        .map(|f| {
            if direction > 0 {
                (f.mean_up_um, f.s_up_um)
            } else {
                (f.mean_down_um, f.s_down_um)
            }
        })
        .unzip();
    [
        t.iter().map(|f| f.target_mm).collect(),
        m.clone(),
        m.iter().zip(&s).map(|(m, s)| m - 2.0 * s).collect(),
        m.iter().zip(&s).map(|(m, s)| m + 2.0 * s).collect(),
    ]
}

/// (targets, deviations) of the positive, then the negative approaches.
fn split_by_direction(ds: &Dataset) -> Result<[(Vec<f64>, Vec<f64>); 2]> {
    let x = ds.numeric("target_mm")?;
    let d = ds.numeric("deviation_um")?;
    let dir = ds.direction()?.step(|| "no direction column".into())?;
    let mut out = [(Vec::new(), Vec::new()), (Vec::new(), Vec::new())];
    for i in 0..x.len() {
        let k = usize::from(dir[i] < 0);
        out[k].0.push(x[i]);
        out[k].1.push(d[i]);
    }
    Ok(out)
}

/// The plots as (file name, SVG text).
pub(super) fn plots(
    axis: &Axis,
    before: &Evaluated,
    after: &Evaluated,
    fitted: &FitResult,
) -> Result<[(&'static str, String); 3]> {
    let test = format!(
        "twin {}, ISO 230-2 {} targets × 5 runs",
        axis.name,
        before.iso.targets.len()
    );
    Ok([
        (
            "deviation_before.svg",
            deviation_before(axis, before, fitted, &test)?,
        ),
        ("deviation_after.svg", deviation_after(after, &test)?),
        (
            "iso230_before_after.svg",
            iso230_before_after(before, after),
        ),
    ])
}

/// Measured deviation of the uncompensated campaign with the fitted table and the twin's truth.
fn deviation_before(
    axis: &Axis,
    before: &Evaluated,
    fitted: &FitResult,
    test: &str,
) -> Result<String> {
    let cond = axis.reference_conditions();
    let n = 801;
    let xs: Vec<f64> = (0..n)
        .map(|k| axis.start_mm + (axis.end_mm - axis.start_mm) * k as f64 / (n - 1) as f64)
        .collect();
    let curve = |f: &dyn Fn(f64) -> f64| xs.iter().map(|&x| f(x)).collect::<Vec<f64>>();
    let [(xf, df), (xb, db)] = split_by_direction(&before.data)?;
    let (up, down) = (axcomp_plot::PALETTE[0], axcomp_plot::PALETTE[1]);
    let mut fig = Figure::new(
        &format!(
            "{test}: measured deviation and fitted table ({}, CV RMS {:.2} µm, raw {:.2} µm)",
            fitted.chosen, fitted.cv_rms_um, fitted.raw_rms_um
        ),
        "target position (mm)",
        "deviation (µm)",
    );
    fig.points("measured ↑ (positive)", &xf, &df)
        .with_colour(up)
        .line("table ↑", &xs, &curve(&|x| fitted.table.deviation_um(x, 1)))
        .with_colour(up)
        .dashed(
            "truth ↑",
            &xs,
            &curve(&|x| axis.true_deviation_um(x, 1, &cond)),
        )
        .with_colour(up)
        .points("measured ↓ (negative)", &xb, &db)
        .with_colour(down)
        .line(
            "table ↓",
            &xs,
            &curve(&|x| fitted.table.deviation_um(x, -1)),
        )
        .with_colour(down)
        .dashed(
            "truth ↓",
            &xs,
            &curve(&|x| axis.true_deviation_um(x, -1, &cond)),
        )
        .with_colour(down);
    Ok(fig.to_svg())
}

/// Measured deviation of the compensated campaign.
fn deviation_after(after: &Evaluated, test: &str) -> Result<String> {
    let (up, down) = (axcomp_plot::PALETTE[0], axcomp_plot::PALETTE[1]);
    let [(xf2, df2), (xb2, db2)] = split_by_direction(&after.data)?;
    let mut fig = Figure::new(
        &format!(
            "{test}: deviation after compensation (new campaign through the firmware compensator, RMS {:.2} µm)",
            after.rms_um
        ),
        "target position (mm)",
        "deviation (µm)",
    );
    fig.points("positive approach ↑", &xf2, &df2)
        .with_colour(up)
        .points("negative approach ↓", &xb2, &db2)
        .with_colour(down)
        .hline(0.0, "0");
    Ok(fig.to_svg())
}

/// Before and after as two panels (each on its own scale), one colour per direction.
fn iso230_before_after(before: &Evaluated, after: &Evaluated) -> String {
    let (up, down) = (axcomp_plot::PALETTE[0], axcomp_plot::PALETTE[1]);
    let panel = |label: &str, e: &Evaluated| {
        let mut fig = Figure::new(
            &format!(
                "{label}: A {:.2}, E {:.2}, B {:.2} µm",
                e.iso.a_um, e.iso.e_um, e.iso.b_um
            ),
            "target position (mm)",
            "mean deviation ± 2s (µm)",
        );
        fig.size(700.0, 460.0);
        for (dname, d, colour) in [("↑", 1i8, up), ("↓", -1i8, down)] {
            let [t, m, lo, hi] = per_direction(&e.iso, d);
            fig.band(&format!("{dname} ±2s"), &t, &lo, &hi)
                .with_colour(colour)
                .line(&format!("{dname} mean"), &t, &m)
                .with_colour(colour);
        }
        fig.hline(0.0, "");
        fig
    };
    let (pb, pa) = (
        panel("Before (uncompensated)", before),
        panel("After (firmware compensator)", after),
    );
    axcomp_plot::panels_svg(&[&pb, &pa], 2)
}
