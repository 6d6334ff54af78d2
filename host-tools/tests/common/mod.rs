//! Helpers shared by the CLI end-to-end tests (each `tests/*.rs` file is its own crate and uses a subset).
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// The shared data directory (`AXCOMP_SHARED`, else `../shared` next to the workspace). When it is absent
/// the test prints `skipped: ../shared not found` and gets `None`, except under `CI`, where it fails.
pub fn shared() -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    match axcomp_data::shared_dir(&root) {
        Some(d) => Some(d),
        None if std::env::var_os("CI").is_some() => panic!("../shared not found (CI is set)"),
        None => {
            println!("skipped: ../shared not found");
            None
        }
    }
}

/// A fresh empty directory for one test, named after the test file, the process and `name`; see
/// [`Scratch`] for when it is removed.
pub fn scratch(name: &str) -> Scratch {
    let d = std::env::temp_dir().join(format!(
        "axcomp-{}-{}-{name}",
        env!("CARGO_CRATE_NAME"),
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    Scratch(d)
}

/// A test's scratch directory. It is removed when the test passes (dropped without a panic in flight) and
/// kept when the test fails, so the files the failing command saw can be looked at; before, every run left
/// its directories in the system temp dir (gigabytes after a day of runs). Derefs to its `Path`.
pub struct Scratch(PathBuf);

impl std::ops::Deref for Scratch {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

impl AsRef<Path> for Scratch {
    fn as_ref(&self) -> &Path {
        &self.0
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        if std::thread::panicking() {
            eprintln!(
                "kept the failing test's scratch directory {}",
                self.0.display()
            );
        } else {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }
}

/// Splits a CSV (no quoting) into its header and rows, comment lines dropped.
pub fn table(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    (header, rows)
}

/// Writes a header and rows as a CSV (no quoting), one line each.
pub fn write_table(path: &Path, header: &[String], rows: &[Vec<String>]) {
    let mut s = header.join(",");
    s.push('\n');
    for r in rows {
        s.push_str(&r.join(","));
        s.push('\n');
    }
    std::fs::write(path, s).unwrap();
}

/// Parses a JSON file written by the CLI.
pub fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{} is not JSON: {e}", path.display()))
}

/// Runs the CLI binary with `args` in `dir`.
pub fn axcomp_in(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run axcomp")
}

/// Every file under `dir` (relative path → bytes), sorted.
pub fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            let rel = p.strip_prefix(dir).unwrap().display().to_string();
            if p.is_dir() {
                out.push((rel + "/", vec![]));
                stack.push(p);
            } else {
                out.push((rel, std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

/// Runs `args` in `dir`: exit 2, `needle` named, no temporary named, the directory exactly as before.
pub fn fails_untouched(args: &[&str], dir: &Path, needle: &str) {
    fails_untouched_naming(args, dir, &[needle]);
}

/// Runs `args` in `dir`: exit 2, every one of `needles` named, no temporary named, the directory exactly as
/// before (nothing written, nothing half-written).
pub fn fails_untouched_naming(args: &[&str], dir: &Path, needles: &[&str]) {
    let before = snapshot(dir);
    let o = axcomp_in(args, dir);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    for needle in needles {
        assert!(err.contains(needle), "{args:?}: must name {needle}: {err}");
    }
    assert!(
        !err.contains("axcomp-tmp"),
        "{args:?}: names a temporary: {err}"
    );
    let after = snapshot(dir);
    assert_eq!(
        before.iter().map(|f| &f.0).collect::<Vec<_>>(),
        after.iter().map(|f| &f.0).collect::<Vec<_>>(),
        "{args:?}: files appeared or vanished"
    );
    assert!(before == after, "{args:?}: an existing output was changed");
}

/// Runs `args` in `dir` and requires success.
/// The standard output of a command that must have succeeded (both streams shown when it did not).
pub fn ok(o: &Output) -> String {
    assert!(
        o.status.success(),
        "axcomp failed: {}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

pub fn ok_in(args: &[&str], dir: &Path) {
    let o = axcomp_in(args, dir);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// The held-out RMS figures (µm) of `fit rtest --json`'s `comparison`: the reported model, the full model,
/// the nominal kinematics and the nominal kinematics with the sphere's set-up offsets only.
pub fn rtest_comparison_rms_um(j: &serde_json::Value) -> (f64, f64, f64, f64) {
    let c = &j["comparison"];
    let rms = |key: &str| {
        c[key]
            .as_f64()
            .unwrap_or_else(|| panic!("comparison.{key} is not a number: {c}"))
    };
    (
        rms("model_rms_um"),
        rms("full_model_rms_um"),
        rms("nominal_rms_um"),
        rms("nominal_setup_rms_um"),
    )
}
