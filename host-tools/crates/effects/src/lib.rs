//! axcomp-effects: the vocabulary of error effects of a linear axis, shared by the twin (which simulates
//! them) and the diagnosis (which names them), so that neither depends on the other for it.
//!
//! Glossary: an **effect kind** is one of the contract's named error sources (`interfaces.md`, "Effect
//! kinds"); its physical parameters and simulation live in the twin (`axcomp_twin::Effect`). The
//! machine-level campaigns (laser lines, R-test, probe touches) have their own vocabularies in
//! [`campaign_kinds`].

pub mod campaign_kinds;
pub mod thermal_model;

pub use campaign_kinds::{DataKind, LineEffect, ProbeEffect, RotaryEffect, UnknownKind};

use core::fmt;
use core::str::FromStr;

use serde::{Deserialize, Serialize};

/// The kinds of error effects, named exactly as in the contract (`interfaces.md`, "Effect kinds").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum EffectKind {
    PitchError,
    Reversal,
    ScaleExpansion,
    ThermalDrift,
    ThermalLag,
    ForceDeflection,
    Cogging,
    InterpolationError,
    EndEffect,
    FollowingError,
    Abbe,
    TimeDrift,
}

/// An effect name that is not one of the contract's effect kinds.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown effect kind `{name}` (expected one of: {})",
    EffectKind::names_joined()
)]
pub struct UnknownEffect {
    pub name: String,
}

impl EffectKind {
    /// Number of kinds.
    pub const COUNT: usize = 12;
    /// All kinds, in the contract's order; `ALL[k.index()] == k`.
    pub const ALL: [EffectKind; Self::COUNT] = [
        EffectKind::PitchError,
        EffectKind::Reversal,
        EffectKind::ScaleExpansion,
        EffectKind::ThermalDrift,
        EffectKind::ThermalLag,
        EffectKind::ForceDeflection,
        EffectKind::Cogging,
        EffectKind::InterpolationError,
        EffectKind::EndEffect,
        EffectKind::FollowingError,
        EffectKind::Abbe,
        EffectKind::TimeDrift,
    ];

    /// The contract's name, e.g. `"pitch_error"`.
    pub const fn name(self) -> &'static str {
        match self {
            EffectKind::PitchError => "pitch_error",
            EffectKind::Reversal => "reversal",
            EffectKind::ScaleExpansion => "scale_expansion",
            EffectKind::ThermalDrift => "thermal_drift",
            EffectKind::ThermalLag => "thermal_lag",
            EffectKind::ForceDeflection => "force_deflection",
            EffectKind::Cogging => "cogging",
            EffectKind::InterpolationError => "interpolation_error",
            EffectKind::EndEffect => "end_effect",
            EffectKind::FollowingError => "following_error",
            EffectKind::Abbe => "abbe",
            EffectKind::TimeDrift => "time_drift",
        }
    }

    /// Parses a contract name (exact, case-sensitive).
    pub fn from_name(name: &str) -> Option<EffectKind> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Position of this kind in [`EffectKind::ALL`] (index into per-kind arrays).
    pub const fn index(self) -> usize {
        self as usize
    }

    /// Parses a comma-separated list such as `pitch_error,reversal` (blanks around names are ignored,
    /// duplicates are kept once, order of first appearance).
    pub fn parse_list(list: &str) -> Result<Vec<EffectKind>, UnknownEffect> {
        let mut kinds = Vec::new();
        for name in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
            let kind: EffectKind = name.parse()?;
            if !kinds.contains(&kind) {
                kinds.push(kind);
            }
        }
        Ok(kinds)
    }

    fn names_joined() -> String {
        Self::ALL.map(|k| k.name()).join(", ")
    }
}

impl fmt::Display for EffectKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for EffectKind {
    type Err = UnknownEffect;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        EffectKind::from_name(s).ok_or_else(|| UnknownEffect { name: s.to_owned() })
    }
}
