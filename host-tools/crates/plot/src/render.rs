//! Drawing a [`Figure`] as SVG: axes, spans, rules, series (lines decimated per pixel column, dense points
//! as one mark per 2 × 2 px cell), legend, and the plot description ([`crate::meta`]).

use std::fmt::Write as _;

use crate::meta::{ChartDesc, SeriesDesc};
use crate::style::FEW_POINTS;
use crate::{Figure, Kind, Series, esc, fmt_tick, nice_ticks, shorten, wrap};

/// Points series with more points than this are drawn as density (one mark per 2 × 2 px cell).
pub const DENSE_POINTS: usize = 2000;

/// Marker radius in the plot and in the legend.
const MARK_R: f64 = 2.8;

fn finite_count(s: &Series) -> usize {
    s.xs.iter()
        .zip(&s.ys)
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .count()
}

impl Figure {
    /// The range of all finite data (x, y): x as fixed by [`Figure::x_axis`] or the data's, y padded and
    /// from 0 on a magnitude axis; (0,1) for empty figures.
    fn bounds(&self) -> ((f64, f64), (f64, f64)) {
        let mut x = (f64::INFINITY, f64::NEG_INFINITY);
        let mut y = (f64::INFINITY, f64::NEG_INFINITY);
        let see = |v: f64, r: &mut (f64, f64)| {
            if v.is_finite() {
                r.0 = r.0.min(v);
                r.1 = r.1.max(v);
            }
        };
        for s in &self.series {
            for (&vx, &vy) in s.xs.iter().zip(&s.ys) {
                if vx.is_finite() && vy.is_finite() {
                    see(vx, &mut x);
                    see(vy, &mut y);
                }
            }
            if let Kind::Band { upper } = &s.kind {
                for &v in upper {
                    see(v, &mut y);
                }
            }
        }
        for sp in &self.spans {
            see(sp.from, &mut x);
            see(sp.to, &mut x);
        }
        for (v, _) in &self.rules {
            see(*v, &mut y);
        }
        let fix = |r: (f64, f64)| {
            if !r.0.is_finite() {
                (0.0, 1.0)
            } else if r.1 - r.0 <= f64::EPSILON * r.0.abs().max(1.0) {
                (r.0 - 0.5, r.1 + 0.5)
            } else {
                r
            }
        };
        let x = self.x_range.unwrap_or_else(|| fix(x));
        if self.magnitude {
            let lo = if y.0.is_finite() { y.0.min(0.0) } else { 0.0 };
            let hi = if y.1.is_finite() && y.1 > lo {
                y.1
            } else {
                lo + 1.0
            };
            return (x, (lo, hi + 0.05 * (hi - lo)));
        }
        let y = fix(y);
        let pad = 0.05 * (y.1 - y.0);
        (x, (y.0 - pad, y.1 + pad))
    }

    /// Renders the figure as a standalone SVG document.
    pub fn to_svg(&self) -> String {
        let (w, h) = (self.width, self.height);
        // The right margin holds the legend: wide enough for the longest series name (~7 px a character).
        let longest = self
            .series
            .iter()
            .map(|s| s.name.chars().count())
            .max()
            .unwrap_or(0);
        // Legend: marker (18 px) + gap (6 px) + text (~7.5 px a character at 12 px) + 12 px to the edge.
        let mr = (50.0 + 7.5 * longest as f64).clamp(90.0, w * 0.45);
        // Legend names longer than the margin holds are shortened (…) rather than cut by the frame.
        let legend_chars = ((mr - 50.0) / 7.5).max(4.0) as usize;
        // Titles wider than the figure (~8 px a character at 15 px) wrap onto more lines.
        let title_lines = wrap(&self.title, ((w - 20.0) / 8.0).max(10.0) as usize);
        let (ml, mb) = (70.0, 55.0);
        let mt = 22.0 + 18.0 * title_lines.len() as f64;
        let (pw, ph) = (w - ml - mr, h - mt - mb);
        let ((x0, x1), (y0, y1)) = self.bounds();
        let (xt, (x0, x1)) = match (self.x_range, self.x_step) {
            (Some(_), step) => {
                let t = match step {
                    Some(st) => (0..)
                        .map(|k| (x0 / st).ceil() * st + k as f64 * st)
                        .take_while(|t| *t <= x1 + 1e-9 * st)
                        .collect(),
                    None => nice_ticks(x0, x1, 8)
                        .into_iter()
                        .filter(|t| *t >= x0 - 1e-9 && *t <= x1 + 1e-9)
                        .collect(),
                };
                (t, (x0, x1))
            }
            (None, _) => {
                let t = nice_ticks(x0, x1, 8);
                let r = (x0.min(t[0]), x1.max(*t.last().unwrap_or(&x1)));
                (t, r)
            }
        };
        let yt = nice_ticks(y0, y1, 6);
        let (y0, y1) = (y0.min(yt[0]), y1.max(*yt.last().unwrap_or(&y1)));
        let sx = |v: f64| ml + (v - x0) / (x1 - x0) * pw;
        let sy = |v: f64| mt + ph - (v - y0) / (y1 - y0) * ph;

        let mut s = crate::svg_open(w, h, &title_lines);
        for sp in &self.spans {
            let (a, b) = (sx(sp.from.max(x0)), sx(sp.to.min(x1)));
            let _ = writeln!(
                s,
                r##"<rect x="{a:.2}" y="{mt}" width="{:.2}" height="{ph}" fill="#F0E442" fill-opacity="0.25"/><text x="{:.2}" y="{}" font-size="11" text-anchor="middle" fill="#555">{}</text>"##,
                (b - a).max(1.0),
                (a + b) / 2.0,
                mt + 12.0,
                esc(&sp.label)
            );
        }
        // Grid and ticks.
        for &t in &xt {
            let px = sx(t);
            let _ = writeln!(
                s,
                r##"<line x1="{px:.2}" y1="{mt}" x2="{px:.2}" y2="{}" stroke="#e5e5e5"/><text x="{px:.2}" y="{}" text-anchor="middle">{}</text>"##,
                mt + ph,
                mt + ph + 16.0,
                fmt_tick(t)
            );
        }
        for &t in &yt {
            let py = sy(t);
            let _ = writeln!(
                s,
                r##"<line x1="{ml}" y1="{py:.2}" x2="{}" y2="{py:.2}" stroke="#e5e5e5"/><text x="{}" y="{:.2}" text-anchor="end">{}</text>"##,
                ml + pw,
                ml - 6.0,
                py + 4.0,
                fmt_tick(t)
            );
        }
        let _ = writeln!(
            s,
            r##"<rect x="{ml}" y="{mt}" width="{pw}" height="{ph}" fill="none" stroke="#333"/>"##
        );
        for (v, label) in &self.rules {
            let py = sy(*v);
            let _ = writeln!(
                s,
                r##"<line x1="{ml}" y1="{py:.2}" x2="{}" y2="{py:.2}" stroke="#777" stroke-dasharray="2,3"/><text x="{}" y="{:.2}" font-size="10" fill="#555">{}</text>"##,
                ml + pw,
                ml + 4.0,
                py - 3.0,
                esc(label)
            );
        }
        // Series, clipped to the plot area.
        let _ = writeln!(
            s,
            r#"<clipPath id="plotarea"><rect x="{ml}" y="{mt}" width="{pw}" height="{ph}"/></clipPath><g clip-path="url(#plotarea)">"#
        );
        let mut descs = Vec::new();
        for se in &self.series {
            descs.push(draw_series(&mut s, se, pw, &sx, &sy));
        }
        let _ = writeln!(s, "</g>");
        // Axis labels and legend.
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" text-anchor="middle">{}</text>"#,
            ml + pw / 2.0,
            h - 14.0,
            esc(&self.x_label)
        );
        let _ = writeln!(
            s,
            r#"<text transform="translate(18,{}) rotate(-90)" text-anchor="middle">{}</text>"#,
            mt + ph / 2.0,
            esc(&self.y_label)
        );
        let lx = ml + pw + 14.0;
        let step = if self.series.is_empty() {
            18.0
        } else {
            (ph / self.series.len() as f64).clamp(11.0, 18.0)
        };
        for (k, (se, d)) in self.series.iter().zip(&descs).enumerate() {
            let ly = mt + 10.0 + step * k as f64;
            let _ = writeln!(
                s,
                r#"{}<text x="{}" y="{}">{}</text>"#,
                legend_mark(se, d, lx, ly),
                lx + 24.0,
                ly + 4.0,
                esc(&shorten(&se.name, legend_chars))
            );
        }
        let desc = ChartDesc {
            chart: "figure",
            title: self.title.clone(),
            x_label: self.x_label.clone(),
            y_label: self.y_label.clone(),
            magnitude: self.magnitude,
            x_axis: (x0, x1),
            y_axis: (y0, y1),
            series: descs,
        };
        s.push_str(&desc.to_element());
        s.push_str("</svg>\n");
        s
    }
}

/// The legend's mark of a series: a line (with its marker when the plot shows markers on it), a marker,
/// or a band swatch.
fn legend_mark(se: &Series, d: &SeriesDesc, lx: f64, ly: f64) -> String {
    match &se.kind {
        Kind::Points => se.marker.svg(lx + 9.0, ly, 3.5, &se.colour, 1.0),
        Kind::Band { .. } => format!(
            r#"<rect x="{lx}" y="{}" width="18" height="10" fill="{}" fill-opacity="0.3"/>"#,
            ly - 5.0,
            se.colour
        ),
        Kind::Line { dashed } => {
            let dash = line_dash(*dashed, se.dash).replace("6,4", "5,3");
            let mut m = format!(
                r#"<line x1="{lx}" y1="{ly}" x2="{}" y2="{ly}" stroke="{}" stroke-width="2"{dash}/>"#,
                lx + 18.0,
                se.colour
            );
            if d.markers > 0 {
                m.push_str(&se.marker.svg(lx + 9.0, ly, 3.0, &se.colour, 1.0));
            }
            m
        }
    }
}

fn line_dash(dashed: bool, slot_dash: Option<&str>) -> String {
    match (dashed, slot_dash) {
        (true, _) => r#" stroke-dasharray="6,4""#.into(),
        (false, Some(d)) => format!(r#" stroke-dasharray="{d}""#),
        (false, None) => String::new(),
    }
}

fn kind_name(k: &Kind) -> &'static str {
    match k {
        Kind::Line { dashed: false } => "line",
        Kind::Line { dashed: true } => "dashed",
        Kind::Points => "points",
        Kind::Band { .. } => "band",
    }
}

/// Draws one series into `s` and says what was drawn.
fn draw_series(
    s: &mut String,
    se: &Series,
    pw: f64,
    sx: &dyn Fn(f64) -> f64,
    sy: &dyn Fn(f64) -> f64,
) -> SeriesDesc {
    let mut d = SeriesDesc {
        name: se.name.clone(),
        kind: kind_name(&se.kind),
        colour: se.colour.clone(),
        marker: se.marker.name(),
        points: finite_count(se),
        ..Default::default()
    };
    let mark = |s: &mut String, x: f64, y: f64, op: f64| {
        s.push_str(&se.marker.svg(sx(x), sy(y), MARK_R, &se.colour, op));
        s.push('\n');
    };
    match &se.kind {
        Kind::Band { upper } => {
            let idx: Vec<usize> = (0..se.xs.len())
                .filter(|&i| se.xs[i].is_finite() && se.ys[i].is_finite() && upper[i].is_finite())
                .collect();
            d.points = idx.len();
            if idx.len() == 1 {
                // One x: an error bar with a marker at its middle.
                let i = idx[0];
                let _ = writeln!(
                    s,
                    r#"<line x1="{x:.2}" y1="{:.2}" x2="{x:.2}" y2="{:.2}" stroke="{}" stroke-width="3" stroke-opacity="0.4"/>"#,
                    sy(se.ys[i]),
                    sy(upper[i]),
                    se.colour,
                    x = sx(se.xs[i])
                );
                mark(s, se.xs[i], (se.ys[i] + upper[i]) / 2.0, 0.6);
                d.markers = 1;
            } else if idx.len() >= 2 {
                let mut p = String::new();
                for (k, &i) in idx.iter().enumerate() {
                    let c = if k == 0 { "M" } else { "L" };
                    let _ = write!(p, "{c}{:.2},{:.2} ", sx(se.xs[i]), sy(upper[i]));
                }
                for &i in idx.iter().rev() {
                    let _ = write!(p, "L{:.2},{:.2} ", sx(se.xs[i]), sy(se.ys[i]));
                }
                let _ = writeln!(
                    s,
                    r#"<path d="{p}Z" fill="{}" fill-opacity="0.18" stroke="none"/>"#,
                    se.colour
                );
                d.segments = 1;
            }
        }
        Kind::Line { dashed } => {
            let (xs, ys) = decimate_line(&se.xs, &se.ys, pw, sx);
            // Runs of consecutive finite vertices: two or more are a line piece, one is a marker.
            let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
            for (&x, &y) in xs.iter().zip(&ys) {
                if x.is_finite() && y.is_finite() {
                    runs.last_mut().unwrap().push((x, y));
                } else if !runs.last().unwrap().is_empty() {
                    runs.push(Vec::new());
                }
            }
            let mut p = String::new();
            for run in runs.iter().filter(|r| r.len() >= 2) {
                for (k, &(x, y)) in run.iter().enumerate() {
                    let c = if k == 0 { "M" } else { "L" };
                    let _ = write!(p, "{c}{:.2},{:.2} ", sx(x), sy(y));
                }
                d.segments += 1;
            }
            if d.segments > 0 {
                let _ = writeln!(
                    s,
                    r#"<path d="{p}" fill="none" stroke="{}" stroke-width="1.6"{}/>"#,
                    se.colour,
                    line_dash(*dashed, se.dash)
                );
            }
            let few = d.points < FEW_POINTS;
            for run in &runs {
                if few || run.len() == 1 {
                    for &(x, y) in run {
                        mark(s, x, y, 0.9);
                        d.markers += 1;
                    }
                }
            }
        }
        Kind::Points if se.xs.len() > DENSE_POINTS => {
            // Dense: one mark per occupied 2 × 2 px cell, all in one path of round dots, so the file stays
            // small (bounded by the plot area, not by the number of points).
            let mut seen = std::collections::HashSet::new();
            let mut p = String::new();
            for (&x, &y) in se.xs.iter().zip(&se.ys) {
                if x.is_finite() && y.is_finite() {
                    let (px, py) = (sx(x), sy(y));
                    if seen.insert(((px / 2.0) as i64, (py / 2.0) as i64)) {
                        let _ = write!(p, "M{px:.1},{py:.1}h0");
                        d.markers += 1;
                    }
                }
            }
            let _ = writeln!(
                s,
                r#"<path d="{p}" stroke="{}" stroke-opacity="0.6" stroke-width="4" stroke-linecap="round" fill="none"/>"#,
                se.colour
            );
        }
        Kind::Points => {
            let op = if d.points > 200 { 0.6 } else { 0.8 };
            for (&x, &y) in se.xs.iter().zip(&se.ys) {
                if x.is_finite() && y.is_finite() {
                    mark(s, x, y, op);
                    d.markers += 1;
                }
            }
        }
    }
    d
}

/// A line with more than 4 vertices per pixel column is reduced to the first, lowest, highest and last
/// vertex of each column (its drawn shape is unchanged); gaps (non-finite values) are kept.
fn decimate_line(xs: &[f64], ys: &[f64], pw: f64, sx: &dyn Fn(f64) -> f64) -> (Vec<f64>, Vec<f64>) {
    if (xs.len() as f64) <= 4.0 * pw {
        return (xs.to_vec(), ys.to_vec());
    }
    let (mut ox, mut oy) = (Vec::new(), Vec::new());
    let mut i = 0;
    while i < xs.len() {
        if !(xs[i].is_finite() && ys[i].is_finite()) {
            ox.push(f64::NAN);
            oy.push(f64::NAN);
            i += 1;
            continue;
        }
        let col = sx(xs[i]).floor();
        let start = i;
        let (mut lo, mut hi) = (i, i);
        while i < xs.len() && xs[i].is_finite() && ys[i].is_finite() && sx(xs[i]).floor() == col {
            if ys[i] < ys[lo] {
                lo = i;
            }
            if ys[i] > ys[hi] {
                hi = i;
            }
            i += 1;
        }
        let mut keep = vec![start, lo, hi, i - 1];
        keep.sort_unstable();
        keep.dedup();
        for k in keep {
            ox.push(xs[k]);
            oy.push(ys[k]);
        }
    }
    (ox, oy)
}
