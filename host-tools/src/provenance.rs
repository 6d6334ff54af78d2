//! Provenance of the files the commands write: one place that builds it and puts it into every model
//! file (and the image's provenance block, `axcomp_core::provenance`).
//!
//! Terms:
//! - *provenance* ([`axcomp_data::Provenance`]): the data file's SHA-256 and length, the filters
//!   (`--where/--rename/--scale`, `--holdout`/`--cv`, the target), the tool and version, the command and
//!   the UTC date.
//! - *stamped model file*: the model's JSON object with a top-level `provenance` field (readers ignore
//!   fields they do not know, so a stamped file reads everywhere an unstamped one did).
//! - *model record*: what an image keeps of a model file: the SHA-256 of its bytes and the data SHA-256
//!   its provenance names ([`model_record`]).

use std::path::Path;

use anyhow::Context;
use axcomp_data::Provenance;
use axcomp_data::provenance::sha256;

use crate::cli::DataArgs;

/// Tool and version written into every model file and image.
pub const TOOL: &str = concat!("axcomp ", env!("CARGO_PKG_VERSION"));

/// The provenance of a model fitted now from `--data` with its filters.
pub fn of_data(
    data: &DataArgs,
    holdout: Option<&str>,
    cv: Option<&str>,
    target: &str,
    command: &str,
) -> anyhow::Result<Provenance> {
    of_file(
        &data.data,
        &data.where_,
        &data.rename,
        &data.scale,
        holdout,
        cv,
        target,
        command,
    )
}

/// The same for commands whose filters are not a [`DataArgs`] (e.g. `fit force`).
#[allow(clippy::too_many_arguments)]
pub fn of_file(
    path: &Path,
    where_: &[String],
    rename: &[String],
    scale: &[String],
    holdout: Option<&str>,
    cv: Option<&str>,
    target: &str,
    command: &str,
) -> anyhow::Result<Provenance> {
    Provenance::of_file(
        path, where_, rename, scale, holdout, cv, target, TOOL, command,
    )
    .with_context(|| format!("{}: cannot hash the data file", path.display()))
}

/// `model` as pretty JSON with `provenance` added at the top level (a model serialising to anything
/// but an object is an internal error).
pub fn stamp<T: serde::Serialize>(model: &T, provenance: &Provenance) -> anyhow::Result<String> {
    let mut v = serde_json::to_value(model)?;
    let o = v
        .as_object_mut()
        .context("a model file is a JSON object (internal error)")?;
    o.insert("provenance".into(), serde_json::to_value(provenance)?);
    let mut text = serde_json::to_string_pretty(&v)?;
    text.push('\n');
    Ok(text)
}

/// [`stamp`] for a model already serialised to JSON text.
pub fn stamp_text(json: &str, provenance: &Provenance) -> anyhow::Result<String> {
    let v: serde_json::Value =
        serde_json::from_str(json).context("a model file serialises to JSON (internal error)")?;
    stamp(&v, provenance)
}

/// The provenance a model file carries, if any.
pub fn read_from(bytes: &[u8]) -> Option<Provenance> {
    let v: serde_json::Value = serde_json::from_slice(bytes).ok()?;
    serde_json::from_value(v.get("provenance")?.clone()).ok()
}

/// 64 hex digits into 32 bytes.
pub fn from_hex(hex: &str) -> Option<[u8; 32]> {
    if hex.len() != 64 || !hex.is_ascii() {
        return None;
    }
    let mut out = [0u8; 32];
    for (i, o) in out.iter_mut().enumerate() {
        *o = u8::from_str_radix(&hex[2 * i..2 * i + 2], 16).ok()?;
    }
    Some(out)
}

/// The image record of the model file at `path`: `role`, the SHA-256 of its bytes and the data SHA-256
/// of its provenance (zero when it has none).
pub fn model_record(
    path: &Path,
    axis: u8,
    role: u8,
) -> anyhow::Result<axcomp_core::provenance::ProvenanceRecord> {
    let bytes = std::fs::read(path).with_context(|| format!("cannot read {}", path.display()))?;
    Ok(model_record_of(&bytes, axis, role))
}

/// [`model_record`] of a model file's bytes (e.g. one written in the same run).
pub fn model_record_of(
    bytes: &[u8],
    axis: u8,
    role: u8,
) -> axcomp_core::provenance::ProvenanceRecord {
    let data = read_from(bytes)
        .and_then(|p| from_hex(&p.source_sha256))
        .unwrap_or([0; 32]);
    axcomp_core::provenance::ProvenanceRecord {
        axis,
        role,
        model_sha256: sha256(bytes),
        data_sha256: data,
    }
}

/// The image's provenance block: [`TOOL`], the date now, `records`.
pub fn image_block(
    records: &[axcomp_core::provenance::ProvenanceRecord],
) -> anyhow::Result<Vec<u8>> {
    let date = axcomp_data::provenance::utc_iso8601(std::time::SystemTime::now());
    Ok(axcomp_image::provenance_block(TOOL, &date, records)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stamped model reads back into its own type (the extra field is ignored) and its provenance
    /// reads back; the hex round trip of the FIPS 180-2 "abc" digest.
    #[test]
    fn stamped_models_read_back() {
        let law = axcomp_thermal::model_file::ModelForceLaw {
            k: 1500.0,
            x_ap: 1.0,
            y_fz: 0.8,
            z_n: 0.0,
        };
        let p = Provenance {
            source_file: "f.csv".into(),
            source_sha256: "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
                .into(),
            source_bytes: 3,
            where_: vec!["test_id=B02".into()],
            rename: vec![],
            scale: vec![],
            holdout: Some("run=5".into()),
            cv: None,
            target: "Fz_N".into(),
            tool: TOOL.into(),
            command: "fit force".into(),
            created_utc: "2026-11-24T05:30:00Z".into(),
        };
        let text = stamp(&law, &p).unwrap();
        let back: axcomp_thermal::model_file::ModelForceLaw = serde_json::from_str(&text).unwrap();
        assert_eq!(back, law);
        assert_eq!(read_from(text.as_bytes()), Some(p.clone()));
        assert_eq!(sha256(b"abc"), from_hex(&p.source_sha256).unwrap());
        assert_eq!(axcomp_image::to_hex(&sha256(b"abc")), p.source_sha256);
        assert!(from_hex("zz").is_none());
    }
}
