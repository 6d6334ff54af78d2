//! What a group image carries of a `fit rtest --effects` model's effects, and what it leaves out.
//! (Applied by three stages: the rotary axes' own tables, the rotary section, the geometric section.)
//!
//! Glossary:
//! - *angle error*: the `rotary_positioning` effect of one rotary axis, actual minus commanded angle
//!   (µrad): for C `C_offset + Σ_k (C_cos{k} cos kc + C_sin{k} sin kc)`, for the tilt axis T
//!   `Σ_d T_t{d} t^d` (t in rad, signed) (`axcomp_rtest::effects`).
//! - *angle table*: a rotary axis's own positioning table in its axis image: the firmware's per-axis
//!   pipeline looks it up at the axis's turn position (counts in `[0, counts per revolution)`) and
//!   subtracts it from that axis's command, as it does a linear axis's table. Its values are the angle
//!   error in the axis image's units (`um_per_count` per count: arc-seconds at the host tools'
//!   convention), [`ANGLE_TABLE_SEGMENTS`] cubic Hermite segments over the turn through the angle
//!   error's values and slopes at the knots. The tilt axis's polynomial is taken in the signed angle
//!   (−180°..180°): the segment holding 180° is continued from its start (a tilt axis does not turn
//!   there).
//! - *wobble*: the `rotary_wobble` effect (a tilt of what an axis carries and its radial motion,
//!   varying with its angle): carried by the rotary section ([`axcomp_core::rotary::RotaryWobble`]: C's
//!   harmonics 1…4 per turn, the tilt axis's powers 1…3 of its angle), the stage adds it to the
//!   location errors; harmonics above 4 per turn are left out (and said).
//! - *linear geometry*: the `linear_geometry` effect (errors of the tool point along X, Y, Z varying
//!   with the linear axes' positions, Legendre degree ≤ 3 over the measured range): carried by the
//!   geometric section as its translational components (`crate::linear_geometry`: one cubic per
//!   segment, held beyond the measured range as the stage holds every grid's ends; added to a
//!   `--geometry` model's on its grid); a degree above 3 is refused.
//! - *left out*: C's wobble harmonics above 4 per turn (said, with the effect named); every other
//!   part of the three modelled effects is carried.

use std::f64::consts::TAU;

use axcomp_core::group::AxisName;
use axcomp_core::rotary::{RotaryWobble, WOBBLE_HARMONICS, WOBBLE_TILT_DEGREE};
use axcomp_core::{
    Compensator, ImageSpec, OutsideStroke, TableSpec, image_len, inspect_image, write_image,
};
use axcomp_numeric::hermite::cubic_hermite;
use axcomp_rtest::RtestModel;
use axcomp_rtest::effects::EffectBasis;

use crate::axis::GroupAxis;
use crate::linear_geometry::{LinearGeometry, linear_geometry_of};
use crate::{Error, Result};

/// Segments of an angle table over one turn (cubic Hermite; the C harmonics of `fit rtest` reach 8 per
/// turn: 16 segments per period).
pub const ANGLE_TABLE_SEGMENTS: u32 = 128;

/// One rotary axis's angle error (µrad) as a function of its angle (rad).
#[derive(Debug, Clone, PartialEq)]
pub enum AngleError {
    /// C: offset, then `(cos k, sin k)` coefficients for k = 1, 2, ...
    Harmonics {
        offset: f64,
        cos_sin: Vec<(f64, f64)>,
    },
    /// The tilt axis: coefficients of `t^d`, d = 0, 1, ...
    Polynomial(Vec<f64>),
}

impl AngleError {
    /// The error (µrad) and its slope (µrad per rad) at angle `a` (rad).
    pub fn value_and_slope(&self, a: f64) -> (f64, f64) {
        match self {
            AngleError::Harmonics { offset, cos_sin } => {
                let mut v = *offset;
                let mut s = 0.0;
                for (k, (c, d)) in cos_sin.iter().enumerate() {
                    let k = (k + 1) as f64;
                    let (sin, cos) = (k * a).sin_cos();
                    v += c * cos + d * sin;
                    s += k * (d * cos - c * sin);
                }
                (v, s)
            }
            AngleError::Polynomial(g) => {
                let (mut v, mut s) = (0.0, 0.0);
                for (d, gd) in g.iter().enumerate() {
                    v += gd * a.powi(d as i32);
                    if d > 0 {
                        s += d as f64 * gd * a.powi(d as i32 - 1);
                    }
                }
                (v, s)
            }
        }
    }

    /// True when every coefficient is zero (no table needed).
    pub fn is_zero(&self) -> bool {
        match self {
            AngleError::Harmonics { offset, cos_sin } => {
                *offset == 0.0 && cos_sin.iter().all(|&(c, s)| c == 0.0 && s == 0.0)
            }
            AngleError::Polynomial(g) => g.iter().all(|&v| v == 0.0),
        }
    }
}

/// What a group image makes of a model's effects: each rotary axis's angle error (carried as its
/// angle table), and a sentence for each part carried and each part left out.
#[derive(Debug, Clone, Default)]
pub struct EffectsInImage {
    pub angle_errors: Vec<(AxisName, AngleError)>,
    /// The `rotary_wobble` effect for the rotary section, if the model has one.
    pub wobble: Option<RotaryWobble>,
    /// The `linear_geometry` effect for the geometric section, if the model has one.
    pub linear: Option<LinearGeometry>,
    pub carried: Vec<String>,
    pub left_out: Vec<String>,
}

/// The model's effects sorted into what the group image carries (`rotary_positioning`: the C and
/// tilt axes' angle tables; `rotary_wobble`: the rotary section; `linear_geometry`: the geometric
/// section) and what it leaves out (see the module glossary).
pub fn effects_in_image(model: &RtestModel) -> Result<EffectsInImage> {
    let tilt = match model.machine.tilt_letter() {
        'a' => AxisName::A,
        _ => AxisName::B,
    };
    let mut out = EffectsInImage::default();
    for e in &model.effects {
        let value = |name: &str| -> Result<f64> {
            e.parameters
                .iter()
                .find(|(n, _)| n == name)
                .map(|(_, p)| p.value)
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    Error::Invalid(format!(
                        "effect `{}`: parameter `{name}` missing or not a number",
                        e.kind
                    ))
                })
        };
        match &e.basis {
            EffectBasis::Positioning {
                c_harmonics,
                tilt_degree,
            } => {
                let c = AngleError::Harmonics {
                    offset: value("C_offset")?,
                    cos_sin: (1..=*c_harmonics)
                        .map(|k| Ok((value(&format!("C_cos{k}"))?, value(&format!("C_sin{k}"))?)))
                        .collect::<Result<_>>()?,
                };
                let t = tilt.letter();
                let g = (0..=*tilt_degree)
                    .map(|d| value(&format!("{t}_t{d}")))
                    .collect::<Result<Vec<_>>>()?;
                out.carried.push(format!(
                    "the model's effect `{}` ({} parameters; RMS {:.3} µm over the fitted poses) is carried \
                     as the angle tables of axes C and {t} ({ANGLE_TABLE_SEGMENTS} segments over the turn, \
                     in each axis's own image)",
                    e.kind,
                    e.parameters.len(),
                    e.rms_over_fit_um
                ));
                out.angle_errors.push((AxisName::C, c));
                out.angle_errors.push((tilt, AngleError::Polynomial(g)));
            }
            EffectBasis::Wobble {
                per_revolution,
                tilt_degree,
            } => {
                let (w, beyond) = wobble(*tilt_degree, per_revolution, tilt.letter(), &value)?;
                out.carried.push(format!(
                    "the model's effect `{}` ({} parameters; RMS {:.3} µm over the fitted poses) is carried \
                     by the rotary section (its wobble: C at {:?} per turn, {} to degree {tilt_degree}), \
                     applied by the rotary stage with the location errors",
                    e.kind,
                    e.parameters.len(),
                    e.rms_over_fit_um,
                    per_revolution
                        .iter()
                        .filter(|&&k| k <= WOBBLE_HARMONICS)
                        .collect::<Vec<_>>(),
                    tilt.letter()
                ));
                if !beyond.is_empty() {
                    out.left_out.push(format!(
                        "the model's effect `{}`: C's wobble at {beyond:?} per turn is not carried (the \
                         rotary stage holds 1…{WOBBLE_HARMONICS} per turn); its correction is left out",
                        e.kind
                    ));
                }
                out.wobble = Some(w);
            }
            EffectBasis::Linear { axes, degree, .. } => {
                out.carried.push(format!(
                    "the model's effect `{}` ({} parameters; RMS {:.3} µm over the fitted poses) is carried \
                     by the geometric section (the translational components of axes {}: positioning and \
                     straightness, Legendre degree 1…{degree} as one cubic per segment), applied by the \
                     geometric stage at the commanded X, Y, Z",
                    e.kind,
                    e.parameters.len(),
                    e.rms_over_fit_um,
                    axes.iter()
                        .filter_map(|&a| ["X", "Y", "Z"].get(a).copied())
                        .collect::<Vec<_>>()
                        .join(", ")
                ));
                out.linear = Some(linear_geometry_of(e)?);
            }
        }
    }
    Ok(out)
}

/// The rotary section's wobble from a `rotary_wobble` effect's parameters (`value` by name, the names of
/// `axcomp_rtest::effects::EffectTerm::param_names`), and the listed C harmonics it cannot hold (above
/// [`WOBBLE_HARMONICS`]). Refused: a tilt degree above [`WOBBLE_TILT_DEGREE`].
fn wobble(
    tilt_degree: usize,
    per_revolution: &[usize],
    tilt: char,
    value: &dyn Fn(&str) -> Result<f64>,
) -> Result<(RotaryWobble, Vec<usize>)> {
    ensure!(
        tilt_degree <= WOBBLE_TILT_DEGREE,
        "effect `rotary_wobble`: tilt degree {tilt_degree}, the rotary stage holds 1…{WOBBLE_TILT_DEGREE}"
    );
    let mut w = RotaryWobble::NONE;
    let mut beyond = Vec::new();
    for &k in per_revolution {
        let Some(row) = k.checked_sub(1).and_then(|i| w.c.get_mut(i)) else {
            beyond.push(k);
            continue;
        };
        let mut i = 0;
        for trig in ["cos", "sin"] {
            for ax in ['x', 'y'] {
                row[i] = value(&format!("C_tilt_{ax}_{trig}{k}"))? as f32;
                row[i + 1] = value(&format!("C_radial_{ax}_{trig}{k}"))? as f32;
                i += 2;
            }
        }
    }
    let perpendicular = if tilt == 'A' { ['y', 'z'] } else { ['x', 'z'] };
    for (d, row) in w.tilt.iter_mut().enumerate().take(tilt_degree) {
        let d = d + 1;
        for (j, ax) in perpendicular.into_iter().enumerate() {
            row[2 * j] = value(&format!("{tilt}_tilt_{ax}_t{d}"))? as f32;
            row[2 * j + 1] = value(&format!("{tilt}_radial_{ax}_t{d}"))? as f32;
        }
    }
    w.validate().map_err(|e| {
        Error::core(
            "effect `rotary_wobble`: not within the rotary stage's range",
            e,
        )
    })?;
    Ok((w, beyond))
}

/// Cubic Hermite segments `[c0, c1, c2, c3]` in t ∈ [0, 1) through `f`'s values and slopes (slope per
/// segment length) at the ends of each of `n` segments of length `h` from `x0`.
fn hermite_segments(n: usize, x0: f64, h: f64, f: impl Fn(f64) -> (f64, f64)) -> Vec<[f32; 4]> {
    (0..n)
        .map(|k| {
            let a = x0 + k as f64 * h;
            let ((y0, s0), (y1, s1)) = (f(a), f(a + h));
            cubic_hermite(y0, s0 * h, y1, s1 * h).map(|c| c as f32)
        })
        .collect()
}

/// `axis`'s image with the angle table of `error` (its header fields and limits kept). Refused: an axis
/// image that already has a table (both would correct the axis's angle) or a thermo-force term.
pub fn with_angle_table(axis: &GroupAxis, error: &AngleError, model: &str) -> Result<Vec<u8>> {
    let letter = axis.name.letter();
    let cpr = axis.counts_per_rev;
    ensure!(
        axis.name.is_rotary() && cpr > 0,
        "axis {letter}: an angle table needs a rotary axis with its counts per revolution"
    );
    let info =
        inspect_image(&axis.image).map_err(|e| Error::core(format!("axis {letter}: image"), e))?;
    let mut comp = Box::new(Compensator::IDENTITY);
    comp.load(&axis.image)
        .map_err(|e| Error::core(format!("axis {letter}: image does not load"), e))?;
    ensure!(
        !comp.has_table() && !info.has_thermo,
        "axis {letter}'s image (--axis {}) has its own {} and the rotary model's `rotary_positioning` \
         ({model}) would correct axis {letter}'s angle as its table too: build axis {letter} with \
         `image build --identity` to keep the model's",
        axis.given_as,
        if comp.has_table() {
            "positioning table"
        } else {
            "thermo-force term"
        }
    );
    let n = ANGLE_TABLE_SEGMENTS;
    let segment_counts = cpr.div_ceil(n);
    let h = segment_counts as f64 / cpr as f64 * TAU;
    // µrad → the image's units: counts of the turn, times its units per count.
    let units = 1e-6 * cpr as f64 / TAU * comp.um_per_count() as f64;
    let signed = matches!(error, AngleError::Polynomial(_));
    let forward: Vec<[f32; 4]> = (0..n as usize)
        .flat_map(|k| {
            // Each segment's angle continued from its start (the signed angle wraps at 180°).
            let mut a0 = k as f64 * h;
            if signed && a0 >= TAU / 2.0 {
                a0 -= TAU;
            }
            hermite_segments(1, a0, h, |a| {
                let (v, s) = error.value_and_slope(a);
                (v * units, s * units)
            })
        })
        .collect();
    let spec = ImageSpec {
        axis_id: info.axis_id,
        um_per_count: comp.um_per_count(),
        counter_bits: info.counter_bits,
        table: Some(TableSpec {
            start_counts: 0,
            segment_counts,
            forward: &forward,
            backward: &[],
            outside: OutsideStroke::Hold,
        }),
        thermo: None,
        limits: comp.limits(),
    };
    let mut buf = vec![0u8; image_len(&spec)];
    let len = write_image(&spec, &mut buf)
        .map_err(|e| Error::core(format!("axis {letter}: the angle table"), e))?;
    buf.truncate(len);
    Ok(buf)
}

/// `axes` with the angle tables of `errors` put into their rotary axes' images (an error that is zero
/// throughout changes nothing); `model` names the rotary model in messages.
pub fn put_angle_tables(
    axes: &mut [GroupAxis],
    errors: &[(AxisName, AngleError)],
    model: &str,
) -> Result<()> {
    for (name, error) in errors {
        if error.is_zero() {
            continue;
        }
        let axis = axes.iter_mut().find(|a| a.name == *name).ok_or_else(|| {
            Error::Invalid(format!(
                "{model}: the model's `rotary_positioning` needs axis {} in the group",
                name.letter()
            ))
        })?;
        axis.image = with_angle_table(axis, error, model)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Hermite table reproduces a C error of 1× and 8× per turn at points between the knots within
    /// 1e-4 of its amplitude (Hermite interpolation error h⁴/384·max|f⁗|: (8·2π/128)⁴/384 ≈ 6e-5), and a
    /// tilt polynomial across 0 (negative angles at turn positions above 180°).
    #[test]
    fn angle_table_follows_the_error() {
        let c = AngleError::Harmonics {
            offset: 1.0,
            cos_sin: vec![
                (5.0, -3.0),
                (0.0, 0.0),
                (0.0, 0.0),
                (0.0, 0.0),
                (0.0, 0.0),
                (0.0, 0.0),
                (0.0, 0.0),
                (2.0, 1.0),
            ],
        };
        let t = AngleError::Polynomial(vec![0.5, 4.0, -2.0]);
        let cpr = 3_600_000u32;
        for (err, amp) in [(&c, 11.0), (&t, 10.0)] {
            let seg = cpr.div_ceil(ANGLE_TABLE_SEGMENTS);
            let h = seg as f64 / cpr as f64 * TAU;
            let signed = matches!(err, AngleError::Polynomial(_));
            for k in 0..ANGLE_TABLE_SEGMENTS as usize {
                let mut a0 = k as f64 * h;
                if signed && a0 >= TAU / 2.0 {
                    a0 -= TAU;
                }
                if signed && (a0 + h).abs() > 2.5 {
                    continue; // beyond a tilt axis's travel: the polynomial is large there.
                }
                let s = hermite_segments(1, a0, h, |a| err.value_and_slope(a))[0];
                for u in [0.0f32, 0.3, 0.5, 0.9] {
                    let got = s[0] + u * (s[1] + u * (s[2] + u * s[3]));
                    let want = err.value_and_slope(a0 + u as f64 * h).0;
                    assert!(
                        (got as f64 - want).abs() < 1e-4 * amp,
                        "{k} {u}: {got} vs {want}"
                    );
                }
            }
        }
    }
}
