//! The rotary location-error model as an image carries it: the machine kind ([`RotaryMachine`]) and
//! the constants with their ranges ([`RotaryLocationSpec`]). Below the group image parser and the
//! stage's runtime ([`crate::rotary`], which re-exports both and holds the glossary).

use crate::axis::AxisName;
use crate::error::{Field, ImageError};

/// The kinematic structure the stage corrects.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
#[repr(u8)]
pub enum RotaryMachine {
    /// C table on an A cradle (A about X).
    #[default]
    AcTrunnion = 1,
    /// C table on a B cradle (B about Y).
    BcTrunnion = 2,
    /// Spindle head: B (about Y) riding on C (about Z).
    BcHead = 3,
}

impl RotaryMachine {
    /// The code stored in the image.
    pub const fn code(self) -> u8 {
        self as u8
    }
    /// From an image code.
    pub const fn from_code(c: u8) -> Option<RotaryMachine> {
        match c {
            1 => Some(RotaryMachine::AcTrunnion),
            2 => Some(RotaryMachine::BcTrunnion),
            3 => Some(RotaryMachine::BcHead),
            _ => None,
        }
    }
    /// The contract's name (`ac-trunnion`, `bc-trunnion`, `bc-head`).
    pub const fn name(self) -> &'static str {
        match self {
            RotaryMachine::AcTrunnion => "ac-trunnion",
            RotaryMachine::BcTrunnion => "bc-trunnion",
            RotaryMachine::BcHead => "bc-head",
        }
    }
    /// The tilt axis: A or B.
    pub const fn tilt_axis(self) -> AxisName {
        match self {
            RotaryMachine::AcTrunnion => AxisName::A,
            _ => AxisName::B,
        }
    }
    /// ISO 230-7 names of [`RotaryLocationSpec::constants`], in order.
    pub const fn constant_names(self) -> [&'static str; 11] {
        let t = match self {
            RotaryMachine::AcTrunnion => ["EY0A", "EZ0A", "EB0A", "EC0A"],
            _ => ["EX0B", "EZ0B", "EA0B", "EC0B"],
        };
        [
            "EX0C", "EY0C", "EA0C", "EB0C", t[0], t[1], t[2], t[3], "EA0Z", "EB0Z", "EC0Y",
        ]
    }
}

/// The location errors of a five-axis machine's two rotary axes, the linear axes' squareness and
/// the geometry the stage needs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RotaryLocationSpec {
    /// Which kinematics (the meaning of the tilt-axis fields and of the tool tip).
    pub machine: RotaryMachine,
    /// C axis line offset in X, µm.
    pub ex0c_um: f32,
    /// C axis line offset in Y, µm.
    pub ey0c_um: f32,
    /// C axis line turned about X, µrad.
    pub ea0c_urad: f32,
    /// C axis line turned about Y, µrad.
    pub eb0c_urad: f32,
    /// A axis line offset in Y (B axis: EX0B, offset in X), µm.
    pub ey0a_um: f32,
    /// A axis line offset in Z (B axis: EZ0B), µm.
    pub ez0a_um: f32,
    /// A axis line turned about Y (B axis: EA0B, turned about X), µrad.
    pub eb0a_urad: f32,
    /// A axis line turned about Z (B axis: EC0B), µrad.
    pub ec0a_urad: f32,
    /// Squareness of the linear axes EA0Z, EB0Z, EC0Y, µrad.
    pub squareness_urad: [f32; 3],
    /// Machine position of the nominal intersection of the rotary axes (head: of the origin the
    /// head's pivot positions are measured from), counts of X, Y, Z.
    pub pivot_counts: [i64; 3],
    /// Trunnion: tool length (spindle gauge line to tool tip, along −Z); head: pivot to tool tip;
    /// µm.
    pub tool_length_um: f32,
    /// Provenance, not used by the stage: bit k set = constant k of
    /// [`RotaryLocationSpec::all_constants`] was not identified by the fit and holds its fixed
    /// prior (0).
    pub not_identified: u16,
    /// The rotary axes' wobble (all zero: none).
    pub wobble: RotaryWobble,
}

/// Harmonics of C's angle a wobble holds (k = 1..=4 per turn).
pub const WOBBLE_HARMONICS: usize = 4;
/// Powers of the tilt axis's angle a wobble holds (t^d, d = 1..=3).
pub const WOBBLE_TILT_DEGREE: usize = 3;
/// Largest |coefficient| of a wobble, µrad or µm (a first-order term, as the location errors).
pub const MAX_WOBBLE: f32 = 1.0e4;

/// The `rotary_wobble` effect of a `fit rtest` model: small rotations w and translations r of what
/// each rotary axis carries (trunnion: the table; head: the tool), varying with its angle, added
/// to the location errors (see [`crate::rotary`]'s glossary for the frames).
///
/// - C (in the frame the tilt axis carries for a trunnion, the machine frame for the head): per
///   harmonic k = 1..=[`WOBBLE_HARMONICS`] the tilt about X (µrad), radial motion along X (µm),
///   tilt about Y (µrad), radial motion along Y (µm), each times cos kc, then the same four times
///   sin kc: `c[k − 1]` = [wx_cos, rx_cos, wy_cos, ry_cos, wx_sin, rx_sin, wy_sin, ry_sin].
/// - the tilt axis (machine frame at zero angles for a trunnion, turned by C for the head): per
///   power d = 1..=[`WOBBLE_TILT_DEGREE`] of its signed angle t (rad, in (−π, π]) the tilt about
///   the axis ⟂ 1 (µrad), radial motion along it (µm), tilt about Z (µrad), radial motion along Z
///   (µm), each times t^d: `tilt[d − 1]`; ⟂ 1 is Y for A, X for B.
///
/// The names and order are those of the host's `axcomp_rtest::effects::EffectBasis::Wobble`
/// parameters (`C_tilt_x_cos1`, `C_radial_x_cos1`, …, `A_tilt_y_t1`, …).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
pub struct RotaryWobble {
    /// C's coefficients per harmonic (see the type's doc).
    pub c: [[f32; 8]; WOBBLE_HARMONICS],
    /// The tilt axis's coefficients per power (see the type's doc).
    pub tilt: [[f32; 4]; WOBBLE_TILT_DEGREE],
}

impl RotaryWobble {
    /// No wobble.
    pub const NONE: RotaryWobble = RotaryWobble {
        c: [[0.0; 8]; WOBBLE_HARMONICS],
        tilt: [[0.0; 4]; WOBBLE_TILT_DEGREE],
    };

    /// Every coefficient, C's then the tilt axis's (the order of the section and of the index of
    /// [`Field::RotaryWobble`]).
    pub fn coefficients(&self) -> impl Iterator<Item = f32> + '_ {
        self.c
            .as_flattened()
            .iter()
            .chain(self.tilt.as_flattened())
            .copied()
    }

    /// True when every coefficient is 0 (a non-finite one is not 0).
    pub fn is_none(&self) -> bool {
        self.scan() == Ok(false)
    }

    /// Every coefficient finite and within ±[`MAX_WOBBLE`].
    pub fn validate(&self) -> Result<(), ImageError> {
        self.scan().map(|_| ())
    }

    /// [`RotaryWobble::validate`], and whether a coefficient is non-zero.
    fn scan(&self) -> Result<bool, ImageError> {
        let c = scan_wobble(self.c.as_flattened(), 0)?;
        Ok(scan_wobble(self.tilt.as_flattened(), 8 * WOBBLE_HARMONICS as u16)? | c)
    }
}

/// [`RotaryWobble::scan`] of the coefficients `v`, the first of which has the index `first`
/// (out of line: load-time code, one copy): whether one is non-zero.
#[inline(never)]
fn scan_wobble(v: &[f32], first: u16) -> Result<bool, ImageError> {
    let mut any = false;
    for (i, &v) in v.iter().enumerate() {
        any |= v != 0.0;
        let index = first + i as u16;
        let field = Field::RotaryWobble;
        if !v.is_finite() {
            return Err(ImageError::NonFinite { field, index });
        }
        if libm::fabsf(v) > MAX_WOBBLE {
            return Err(ImageError::OutOfRange { field, index });
        }
    }
    Ok(any)
}

impl RotaryLocationSpec {
    /// An AC trunnion without errors, pivot at 0, no tool (a base for struct updates).
    pub const ZERO_AC: RotaryLocationSpec = RotaryLocationSpec {
        machine: RotaryMachine::AcTrunnion,
        ex0c_um: 0.0,
        ey0c_um: 0.0,
        ea0c_urad: 0.0,
        eb0c_urad: 0.0,
        ey0a_um: 0.0,
        ez0a_um: 0.0,
        eb0a_urad: 0.0,
        ec0a_urad: 0.0,
        squareness_urad: [0.0; 3],
        pivot_counts: [0; 3],
        tool_length_um: 0.0,
        not_identified: 0,
        wobble: RotaryWobble::NONE,
    };

    /// The 8 location errors in the order of the fields (µm, µm, µrad, µrad, µm, µm, µrad, µrad).
    pub fn constants(&self) -> [f32; 8] {
        [
            self.ex0c_um,
            self.ey0c_um,
            self.ea0c_urad,
            self.eb0c_urad,
            self.ey0a_um,
            self.ez0a_um,
            self.eb0a_urad,
            self.ec0a_urad,
        ]
    }

    /// The 8 location errors and the 3 squareness terms, in the order of
    /// [`RotaryMachine::constant_names`].
    pub fn all_constants(&self) -> [f32; 11] {
        let c = self.constants();
        let s = self.squareness_urad;
        [
            c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], s[0], s[1], s[2],
        ]
    }

    /// True if a schema version-1 rotary section (AC trunnion, no squareness) holds it exactly.
    pub fn fits_version_1(&self) -> bool {
        self.machine == RotaryMachine::AcTrunnion
            && self.squareness_urad == [0.0; 3]
            && self.not_identified == 0
            && self.wobble.is_none()
    }

    /// Range checks: every constant finite, offsets ≤ 10 mm, angles ≤ 10 mrad (the model is
    /// first order), |pivot| ≤ 2^62 counts, tool length in [0, 10 m], `not_identified` naming
    /// constants only (and each of them 0), the wobble's coefficients
    /// ([`RotaryWobble::validate`]).
    pub fn validate(&self) -> Result<(), ImageError> {
        self.wobble.validate()?;
        if self.not_identified >> 11 != 0 {
            return Err(ImageError::OutOfRange {
                field: Field::Reserved,
                index: 0,
            });
        }
        for (i, v) in self.all_constants().into_iter().enumerate() {
            if self.not_identified >> i & 1 == 1 && v != 0.0 {
                return Err(ImageError::OutOfRange {
                    field: Field::RotaryLocation,
                    index: i as u16,
                });
            }
        }
        for (i, v) in self.all_constants().into_iter().enumerate() {
            if !v.is_finite() {
                return Err(ImageError::NonFinite {
                    field: Field::RotaryLocation,
                    index: i as u16,
                });
            }
            if libm::fabsf(v) > 1.0e4 {
                return Err(ImageError::OutOfRange {
                    field: Field::RotaryLocation,
                    index: i as u16,
                });
            }
        }
        for (i, p) in self.pivot_counts.iter().enumerate() {
            if !(-(1i64 << 62)..=(1i64 << 62)).contains(p) {
                return Err(ImageError::OutOfRange {
                    field: Field::Pivot,
                    index: i as u16,
                });
            }
        }
        let l = self.tool_length_um;
        if !l.is_finite() {
            return Err(ImageError::NonFinite {
                field: Field::ToolLength,
                index: 0,
            });
        }
        if !(0.0..=1.0e7).contains(&l) {
            return Err(ImageError::OutOfRange {
                field: Field::ToolLength,
                index: 0,
            });
        }
        Ok(())
    }
}
