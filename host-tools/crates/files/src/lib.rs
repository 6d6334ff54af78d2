//! The one atomic file write of the host libraries.
//!
//! Glossary:
//! - *target*: the file the caller names;
//! - *temporary*: a sibling of the target, `.NAME.axcomp-tmp-PID-K` (process id, a per-process counter),
//!   in the same directory so that the final rename never crosses a file system.
//!
//! [`write_atomic`] writes the bytes to the temporary, syncs it, and renames it over the target: a reader
//! sees either the old file or the whole new one, never a half-written file. On any error the temporary
//! is removed and the target is left as it was. Library reports, tables, twin campaigns and plots use it;
//! the CLI's `OutputSet` (several files all or nothing) stages each file under the same naming.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

static NEXT_TEMPORARY: AtomicU64 = AtomicU64::new(0);

/// The temporary sibling for `target` (`.NAME.axcomp-tmp-PID-K`); an error if `target` names no file.
pub fn temporary_for(target: &Path) -> io::Result<PathBuf> {
    let name = target.file_name().ok_or_else(|| {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!("{} is not a file path", target.display()),
        )
    })?;
    let dir = target
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    let k = NEXT_TEMPORARY.fetch_add(1, Ordering::Relaxed);
    Ok(dir.join(format!(
        ".{}.axcomp-tmp-{}-{k}",
        name.to_string_lossy(),
        std::process::id()
    )))
}

/// Writes `bytes` to `path` through a synced temporary sibling and a rename (see the module docs).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let tmp = temporary_for(path)?;
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("axcomp-files-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn replaces_the_target_and_leaves_no_temporary() {
        let d = scratch("replace");
        let f = d.join("out.txt");
        write_atomic(&f, b"one").unwrap();
        write_atomic(&f, b"two").unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"two");
        let names: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("out.txt")]);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_failed_write_leaves_the_target_and_no_temporary() {
        let d = scratch("fail");
        // The target is a directory: the rename fails, the directory and its content stay, and the
        // temporary is removed again.
        let target = d.join("sub");
        std::fs::create_dir(&target).unwrap();
        std::fs::write(target.join("keep"), b"x").unwrap();
        assert!(write_atomic(&target, b"new").is_err());
        assert_eq!(std::fs::read(target.join("keep")).unwrap(), b"x");
        let names: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("sub")]);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_missing_directory_is_an_error_naming_nothing_written() {
        let d = scratch("missing");
        let f = d.join("no-such-dir").join("out.txt");
        assert!(write_atomic(&f, b"x").is_err());
        assert!(!f.exists());
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_path_without_a_file_name_is_refused() {
        let e = write_atomic(Path::new("/"), b"x").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
    }
}
