//! `axcomp-plot`: small, dependency-free SVG charts and Markdown tables for the axcomp reports, all in one
//! style ([`style`]).
//!
//! Glossary:
//! - *figure*: one chart with a title, two axis labels and any number of series;
//! - *series*: a line (polyline through the points, gaps at non-finite values), points (markers), or a band
//!   (filled area between a lower and an upper curve, e.g. a residual ±2s band);
//! - *span*: a shaded vertical region of the x axis with a label (a located gap region, a held-out phase);
//! - *rule*: a horizontal reference line (zero, a tolerance);
//! - *magnitude axis*: a value axis declared with [`Figure::magnitude`] (|e|, an RMS): it starts at 0;
//! - *plot description*: a JSON `<metadata class="axcomp-plot">` element in every SVG naming the axes,
//!   their ranges and what was drawn of each series (points, markers, line segments), so that a test can
//!   check a figure without matching its drawing ([`descriptions`]).
//!
//! A line with fewer than [`style::FEW_POINTS`] points also shows its markers, and a run of one point
//! between gaps is drawn as a marker, never as an invisible one-point line.
//!
//! ```
//! let mut fig = axcomp_plot::Figure::new("Deviation", "position (mm)", "deviation (µm)");
//! fig.line("forward", &[0.0, 1.0, 2.0], &[1.0, 3.0, 2.0]);
//! fig.vspan(0.5, 1.5, "held out");
//! let svg = fig.to_svg();
//! assert!(svg.starts_with("<svg"));
//! assert_eq!(axcomp_plot::descriptions(&svg).len(), 1);
//! ```

use std::fmt::Write as _;
use std::path::Path;

mod bar;
mod coloured;
mod meta;
mod render;
pub mod style;

pub use bar::BarChart;
pub use meta::descriptions;
pub use style::{PALETTE, label};

#[derive(Debug, Clone)]
enum Kind {
    Line { dashed: bool },
    Points,
    Band { upper: Vec<f64> },
}

#[derive(Debug, Clone)]
struct Series {
    name: String,
    xs: Vec<f64>,
    ys: Vec<f64>,
    kind: Kind,
    colour: String,
    /// The dash of a solid line past the palette's first round.
    dash: Option<&'static str>,
    marker: style::Marker,
}

#[derive(Debug, Clone)]
struct Span {
    from: f64,
    to: f64,
    label: String,
}

/// One chart. Build it with the series methods, then [`Figure::to_svg`] or [`Figure::save_svg`].
#[derive(Debug, Clone)]
pub struct Figure {
    title: String,
    x_label: String,
    y_label: String,
    width: f64,
    height: f64,
    series: Vec<Series>,
    spans: Vec<Span>,
    rules: Vec<(f64, String)>,
    next_slot: usize,
    magnitude: bool,
    x_range: Option<(f64, f64)>,
    x_step: Option<f64>,
}

impl Figure {
    /// A new empty 900×500 figure.
    pub fn new(title: &str, x_label: &str, y_label: &str) -> Self {
        Figure {
            title: title.to_owned(),
            x_label: x_label.to_owned(),
            y_label: y_label.to_owned(),
            width: 900.0,
            height: 500.0,
            series: Vec::new(),
            spans: Vec::new(),
            rules: Vec::new(),
            next_slot: 0,
            magnitude: false,
            x_range: None,
            x_step: None,
        }
    }

    /// Sets the size in pixels (minimum 200×150).
    pub fn size(&mut self, width: f64, height: f64) -> &mut Self {
        self.width = width.max(200.0);
        self.height = height.max(150.0);
        self
    }

    /// Replaces the title (when its headline figure is known only once the series are computed).
    pub fn set_title(&mut self, title: &str) -> &mut Self {
        title.clone_into(&mut self.title);
        self
    }

    /// Declares the value (y) axis a magnitude (|e|, an RMS, a range): it starts at 0.
    pub fn magnitude(&mut self) -> &mut Self {
        self.magnitude = true;
        self
    }

    /// Fixes the x axis to `lo..hi` (e.g. a rotary axis's 0…360°) with ticks every `step` (none: chosen).
    pub fn x_axis(&mut self, lo: f64, hi: f64, step: Option<f64>) -> &mut Self {
        if lo.is_finite() && hi.is_finite() && hi > lo {
            self.x_range = Some((lo, hi));
            self.x_step = step.filter(|s| *s > 0.0 && (hi - lo) / s <= 50.0);
        }
        self
    }

    fn push(&mut self, name: &str, xs: &[f64], ys: &[f64], kind: Kind) -> &mut Self {
        let n = xs.len().min(ys.len());
        let (colour, dash, marker) = style::slot(self.next_slot);
        self.next_slot += 1;
        self.series.push(Series {
            name: name.to_owned(),
            xs: xs[..n].to_vec(),
            ys: ys[..n].to_vec(),
            kind,
            colour: colour.to_owned(),
            dash,
            marker,
        });
        self
    }

    /// A solid line through `(xs[i], ys[i])`; non-finite values break the line.
    pub fn line(&mut self, name: &str, xs: &[f64], ys: &[f64]) -> &mut Self {
        self.push(name, xs, ys, Kind::Line { dashed: false })
    }

    /// A dashed line (for models, predictions, references).
    pub fn dashed(&mut self, name: &str, xs: &[f64], ys: &[f64]) -> &mut Self {
        self.push(name, xs, ys, Kind::Line { dashed: true })
    }

    /// Markers at `(xs[i], ys[i])`; non-finite points are skipped.
    pub fn points(&mut self, name: &str, xs: &[f64], ys: &[f64]) -> &mut Self {
        self.push(name, xs, ys, Kind::Points)
    }

    /// A filled band between `lo` and `hi` over `xs` (xs should be sorted).
    pub fn band(&mut self, name: &str, xs: &[f64], lo: &[f64], hi: &[f64]) -> &mut Self {
        let n = xs.len().min(lo.len()).min(hi.len());
        self.push(
            name,
            &xs[..n],
            &lo[..n],
            Kind::Band {
                upper: hi[..n].to_vec(),
            },
        )
    }

    /// Sets the colour (any SVG colour, e.g. one of [`PALETTE`]) of the series added last, so that a line
    /// and its points can share one colour: `fig.points(..).with_colour(PALETTE[1])`.
    pub fn with_colour(&mut self, colour: &str) -> &mut Self {
        if let Some(s) = self.series.last_mut() {
            s.colour = colour.to_owned();
        }
        self
    }

    /// Gives the series added last the colour, dash and marker of the one before it (a fitted line drawn
    /// in the colour of the points it was fitted to), and hands its own style slot back.
    pub fn like_previous(&mut self) -> &mut Self {
        let n = self.series.len();
        if n >= 2 {
            let (colour, dash, marker) = {
                let p = &self.series[n - 2];
                (p.colour.clone(), p.dash, p.marker)
            };
            let s = &mut self.series[n - 1];
            (s.colour, s.dash, s.marker) = (colour, dash, marker);
            self.next_slot -= 1;
        }
        self
    }

    /// A shaded vertical region `from..to` with a label.
    pub fn vspan(&mut self, from: f64, to: f64, label: &str) -> &mut Self {
        self.spans.push(Span {
            from: from.min(to),
            to: from.max(to),
            label: label.to_owned(),
        });
        self
    }

    /// A horizontal reference line at `y`.
    pub fn hline(&mut self, y: f64, label: &str) -> &mut Self {
        self.rules.push((y, label.to_owned()));
        self
    }

    /// Writes the SVG to `path` (through a temporary file renamed into place, so a reader never sees half a file).
    pub fn save_svg(&self, path: impl AsRef<Path>) -> std::io::Result<()> {
        write_atomic(path.as_ref(), self.to_svg().as_bytes())
    }
}

/// Several figures side by side in one SVG (`columns` per row), each keeping its own title, axes and
/// legend — for comparisons that would crowd one panel (e.g. before / after per direction).
pub fn panels_svg(figures: &[&Figure], columns: usize) -> String {
    let columns = columns.max(1);
    let rows = figures.len().div_ceil(columns);
    let cw = figures.iter().map(|f| f.width).fold(0.0, f64::max);
    let ch = figures.iter().map(|f| f.height).fold(0.0, f64::max);
    let (w, h) = (cw * columns as f64, ch * rows as f64);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    for (k, f) in figures.iter().enumerate() {
        let (x, y) = (cw * (k % columns) as f64, ch * (k / columns) as f64);
        // Each panel's clip path gets its own id.
        let inner = f
            .to_svg()
            .replace("id=\"plotarea\"", &format!("id=\"plotarea{k}\""))
            .replace("url(#plotarea)", &format!("url(#plotarea{k})"));
        let inner = inner.replacen("<svg ", &format!("<svg x=\"{x}\" y=\"{y}\" "), 1);
        s.push_str(&inner);
    }
    s.push_str("</svg>\n");
    s
}

/// `text` cut to `max` characters with a final `…` when longer.
fn shorten(text: &str, max: usize) -> String {
    if text.chars().count() <= max {
        text.to_owned()
    } else {
        let mut t: String = text.chars().take(max.saturating_sub(1)).collect();
        t.push('…');
        t
    }
}

/// Splits a title into lines of at most `max_chars` characters at spaces.
fn wrap(text: &str, max_chars: usize) -> Vec<String> {
    let mut lines: Vec<String> = Vec::new();
    let mut cur = String::new();
    for word in text.split(' ') {
        if !cur.is_empty() && cur.chars().count() + 1 + word.chars().count() > max_chars {
            lines.push(std::mem::take(&mut cur));
        }
        if !cur.is_empty() {
            cur.push(' ');
        }
        cur.push_str(word);
    }
    if !cur.is_empty() {
        lines.push(cur);
    }
    lines
}

/// The host libraries' one atomic write (temporary sibling, sync, rename): see `axcomp-files`.
use axcomp_files::write_atomic;

/// "Nice" tick positions (1, 2, 5 × 10^k steps) covering `lo..hi` with about `target` ticks.
pub fn nice_ticks(lo: f64, hi: f64, target: usize) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite()) || hi <= lo {
        return vec![lo, hi];
    }
    let raw = (hi - lo) / target.max(2) as f64;
    let mag = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 2.5, 5.0, 10.0]
        .iter()
        .map(|m| m * mag)
        .find(|&s| s >= raw)
        .unwrap_or(10.0 * mag);
    let start = (lo / step).floor() * step;
    let mut ticks = Vec::new();
    let mut k = 0;
    loop {
        let t = start + k as f64 * step;
        ticks.push(if t.abs() < step * 1e-9 { 0.0 } else { t });
        if t >= hi - step * 1e-9 || k > 1000 {
            break;
        }
        k += 1;
    }
    ticks
}

fn fmt_tick(v: f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".into()
    } else if !(1e-3..1e5).contains(&a) {
        format!("{v:.1e}")
    } else {
        let s = format!("{v:.4}");
        s.trim_end_matches('0').trim_end_matches('.').to_owned()
    }
}

/// The opening of a chart's SVG: the root element, a white background and the title lines, centred.
fn svg_open<S: AsRef<str>>(w: f64, h: f64, title_lines: &[S]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" viewBox="0 0 {w} {h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="{w}" height="{h}" fill="white"/>"#);
    for (k, line) in title_lines.iter().enumerate() {
        let _ = writeln!(
            s,
            r#"<text x="{}" y="{}" font-size="15" text-anchor="middle">{}</text>"#,
            w / 2.0,
            24.0 + 18.0 * k as f64,
            esc(line.as_ref())
        );
    }
    s
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// A Markdown table: a header row, an alignment row (numbers right-aligned), then `rows`.
pub fn markdown_table<S: AsRef<str>>(headers: &[&str], rows: &[Vec<S>]) -> String {
    let mut out = String::new();
    out.push('|');
    for h in headers {
        let _ = write!(out, " {} |", h.replace('|', "\\|"));
    }
    out.push_str("\n|");
    for _ in headers {
        out.push_str("---|");
    }
    out.push('\n');
    for r in rows {
        out.push('|');
        for c in r {
            let _ = write!(out, " {} |", c.as_ref().replace('|', "\\|"));
        }
        out.push('\n');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_nice_and_cover_the_range() {
        let t = nice_ticks(-20.3, 19.7, 8);
        assert!(t[0] <= -20.3 && *t.last().unwrap() >= 19.7, "{t:?}");
        // Step 5 for a 40-wide range at 8 ticks (reference: 1-2-2.5-5 sequence).
        assert!((t[1] - t[0] - 5.0).abs() < 1e-12, "{t:?}");
        assert!(t.contains(&0.0));
    }

    fn describe(svg: &str) -> Vec<serde_json::Value> {
        descriptions(svg)
            .iter()
            .map(|d| serde_json::from_str(d).unwrap())
            .collect()
    }

    #[test]
    fn svg_contains_every_series_and_skips_nan() {
        let mut f = Figure::new("T <1>", "x", "y");
        f.line("a", &[0.0, 1.0, f64::NAN, 3.0], &[0.0, 1.0, 2.0, 3.0]);
        f.points("b", &[0.0, 1.0], &[1.0, f64::INFINITY]);
        f.band("c", &[0.0, 1.0], &[-1.0, -1.0], &[1.0, 1.0]);
        f.vspan(0.2, 0.4, "gap");
        f.hline(0.0, "zero");
        let s = f.to_svg();
        assert!(s.contains("T &lt;1&gt;"));
        assert!(s.contains(">gap<") && s.contains(">zero<"));
        assert!(!s.contains("NaN") && !s.contains("inf"));
        let d = &describe(&s)[0];
        assert_eq!(d["title"], "T <1>");
        let series = d["series"].as_array().unwrap();
        // "a": the NaN splits it into a piece of two points and one lone point; with 3 < FEW_POINTS points
        // every point has its marker.
        assert_eq!(series[0]["points"], 3);
        assert_eq!(series[0]["segments"], 1);
        assert_eq!(series[0]["markers"], 3);
        // "b": one finite point, one marker.
        assert_eq!(series[1]["points"], 1);
        assert_eq!(series[1]["markers"], 1);
        assert_eq!(series[2]["segments"], 1);
        // The line piece: one path with one move-to.
        let path = s
            .lines()
            .find(|l| l.contains("stroke-width=\"1.6\""))
            .unwrap();
        assert_eq!(path.matches('M').count(), 1, "{path}");
    }

    /// A one-point line is drawn as a marker (as an "M x,y" path it would be invisible); a long line shows
    /// no markers except at lone points between gaps.
    #[test]
    fn lone_points_are_markers() {
        let mut f = Figure::new("t", "x (mm)", "y (µm)");
        f.line("one", &[5.0], &[1.0]);
        let xs: Vec<f64> = (0..40).map(f64::from).collect();
        let mut ys: Vec<f64> = xs.iter().map(|x| x.sin()).collect();
        ys[19] = f64::NAN;
        ys[21] = f64::NAN;
        f.line("long", &xs, &ys);
        let d = &describe(&f.to_svg())[0];
        let s = d["series"].as_array().unwrap();
        assert_eq!(
            (&s[0]["markers"], &s[0]["segments"]),
            (&1.into(), &0.into())
        );
        // 40 − 2 NaN = 38 points in pieces 0..19, {20}, 22..40: two pieces and one lone marker.
        assert_eq!(
            (&s[1]["markers"], &s[1]["segments"]),
            (&1.into(), &2.into())
        );
    }

    /// A magnitude axis starts at 0 (reference: the data's minimum is 3, which would otherwise be padded to
    /// about 2.9), a fixed x axis keeps its range and its tick step.
    #[test]
    fn magnitude_and_fixed_axis() {
        let mut f = Figure::new("t", "C angle (°)", "|d| (µm)");
        f.line("a", &[0.0, 180.0, 360.0], &[3.0, 4.0, 5.0])
            .magnitude()
            .x_axis(0.0, 360.0, Some(45.0));
        let svg = f.to_svg();
        let d = &describe(&svg)[0];
        assert_eq!(d["magnitude"], true);
        assert_eq!(d["y_axis"][0], 0.0);
        assert!(d["y_axis"][1].as_f64().unwrap() >= 5.0);
        assert_eq!(
            (d["x_axis"][0].as_f64(), d["x_axis"][1].as_f64()),
            (Some(0.0), Some(360.0))
        );
        assert!(svg.contains(">315<") && !svg.contains(">400<"));
    }

    /// `like_previous` gives a fitted line its points' colour and marker, and the next series the next slot.
    #[test]
    fn a_line_and_its_points_share_one_colour() {
        let mut f = Figure::new("t", "x", "y");
        f.points("Fx", &[1.0, 2.0], &[1.0, 2.0])
            .line("Fx fit", &[1.0, 2.0], &[1.0, 2.0])
            .like_previous()
            .points("Fy", &[1.0, 2.0], &[3.0, 4.0]);
        let d = &describe(&f.to_svg())[0];
        let s = d["series"].as_array().unwrap();
        assert_eq!(s[0]["colour"], s[1]["colour"]);
        assert_eq!(s[2]["colour"], PALETTE[1]);
    }

    /// A 1e6-point series becomes a density of at most one mark per 2 × 2 px cell: the SVG stays under
    /// 1 MB (bound: the plot area / 4 cells × ~20 bytes), and a 1e6-vertex line is reduced per pixel column.
    #[test]
    fn large_series_stay_small() {
        let n = 1_000_000;
        let xs: Vec<f64> = (0..n).map(|i| i as f64 / n as f64 * 400.0).collect();
        let ys: Vec<f64> = xs
            .iter()
            .enumerate()
            .map(|(i, x)| (x / 30.0).sin() * 20.0 + (i % 97) as f64 * 0.05)
            .collect();
        let mut f = Figure::new("big", "x", "y");
        f.points("p", &xs, &ys).line("l", &xs, &ys);
        let svg = f.to_svg();
        assert!(svg.len() < 1_000_000, "{} bytes", svg.len());
        assert!(svg.contains("stroke-linecap=\"round\""));
    }

    #[test]
    fn panels_and_bars_render() {
        let mut a = Figure::new("a", "x", "y");
        a.line("l", &[0.0, 1.0], &[0.0, 1.0]);
        let b = a.clone();
        let s = panels_svg(&[&a, &b], 2);
        assert!(s.contains("plotarea0") && s.contains("plotarea1"));
        assert!(s.contains("x=\"900\""), "second panel to the right");
        let mut bars = BarChart::new("RMS per condition", "RMS / µm", &["heating", "cooling"]);
        bars.series("raw", &[10.0, 20.0])
            .series("model", &[2.0, 5.5]);
        let svg = bars.to_svg();
        assert_eq!(
            svg.matches("<rect").count(),
            1 + 4 + 2 + 1,
            "background + 4 bars + 2 legend + frame"
        );
        let d = &describe(&svg)[0];
        assert_eq!(d["series"][1]["segments"], 2, "two bars of the model");
        assert!(svg.contains(">5.50<") && svg.contains(">cooling<"));
    }

    #[test]
    fn empty_figure_renders() {
        let s = Figure::new("empty", "x", "y").to_svg();
        assert!(s.ends_with("</svg>\n"));
    }

    #[test]
    fn markdown_table_shape() {
        let t = markdown_table(&["a", "b"], &[vec!["1", "2|3"]]);
        assert_eq!(t, "| a | b |\n|---|---|\n| 1 | 2\\|3 |\n");
    }

    #[test]
    fn save_is_atomic_and_complete() {
        let dir = std::env::temp_dir().join(format!("axcomp-plot-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("f.svg");
        let mut f = Figure::new("t", "x", "y");
        f.line("l", &[0.0, 1.0], &[0.0, 1.0]);
        f.save_svg(&p).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), f.to_svg());
        assert!(!dir.join("f.svg.tmp").exists());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
