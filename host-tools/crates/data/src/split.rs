//! `--holdout` and `--cv`: which rows judge a model and which fit it.
//!
//! Terms:
//! - *holdout*: rows held out from fitting, used only to judge. `COL=V1,V2,...` holds out rows whose cell
//!   equals one of the values (as numbers when both read as numbers, else as text); `COL>=X`, `COL>X`,
//!   `COL<=X`, `COL<X` hold out rows by a numeric threshold.
//! - *group*: rows sharing one value of a column; `--cv COL` leaves one group out at a time.

use crate::{DataError, Dataset, WantedCell, parse_number};

/// How a command splits its rows into fitting and judging.
#[derive(Debug, Clone, PartialEq)]
pub enum Split {
    /// `--holdout SPEC`.
    Holdout(HoldoutSpec),
    /// `--cv COL`: leave-one-group-out cross-validation over the values of COL.
    Cv(String),
}

impl Split {
    /// From the optional `--holdout` and `--cv` values; both at once is an error, neither is `None`.
    pub fn from_args(holdout: Option<&str>, cv: Option<&str>) -> Result<Option<Split>, DataError> {
        match (holdout, cv) {
            (Some(h), Some(c)) => Err(DataError::BadOption {
                option: "--holdout/--cv",
                text: format!("--holdout {h} --cv {c}"),
                reason: "give either --holdout or --cv, not both".into(),
            }),
            (Some(h), None) => Ok(Some(Split::Holdout(HoldoutSpec::parse(h)?))),
            (None, Some(c)) => Ok(Some(Split::Cv(Split::parse_cv(c)?))),
            (None, None) => Ok(None),
        }
    }

    /// Checks a `--cv` column name (non-empty).
    pub fn parse_cv(s: &str) -> Result<String, DataError> {
        let s = s.trim();
        if s.is_empty() {
            return Err(DataError::BadOption {
                option: "--cv",
                text: s.into(),
                reason: "the column name is empty".into(),
            });
        }
        Ok(s.to_string())
    }
}

/// Comparison of a `--holdout` spec.
#[derive(Debug, Clone, PartialEq)]
pub enum HoldoutRule {
    /// `COL=V1,V2,...`
    OneOf(Vec<String>),
    /// `COL>=X`
    AtLeast(f64),
    /// `COL>X`
    Above(f64),
    /// `COL<=X`
    AtMost(f64),
    /// `COL<X`
    Below(f64),
}

/// A parsed `--holdout` spec.
#[derive(Debug, Clone, PartialEq)]
pub struct HoldoutSpec {
    pub column: String,
    pub rule: HoldoutRule,
    text: String,
}

impl HoldoutSpec {
    /// Parses `COL=V1,V2`, `COL>=X`, `COL>X`, `COL<=X` or `COL<X`.
    pub fn parse(s: &str) -> Result<Self, DataError> {
        let bad = |reason: String| DataError::BadOption {
            option: "--holdout",
            text: s.to_string(),
            reason,
        };
        let ops: [(&str, u8); 5] = [(">=", 0), ("<=", 1), (">", 2), ("<", 3), ("=", 4)];
        // The first operator character in the string decides.
        let at = s
            .find(['>', '<', '='])
            .ok_or_else(|| bad("expected COL=V1,V2 or COL>=X, COL>X, COL<=X, COL<X".into()))?;
        let (op, kind) = ops
            .iter()
            .find(|(op, _)| s[at..].starts_with(op))
            .copied()
            .expect("one of the operators starts at `at`");
        let column = s[..at].trim();
        if column.is_empty() {
            return Err(bad("the column name is empty".into()));
        }
        let value = s[at + op.len()..].trim();
        let threshold = || -> Result<f64, DataError> {
            match parse_number(value) {
                Some(x) if x.is_finite() => Ok(x),
                _ => Err(bad(format!("`{value}` is not a finite number"))),
            }
        };
        let rule = match kind {
            0 => HoldoutRule::AtLeast(threshold()?),
            1 => HoldoutRule::AtMost(threshold()?),
            2 => HoldoutRule::Above(threshold()?),
            3 => HoldoutRule::Below(threshold()?),
            _ => {
                let values: Vec<String> = value.split(',').map(|v| v.trim().to_string()).collect();
                if values.iter().any(String::is_empty) {
                    return Err(bad("empty value in the list".into()));
                }
                HoldoutRule::OneOf(values)
            }
        };
        Ok(Self {
            column: column.to_string(),
            rule,
            text: s.to_string(),
        })
    }

    /// The spec as the user wrote it.
    pub fn as_str(&self) -> &str {
        &self.text
    }

    /// `true` = held out. Fails when the column is missing or (for thresholds) not numeric, and when the
    /// spec holds out no row or every row (nothing to judge on, or nothing left to fit).
    pub fn mask(&self, ds: &Dataset) -> Result<Vec<bool>, DataError> {
        let mask: Vec<bool> = match &self.rule {
            HoldoutRule::OneOf(values) => {
                let want: Vec<WantedCell> = values
                    .iter()
                    .map(|v| WantedCell::new(&self.column, v))
                    .collect();
                let cells = ds
                    .text(&self.column)
                    .map_err(|e| with_purpose(e, " (named by --holdout)"))?;
                // A listed value that matches no row is a typo or another file's label: holding out the
                // others alone would report the model as judged on rows it was fitted on.
                let unmatched: Vec<&str> = values
                    .iter()
                    .zip(&want)
                    .filter(|(_, w)| !cells.iter().any(|t| w.matches(t)))
                    .map(|(v, _)| v.as_str())
                    .collect();
                if !unmatched.is_empty() && unmatched.len() < values.len() {
                    let mut present: Vec<&str> = Vec::new();
                    for t in &cells {
                        if !present.contains(t) {
                            present.push(t);
                        }
                    }
                    let shown = present.len().min(12);
                    return Err(DataError::BadOption {
                        option: "--holdout",
                        text: self.text.clone(),
                        reason: format!(
                            "{} {} in no row of {} (column `{}` has {}{})",
                            unmatched.join(", "),
                            if unmatched.len() == 1 { "is" } else { "are" },
                            ds.source(),
                            self.column,
                            present[..shown].join(", "),
                            if present.len() > shown { ", …" } else { "" }
                        ),
                    });
                }
                cells
                    .iter()
                    .map(|t| want.iter().any(|w| w.matches(t)))
                    .collect()
            }
            rule => {
                let x = ds
                    .numeric(&self.column)
                    .map_err(|e| with_purpose(e, " (named by --holdout)"))?;
                x.iter()
                    .map(|&v| match *rule {
                        HoldoutRule::AtLeast(t) => v >= t,
                        HoldoutRule::Above(t) => v > t,
                        HoldoutRule::AtMost(t) => v <= t,
                        HoldoutRule::Below(t) => v < t,
                        HoldoutRule::OneOf(_) => unreachable!(),
                    })
                    .collect()
            }
        };
        let held = mask.iter().filter(|m| **m).count();
        if held == 0 {
            return Err(DataError::BadOption {
                option: "--holdout",
                text: self.text.clone(),
                reason: format!(
                    "selects no rows of {} (nothing held out to judge on)",
                    ds.source()
                ),
            });
        }
        if held == mask.len() {
            return Err(DataError::BadOption {
                option: "--holdout",
                text: self.text.clone(),
                reason: format!("selects every row of {} (nothing left to fit)", ds.source()),
            });
        }
        Ok(mask)
    }
}

fn with_purpose(e: DataError, purpose: &str) -> DataError {
    match e {
        DataError::MissingColumn {
            file,
            name,
            available,
            ..
        } => DataError::MissingColumn {
            file,
            name,
            purpose: purpose.to_string(),
            available,
        },
        e => e,
    }
}

/// Group id per row (0-based, in order of first appearance) and the label of each group, by the text of
/// column `col` (alias-aware: `run` finds `cycle`). Numerically equal cells (`1`, `1.0`) share a group.
pub fn groups(ds: &Dataset, col: &str) -> Result<(Vec<usize>, Vec<String>), DataError> {
    let text = ds
        .text(col)
        .map_err(|e| with_purpose(e, " (named by --cv)"))?;
    // Keyed by the number (0.0 and −0.0 alike) when the cell reads as one, else by the trimmed text:
    // one hash lookup per row (campaigns of thousands of runs).
    #[derive(Hash, PartialEq, Eq)]
    enum Key {
        Number(u64),
        Text(String),
    }
    let mut labels: Vec<String> = Vec::new();
    let mut index: std::collections::HashMap<Key, usize> = std::collections::HashMap::new();
    let mut ids = Vec::with_capacity(text.len());
    for t in text {
        let t = t.trim();
        let key = match parse_number(t) {
            Some(0.0) => Key::Number(0),
            Some(v) => Key::Number(v.to_bits()),
            None => Key::Text(t.to_string()),
        };
        let next = labels.len();
        let id = *index.entry(key).or_insert(next);
        if id == next {
            labels.push(t.to_string());
        }
        ids.push(id);
    }
    Ok((ids, labels))
}
