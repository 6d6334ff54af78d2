//! `axcomp-plot`: small, dependency-free SVG charts and Markdown tables for the axcomp reports.
//!
//! Glossary:
//! - *figure*: one chart with a title, two axis labels and any number of series;
//! - *series*: a line (polyline through the points, gaps at non-finite values), points (markers), or a band
//!   (filled area between a lower and an upper curve, e.g. a residual ±2s band);
//! - *span*: a shaded vertical region of the x axis with a label (a located gap region, a held-out phase);
//! - *rule*: a horizontal reference line (zero, a tolerance).
//!
//! ```
//! let mut fig = axcomp_plot::Figure::new("Deviation", "position / mm", "deviation / µm");
//! fig.line("forward", &[0.0, 1.0, 2.0], &[1.0, 3.0, 2.0]);
//! fig.vspan(0.5, 1.5, "held out");
//! let svg = fig.to_svg();
//! assert!(svg.starts_with("<svg"));
//! ```

use std::fmt::Write as _;
use std::path::Path;

mod coloured;

/// Colours cycled through by series that do not choose one (colour-blind friendly, Okabe–Ito).
pub const PALETTE: [&str; 8] = [
    "#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#F0E442",
];

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
    next_colour: usize,
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
            next_colour: 0,
        }
    }

    /// Sets the size in pixels (minimum 200×150).
    pub fn size(&mut self, width: f64, height: f64) -> &mut Self {
        self.width = width.max(200.0);
        self.height = height.max(150.0);
        self
    }

    fn colour(&mut self) -> String {
        let c = PALETTE[self.next_colour % PALETTE.len()];
        self.next_colour += 1;
        c.to_owned()
    }

    fn push(&mut self, name: &str, xs: &[f64], ys: &[f64], kind: Kind) -> &mut Self {
        let n = xs.len().min(ys.len());
        let colour = self.colour();
        self.series.push(Series {
            name: name.to_owned(),
            xs: xs[..n].to_vec(),
            ys: ys[..n].to_vec(),
            kind,
            colour,
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

    /// The range of all finite data (x, y), padded; (0,1) for empty figures.
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
            for &v in &s.xs {
                see(v, &mut x);
            }
            for &v in &s.ys {
                see(v, &mut y);
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
        let x = fix(x);
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
        let xt = nice_ticks(x0, x1, 8);
        let yt = nice_ticks(y0, y1, 6);
        let (x0, x1) = (x0.min(xt[0]), x1.max(*xt.last().unwrap_or(&x1)));
        let (y0, y1) = (y0.min(yt[0]), y1.max(*yt.last().unwrap_or(&y1)));
        let sx = |v: f64| ml + (v - x0) / (x1 - x0) * pw;
        let sy = |v: f64| mt + ph - (v - y0) / (y1 - y0) * ph;

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
                esc(line)
            );
        }
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
        for se in &self.series {
            match &se.kind {
                Kind::Band { upper } => {
                    let mut d = String::new();
                    let idx: Vec<usize> = (0..se.xs.len())
                        .filter(|&i| {
                            se.xs[i].is_finite() && se.ys[i].is_finite() && upper[i].is_finite()
                        })
                        .collect();
                    for (k, &i) in idx.iter().enumerate() {
                        let _ = write!(
                            d,
                            "{}{:.2},{:.2} ",
                            if k == 0 { "M" } else { "L" },
                            sx(se.xs[i]),
                            sy(upper[i])
                        );
                    }
                    for &i in idx.iter().rev() {
                        let _ = write!(d, "L{:.2},{:.2} ", sx(se.xs[i]), sy(se.ys[i]));
                    }
                    if !idx.is_empty() {
                        let _ = writeln!(
                            s,
                            r#"<path d="{d}Z" fill="{}" fill-opacity="0.18" stroke="none"/>"#,
                            se.colour
                        );
                    }
                }
                Kind::Line { dashed } => {
                    let mut d = String::new();
                    let mut pen_down = false;
                    let (xs, ys) = decimate_line(&se.xs, &se.ys, pw, &sx);
                    for (&x, &y) in xs.iter().zip(&ys) {
                        if x.is_finite() && y.is_finite() {
                            let _ = write!(
                                d,
                                "{}{:.2},{:.2} ",
                                if pen_down { "L" } else { "M" },
                                sx(x),
                                sy(y)
                            );
                            pen_down = true;
                        } else {
                            pen_down = false;
                        }
                    }
                    let dash = if *dashed {
                        r#" stroke-dasharray="6,4""#
                    } else {
                        ""
                    };
                    let _ = writeln!(
                        s,
                        r#"<path d="{d}" fill="none" stroke="{}" stroke-width="1.6"{dash}/>"#,
                        se.colour
                    );
                }
                Kind::Points if se.xs.len() > DENSE_POINTS => {
                    // Dense: one mark per occupied 2 × 2 px cell, all in one path of round dots, so the
                    // file stays small (bounded by the plot area, not by the number of points).
                    let mut seen = std::collections::HashSet::new();
                    let mut d = String::new();
                    for (&x, &y) in se.xs.iter().zip(&se.ys) {
                        if x.is_finite() && y.is_finite() {
                            let (px, py) = (sx(x), sy(y));
                            if seen.insert(((px / 2.0) as i64, (py / 2.0) as i64)) {
                                let _ = write!(d, "M{px:.1},{py:.1}h0");
                            }
                        }
                    }
                    let _ = writeln!(
                        s,
                        r#"<path d="{d}" stroke="{}" stroke-opacity="0.6" stroke-width="4" stroke-linecap="round" fill="none"/>"#,
                        se.colour
                    );
                }
                Kind::Points => {
                    for (&x, &y) in se.xs.iter().zip(&se.ys) {
                        if x.is_finite() && y.is_finite() {
                            let _ = writeln!(
                                s,
                                r#"<circle cx="{:.2}" cy="{:.2}" r="2.6" fill="{}" fill-opacity="0.75"/>"#,
                                sx(x),
                                sy(y),
                                se.colour
                            );
                        }
                    }
                }
            }
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
        for (k, se) in self.series.iter().enumerate() {
            let ly = mt + 10.0 + step * k as f64;
            let mark = match se.kind {
                Kind::Points => format!(
                    r#"<circle cx="{}" cy="{ly}" r="3.5" fill="{}"/>"#,
                    lx + 9.0,
                    se.colour
                ),
                Kind::Band { .. } => format!(
                    r#"<rect x="{lx}" y="{}" width="18" height="10" fill="{}" fill-opacity="0.3"/>"#,
                    ly - 5.0,
                    se.colour
                ),
                Kind::Line { dashed } => format!(
                    r#"<line x1="{lx}" y1="{ly}" x2="{}" y2="{ly}" stroke="{}" stroke-width="2"{}/>"#,
                    lx + 18.0,
                    se.colour,
                    if dashed {
                        r#" stroke-dasharray="5,3""#
                    } else {
                        ""
                    }
                ),
            };
            let _ = writeln!(
                s,
                r#"{mark}<text x="{}" y="{}">{}</text>"#,
                lx + 24.0,
                ly + 4.0,
                esc(&shorten(&se.name, legend_chars))
            );
        }
        s.push_str("</svg>\n");
        s
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

/// A bar chart of values per category (e.g. a residual RMS per operating condition), one bar per series
/// within each category, with the value printed above each bar. The y axis starts at 0 when all values are
/// ≥ 0.
#[derive(Debug, Clone)]
pub struct BarChart {
    title: String,
    y_label: String,
    categories: Vec<String>,
    series: Vec<(String, Vec<f64>, String)>,
}

impl BarChart {
    pub fn new(title: &str, y_label: &str, categories: &[&str]) -> Self {
        BarChart {
            title: title.to_owned(),
            y_label: y_label.to_owned(),
            categories: categories.iter().map(|c| (*c).to_owned()).collect(),
            series: Vec::new(),
        }
    }

    /// One value per category (missing or non-finite values draw no bar).
    pub fn series(&mut self, name: &str, values: &[f64]) -> &mut Self {
        let colour = PALETTE[self.series.len() % PALETTE.len()].to_owned();
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
                esc(line)
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
        let slot = pw / n as f64;
        let bw = (slot * 0.8 / per as f64).min(60.0);
        for (c, cat) in self.categories.iter().enumerate() {
            let cx = ml + slot * (c as f64 + 0.5);
            for (k, (_, v, colour)) in self.series.iter().enumerate() {
                let Some(&v) = v.get(c) else { continue };
                if !v.is_finite() {
                    continue;
                }
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

/// Points series with more points than this are drawn as density (one mark per 2 × 2 px cell).
pub const DENSE_POINTS: usize = 2000;

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
pub use axcomp_files::write_atomic;

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
        assert_eq!(
            s.matches("<circle").count(),
            1 + 1,
            "one finite point + one legend marker"
        );
        assert!(s.contains(">gap<") && s.contains(">zero<"));
        assert!(!s.contains("NaN") && !s.contains("inf"));
        // The NaN breaks the line into two pieces: two move-to commands.
        let path = s
            .lines()
            .find(|l| l.contains("stroke-width=\"1.6\""))
            .unwrap();
        assert_eq!(path.matches('M').count(), 2, "{path}");
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
