//! Exports of a fitted positioning table to formats other tools read.
//!
//! Glossary:
//! - *nominal*: the commanded joint position (mm) at which a compensation entry applies.
//! - *forward / reverse*: LinuxCNC's words for moving in the positive / negative direction; they match our
//!   forward (positive approach) / backward (negative approach) tables.
//! - *trim*: the amount LinuxCNC adds to the motor command at a nominal position. Our table holds the
//!   predicted deviation (reached − target, µm), so the trim is −deviation (converted to mm).
//! - *step*: spacing (mm) of the exported sample positions; the last sample sits exactly at the table end.
//!
//! Formats (LinuxCNC `[JOINT_n]COMP_FILE` / `COMP_FILE_TYPE`, as read by `usrmotLoadComp` in
//! `src/emc/motion/usrmotintf.cc`: whitespace-separated `nominal a b` triples, one per line, nominal
//! increasing, reading stops at the first line that is not three numbers, so no header or comment lines;
//! at most 256 entries, `EMCMOT_COMP_SIZE`):
//! - `linuxcnc0` (type 0): `nominal forward reverse` where forward/reverse are the positions the joint
//!   actually reaches when commanded to `nominal` moving forward/reverse, i.e. `nominal + deviation`;
//!   LinuxCNC converts them to trims `nominal − forward`.
//! - `linuxcnc1` (type 1): `nominal forward-trim reverse-trim`, trims = −deviation.
//! - `csv`: `position_mm,forward_um,backward_um`, the predicted deviation in µm (our sign).
//!
//! Units: machine units are assumed to be mm (`[TRAJ]LINEAR_UNITS = mm`).

use crate::table_file::TableFile;

/// Most entries LinuxCNC keeps per joint (`EMCMOT_COMP_SIZE`).
pub const LINUXCNC_MAX_ENTRIES: usize = 256;

/// Resolution of the exported positions (printed with 6 decimals, mm).
pub const NOMINAL_RESOLUTION_MM: f64 = 1e-6;

/// Most samples of any export (guards against a tiny `--step`).
pub const MAX_SAMPLES: usize = 1_000_000;

/// Output format of [`export`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ExportFormat {
    /// LinuxCNC `COMP_FILE_TYPE = 0`.
    LinuxCnc0,
    /// LinuxCNC `COMP_FILE_TYPE = 1`.
    LinuxCnc1,
    /// `position_mm,forward_um,backward_um`.
    Csv,
}

impl std::str::FromStr for ExportFormat {
    type Err = ExportError;
    fn from_str(s: &str) -> Result<Self, ExportError> {
        match s {
            "linuxcnc0" => Ok(Self::LinuxCnc0),
            "linuxcnc1" => Ok(Self::LinuxCnc1),
            "csv" => Ok(Self::Csv),
            other => Err(ExportError::UnknownFormat(other.to_string())),
        }
    }
}

/// Why an export cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExportError {
    #[error("unknown export format `{0}` (expected linuxcnc0, linuxcnc1 or csv)")]
    UnknownFormat(String),
    #[error("--step {0} mm: the step must be a finite number > 0")]
    BadStep(f64),
    #[error(
        "--step {step_mm} mm gives {count} entries over the {stroke_mm} mm stroke; {format} takes at most {max} (use a larger step)"
    )]
    TooManyEntries {
        step_mm: f64,
        stroke_mm: f64,
        count: usize,
        max: usize,
        format: &'static str,
    },
    #[error(
        "the table spans {stroke_mm} mm, less than the exported positions' resolution of 1e-6 mm: its start and end would be one position"
    )]
    StrokeTooShort { stroke_mm: f64 },
    #[error(transparent)]
    Table(#[from] crate::table_file::TableError),
}

/// One exported sample: predicted deviation per direction at a position.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    pub position_mm: f64,
    pub forward_um: f64,
    pub backward_um: f64,
}

/// Samples the table from `start_mm` to its end every `step_mm` (last sample exactly at the end).
pub fn sample_table(
    table: &TableFile,
    step_mm: f64,
    max: usize,
) -> Result<Vec<Sample>, ExportError> {
    table.validate()?;
    if !(step_mm.is_finite() && step_mm > 0.0) {
        return Err(ExportError::BadStep(step_mm));
    }
    let stroke = table.end_mm() - table.start_mm;
    // Steps that fit, tolerating rounding (a 0.1 mm step over 10 mm gives 100 steps, not 101).
    let mut steps = ((stroke / step_mm) - 1e-9).ceil().max(1.0);
    // A last regular sample within the files' resolution (NOMINAL_RESOLUTION_MM) of the end would print
    // as a second entry at the end, and LinuxCNC refuses nominals that do not increase ("compensation
    // values must increase"): the end takes its place.
    if steps >= 2.0 && stroke - (steps - 1.0) * step_mm < NOMINAL_RESOLUTION_MM {
        steps -= 1.0;
    }
    if stroke < NOMINAL_RESOLUTION_MM {
        return Err(ExportError::StrokeTooShort { stroke_mm: stroke });
    }
    let count = steps + 1.0;
    if count > max as f64 {
        return Err(ExportError::TooManyEntries {
            step_mm,
            stroke_mm: stroke,
            count: if count > usize::MAX as f64 {
                usize::MAX
            } else {
                count as usize
            },
            max,
            format: "",
        });
    }
    let steps = steps as usize;
    Ok((0..=steps)
        .map(|k| {
            let x = if k == steps {
                table.end_mm()
            } else {
                table.start_mm + step_mm * k as f64
            };
            Sample {
                position_mm: x,
                forward_um: table.deviation_um(x, 1),
                backward_um: table.deviation_um(x, -1),
            }
        })
        .collect())
}

/// Renders samples in `format` (see the module docs). Text ends with a newline.
pub fn render(format: ExportFormat, samples: &[Sample]) -> String {
    let mut out = String::new();
    match format {
        ExportFormat::Csv => {
            out.push_str("position_mm,forward_um,backward_um\n");
            for s in samples {
                out.push_str(&format!(
                    "{:.6},{:.4},{:.4}\n",
                    s.position_mm, s.forward_um, s.backward_um
                ));
            }
        }
        ExportFormat::LinuxCnc0 => {
            for s in samples {
                // Reached positions from the nominal as printed, so that LinuxCNC's trim
                // `nominal − forward` is −deviation to the file's last digit.
                let nominal = format!("{:.6}", s.position_mm);
                let at: f64 = nominal.parse().unwrap_or(s.position_mm);
                let fwd = at + s.forward_um / 1000.0;
                let rev = at + s.backward_um / 1000.0;
                out.push_str(&format!("{nominal} {fwd:.7} {rev:.7}\n"));
            }
        }
        ExportFormat::LinuxCnc1 => {
            for s in samples {
                let fwd_trim = -s.forward_um / 1000.0;
                let rev_trim = -s.backward_um / 1000.0;
                out.push_str(&format!(
                    "{:.6} {:.7} {:.7}\n",
                    s.position_mm, fwd_trim, rev_trim
                ));
            }
        }
    }
    out
}

/// Samples `table` every `step_mm` and renders it in `format`.
pub fn export(
    table: &TableFile,
    format: ExportFormat,
    step_mm: f64,
) -> Result<String, ExportError> {
    let (max, name) = match format {
        ExportFormat::Csv => (MAX_SAMPLES, "csv"),
        ExportFormat::LinuxCnc0 => (LINUXCNC_MAX_ENTRIES, "linuxcnc0"),
        ExportFormat::LinuxCnc1 => (LINUXCNC_MAX_ENTRIES, "linuxcnc1"),
    };
    let samples = sample_table(table, step_mm, max).map_err(|e| match e {
        ExportError::TooManyEntries {
            step_mm,
            stroke_mm,
            count,
            max,
            ..
        } => ExportError::TooManyEntries {
            step_mm,
            stroke_mm,
            count,
            max,
            format: name,
        },
        e => e,
    })?;
    Ok(render(format, &samples))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Forward deviation 10 + 2·x µm (linear in segment t), backward a constant −5 µm, over 0..20 mm.
    fn table() -> TableFile {
        TableFile {
            format: crate::table_file::FORMAT.into(),
            axis: "X".into(),
            start_mm: 0.0,
            segment_mm: 10.0,
            // segment 0: x∈[0,10): 10 + 20 t; segment 1: x∈[10,20): 30 + 20 t.
            forward: vec![[10.0, 20.0, 0.0, 0.0], [30.0, 20.0, 0.0, 0.0]],
            backward: vec![[-5.0, 0.0, 0.0, 0.0], [-5.0, 0.0, 0.0, 0.0]],
            model: "test".into(),
            cv_rms_um: 0.0,
            raw_rms_um: 0.0,
            cv_method: String::new(),
            provenance: None,
        }
    }

    fn rows(text: &str) -> Vec<Vec<f64>> {
        text.lines()
            .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
            .collect()
    }

    #[test]
    fn sampling_ends_exactly_at_the_table_end() {
        let s = sample_table(&table(), 7.0, 100).unwrap();
        let xs: Vec<f64> = s.iter().map(|s| s.position_mm).collect();
        assert_eq!(xs, vec![0.0, 7.0, 14.0, 20.0]);
        // Reference: forward 10 + 2x → 24 at x=7; backward −5 everywhere. Tolerance 1e-12 (Horner, exact t).
        assert!((s[1].forward_um - 24.0).abs() < 1e-12);
        assert_eq!(s[1].backward_um, -5.0);
        let s = sample_table(&table(), 0.1, 1000).unwrap();
        assert_eq!(
            s.len(),
            201,
            "0.1 mm over 20 mm: 200 steps + 1, rounding tolerated"
        );
    }

    #[test]
    fn linuxcnc_type0_holds_reached_positions_and_type1_trims() {
        // At x = 10 mm: forward deviation 30 µm, backward −5 µm.
        let t0 = export(&table(), ExportFormat::LinuxCnc0, 10.0).unwrap();
        let r = rows(&t0);
        assert_eq!(r.len(), 3);
        // Type 0: positions reached = nominal + deviation: 10.030 mm forward, 9.995 mm reverse.
        assert_eq!(r[1], vec![10.0, 10.03, 9.995]);
        // LinuxCNC converts type 0 to trims nominal − reached; those must equal our type 1 values.
        let r1 = rows(&export(&table(), ExportFormat::LinuxCnc1, 10.0).unwrap());
        for (a, b) in r.iter().zip(&r1) {
            assert_eq!(a[0], b[0]);
            assert!(
                (a[0] - a[1] - b[1]).abs() < 1e-9 && (a[0] - a[2] - b[2]).abs() < 1e-9,
                "{a:?} {b:?}"
            );
        }
        assert_eq!(r1[1], vec![10.0, -0.03, 0.005]);
        // No header or comment: LinuxCNC stops reading at the first line that is not three numbers.
        assert!(t0.lines().all(|l| l.split_whitespace().count() == 3));
        // Nominal strictly increasing.
        assert!(r.windows(2).all(|w| w[1][0] > w[0][0]));
    }

    #[test]
    fn csv_has_the_contract_header() {
        let text = export(&table(), ExportFormat::Csv, 10.0).unwrap();
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("position_mm,forward_um,backward_um"));
        assert_eq!(lines.next(), Some("0.000000,10.0000,-5.0000"));
    }

    #[test]
    fn bad_step_and_too_many_entries() {
        assert_eq!(
            export(&table(), ExportFormat::Csv, 0.0),
            Err(ExportError::BadStep(0.0))
        );
        assert!(matches!(
            export(&table(), ExportFormat::Csv, f64::NAN),
            Err(ExportError::BadStep(_))
        ));
        let e = export(&table(), ExportFormat::LinuxCnc1, 0.01).unwrap_err();
        assert!(e.to_string().contains("linuxcnc1 takes at most 256"), "{e}");
        assert!("lcnc".parse::<ExportFormat>().is_err());
        assert_eq!(
            "linuxcnc0".parse::<ExportFormat>().unwrap(),
            ExportFormat::LinuxCnc0
        );
    }

    #[test]
    fn unidirectional_table_exports_the_same_both_ways() {
        let mut t = table();
        t.backward.clear();
        let s = sample_table(&t, 5.0, 100).unwrap();
        assert!(s.iter().all(|s| s.forward_um == s.backward_um));
    }
}
