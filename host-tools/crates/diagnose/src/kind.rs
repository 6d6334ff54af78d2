//! Effect kinds of the contract vocabulary (`../shared/spec/interfaces.md`, "Effect kinds").
//!
//! Glossary: **kind** = the name of an error source as used by `--model`, the twin and the diagnosis.

use core::fmt;

/// An error source, named exactly as in the contract.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
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

impl EffectKind {
    /// Every kind, in contract order.
    pub const ALL: [EffectKind; 12] = [
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

    /// The contract name (`pitch_error`, `reversal`, ...).
    pub fn name(self) -> &'static str {
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

    /// Parses a contract name.
    pub fn from_name(s: &str) -> Option<EffectKind> {
        EffectKind::ALL.into_iter().find(|k| k.name() == s.trim())
    }

    /// Parses a comma-separated list (`pitch_error,reversal`); an empty list is allowed.
    pub fn parse_list(s: &str) -> Result<Vec<EffectKind>, String> {
        let mut out = Vec::new();
        for part in s.split(',').map(str::trim).filter(|p| !p.is_empty()) {
            let k = EffectKind::from_name(part).ok_or_else(|| {
                let known: Vec<&str> = EffectKind::ALL.iter().map(|k| k.name()).collect();
                format!("unknown effect kind `{part}` (known: {})", known.join(", "))
            })?;
            if !out.contains(&k) {
                out.push(k);
            }
        }
        Ok(out)
    }
}

impl fmt::Display for EffectKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        for k in EffectKind::ALL {
            assert_eq!(EffectKind::from_name(k.name()), Some(k));
        }
        assert!(EffectKind::parse_list("pitch_error,bogus").is_err());
        assert_eq!(
            EffectKind::parse_list("pitch_error, reversal,pitch_error").unwrap(),
            vec![EffectKind::PitchError, EffectKind::Reversal]
        );
    }
}
