//! The calibration file: the effective-radius model with its range of validity, and the correction of a
//! touch to its contact point.

use serde::{Deserialize, Serialize};

use crate::{
    AZIMUTH_POLE_DEG, DIRECTION_MARGIN_DEG, DirSpeed, FORMAT, ProbeError, Structure, Touch,
};

/// A probe calibration: the file `axcomp fit probe --out CAL` writes and `axcomp predict` reads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// Always [`FORMAT`].
    pub format: String,
    pub sphere_center_mm: [f64; 3],
    pub sphere_diameter_mm: f64,
    /// Mean effective radius over the calibration directions at zero speed, mm.
    pub stylus_radius_mm: f64,
    /// The model of the effective radius.
    pub structure: Structure,
    /// Its coefficients (mm; speed coefficients in mm per mm/s).
    pub coef_mm: Vec<f64>,
    /// Probing speeds seen in calibration, mm/min.
    pub feed_range_mm_min: [f64; 2],
    /// Elevations (of the normal) seen in calibration, degrees.
    pub elevation_range_deg: [f64; 2],
    /// The widest azimuth arc `[from, to]` (degrees, counter-clockwise from `from`) without calibration
    /// touches below [`AZIMUTH_POLE_DEG`], when it is wider than [`AZIMUTH_GAP_COVERED_DEG`] (e.g. a sphere
    /// probed from one side only); `None` when the touches go round (and in files written before it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub azimuth_gap_deg: Option<[f64; 2]>,
    /// RMS radial residual of the calibration touches (inliers), µm.
    pub fit_rms_um: f64,
}

impl Calibration {
    /// Effective radius (mm) for a touch.
    pub fn effective_radius_mm(&self, t: &Touch) -> f64 {
        self.structure.eval(&self.coef_mm, t.dir_speed())
    }

    /// Pretravel (µm) relative to the stylus radius: `stylus_radius − r_eff`.
    pub fn pretravel_um(&self, d: DirSpeed) -> f64 {
        (self.stylus_radius_mm - self.structure.eval(&self.coef_mm, d)) * 1000.0
    }

    /// The corrected contact (surface) point `p + r_eff·u`.
    pub fn contact_mm(&self, t: &Touch) -> [f64; 3] {
        let r = self.effective_radius_mm(t);
        [
            t.position_mm[0] + r * t.approach[0],
            t.position_mm[1] + r * t.approach[1],
            t.position_mm[2] + r * t.approach[2],
        ]
    }

    /// Whether the calibration can correct this touch: a speed inside what it can tell (the calibrated
    /// range, or up to 1.5× its top speed by the linear speed term), an elevation not more than 10° below the
    /// lowest calibrated one. The error says why.
    pub fn check_touch(&self, t: &Touch) -> Result<(), String> {
        let [lo, hi] = self.feed_range_mm_min;
        let f = t.feed_mm_min;
        if hi - lo <= 1e-9 * hi.max(1.0) {
            if hi == 0.0 && f != 0.0 {
                return Err(format!(
                    "feed_mm_min {f}: the calibration's touches had no feed_mm_min column (one speed, not \
                     known), so it cannot tell the pretravel at a given speed; leave the column out (--rename \
                     feed_mm_min=feed_unused) if these touches were probed at the calibration's speed, or \
                     calibrate with feed_mm_min"
                ));
            }
            if (f - lo).abs() > 0.01 * lo.max(1.0) {
                return Err(format!(
                    "feed_mm_min {f}: the calibration saw only {lo} mm/min, so it cannot tell the pretravel at \
                     another speed"
                ));
            }
        } else if !(f >= 0.0 && f <= 1.5 * hi) {
            return Err(format!(
                "feed_mm_min {f} is outside what the calibration can predict (0 … {} mm/min; calibrated \
                 {lo} … {hi})",
                1.5 * hi
            ));
        }
        let el = t.dir_speed().elevation_deg();
        if let Some([from, to]) = self.azimuth_gap_deg
            && el < AZIMUTH_POLE_DEG
        {
            let az = t.dir_speed().azimuth_deg();
            let width = match (to - from).rem_euclid(360.0) {
                0.0 => 360.0,
                w => w,
            };
            let inside = (az - from).rem_euclid(360.0);
            if inside > DIRECTION_MARGIN_DEG && inside < width - DIRECTION_MARGIN_DEG {
                return Err(format!(
                    "the surface normal's azimuth {az:.1}° lies in the arc {from:.1}° … {to:.1}° \
                     (counter-clockwise) where the calibration has no touches, more than \
                     {DIRECTION_MARGIN_DEG}° from the nearest calibrated azimuth: it cannot tell the \
                     pretravel there"
                ));
            }
        }
        if el < self.elevation_range_deg[0] - 10.0 {
            return Err(format!(
                "the surface normal's elevation {el:.1}° is more than 10° below the lowest calibrated \
                 elevation {:.1}°",
                self.elevation_range_deg[0]
            ));
        }
        Ok(())
    }

    /// Checks format and sizes.
    pub fn validate(&self) -> Result<(), String> {
        if self.format != FORMAT {
            return Err(format!("format is `{}`, expected `{FORMAT}`", self.format));
        }
        if self.coef_mm.len() != self.structure.len() {
            return Err(format!(
                "{} coefficients for a model with {}",
                self.coef_mm.len(),
                self.structure.len()
            ));
        }
        if self.coef_mm.iter().any(|c| !c.is_finite())
            || !self.stylus_radius_mm.is_finite()
            || self.sphere_diameter_mm.is_nan()
            || self.sphere_diameter_mm <= 0.0
        {
            return Err("non-finite coefficient, stylus radius or diameter".into());
        }
        let gap = self.azimuth_gap_deg.unwrap_or_default();
        let values = [
            ("sphere_center_mm", &self.sphere_center_mm[..]),
            ("sphere_diameter_mm", &[self.sphere_diameter_mm][..]),
            ("stylus_radius_mm", &[self.stylus_radius_mm][..]),
            ("coef_mm", &self.coef_mm[..]),
            ("feed_range_mm_min", &self.feed_range_mm_min[..]),
            ("elevation_range_deg", &self.elevation_range_deg[..]),
            ("azimuth_gap_deg", &gap[..]),
            ("fit_rms_um", &[self.fit_rms_um][..]),
        ];
        for (name, v) in values {
            if let Some((i, x)) = v
                .iter()
                .enumerate()
                .find(|(_, x)| !(x.is_finite() && x.abs() < 1e12))
            {
                return Err(format!(
                    "{name}[{i}] is {x:e}, not a finite number of plausible size"
                ));
            }
        }
        if self.feed_range_mm_min[0] > self.feed_range_mm_min[1]
            || self.elevation_range_deg[0] > self.elevation_range_deg[1]
        {
            return Err(
                "feed_range_mm_min / elevation_range_deg: lower end above upper end".into(),
            );
        }
        Ok(())
    }

    pub fn from_json(path: &str, text: &str) -> Result<Self, ProbeError> {
        let c: Calibration = serde_json::from_str(text).map_err(|e| ProbeError::File {
            path: path.into(),
            what: format!("not a probe calibration: {e}"),
        })?;
        c.validate().map_err(|what| ProbeError::File {
            path: path.into(),
            what,
        })?;
        Ok(c)
    }

    pub fn to_json(&self) -> String {
        let mut s = serde_json::to_string_pretty(self).expect("calibration serialises");
        s.push('\n');
        s
    }
}
