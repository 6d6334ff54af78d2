//! The effect vocabularies of the machine-level campaigns (contract `interfaces.md`, "Effect kinds for
//! geometry, rotary-axis and probe data"): laser lines of a three-axis machine ([`LineEffect`]), R-test or
//! sphere-centre data of a five-axis machine ([`RotaryEffect`]) and probe touches ([`ProbeEffect`]).
//! Each is a closed list of contract names; the twin simulates them and the diagnosis names them.
//!
//! Glossary:
//! - **data kind** ([`DataKind`]): which campaign a measurement file holds, told by its columns.
//! - **base model** (`--model`): `geometry` (or a subset of the 21 ISO names) for lines,
//!   `location_errors` for R-test data, `probe_radius` / `probe_pretravel` for touches.

use core::fmt;
use core::str::FromStr;

use serde::{Deserialize, Serialize};

/// A name that is not in a vocabulary.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown {vocabulary} effect kind `{name}` (expected one of: {expected})")]
pub struct UnknownKind {
    /// Which vocabulary was asked (`laser-line`, `R-test`, `probe`).
    pub vocabulary: &'static str,
    pub name: String,
    pub expected: String,
}

macro_rules! vocabulary {
    ($(#[$doc:meta])* $ty:ident, $vocab:literal, { $($(#[$vdoc:meta])* $variant:ident => $name:literal),+ $(,)? }) => {
        $(#[$doc])*
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
        #[serde(rename_all = "snake_case")]
        pub enum $ty {
            $($(#[$vdoc])* $variant),+
        }

        impl $ty {
            /// All kinds, in the contract's order.
            pub const ALL: &'static [$ty] = &[$($ty::$variant),+];

            /// The contract's name.
            pub const fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name),+
                }
            }

            /// Parses a contract name (exact, case-sensitive).
            pub fn from_name(name: &str) -> Option<$ty> {
                Self::ALL.iter().copied().find(|k| k.name() == name)
            }

            /// Parses a comma-separated list (blanks ignored, duplicates kept once).
            pub fn parse_list(list: &str) -> Result<Vec<$ty>, UnknownKind> {
                let mut kinds = Vec::new();
                for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
                    let kind: $ty = name.parse()?;
                    if !kinds.contains(&kind) {
                        kinds.push(kind);
                    }
                }
                Ok(kinds)
            }
        }

        impl fmt::Display for $ty {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(self.name())
            }
        }

        impl FromStr for $ty {
            type Err = UnknownKind;
            fn from_str(s: &str) -> Result<Self, Self::Err> {
                $ty::from_name(s).ok_or_else(|| UnknownKind {
                    vocabulary: $vocab,
                    name: s.to_owned(),
                    expected: Self::ALL.iter().map(|k| k.name()).collect::<Vec<_>>().join(", "),
                })
            }
        }
    };
}

vocabulary!(
    /// Unmodelled effects on laser-line data of a three-axis machine.
    LineEffect, "laser-line", {
        /// Angular errors acting through tool (reflector) offsets.
        AbbeAngular => "abbe_angular",
        /// A squareness error between two axes.
        Squareness => "squareness",
        /// Straightness of an axis (error across its own travel).
        Straightness => "straightness",
        /// An axis's error depending on another axis's position (not rigid body).
        CrossCoupling => "cross_coupling",
        /// Error linear in the temperature rises during the measurement.
        ThermalDrift => "thermal_drift",
        /// Error drifting with time that temperatures do not explain.
        TimeDrift => "time_drift",
    }
);

vocabulary!(
    /// Unmodelled effects on R-test (or sphere-centre) data of a five-axis machine.
    RotaryEffect, "R-test", {
        /// Angular positioning error of a rotary axis versus its angle.
        RotaryPositioning => "rotary_positioning",
        /// Tilt or radial run-out of a rotary axis varying with its angle.
        RotaryWobble => "rotary_wobble",
        /// The linear axes' own geometric errors.
        LinearGeometry => "linear_geometry",
        /// The sphere (or R-test head) set-up moving during the measurement.
        SetupDrift => "setup_drift",
        /// Error linear in the temperature rises during the measurement.
        ThermalDrift => "thermal_drift",
        /// Error drifting with time that temperatures do not explain.
        TimeDrift => "time_drift",
    }
);

vocabulary!(
    /// Unmodelled effects on touch-probe data.
    ProbeEffect, "probe", {
        /// Direction-dependent pretravel with the probe's kinematic lobes (e.g. three-lobe).
        Lobing => "lobing",
        /// Pretravel growing with the probing speed.
        SpeedPretravel => "speed_pretravel",
        /// Stylus bending: pretravel growing with the lateral component of the approach.
        StylusBending => "stylus_bending",
        /// Latch latency: the latched position late by velocity × latency, along the motion.
        LatchLatency => "latch_latency",
        /// The machine's own geometric error at the touched points.
        MachineGeometry => "machine_geometry",
        /// Error linear in the temperature rises during the measurement.
        ThermalDrift => "thermal_drift",
    }
);

/// Base models (`--model`) of the machine-level campaigns.
pub mod base_model {
    /// Laser lines: the rigid 21-term model (or a subset by ISO name).
    pub const GEOMETRY: &str = "geometry";
    /// R-test / sphere centres: the identified location errors.
    pub const LOCATION_ERRORS: &str = "location_errors";
    /// Probe touches: one effective stylus radius.
    pub const PROBE_RADIUS: &str = "probe_radius";
    /// Probe touches: pretravel by direction and speed.
    pub const PROBE_PRETRAVEL: &str = "probe_pretravel";
}

/// Which campaign a measurement file holds, told by its columns (contract tables).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DataKind {
    /// One axis: `target_mm`, `deviation_um` (ISO 230-2 runs, scans, ...).
    Axis,
    /// Laser lines of a three-axis machine: `x_mm`, `y_mm`, `z_mm`, `line`, `deviation_um`.
    LaserLines,
    /// R-test or sphere centres: `x_mm`, `y_mm`, `z_mm`, `a_deg`|`b_deg`, `c_deg`, `dx_um`, `dy_um`, `dz_um`.
    RTest,
    /// Probe touches: `x_mm`, `y_mm`, `z_mm`, `approach_x`, `approach_y`, `approach_z`.
    ProbeTouches,
}

impl DataKind {
    /// The kind of a file from its column names (exact contract names; aliases are resolved before).
    /// `None` when the columns match no contract table.
    pub fn detect<S: AsRef<str>>(columns: &[S]) -> Option<DataKind> {
        let has = |c: &str| columns.iter().any(|s| s.as_ref() == c);
        let xyz = has("x_mm") && has("y_mm") && has("z_mm");
        if xyz && has("approach_x") && has("approach_y") && has("approach_z") {
            Some(DataKind::ProbeTouches)
        } else if xyz
            && (has("a_deg") || has("b_deg"))
            && has("c_deg")
            && has("dx_um")
            && has("dy_um")
            && has("dz_um")
        {
            Some(DataKind::RTest)
        } else if xyz && has("line") && has("deviation_um") {
            Some(DataKind::LaserLines)
        } else if has("target_mm") || has("deviation_um") {
            Some(DataKind::Axis)
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_match_the_contract_table() {
        // Reference: interfaces.md, "Effect kinds for geometry, rotary-axis and probe data".
        let lines: Vec<&str> = LineEffect::ALL.iter().map(|k| k.name()).collect();
        assert_eq!(
            lines,
            [
                "abbe_angular",
                "squareness",
                "straightness",
                "cross_coupling",
                "thermal_drift",
                "time_drift"
            ]
        );
        let rotary: Vec<&str> = RotaryEffect::ALL.iter().map(|k| k.name()).collect();
        assert_eq!(
            rotary,
            [
                "rotary_positioning",
                "rotary_wobble",
                "linear_geometry",
                "setup_drift",
                "thermal_drift",
                "time_drift"
            ]
        );
        let probe: Vec<&str> = ProbeEffect::ALL.iter().map(|k| k.name()).collect();
        assert_eq!(
            probe,
            [
                "lobing",
                "speed_pretravel",
                "stylus_bending",
                "latch_latency",
                "machine_geometry",
                "thermal_drift"
            ]
        );
        for k in LineEffect::ALL {
            assert_eq!(k.name().parse::<LineEffect>().unwrap(), *k);
        }
        let e = "lobing,wobble".parse::<ProbeEffect>().unwrap_err();
        assert_eq!(e.name, "lobing,wobble");
        let e = ProbeEffect::parse_list("lobing, wobble").unwrap_err();
        assert!(
            e.to_string().contains("unknown probe effect kind `wobble`"),
            "{e}"
        );
        assert_eq!(
            RotaryEffect::parse_list("setup_drift,setup_drift , time_drift").unwrap(),
            [RotaryEffect::SetupDrift, RotaryEffect::TimeDrift]
        );
    }

    #[test]
    fn data_kind_from_columns() {
        let k = |c: &[&str]| DataKind::detect(c);
        assert_eq!(
            k(&["x_mm", "y_mm", "z_mm", "line", "deviation_um", "beam_x"]),
            Some(DataKind::LaserLines)
        );
        assert_eq!(
            k(&[
                "x_mm", "y_mm", "z_mm", "a_deg", "c_deg", "dx_um", "dy_um", "dz_um"
            ]),
            Some(DataKind::RTest)
        );
        assert_eq!(
            k(&[
                "x_mm", "y_mm", "z_mm", "b_deg", "c_deg", "dx_um", "dy_um", "dz_um", "path"
            ]),
            Some(DataKind::RTest)
        );
        assert_eq!(
            k(&[
                "x_mm",
                "y_mm",
                "z_mm",
                "approach_x",
                "approach_y",
                "approach_z",
                "feed_mm_min"
            ]),
            Some(DataKind::ProbeTouches)
        );
        assert_eq!(
            k(&["target_mm", "deviation_um", "run"]),
            Some(DataKind::Axis)
        );
        assert_eq!(k(&["x_mm", "y_mm"]), None);
    }
}
