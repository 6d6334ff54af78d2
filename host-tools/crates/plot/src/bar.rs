//! Bar charts: one bar per series within each category, the value printed above each bar.

use std::fmt::Write as _;

use crate::meta::{ChartDesc, SeriesDesc};
use crate::{esc, fmt_tick, nice_ticks, shorten, wrap};

/// A bar chart of values per category (e.g. a residual RMS per operating condition), one bar per series
/// within each category, with the value printed above each bar. The y axis starts at 0 when all values are
/// ≥ 0.
#[derive(Debug, Clone)]
pub struct BarChart {
    title: String,
    y_label: String,
    categories: Vec<String>,
    series: Vec<(String, Vec<f64>, String)>,
    magnitude: bool,
}

impl BarChart {
    pub fn new(title: &str, y_label: &str, categories: &[&str]) -> Self {
        BarChart {
            title: title.to_owned(),
            y_label: y_label.to_owned(),
            categories: categories.iter().map(|c| (*c).to_owned()).collect(),
            series: Vec::new(),
            magnitude: false,
        }
    }

    /// Declares the values magnitudes (RMS, ranges): the axis starts at 0 and the plot description says so.
    pub fn magnitude(&mut self) -> &mut Self {
        self.magnitude = true;
        self
    }

    /// One value per category (missing or non-finite values draw no bar).
    pub fn series(&mut self, name: &str, values: &[f64]) -> &mut Self {
        let colour = crate::style::slot(self.series.len()).0.to_owned();
        self.series.push((name.to_owned(), values.to_vec(), colour));
        self
    }

    pub fn to_svg(&self) -> String {
        let n = self.categories.len().max(1);
        let per = self.series.len().max(1);
        let w = (140.0 + n as f64 * (24.0 * per as f64 + 40.0)).clamp(500.0, 1400.0);
        let h = 460.0;
        let longest = self
            .series
            .iter()
            .map(|s| s.0.chars().count())
            .max()
            .unwrap_or(0);
        let mr = (40.0 + 7.0 * longest as f64).clamp(40.0, w * 0.4);
        let title_lines = wrap(&self.title, ((w - 20.0) / 8.0) as usize);
        let (ml, mb) = (70.0, 80.0);
        let mt = 22.0 + 18.0 * title_lines.len() as f64 + 14.0;
        let (pw, ph) = (w - ml - mr, h - mt - mb);
        let vals = self
            .series
            .iter()
            .flat_map(|s| s.1.iter().copied())
            .filter(|v| v.is_finite());
        let (mut y0, mut y1) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
        if !y0.is_finite() {
            (y0, y1) = (0.0, 1.0);
        }
        y0 = y0.min(0.0);
        y1 = y1.max(0.0);
        if y1 - y0 <= 0.0 {
            y1 = y0 + 1.0;
        }
        y1 += 0.08 * (y1 - y0); // room for the value labels
        let yt = nice_ticks(y0, y1, 6);
        let (y0, y1) = (y0.min(yt[0]), y1.max(*yt.last().unwrap_or(&y1)));
        let sy = |v: f64| mt + ph - (v - y0) / (y1 - y0) * ph;
        let mut s = crate::svg_open(w, h, &title_lines);
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
        let slot = pw / n as f64;
        let mut drawn = vec![0usize; self.series.len()];
        let bw = (slot * 0.8 / per as f64).min(60.0);
        for (c, cat) in self.categories.iter().enumerate() {
            let cx = ml + slot * (c as f64 + 0.5);
            for (k, (_, v, colour)) in self.series.iter().enumerate() {
                let Some(&v) = v.get(c) else { continue };
                if !v.is_finite() {
                    continue;
                }
                drawn[k] += 1;
                let x = cx - bw * per as f64 / 2.0 + bw * k as f64;
                let (top, bottom) = (sy(v.max(0.0)), sy(v.min(0.0)));
                let _ = writeln!(
                    s,
                    r#"<rect x="{x:.2}" y="{top:.2}" width="{:.2}" height="{:.2}" fill="{colour}"/><text x="{:.2}" y="{:.2}" font-size="10" text-anchor="middle">{}</text>"#,
                    bw * 0.92,
                    (bottom - top).max(0.5),
                    x + bw * 0.46,
                    top - 3.0,
                    fmt_value(v)
                );
            }
            let _ = writeln!(
                s,
                r#"<text x="{cx:.2}" y="{}" text-anchor="middle">{}</text>"#,
                mt + ph + 16.0,
                esc(&shorten(cat, (slot / 6.5).max(4.0) as usize))
            );
        }
        let _ = writeln!(
            s,
            r##"<rect x="{ml}" y="{mt}" width="{pw}" height="{ph}" fill="none" stroke="#333"/><line x1="{ml}" y1="{:.2}" x2="{}" y2="{:.2}" stroke="#333"/>"##,
            sy(0.0),
            ml + pw,
            sy(0.0)
        );
        let _ = writeln!(
            s,
            r#"<text transform="translate(18,{}) rotate(-90)" text-anchor="middle">{}</text>"#,
            mt + ph / 2.0,
            esc(&self.y_label)
        );
        for (k, (name, _, colour)) in self.series.iter().enumerate() {
            let ly = mt + 10.0 + 18.0 * k as f64;
            let _ = writeln!(
                s,
                r#"<rect x="{}" y="{}" width="14" height="10" fill="{colour}"/><text x="{}" y="{}">{}</text>"#,
                ml + pw + 12.0,
                ly - 5.0,
                ml + pw + 32.0,
                ly + 4.0,
                esc(name)
            );
        }
        let desc = ChartDesc {
            chart: "bars",
            title: self.title.clone(),
            y_label: self.y_label.clone(),
            magnitude: self.magnitude,
            x_axis: (0.0, n as f64),
            y_axis: (y0, y1),
            series: self
                .series
                .iter()
                .zip(&drawn)
                .map(|((name, v, colour), &bars)| SeriesDesc {
                    name: name.clone(),
                    kind: "bars",
                    colour: colour.clone(),
                    marker: "bar",
                    points: v.iter().filter(|x| x.is_finite()).count(),
                    markers: 0,
                    segments: bars,
                })
                .collect(),
            ..Default::default()
        };
        s.push_str(&desc.to_element());
        s.push_str("</svg>\n");
        s
    }
}

fn fmt_value(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else if v.abs() >= 10.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.2}")
    }
}
