//! Helpers shared by the CLI end-to-end tests (each `tests/*.rs` file is its own crate and uses a subset).
#![allow(dead_code)]

use std::path::{Path, PathBuf};

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

/// A fresh empty directory for one test, named after the test file, the process and `name`.
pub fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!(
        "axcomp-{}-{}-{name}",
        env!("CARGO_CRATE_NAME"),
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Parses a JSON file written by the CLI.
pub fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{} is not JSON: {e}", path.display()))
}
