//! Helpers shared by the commands: loading a measurement CSV with the common options, telling a model
//! file's kind, and writing output files so that nothing is half-written. Imports no command.
//!
//! Terms:
//! - *common options*: `--data`, `--where`, `--rename`, `--scale` ([`crate::cli::DataArgs`]).
//! - *atomic write*: the bytes go to a temporary file next to the target, which is then renamed over it;
//!   a failure leaves no partial file behind. Several outputs: [`crate::output::OutputSet`] (all or none).

use std::path::Path;

use anyhow::{Context, bail};

use axcomp_data::{Dataset, LoadOptions, Split};
use axcomp_kinematics::rotary::{FiveAxis, MachineKind};

use crate::cli::DataArgs;

/// The kind of a model file, from its `format` field.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModelKind {
    Positioning,
    Thermal,
    Probe,
    Geometry,
    Rtest,
    /// A force law of `fit force --out` (no `format` field: `k`, `x_ap`, `y_fz`, `z_n`).
    ForceLaw,
}

/// Reads the `format` field of a model file.
pub fn model_kind(path: &std::path::Path) -> anyhow::Result<ModelKind> {
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    let text = axcomp_files::model_text(&bytes)
        .map_err(|why| anyhow::anyhow!("{} {why}", path.display()))?;
    let v: serde_json::Value = serde_json::from_str(text)
        .with_context(|| format!("{}: not a JSON model file", path.display()))?;
    let format = v.get("format").and_then(|f| f.as_str()).unwrap_or("");
    match v.get("kind").and_then(|k| k.as_str()) {
        Some("rtest") if format.is_empty() => return Ok(ModelKind::Rtest),
        Some(kind) if format.is_empty() => bail!(
            "{}: model kind `{kind}` is not one this reader knows (an R-test model has \"kind\": \"rtest\")",
            path.display()
        ),
        _ => {}
    }
    if format.is_empty()
        && ["k", "x_ap", "y_fz", "z_n"]
            .iter()
            .all(|k| v[k].is_number())
    {
        return Ok(ModelKind::ForceLaw);
    }
    Ok(match format {
        axcomp_positioning::table_file::FORMAT => ModelKind::Positioning,
        axcomp_thermal::model_file::FORMAT => ModelKind::Thermal,
        axcomp_probe::FORMAT => ModelKind::Probe,
        axcomp_geometry::model::MODEL_FORMAT => ModelKind::Geometry,
        other => bail!(
            "{}: unknown model format `{other}` (expected {}, {}, {}, {}, an R-test model with \"kind\": \"rtest\" or a force law of `fit force --out`)",
            path.display(),
            axcomp_positioning::table_file::FORMAT,
            axcomp_thermal::model_file::FORMAT,
            axcomp_probe::FORMAT,
            axcomp_geometry::model::MODEL_FORMAT
        ),
    })
}

/// An output path's directory exists (`what`: the option, e.g. `--out`), checked before any work.
pub fn check_parent(path: &Path, what: &str) -> anyhow::Result<()> {
    let parent = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if !parent.is_dir() {
        bail!(
            "{what} {}: directory {} does not exist",
            path.display(),
            parent.display()
        );
    }
    Ok(())
}

/// Parses `--where/--rename/--scale`.
pub fn load_options(args: &DataArgs) -> anyhow::Result<LoadOptions> {
    Ok(LoadOptions::from_args(
        &args.where_,
        &args.rename,
        &args.scale,
    )?)
}

/// Loads `--data` with the common options applied (rename, scale, where). Errors name file, line, column.
pub fn load_dataset(args: &DataArgs) -> anyhow::Result<Dataset> {
    let opts = load_options(args)?;
    Ok(Dataset::load(&args.data, &opts)?)
}

/// For a message about a missing `time_s` ([`Dataset::time_hint`]).
pub fn time_hint(ds: &Dataset) -> &'static str {
    ds.time_hint()
}

/// `--holdout` / `--cv` into a [`Split`] (`None` when neither is given; both is an error).
pub fn split_from(holdout: Option<&str>, cv: Option<&str>) -> anyhow::Result<Option<Split>> {
    Ok(Split::from_args(holdout, cv)?)
}

/// Writes `bytes` to `path` through a temporary file in the same directory and a rename (a one-file
/// [`crate::output::OutputSet`]; commands with several outputs use the set directly).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    crate::output::write_one(path, bytes)?;
    Ok(())
}

/// Serialises `value` as pretty JSON and writes it atomically.
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> anyhow::Result<()> {
    let mut text = serde_json::to_string_pretty(value)?;
    text.push('\n');
    write_atomic(path, text.as_bytes())
}

/// Prints each data warning on stderr (`axcomp: warning: …`); with `strict` (`--strict`) any warning is
/// an error (exit 2) after they are all printed.
pub fn report_warnings(
    warnings: &[axcomp_data::sanity::DataWarning],
    strict: bool,
) -> anyhow::Result<()> {
    for w in warnings {
        eprintln!("axcomp: warning: {}", w.message);
    }
    if strict && !warnings.is_empty() {
        anyhow::bail!(
            "--strict: {} data warning(s) (above); fix the data or drop --strict",
            warnings.len()
        );
    }
    Ok(())
}

/// The file name of a path inside a report folder (`report.md` of `rep/report.md`).
pub fn file_name(path: &std::path::Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// A fit's JSON report with its data warnings added as `warnings` (the same findings as on stderr: kind,
/// column, message, file lines), `[]` when there are none.
pub fn with_warnings(
    mut report: serde_json::Value,
    warnings: &[axcomp_data::sanity::DataWarning],
) -> anyhow::Result<serde_json::Value> {
    if let Some(o) = report.as_object_mut() {
        o.insert("warnings".into(), serde_json::to_value(warnings)?);
    }
    Ok(report)
}

/// A numeric option is a finite number in `lo … hi` (a size bound keeps the work and memory in
/// check); the error names the option and the range.
pub fn check_range(option: &str, v: f64, lo: f64, hi: f64) -> anyhow::Result<()> {
    if !(v.is_finite() && v >= lo && v <= hi) {
        anyhow::bail!("{option} {v}: need a finite number in {lo} … {hi}");
    }
    Ok(())
}

/// A count option lies in `lo … hi`; the error names the option and the range.
pub fn check_count(option: &str, n: usize, lo: usize, hi: usize) -> anyhow::Result<()> {
    if !(lo..=hi).contains(&n) {
        anyhow::bail!("{option} {n}: need {lo} … {hi}");
    }
    Ok(())
}

/// Longest `--pivot-mm` (10 m): beyond, no spindle head.
const MAX_PIVOT_MM: f64 = 1.0e4;

/// `--machine` and `--pivot-mm` into the nominal kinematics.
pub fn machine_from(kind: &str, pivot_mm: Option<f64>) -> anyhow::Result<FiveAxis> {
    let Some(k) = MachineKind::parse(kind) else {
        anyhow::bail!("--machine `{kind}`: expected ac-trunnion, bc-trunnion or bc-head");
    };
    match (k, pivot_mm) {
        (MachineKind::BcHead, None) => {
            anyhow::bail!("--machine bc-head needs --pivot-mm L (B axis to tool point, mm)")
        }
        (MachineKind::BcHead, Some(l)) if !(l.is_finite() && l > 0.0 && l <= MAX_PIVOT_MM) => {
            anyhow::bail!("--pivot-mm {l}: need a length > 0 mm, at most {MAX_PIVOT_MM} mm")
        }
        (MachineKind::BcHead, Some(l)) => Ok(FiveAxis::new(k, l)),
        (_, Some(_)) => anyhow::bail!("--pivot-mm is for --machine bc-head only"),
        (_, None) => Ok(FiveAxis::new(k, 0.0)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn atomic_write_replaces_and_leaves_no_temp_file() {
        let dir = std::env::temp_dir().join(format!("axcomp-common-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("out.txt");
        write_atomic(&f, b"one").unwrap();
        write_atomic(&f, b"two").unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"two");
        let names: Vec<_> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names.len(), 1, "{names:?}");
        // A missing directory is an error naming the path, and nothing is created.
        let bad = dir.join("no/such/dir/out.txt");
        assert!(
            write_atomic(&bad, b"x")
                .unwrap_err()
                .to_string()
                .contains("no/such/dir")
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
