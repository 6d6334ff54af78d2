//! Series with a chosen colour (additive to [`Figure`]'s cycling palette), so that one quantity — e.g.
//! an approach direction — keeps one colour across several series or figures.

use crate::{Figure, Kind, Series};

impl Figure {
    /// Markers at `(xs[i], ys[i])` in `colour` (any SVG colour, e.g. one of [`crate::PALETTE`]); the
    /// palette cycle of the other series is not advanced.
    pub fn points_coloured(
        &mut self,
        name: &str,
        xs: &[f64],
        ys: &[f64],
        colour: &str,
    ) -> &mut Self {
        let n = xs.len().min(ys.len());
        self.series.push(Series {
            name: name.to_owned(),
            xs: xs[..n].to_vec(),
            ys: ys[..n].to_vec(),
            kind: Kind::Points,
            colour: colour.to_owned(),
            dash: None,
            marker: crate::style::Marker::Circle,
        });
        self
    }
}

#[cfg(test)]
mod tests {
    use crate::{Figure, PALETTE};

    #[test]
    fn chosen_colour_is_used_for_markers_and_legend() {
        let mut f = Figure::new("t", "x (mm)", "y (µm)");
        f.points_coloured("forward", &[0.0, 1.0], &[1.0, 2.0], PALETTE[0]);
        f.points_coloured("reverse", &[0.0, 1.0], &[2.0, 1.0], PALETTE[1]);
        let svg = f.to_svg();
        // Two markers + one legend marker per series, and the colour in the plot description.
        assert_eq!(svg.matches(PALETTE[0]).count(), 3 + 1, "{svg}");
        assert_eq!(svg.matches(PALETTE[1]).count(), 3 + 1, "{svg}");
    }
}
