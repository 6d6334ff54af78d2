//! Where a fitted model came from: the source file's SHA-256, the options that selected and transformed its
//! rows, the tool version and the date. Model files carry it (`provenance`), so a table in a drive can be
//! traced back to the exact measurement it was fitted on.
//!
//! Terms:
//! - *source digest*: SHA-256 of the file's bytes as read (lower-case hex), and its length;
//! - *filters*: `--where`, `--rename`, `--scale` as given, plus how rows were held out (`--holdout`) or
//!   cross-validated (`--cv`) and the error column (`--target`);
//! - *header line*: [`Provenance::header_line`], one line of `key=value` pairs for an image header or a
//!   log (no newline, printable ASCII apart from user-supplied names).

use std::io::Read;
use std::path::Path;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::DataError;

/// The provenance of a model file (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Provenance {
    /// The data file as the user named it.
    pub source_file: String,
    /// SHA-256 of the file's bytes, lower-case hex.
    pub source_sha256: String,
    /// Length of the file in bytes.
    pub source_bytes: u64,
    /// `--where COL=VALUE`, in order.
    #[serde(default)]
    pub where_: Vec<String>,
    /// `--rename OLD=NEW`, in order.
    #[serde(default)]
    pub rename: Vec<String>,
    /// `--scale COL=FACTOR`, in order.
    #[serde(default)]
    pub scale: Vec<String>,
    /// `--holdout SPEC`, when rows were held out.
    #[serde(default)]
    pub holdout: Option<String>,
    /// `--cv COL`, when given.
    #[serde(default)]
    pub cv: Option<String>,
    /// The modelled column.
    #[serde(default)]
    pub target: String,
    /// Producing tool and version, e.g. `axcomp 0.1.0`.
    pub tool: String,
    /// Command that wrote the file, e.g. `fit positioning`.
    #[serde(default)]
    pub command: String,
    /// UTC time of writing, ISO 8601 (`2026-11-24T02:58:00Z`).
    pub created_utc: String,
}

/// SHA-256 (lower-case hex) and length of a file, read in 64 KiB blocks.
pub fn file_sha256(path: &Path) -> Result<(String, u64), DataError> {
    let io = |cause| DataError::Io {
        file: path.display().to_string(),
        cause,
    };
    let mut f = std::fs::File::open(path).map_err(io)?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    let mut n = 0u64;
    loop {
        let k = f.read(&mut buf).map_err(io)?;
        if k == 0 {
            break;
        }
        h.update(&buf[..k]);
        n += k as u64;
    }
    Ok((hex(&h.finalize()), n))
}

/// SHA-256 (lower-case hex) of bytes in memory (e.g. a CSV written in the same run).
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// SHA-256 of bytes in memory, raw (as an image's provenance record holds it).
pub fn sha256(bytes: &[u8]) -> [u8; 32] {
    Sha256::digest(bytes).into()
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// UTC date and time of `t` as `YYYY-MM-DDTHH:MM:SSZ` (proleptic Gregorian; H. Hinnant's civil_from_days).
pub fn utc_iso8601(t: std::time::SystemTime) -> String {
    let secs = t
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_secs()) as i64;
    let (days, rem) = (secs.div_euclid(86_400), secs.rem_euclid(86_400));
    let z = days + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    let y = yoe + era * 400 + i64::from(m <= 2);
    format!(
        "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}Z",
        rem / 3600,
        (rem / 60) % 60,
        rem % 60
    )
}

impl Provenance {
    /// The provenance of a model fitted now from `path` with the given options; `tool` is e.g.
    /// `axcomp 0.1.0`.
    #[allow(clippy::too_many_arguments)]
    pub fn of_file(
        path: &Path,
        where_: &[String],
        rename: &[String],
        scale: &[String],
        holdout: Option<&str>,
        cv: Option<&str>,
        target: &str,
        tool: &str,
        command: &str,
    ) -> Result<Self, DataError> {
        let (source_sha256, source_bytes) = file_sha256(path)?;
        Ok(Provenance {
            source_file: path.display().to_string(),
            source_sha256,
            source_bytes,
            where_: where_.to_vec(),
            rename: rename.to_vec(),
            scale: scale.to_vec(),
            holdout: holdout.map(str::to_string),
            cv: cv.map(str::to_string),
            target: target.to_string(),
            tool: tool.to_string(),
            command: command.to_string(),
            created_utc: utc_iso8601(std::time::SystemTime::now()),
        })
    }

    /// One line of `key=value` pairs (values with spaces quoted) for an image header or a log, e.g.
    /// `sha256=9f… bytes=123 file=runs.csv where=test_id=B02 tool="axcomp 0.1.0" utc=2026-…Z`.
    /// The file name is reduced to its last component to keep the line short.
    pub fn header_line(&self) -> String {
        let q = |v: &str| {
            if v.contains([' ', '"', ';']) || v.is_empty() {
                format!("{v:?}")
            } else {
                v.to_string()
            }
        };
        let name = Path::new(&self.source_file)
            .file_name()
            .map_or(self.source_file.clone(), |n| {
                n.to_string_lossy().into_owned()
            });
        let mut s = format!(
            "sha256={} bytes={} file={}",
            self.source_sha256,
            self.source_bytes,
            q(&name)
        );
        for (k, v) in [
            ("where", &self.where_),
            ("rename", &self.rename),
            ("scale", &self.scale),
        ] {
            for x in v {
                s.push_str(&format!(" {k}={}", q(x)));
            }
        }
        if let Some(h) = &self.holdout {
            s.push_str(&format!(" holdout={}", q(h)));
        }
        if let Some(c) = &self.cv {
            s.push_str(&format!(" cv={}", q(c)));
        }
        if !self.target.is_empty() {
            s.push_str(&format!(" target={}", q(&self.target)));
        }
        s.push_str(&format!(" tool={} utc={}", q(&self.tool), self.created_utc));
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: the SHA-256 test vector of "abc" (FIPS 180-2, appendix B.1).
    #[test]
    fn sha256_of_a_file_matches_the_fips_vector() {
        let p = std::env::temp_dir().join(format!("axcomp-prov-{}.txt", std::process::id()));
        std::fs::write(&p, "abc").unwrap();
        let (h, n) = file_sha256(&p).unwrap();
        assert_eq!(
            h,
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
        assert_eq!(n, 3);
        assert_eq!(sha256_hex(b"abc"), h);
        let pr = Provenance::of_file(
            &p,
            &["test_id=B02".into()],
            &[],
            &["x=2".into()],
            Some("run=5"),
            None,
            "deviation_um",
            "axcomp 0.1.0",
            "fit positioning",
        )
        .unwrap();
        let line = pr.header_line();
        assert!(line.starts_with("sha256=ba7816bf"), "{line}");
        assert!(line.contains("where=test_id=B02") && line.contains("holdout=run=5"));
        assert!(line.contains("tool=\"axcomp 0.1.0\""), "{line}");
        std::fs::remove_file(&p).unwrap();
    }

    /// Reference dates: 0 s = 1970-01-01T00:00:00Z; 951 782 400 s = 2000-02-29T00:00:00Z (leap day);
    /// 1 795 574 096 s = 2026-11-25T02:34:56Z (computed with `date -u -d @1795574096`).
    #[test]
    fn utc_dates() {
        let at = |s: u64| utc_iso8601(std::time::UNIX_EPOCH + std::time::Duration::from_secs(s));
        assert_eq!(at(0), "1970-01-01T00:00:00Z");
        assert_eq!(at(951_782_400), "2000-02-29T00:00:00Z");
        assert_eq!(at(1_795_574_096), "2026-11-25T02:34:56Z");
    }
}
