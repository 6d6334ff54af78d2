//! The plot description: a JSON object in a `<metadata class="axcomp-plot">` element of every SVG, naming
//! the axes, their drawn ranges and what was drawn of each series, so that tests check a figure by what it
//! says it drew rather than by matching its drawing.
//!
//! Fields: `chart` ("figure" or "bars"), `title`, `x_label`, `y_label`, `magnitude` (the value axis was
//! declared a magnitude), `x_axis` and `y_axis` (`[lo, hi]` as drawn), `series`: per series `name`, `kind`
//! ("line", "dashed", "points", "band", "bars"), `colour`, `marker`, `points` (finite values given),
//! `markers` (markers drawn), `segments` (line pieces of two or more points drawn, or bars).

use std::fmt::Write as _;

/// What was drawn of one series.
#[derive(Debug, Clone, Default)]
pub(crate) struct SeriesDesc {
    pub name: String,
    pub kind: &'static str,
    pub colour: String,
    pub marker: &'static str,
    pub points: usize,
    pub markers: usize,
    pub segments: usize,
}

/// What was drawn of one chart.
#[derive(Debug, Clone, Default)]
pub(crate) struct ChartDesc {
    pub chart: &'static str,
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub magnitude: bool,
    pub x_axis: (f64, f64),
    pub y_axis: (f64, f64),
    pub series: Vec<SeriesDesc>,
}

fn json_str(s: &str) -> String {
    let mut o = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => o.push_str("\\\""),
            '\\' => o.push_str("\\\\"),
            c if (c as u32) < 0x20 => {
                let _ = write!(o, "\\u{:04x}", c as u32);
            }
            c => o.push(c),
        }
    }
    o.push('"');
    o
}

fn json_num(v: f64) -> String {
    if v.is_finite() {
        format!("{v}")
    } else {
        "null".into()
    }
}

impl ChartDesc {
    /// The `<metadata>` element (its JSON escaped for XML).
    pub fn to_element(&self) -> String {
        let mut j = String::new();
        let _ = write!(
            j,
            r#"{{"chart":{},"title":{},"x_label":{},"y_label":{},"magnitude":{},"x_axis":[{},{}],"y_axis":[{},{}],"series":["#,
            json_str(self.chart),
            json_str(&self.title),
            json_str(&self.x_label),
            json_str(&self.y_label),
            self.magnitude,
            json_num(self.x_axis.0),
            json_num(self.x_axis.1),
            json_num(self.y_axis.0),
            json_num(self.y_axis.1)
        );
        for (k, s) in self.series.iter().enumerate() {
            let _ = write!(
                j,
                r#"{}{{"name":{},"kind":{},"colour":{},"marker":{},"points":{},"markers":{},"segments":{}}}"#,
                if k == 0 { "" } else { "," },
                json_str(&s.name),
                json_str(s.kind),
                json_str(&s.colour),
                json_str(s.marker),
                s.points,
                s.markers,
                s.segments
            );
        }
        j.push_str("]}");
        format!(
            "<metadata class=\"axcomp-plot\">{}</metadata>\n",
            crate::esc(&j)
        )
    }
}

/// The plot descriptions (JSON text, one per chart; a panel SVG holds several) found in an SVG written by
/// this crate.
pub fn descriptions(svg: &str) -> Vec<String> {
    const OPEN: &str = "<metadata class=\"axcomp-plot\">";
    let mut out = Vec::new();
    let mut rest = svg;
    while let Some(a) = rest.find(OPEN) {
        let body = &rest[a + OPEN.len()..];
        let Some(b) = body.find("</metadata>") else {
            break;
        };
        out.push(
            body[..b]
                .replace("&quot;", "\"")
                .replace("&lt;", "<")
                .replace("&gt;", ">")
                .replace("&amp;", "&"),
        );
        rest = &body[b..];
    }
    out
}
