//! The one style of every axcomp plot: a colour, dash and marker per series that does not repeat within a
//! figure, axis labels written `quantity (unit)` with the units spelled one way, angles without "−0".
//!
//! Glossary:
//! - *slot*: the position of a series in a figure's automatic style cycle; slot k takes colour
//!   `PALETTE[k % 16]`, and past the palette a dash pattern and a marker shape of their own, so that no two
//!   slots of a figure look alike (up to 64 series);
//! - *magnitude*: a quantity that cannot be negative (|e|, an RMS, a range); its value axis starts at 0.

/// Qualitative colours, colour-blind friendly first (Okabe–Ito without its yellow, which does not read on
/// white), then Tableau and Tol colours distinct from them.
pub const PALETTE: [&str; 16] = [
    "#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#000000", "#8C564B",
    "#7F7F7F", "#BCBD22", "#9467BD", "#17BECF", "#882255", "#44AA99", "#332288", "#DDAA33",
];

/// A series with fewer finite points than this is drawn with a marker at every point (a line alone would
/// hide how few values it rests on).
pub const FEW_POINTS: usize = 12;

/// The shape of a series' markers.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    Circle,
    Square,
    Triangle,
    Diamond,
}

impl Marker {
    pub fn name(self) -> &'static str {
        match self {
            Marker::Circle => "circle",
            Marker::Square => "square",
            Marker::Triangle => "triangle",
            Marker::Diamond => "diamond",
        }
    }

    /// The SVG element of one marker of radius `r` centred at `(x, y)`.
    pub fn svg(self, x: f64, y: f64, r: f64, colour: &str, opacity: f64) -> String {
        let fill = format!(r#"fill="{colour}" fill-opacity="{opacity}""#);
        match self {
            Marker::Circle => format!(r#"<circle cx="{x:.2}" cy="{y:.2}" r="{r}" {fill}/>"#),
            Marker::Square => format!(
                r#"<rect x="{:.2}" y="{:.2}" width="{:.2}" height="{:.2}" {fill}/>"#,
                x - 0.9 * r,
                y - 0.9 * r,
                1.8 * r,
                1.8 * r
            ),
            Marker::Triangle => format!(
                r#"<path d="M{x:.2},{:.2}L{:.2},{:.2}L{:.2},{:.2}Z" {fill}/>"#,
                y - 1.2 * r,
                x + 1.1 * r,
                y + 0.8 * r,
                x - 1.1 * r,
                y + 0.8 * r
            ),
            Marker::Diamond => format!(
                r#"<path d="M{x:.2},{:.2}L{:.2},{y:.2}L{x:.2},{:.2}L{:.2},{y:.2}Z" {fill}/>"#,
                y - 1.3 * r,
                x + 1.1 * r,
                y + 1.3 * r,
                x - 1.1 * r
            ),
        }
    }
}

/// The look of slot `k`: its colour, the dash of a solid line in it (`None` = solid), its marker.
pub fn slot(k: usize) -> (&'static str, Option<&'static str>, Marker) {
    const DASHES: [Option<&str>; 4] = [None, Some("2,3"), Some("8,3,2,3"), Some("1,2")];
    const MARKERS: [Marker; 4] = [
        Marker::Circle,
        Marker::Square,
        Marker::Triangle,
        Marker::Diamond,
    ];
    let round = (k / PALETTE.len()) % 4;
    (PALETTE[k % PALETTE.len()], DASHES[round], MARKERS[round])
}

/// The units axis labels are written in, each spelled one way (`µm`, never `um` or `micron`; `°`, never
/// `deg`).
pub const UNITS: [&str; 19] = [
    "µm", "mm", "°", "N", "K", "°C", "s", "min", "h", "µrad", "mm/min", "mm/s", "rpm", "N/mm²",
    "N/mm", "µm/K", "%", "mm/rev", "µm/m",
];

/// An axis label in the one style: `quantity (unit)`; `unit` must be one of [`UNITS`].
pub fn label(quantity: &str, unit: &str) -> String {
    debug_assert!(UNITS.contains(&unit), "unit {unit} is not one of UNITS");
    format!("{quantity} ({unit})")
}

/// Checks an axis label against the style: a quantity, then either nothing (a count, an index) or one unit
/// of [`UNITS`] in parentheses at the end; no `quantity / unit`, no unit spelled another way (`um`, `deg`).
pub fn check_label(label: &str) -> Result<(), String> {
    let bad = ["um", "deg", "degC", "micron", "microns", "mrad", "urad"];
    let words = label
        .split(|c: char| !(c.is_alphanumeric() || c == '_'))
        .filter(|w| !w.is_empty());
    for w in words {
        if bad.contains(&w) {
            return Err(format!("{label:?}: unit spelled {w:?}"));
        }
        if w.ends_with("_um") || w.ends_with("_mm") || w.ends_with("_deg") {
            return Err(format!("{label:?}: a raw column name {w:?}"));
        }
    }
    if label.contains(" / ") {
        return Err(format!(
            "{label:?}: write the unit as `(unit)`, not `/ unit`"
        ));
    }
    if label.trim().is_empty() {
        return Err("an empty axis label".into());
    }
    match label.rfind('(') {
        Some(open) if label.ends_with(')') => {
            let unit = &label[open + 1..label.len() - 1];
            if UNITS.contains(&unit) || !unit.chars().any(|c| c.is_alphabetic() || c == '°') {
                Ok(())
            } else {
                // A parenthesis that is not a unit (e.g. "pose (held-out)") is allowed only when it holds
                // words of more than one kind; a lone token there reads as a unit.
                if unit.contains(' ') {
                    Ok(())
                } else {
                    Err(format!("{label:?}: unit {unit:?} is not one of {UNITS:?}"))
                }
            }
        }
        _ if label.contains('(') || label.contains(')') => {
            Err(format!("{label:?}: the unit must close the label"))
        }
        _ => Ok(()),
    }
}

/// `v` with `decimals` decimals, never "-0.0" (a tilt of −0.00001° is written 0.0).
pub fn fmt_fixed(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    if s.starts_with('-') && s[1..].chars().all(|c| c == '0' || c == '.') {
        s[1..].to_owned()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_do_not_repeat_within_64() {
        let mut seen = std::collections::HashSet::new();
        for k in 0..64 {
            let (c, d, m) = slot(k);
            assert!(seen.insert((c, d, m.name())), "slot {k} repeats");
        }
        assert_eq!(slot(0).0, PALETTE[0]);
        assert_eq!(slot(16).0, PALETTE[0]);
        assert_ne!(slot(16).2, slot(0).2);
    }

    #[test]
    fn labels_follow_the_style() {
        for ok in [
            "deviation (µm)",
            "C angle (°)",
            "feed (mm/min)",
            "sample",
            "|e| (µm)",
        ] {
            check_label(ok).unwrap();
        }
        for bad in [
            "dx_um",
            "|d| (um)",
            "C angle (deg)",
            "deviation / µm",
            "force (lbf)",
            "x (",
        ] {
            assert!(check_label(bad).is_err(), "{bad}");
        }
        assert_eq!(label("force", "N"), "force (N)");
    }

    #[test]
    fn no_negative_zero() {
        assert_eq!(fmt_fixed(-0.00001, 1), "0.0");
        assert_eq!(fmt_fixed(-0.26, 1), "-0.3");
        assert_eq!(fmt_fixed(12.345, 2), "12.35");
    }
}
