//! A `fit geometry` model as the group image's geometric section (see the crate glossary).

use axcomp_core::geometric::{
    COMPONENT_NAMES, FUNCTIONS_PER_AXIS, GeometricCoefficients, GeometricGrid, GeometricSpec,
};
use axcomp_geometry::GeometryModel;

use crate::axis::GroupAxis;
use crate::{Error, Result};

/// A `fit geometry` model converted for the core's geometric stage (owned coefficients).
#[derive(Debug, Clone, PartialEq)]
pub struct GeometricSection {
    pub chain: [u8; 3],
    pub work_axes: u8,
    pub identified: u32,
    pub tool_offset_um: [f32; 3],
    pub squareness_urad: [f32; 3],
    pub grids: [GeometricGrid; 3],
    pub coefficients: Vec<[f32; 4]>,
}

impl GeometricSection {
    /// The core's view of it.
    pub fn spec(&self) -> GeometricSpec<'_> {
        GeometricSpec {
            chain: self.chain,
            work_axes: self.work_axes,
            identified: self.identified,
            tool_offset_um: self.tool_offset_um,
            squareness_urad: self.squareness_urad,
            grids: self.grids,
            coefficients: GeometricCoefficients::Values(&self.coefficients),
        }
    }
    /// The stroke (start, end counts) each grid spans, for X, Y, Z.
    pub fn strokes(&self) -> [(i64, i64); 3] {
        self.grids.map(|g| {
            (
                g.start_counts,
                g.end_counts().clamp(i64::MIN as i128, i64::MAX as i128) as i64,
            )
        })
    }
}

/// Horner coefficients `[c0, c1, c2, c3]` in t ∈ [0, 1) of the uniform cubic B-spline segment with
/// control coefficients `c` (the basis of `axcomp_geometry::spline::AxisGrid::local`).
pub fn bspline_segment_to_horner(c: [f64; 4]) -> [f64; 4] {
    [
        (c[0] + 4.0 * c[1] + c[2]) / 6.0,
        (c[2] - c[0]) / 2.0,
        (c[0] - 2.0 * c[1] + c[2]) / 2.0,
        (-c[0] + 3.0 * c[1] - 3.0 * c[2] + c[3]) / 6.0,
    ]
}

/// Converts a `fit geometry` model for the core's geometric stage: the axes' scales
/// `um_per_count` (X, Y, Z) put the grids on whole counts (else an error naming the axis), the
/// tool offset is in mm. Every component goes in with the values the model file holds, which are
/// the values `axcomp predict` uses: an identified one as fitted; a *not separable* one (marked
/// `identified: false`, only its combination with others is measured) at its minimum-norm share
/// (`fit geometry`'s default) or whatever share the method gave it; one that is not identified for
/// another reason (no reading sensitive to it, fixed by the seven-line method) holds zeros in the
/// model and so goes in as zero. The identified mask records the model's `identified` flags
/// unchanged, so a clear bit with non-zero functions is a not-separable component (see
/// [`geometric_component_nonzero`]).
pub fn geometric_from_model(
    model: &GeometryModel,
    um_per_count: [f64; 3],
    tool_offset_mm: [f64; 3],
) -> Result<GeometricSection> {
    let mut grids = [GeometricGrid {
        start_counts: 0,
        segment_counts: 1,
        n_segments: 1,
    }; 3];
    for k in 0..3 {
        let g = &model.grids[k];
        let upc = um_per_count[k];
        ensure!(
            upc.is_finite() && upc > 0.0,
            "axis {}: µm per count {upc} must be a finite number > 0",
            "XYZ".as_bytes()[k] as char
        );
        let per_mm = 1000.0 / upc;
        let start = g.lo * per_mm;
        let seg = (g.hi - g.lo) * per_mm / g.intervals.max(1) as f64;
        let whole = |x: f64| (x - x.round()).abs() <= 1e-9 * x.abs().max(1.0);
        ensure!(
            g.intervals >= 1
                && g.intervals <= axcomp_core::geometric::MAX_GEOMETRIC_SEGMENTS as usize
                && whole(start)
                && whole(seg)
                && seg.round() >= 1.0
                && seg.round() * g.intervals as f64 <= u32::MAX as f64,
            "geometry model: the {} grid ({} .. {} mm, {} intervals) does not fall on whole counts \
             of {upc} µm (start {start} counts, knot spacing {seg} counts); the core's grid needs \
             whole counts and 1..=1024 intervals",
            "XYZ".as_bytes()[k] as char,
            g.lo,
            g.hi,
            g.intervals
        );
        grids[k] = GeometricGrid {
            start_counts: start.round() as i64,
            segment_counts: seg.round() as u32,
            n_segments: g.intervals as u32,
        };
    }
    let mut identified = 0u32;
    for (i, c) in model.components.iter().enumerate().take(21) {
        if c.identified {
            identified |= 1 << i;
        }
    }
    let mut coefficients = Vec::new();
    for k in 0..3 {
        let n = model.grids[k].intervals;
        for seg in 0..n {
            for f in 0..6 {
                let comp = &model.components[6 * k + f];
                ensure!(
                    comp.coefficients.len() == n + 3,
                    "geometry model: {} has {} spline coefficients, its axis's grid needs {}",
                    comp.name,
                    comp.coefficients.len(),
                    n + 3
                );
                let c = [0, 1, 2, 3].map(|j| comp.coefficients[seg + j]);
                coefficients.push(bspline_segment_to_horner(c).map(|v| v as f32));
            }
        }
    }
    let sq = |i: usize| model.components[18 + i].value as f32;
    let chain = model.topology.chain();
    ensure!(
        chain.len() == 3,
        "geometry model: the stacking must have 3 axes"
    );
    let section = GeometricSection {
        chain: [0, 1, 2].map(|i| chain[i].index() as u8),
        work_axes: model.topology.work.len() as u8,
        identified,
        tool_offset_um: tool_offset_mm.map(|v| (v * 1000.0) as f32),
        squareness_urad: [sq(0), sq(1), sq(2)],
        grids,
        coefficients,
    };
    section
        .spec()
        .validate()
        .map_err(|e| Error::Invalid(format!("geometry model: {e}")))?;
    Ok(section)
}

/// The geometric section of a group from `model` (named `label` in messages) with the X, Y, Z
/// images' scales; each axis table must span the model's grid of its axis.
pub fn geometric_for_group(
    model: &GeometryModel,
    label: &str,
    tool_offset_mm: [f64; 3],
    axes: &[GroupAxis],
) -> Result<GeometricSection> {
    let (upc, tables) = crate::linear_geometry::linear_scales(axes, label)?;
    let g = geometric_from_model(model, upc, tool_offset_mm)
        .map_err(|e| Error::Invalid(format!("{label}: {e}")))?;
    for (k, t) in tables.iter().enumerate() {
        if let Some((lo, hi)) = t {
            let (glo, ghi) = g.strokes()[k];
            ensure!(
                (*lo, *hi) == (glo, ghi),
                "{label}: axis {}'s positioning table spans {lo} .. {hi} counts, the \
                 geometry model's {} grid {glo} .. {ghi} counts; the group's tables of an axis \
                 must span one stroke",
                "XYZ".as_bytes()[k] as char,
                "XYZ".as_bytes()[k] as char
            );
        }
    }
    Ok(g)
}

/// Leaves the named components out of `g` (`--exclude-geometric`): their functions (or squareness
/// constant) are stored as zero and their identified bit is kept, which is how `image inspect` tells an
/// excluded identified component from one the fit did not identify. A not-separable component (bit
/// clear, non-zero values) may be left out too; it then reads as not identified, stored as zero. A
/// name that is not one of the 21, or a component already stored as zero (nothing to leave out), is
/// an error naming it.
pub fn exclude_geometric_components(g: &mut GeometricSection, names: &[String]) -> Result<()> {
    for name in names {
        let name = name.trim();
        let i = COMPONENT_NAMES
            .iter()
            .position(|n| n.eq_ignore_ascii_case(name))
            .ok_or_else(|| {
                Error::Invalid(format!(
                    "--exclude-geometric {name}: not an ISO 230-1 component name ({})",
                    COMPONENT_NAMES.join(", ")
                ))
            })?;
        ensure!(
            g.identified >> i & 1 == 1 || geometric_component_nonzero(&g.spec(), i),
            "--exclude-geometric {name}: the geometry model did not identify {} and holds zero for \
             it (it is stored as zero already): nothing to leave out",
            COMPONENT_NAMES[i]
        );
        if i >= 18 {
            g.squareness_urad[i - 18] = 0.0;
        } else {
            let (k, f) = (i / 6, i % 6);
            let before: usize = g.grids[..k].iter().map(|gr| gr.n_segments as usize).sum();
            for seg in 0..g.grids[k].n_segments as usize {
                g.coefficients[(before + seg) * FUNCTIONS_PER_AXIS + f] = [0.0; 4];
            }
        }
    }
    Ok(())
}

/// True if component `i` (of [`COMPONENT_NAMES`]) of the geometric section has a non-zero value:
/// with its identified bit clear, a not-separable component stored at its share of the combination.
pub fn geometric_component_nonzero(g: &GeometricSpec, i: usize) -> bool {
    if i >= 18 {
        return g.squareness_urad[i - 18] != 0.0;
    }
    let (k, f) = (i / 6, i % 6);
    (0..g.grids[k].n_segments as usize).any(|seg| g.segment(k, seg, f) != [0.0; 4])
}
