//! A `fit rtest --effects linear_geometry` effect as the group image's geometric section: its
//! translational components (positioning and straightness of each linear axis), alone or added to a
//! `fit geometry` model's.
//!
//! Glossary:
//! - *linear geometry*: the effect's displacement `d` (µm, the R-test's `d = sphere − tool point`)
//!   along X, Y, Z as Legendre polynomials `P_1…P_3` of each moving linear axis's position `q`
//!   (mm, `FiveAxis::linear_positions`) mapped to −1…1 over its measured range `range_mm`
//!   (`axcomp_rtest::effects::EffectBasis::Linear`). The tool point's error relative to the
//!   workpiece is its negative, `e = −d`: that is what the geometric stage holds, as its components
//!   `EXa`, `EYa`, `EZa` of axis a (no angular or squareness term).
//! - *counts of q*: the commanded counts of axis a at which the linear axes sit at `q`: the
//!   rotary section's placement, `pivot_counts[a] + q·1000/µm-per-count`, plus a trunnion's tool
//!   length in whole counts of Z on Z (as the rotary stage folds it).
//! - *measured range, widened*: the cubic is exact over the measured range; the grid's knots rarely
//!   fall on its ends, so the cubic runs on to the nearest knots outside it (under one count alone,
//!   under one segment of a `fit geometry` grid) and the stage holds the values there beyond them,
//!   as it holds every function at its grid's ends (`predict` refuses poses outside the range).
//! - *constant segments*: alone, each moving axis's grid is one segment over its widened range, with
//!   segments of the held value added on the pivot's side until the stroke lies near the pivot (the
//!   group's check); an axis the effect does not move gets a zero grid (its table's stroke, if it has
//!   a table, else one count at the pivot). A moving axis with a positioning table of its own is
//!   refused: both would correct its positioning.
//! - *summed*: with a `fit geometry` model, the effect is added to its `EXa`, `EYa`, `EZa` on the
//!   model's grids (exact there: a cubic is a cubic on every segment), which must cover the measured
//!   range (else refused rather than cut). The sum is right when the R-test was measured with that
//!   model's compensation active; `image group` says so.

use axcomp_core::Compensator;
use axcomp_core::geometric::{COMPONENT_NAMES, FUNCTIONS_PER_AXIS, GeometricGrid};
use axcomp_core::group::AxisName;
use axcomp_core::rotary::{RotaryLocationSpec, RotaryMachine};
use axcomp_rtest::effect_model::EffectModel;
use axcomp_rtest::effects::EffectBasis;

use crate::axis::GroupAxis;
use crate::geometric::GeometricSection;
use crate::{Error, Result};

/// The Legendre degree the section's cubic segments hold.
pub const MAX_LEGENDRE_DEGREE: usize = 3;

/// One moving linear axis's part of the effect.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearAxisError {
    /// 0 = X, 1 = Y, 2 = Z.
    pub axis: usize,
    /// The measured range of `q`, mm.
    pub range_mm: [f64; 2],
    /// Per degree k = 1…, the coefficients of `P_k` along X, Y, Z (µm of `d`).
    pub legendre: Vec<[f64; 3]>,
    /// Per direction X, Y, Z: some parameter of it is identified.
    pub identified: [bool; 3],
}

impl LinearAxisError {
    /// Power-basis coefficients in the normalised position x ∈ −1…1 of the tool point's error
    /// `e = −d` along direction `c`.
    fn power(&self, c: usize) -> [f64; 4] {
        const P: [[f64; 4]; 3] = [
            [0.0, 1.0, 0.0, 0.0],
            [-0.5, 0.0, 1.5, 0.0],
            [0.0, -1.5, 0.0, 2.5],
        ];
        let mut out = [0.0; 4];
        for (k, l) in self.legendre.iter().enumerate() {
            for (o, p) in out.iter_mut().zip(P[k]) {
                *o -= l[c] * p;
            }
        }
        out
    }

    /// The normalised position x of `q` mm.
    fn x_of(&self, q: f64) -> f64 {
        let [lo, hi] = self.range_mm;
        2.0 * (q - lo) / (hi - lo) - 1.0
    }

    /// The tool point's error e (µm, along X, Y, Z) at `q` mm, the cubic continued beyond the range.
    pub fn error_um(&self, q: f64) -> [f64; 3] {
        let x = self.x_of(q);
        [0, 1, 2].map(|c| {
            let p = self.power(c);
            p[0] + x * (p[1] + x * (p[2] + x * p[3]))
        })
    }
}

/// The effect `linear_geometry` of a model, per moving axis; `kind` names it in messages.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearGeometry {
    pub axes: Vec<LinearAxisError>,
    /// RMS of the correction over the fitted poses, µm (the model file's).
    pub rms_over_fit_um: f64,
}

/// The effect's parameters by axis (names `X_P{k}_d{x,y,z}`). Refused: a degree the section's cubics
/// cannot hold, a range that is empty or not finite, a missing or non-finite parameter.
pub fn linear_geometry_of(e: &EffectModel) -> Result<LinearGeometry> {
    let EffectBasis::Linear {
        axes,
        degree,
        range_mm,
    } = &e.basis
    else {
        bail!("effect `{}`: not a linear-geometry basis", e.kind);
    };
    ensure!(
        *degree <= MAX_LEGENDRE_DEGREE && axes.len() == range_mm.len(),
        "effect `{}`: Legendre degree {degree} over {} axes with {} ranges; the geometric section \
         holds cubics (degree ≤ {MAX_LEGENDRE_DEGREE}), one range per axis",
        e.kind,
        axes.len(),
        range_mm.len()
    );
    let mut out = Vec::new();
    for (&a, &r) in axes.iter().zip(range_mm) {
        let letter = ["X", "Y", "Z"].get(a).copied().ok_or_else(|| {
            Error::Invalid(format!(
                "effect `{}`: axis index {a} is not X, Y or Z",
                e.kind
            ))
        })?;
        ensure!(
            r.iter().all(|v| v.is_finite()) && r[1] > r[0],
            "effect `{}`: axis {letter}'s range {r:?} mm is not an interval",
            e.kind
        );
        let mut legendre = Vec::new();
        let mut identified = [false; 3];
        for k in 1..=*degree {
            let mut row = [0.0; 3];
            for (c, comp) in ["dx", "dy", "dz"].into_iter().enumerate() {
                let name = format!("{letter}_P{k}_{comp}");
                let p = e
                    .parameters
                    .iter()
                    .find(|(n, _)| *n == name)
                    .map(|(_, p)| p)
                    .filter(|p| p.value.is_finite())
                    .ok_or_else(|| {
                        Error::Invalid(format!(
                            "effect `{}`: parameter `{name}` missing or not a number",
                            e.kind
                        ))
                    })?;
                row[c] = p.value;
                identified[c] |= p.identified;
            }
            legendre.push(row);
        }
        out.push(LinearAxisError {
            axis: a,
            range_mm: r,
            legendre,
            identified,
        });
    }
    Ok(LinearGeometry {
        axes: out,
        rms_over_fit_um: e.rms_over_fit_um,
    })
}

/// Where the rotary section puts the linear axes: the pivot (counts of X, Y, Z) and, for a trunnion,
/// the tool length in whole counts of Z (the rotary stage's `tool_counts_z`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    pub pivot_counts: [i64; 3],
    pub tool_counts_z: i64,
}

impl Placement {
    /// The placement of the rotary section `spec` with the Z axis's image in `axes` (its µm per count,
    /// f32 as the core reads it, for a trunnion's tool length in whole counts).
    pub fn of(spec: &RotaryLocationSpec, axes: &[GroupAxis]) -> Result<Placement> {
        let tool_counts_z = if spec.machine == RotaryMachine::BcHead {
            0
        } else {
            let z = axes.iter().find(|a| a.name == AxisName::Z).ok_or_else(|| {
                Error::Invalid("the rotary model needs axis Z in the group".into())
            })?;
            let mut comp = Box::new(Compensator::IDENTITY);
            comp.load(&z.image)
                .map_err(|e| Error::core("axis Z: image does not load", e))?;
            // As the rotary stage folds it (a loaded image's scale is > 0).
            (spec.tool_length_um as f64 / comp.um_per_count() as f64).round() as i64
        };
        Ok(Placement {
            pivot_counts: spec.pivot_counts,
            tool_counts_z,
        })
    }

    /// The counts of axis `a` at `q` mm with `upc` µm per count (not rounded).
    fn counts(&self, a: usize, q: f64, upc: f64) -> f64 {
        let tool = if a == 2 { self.tool_counts_z } else { 0 };
        (self.pivot_counts[a] + tool) as f64 + q * 1000.0 / upc
    }
}

/// The stroke (start, end counts) of each of X, Y, Z's positioning tables, if it has one.
pub type TableStrokes = [Option<(i64, i64)>; 3];

/// X, Y, Z's µm per count (the f32's shortest decimal, the scale meant) and the stroke of each one's
/// positioning table, if it has one.
pub fn linear_scales(axes: &[GroupAxis], label: &str) -> Result<([f64; 3], TableStrokes)> {
    let mut upc = [0.0f64; 3];
    let mut tables = [None; 3];
    for (k, name) in [AxisName::X, AxisName::Y, AxisName::Z]
        .into_iter()
        .enumerate()
    {
        let Some(axis) = axes.iter().find(|a| a.name == name) else {
            bail!(
                "{label}: the geometric stage needs axis {} in the group (--axis {}=IMAGE)",
                name.letter(),
                name.letter()
            );
        };
        let mut comp = Box::new(Compensator::IDENTITY);
        comp.load(&axis.image)
            .map_err(|e| Error::core(format!("axis {}: image does not load", name.letter()), e))?;
        upc[k] = comp
            .um_per_count()
            .to_string()
            .parse::<f64>()
            .unwrap_or(comp.um_per_count() as f64);
        if comp.has_table() {
            let n = comp.forward_segments().len() as i64;
            let start = comp.table_start_counts();
            tables[k] = Some((start, start + n * comp.segment_counts() as i64));
        }
    }
    Ok((upc, tables))
}

/// A zero geometric section for `lin` alone: per moving axis one segment over its measured range
/// (whole counts, widened outward), constant segments added towards the pivot (see the glossary).
/// Refused: a moving axis with its own positioning table (both would correct its positioning).
fn zero_section(
    lin: &LinearGeometry,
    place: &Placement,
    upc: [f64; 3],
    tables: TableStrokes,
    label: &str,
) -> Result<GeometricSection> {
    let mut grids = [GeometricGrid {
        start_counts: 0,
        segment_counts: 1,
        n_segments: 1,
    }; 3];
    for (a, grid) in grids.iter_mut().enumerate() {
        let letter = "XYZ".as_bytes()[a] as char;
        let p = place.pivot_counts[a];
        let Some(e) = lin.axes.iter().find(|e| e.axis == a) else {
            let (lo, hi) = tables[a].unwrap_or((p, p + 1));
            *grid = GeometricGrid {
                start_counts: lo,
                segment_counts: u32::try_from(hi - lo).unwrap_or(u32::MAX).max(1),
                n_segments: 1,
            };
            continue;
        };
        ensure!(
            tables[a].is_none(),
            "{label}: axis {letter}'s image has a positioning table and the model's \
             `linear_geometry` corrects {letter}'s positioning too (E{letter}{letter}): build axis \
             {letter} with `image build --identity` to keep the model's, or fit without \
             `--effects linear_geometry` to keep the table"
        );
        let lo = place.counts(a, e.range_mm[0], upc[a]).floor() as i64;
        let hi = place.counts(a, e.range_mm[1], upc[a]).ceil() as i64;
        let h = u32::try_from((hi - lo).max(1)).map_err(|_| {
            Error::Invalid(format!(
                "{label}: axis {letter}'s range spans more than 2^32 counts"
            ))
        })?;
        let (mut before, mut after) = (0i64, 0i64);
        loop {
            let n = 1 + before + after;
            let (start, end) = (lo - before * h as i64, hi + after * h as i64);
            let w = end - start;
            if p >= start - w && p <= end + w {
                break;
            }
            ensure!(
                n < axcomp_core::geometric::MAX_GEOMETRIC_SEGMENTS as i64,
                "{label}: axis {letter}'s measured range ({:.3} .. {:.3} mm) lies too far from the \
                 pivot ({p} counts) for the group's stroke check",
                e.range_mm[0],
                e.range_mm[1]
            );
            if p < start {
                before += 1;
            } else {
                after += 1;
            }
        }
        *grid = GeometricGrid {
            start_counts: lo - before * h as i64,
            segment_counts: h,
            n_segments: (1 + before + after) as u32,
        };
    }
    let n: usize = grids.iter().map(|g| g.n_segments as usize).sum();
    Ok(GeometricSection {
        chain: [0, 1, 2],
        work_axes: 0,
        identified: 0,
        tool_offset_um: [0.0; 3],
        squareness_urad: [0.0; 3],
        grids,
        coefficients: vec![[0.0; 4]; n * FUNCTIONS_PER_AXIS],
    })
}

/// Horner coefficients in t ∈ [0, 1) of the power polynomial `p` in x at x = x0 + beta·t.
fn shifted(p: [f64; 4], x0: f64, beta: f64) -> [f64; 4] {
    const BINOM: [[f64; 4]; 4] = [
        [1.0, 0.0, 0.0, 0.0],
        [1.0, 1.0, 0.0, 0.0],
        [1.0, 2.0, 1.0, 0.0],
        [1.0, 3.0, 3.0, 1.0],
    ];
    std::array::from_fn(|n| {
        let s: f64 = (n..4)
            .map(|j| p[j] * BINOM[j][n] * x0.powi((j - n) as i32))
            .sum();
        s * beta.powi(n as i32)
    })
}

/// Adds `lin` to `g`'s translational functions on `g`'s grids (see the glossary) and sets the
/// identified bits of the components it carries; returns one sentence per axis on the range widened.
/// Refused: a grid that does not cover an axis's measured range.
fn add_to_section(
    g: &mut GeometricSection,
    lin: &LinearGeometry,
    place: &Placement,
    upc: [f64; 3],
    label: &str,
) -> Result<Vec<String>> {
    let mut said = Vec::new();
    for e in &lin.axes {
        let a = e.axis;
        let letter = "XYZ".as_bytes()[a] as char;
        let grid = g.grids[a];
        let h = grid.segment_counts as f64;
        let (c_lo, c_hi) = (
            place.counts(a, e.range_mm[0], upc[a]),
            place.counts(a, e.range_mm[1], upc[a]),
        );
        let pos = |c: f64| (c - grid.start_counts as f64) / h;
        let (s_lo, s_hi) = (pos(c_lo).floor(), pos(c_hi).ceil());
        ensure!(
            s_lo >= 0.0 && s_hi <= grid.n_segments as f64,
            "{label}: the model's `linear_geometry` of axis {letter} is measured over {:.3} .. \
             {:.3} mm ({c_lo:.0} .. {c_hi:.0} counts), beyond the geometric grid's {} .. {} counts \
             (the stage would hold it within its measured range): refusing rather than cutting it",
            e.range_mm[0],
            e.range_mm[1],
            grid.start_counts,
            grid.end_counts()
        );
        let (s_lo, s_hi) = (s_lo as usize, s_hi as usize);
        let q_of = |s: usize| {
            let c = grid.start_counts as f64 + s as f64 * h;
            let tool = if a == 2 { place.tool_counts_z } else { 0 };
            (c - (place.pivot_counts[a] + tool) as f64) * upc[a] / 1000.0
        };
        let beta = 2.0 * h * upc[a] / 1000.0 / (e.range_mm[1] - e.range_mm[0]);
        let before: usize = g.grids[..a].iter().map(|gr| gr.n_segments as usize).sum();
        for s in 0..grid.n_segments as usize {
            let at = s.clamp(s_lo, s_hi);
            let x0 = e.x_of(q_of(at));
            for c in 0..3 {
                let p = e.power(c);
                let horner = if s < s_lo || s >= s_hi {
                    [p[0] + x0 * (p[1] + x0 * (p[2] + x0 * p[3])), 0.0, 0.0, 0.0]
                } else {
                    shifted(p, x0, beta)
                };
                let dst = &mut g.coefficients[(before + s) * FUNCTIONS_PER_AXIS + c];
                for (d, v) in dst.iter_mut().zip(horner) {
                    *d = (*d as f64 + v) as f32;
                }
            }
        }
        for c in 0..3 {
            if e.identified[c] {
                g.identified |= 1 << (6 * a + c);
            }
        }
        let carried: Vec<&str> = (0..3).map(|c| COMPONENT_NAMES[6 * a + c]).collect();
        let [lo, hi] = e.range_mm;
        let (k_lo, k_hi) = (q_of(s_lo), q_of(s_hi));
        let widened = if (k_lo - lo).abs() < 5e-4 && (k_hi - hi).abs() < 5e-4 {
            String::new()
        } else {
            format!(", the cubic continued to the grid's knots at {k_lo:.3} .. {k_hi:.3} mm")
        };
        said.push(format!(
            "axis {letter}: {} over the measured {lo:.3} .. {hi:.3} mm{widened}, held beyond",
            carried.join(", "),
        ));
    }
    Ok(said)
}

/// The geometric section of a group carrying `lin` (a `fit rtest` model's `linear_geometry`, named
/// `label` in messages): added to `base` (a `fit geometry` model's section, on its grids) if given,
/// else alone on grids of its own (see the glossary). Returns the section and one sentence per axis.
pub fn with_linear_geometry(
    lin: &LinearGeometry,
    place: &Placement,
    axes: &[GroupAxis],
    base: Option<GeometricSection>,
    label: &str,
) -> Result<(GeometricSection, Vec<String>)> {
    let (upc, tables) = linear_scales(axes, label)?;
    let mut g = match base {
        Some(g) => g,
        None => zero_section(lin, place, upc, tables, label)?,
    };
    let said = add_to_section(&mut g, lin, place, upc, label)?;
    g.spec()
        .validate()
        .map_err(|e| Error::Invalid(format!("{label}: the linear geometry's section: {e}")))?;
    Ok((g, said))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The section's translational functions (X, Y, Z of axis `a`) at `counts`, clamped to the grid.
    fn translation_at(g: &GeometricSection, a: usize, counts: f64) -> [f64; 3] {
        let spec = g.spec();
        let gr = g.grids[a];
        let r = ((counts - gr.start_counts as f64) / gr.segment_counts as f64)
            .clamp(0.0, gr.n_segments as f64);
        let s = (r.floor() as usize).min(gr.n_segments as usize - 1);
        let t = (r - s as f64) as f32;
        [0, 1, 2].map(|c| {
            let p = spec.segment(a, s, c);
            (p[0] + t * (p[1] + t * (p[2] + t * p[3]))) as f64
        })
    }

    /// Added to a `fit geometry` section (grids of 10 segments over ±250 mm, every function 1 µm
    /// constant): on the grid the sum is the base's 1 µm plus e inside the measured range (1e-4 µm, as
    /// above), beyond the knots enclosing it the base plus the held end value; angular functions and
    /// identified bits of the base untouched. A grid short of the measured range is refused.
    #[test]
    fn added_to_a_geometry_model_on_its_grid() {
        let e = LinearAxisError {
            axis: 1,
            range_mm: [-101.37, 77.2],
            legendre: vec![[1.0, 2.0, -3.0], [0.5, -0.5, 0.2], [0.3, 0.1, -0.2]],
            identified: [true; 3],
        };
        let lin = LinearGeometry {
            axes: vec![e.clone()],
            rms_over_fit_um: 1.0,
        };
        let place = Placement {
            pivot_counts: [0; 3],
            tool_counts_z: 0,
        };
        let upc = [0.1; 3];
        let grid = GeometricGrid {
            start_counts: -2_500_000,
            segment_counts: 500_000,
            n_segments: 10,
        };
        let base = GeometricSection {
            chain: [0, 1, 2],
            work_axes: 1,
            identified: 1 << 9,
            tool_offset_um: [0.0; 3],
            squareness_urad: [0.0; 3],
            grids: [grid; 3],
            coefficients: vec![[1.0, 0.0, 0.0, 0.0]; 30 * FUNCTIONS_PER_AXIS],
        };
        let mut g = base.clone();
        let said = add_to_section(&mut g, &lin, &place, upc, "t").unwrap();
        assert!(
            said[0].contains("knots at -150.000 .. 100.000 mm"),
            "{said:?}"
        );
        assert_eq!(g.identified, 1 << 9 | 0b111 << 6);
        for i in -15..=15 {
            let q = 250.0 * i as f64 / 15.0;
            let got = translation_at(&g, 1, q * 1e4);
            let want = e.error_um(q.clamp(-150.0, 100.0));
            for c in 0..3 {
                assert!(
                    (got[c] - 1.0 - want[c]).abs() < 1e-4,
                    "{q} {c}: {got:?} {want:?}"
                );
            }
        }
        assert!((0..10).all(|s| g.spec().segment(1, s, 3) == [1.0, 0.0, 0.0, 0.0]));
        let mut short = base.clone();
        short.grids[1].n_segments = 4;
        short.coefficients.truncate(24 * FUNCTIONS_PER_AXIS);
        let err = add_to_section(&mut short, &lin, &place, upc, "t")
            .unwrap_err()
            .to_string();
        assert!(err.contains("beyond the geometric grid"), "{err}");
    }

    /// The section's segments reproduce e = −d of a cubic over the measured range (values at 0.1 of
    /// the range's width apart, within 1e-4 µm: f32 Horner coefficients of a ≤ 20 µm cubic) and hold
    /// the end values beyond it; the Y axis (not moved) is zero; the trunnion's tool counts shift Z.
    #[test]
    fn section_follows_the_cubic_and_holds_beyond() {
        let lin = LinearGeometry {
            axes: vec![
                LinearAxisError {
                    axis: 0,
                    range_mm: [-123.4567, 201.3],
                    legendre: vec![[4.0, -1.0, 0.5], [2.0, 3.0, -0.7], [-1.5, 0.2, 1.1]],
                    identified: [true; 3],
                },
                LinearAxisError {
                    axis: 2,
                    range_mm: [-60.2, 80.9],
                    legendre: vec![[0.1, 0.2, 2.0], [0.0, 0.0, -1.0], [0.3, 0.0, 0.4]],
                    identified: [true, false, true],
                },
            ],
            rms_over_fit_um: 1.0,
        };
        let place = Placement {
            pivot_counts: [1_000_000, -2_000_000, 3_000_000],
            tool_counts_z: 1_000_000,
        };
        let upc = [0.1; 3];
        let mut g = zero_section(&lin, &place, upc, [None; 3], "t").unwrap();
        add_to_section(&mut g, &lin, &place, upc, "t").unwrap();
        assert_eq!(g.identified, 0b111 | 0b101 << 12);
        let spec = g.spec();
        spec.validate().unwrap();
        let eval = |a: usize, counts: f64| translation_at(&g, a, counts);
        for e in &lin.axes {
            let [lo, hi] = e.range_mm;
            for i in -3..=13 {
                let q = lo + (hi - lo) * i as f64 / 10.0;
                let want = e.error_um(q.clamp(lo, hi));
                let got = eval(e.axis, place.counts(e.axis, q, upc[e.axis]));
                for c in 0..3 {
                    // Beyond the range the held value is that at the widened end (< 1 count off).
                    assert!(
                        (got[c] - want[c]).abs() < 1e-4,
                        "{} {q} {c}: {got:?} {want:?}",
                        e.axis
                    );
                }
            }
        }
        assert!(
            (0..g.grids[1].n_segments as usize)
                .all(|s| (0..6).all(|f| spec.segment(1, s, f) == [0.0; 4]))
        );
        // An axis the effect moves with a positioning table of its own: refused (both would correct
        // its positioning); a table on an axis it does not move gives that axis's zero grid.
        let table = Some((-5_000_000, 5_000_000));
        let err = zero_section(&lin, &place, upc, [table, None, None], "t").unwrap_err();
        assert!(
            err.to_string()
                .contains("axis X's image has a positioning table"),
            "{err}"
        );
        let z = zero_section(&lin, &place, upc, [None, table, None], "t").unwrap();
        assert_eq!(
            (z.grids[1].start_counts, z.grids[1].segment_counts),
            (-5_000_000, 10_000_000)
        );
    }
}
