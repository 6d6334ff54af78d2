//! The one atomic file write of the host libraries.
//!
//! Glossary:
//! - *target*: the file the caller names;
//! - *temporary*: a sibling of the target, `.NAME.axcomp-tmp-PID-K` (process id, a per-process counter),
//!   in the same directory so that the final rename never crosses a file system.
//!
//! - *destination*: what a write does with a target ([`destination`]): a regular file, or a path where
//!   none exists yet, is *replaced* through a temporary; a symbolic link to a regular file replaces the
//!   file it points to and stays a link; a device, FIFO or socket (`/dev/null`, `/dev/stdout`, a named
//!   pipe), or anything reached through `/proc` (`/dev/stdout`, `/dev/fd/N`), is written *in place*,
//!   since a rename would put a regular file where the device was (run as root, `--out /dev/null` used
//!   to turn `/dev/null` into a regular file for the whole machine).
//!
//! [`write_atomic`] writes the bytes to the temporary, syncs it, and renames it over the target: a reader
//! sees either the old file or the whole new one, never a half-written file. On any error the temporary
//! is removed and the target is left as it was. An in-place destination is opened for appending and
//! written once. Library reports, tables, model files, twin campaigns and plots use it; the CLI's
//! `OutputSet` (several files all or nothing) stages each file under the same naming and takes the same
//! [`destination`].

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

/// Where a write to a target goes (see the module docs).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Destination {
    /// Replace this regular file (the target, or the file a symbolic link points to) through a temporary
    /// beside it.
    Replace(PathBuf),
    /// Write into the target as it is: a device, FIFO or socket, or a path through `/proc`.
    InPlace,
}

/// The [`Destination`] of a write to `target`. A path that does not exist (or a link that points
/// nowhere) is replaced, so the write creates it.
pub fn destination(target: &Path) -> Destination {
    let Ok(own) = std::fs::symlink_metadata(target) else {
        return Destination::Replace(target.to_path_buf());
    };
    if own.is_dir() {
        // Not a file at all: the write fails as for any directory, naming the target.
        return Destination::Replace(target.to_path_buf());
    }
    if through_proc(target) {
        return Destination::InPlace;
    }
    if own.is_file() {
        return Destination::Replace(target.to_path_buf());
    }
    if own.file_type().is_symlink() {
        match std::fs::metadata(target) {
            Err(_) => return Destination::Replace(target.to_path_buf()),
            Ok(m) if m.is_file() => {
                if let Ok(real) = std::fs::canonicalize(target) {
                    return Destination::Replace(real);
                }
            }
            Ok(_) => {}
        }
    }
    Destination::InPlace
}

/// True when `target`'s directory, or a link on its way, lies in `/proc` (`/dev/stdout` →
/// `/proc/self/fd/1`, `/dev/fd/N`): a file reached that way is an open file of this process, to be written
/// into, never renamed over.
fn through_proc(target: &Path) -> bool {
    let proc = Path::new("/proc");
    let dir = target
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if std::fs::canonicalize(dir).is_ok_and(|d| d.starts_with(proc)) {
        return true;
    }
    let mut link = target.to_path_buf();
    for _ in 0..40 {
        let Ok(next) = std::fs::read_link(&link) else {
            return false;
        };
        let next = match link.parent() {
            Some(p) if next.is_relative() => p.join(next),
            _ => next,
        };
        if next.starts_with(proc) {
            return true;
        }
        link = next;
    }
    false
}

/// Writes `bytes` into an in-place destination (opened for appending, never created or renamed).
pub fn write_in_place(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let mut f = std::fs::OpenOptions::new().append(true).open(path)?;
    f.write_all(bytes)?;
    f.flush()
}

/// Writes `bytes` to `path` through a synced temporary sibling and a rename, or in place for a device,
/// FIFO or socket (see the module docs).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let path = match destination(path) {
        Destination::InPlace => return write_in_place(path, bytes),
        Destination::Replace(real) => real,
    };
    let tmp = temporary_for(&path)?;
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, &path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// The text of a JSON model file (a positioning table, a thermal model, ...) from its bytes: a UTF-8
/// byte-order mark (some Windows editors write one) is dropped; a binary file is an error that says
/// what it looks like (a firmware image of `axcomp image build`, a trace of `axcomp trace`) instead of
/// a UTF-8 decoding error.
pub fn model_text(bytes: &[u8]) -> Result<&str, String> {
    if bytes.starts_with(b"AXCI") {
        return Err(
            "is a firmware image (binary, `axcomp image build`), not a JSON model file".into(),
        );
    }
    if bytes.starts_with(b"AXTR") {
        return Err("is a firmware trace (binary, `axcomp trace`), not a JSON model file".into());
    }
    let bytes = bytes.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(bytes);
    std::str::from_utf8(bytes).map_err(|e| {
        format!(
            "is not a text file (invalid UTF-8 at byte {}), not a JSON model file",
            e.valid_up_to()
        )
    })
}

/// What a model file's `format` value says it is (`axcomp-thermal-model/1` → a thermal model of
/// `fit thermal --out`), for a message when a file of one kind is given where another is expected.
pub fn model_kind(format: &str) -> Option<&'static str> {
    let kinds = [
        (
            "axcomp-positioning-table",
            "a positioning table (`fit positioning --out`)",
        ),
        (
            "axcomp-thermal-model",
            "a thermal model (`fit thermal --out`)",
        ),
        (
            "axcomp-geometry-model",
            "a geometry model (`fit geometry --out`)",
        ),
        (
            "axcomp-probe-calibration",
            "a probe calibration (`fit probe --out`)",
        ),
    ];
    kinds
        .iter()
        .find(|(prefix, _)| format.starts_with(prefix))
        .map(|(_, kind)| *kind)
}

/// The message for a model file whose `format` is not `expected` (`what`: "positioning table", "thermal
/// model"), or `None` when it is (or the text has no `format`, left to the loader's own parse error): said
/// before serde's first missing field would be, naming another version of the same format or the kind of
/// model the file is ([`model_kind`]).
pub fn wrong_format(text: &str, expected: &str, what: &str) -> Option<String> {
    let value: serde_json::Value = serde_json::from_str(text).ok()?;
    let format = value.get("format")?.as_str()?;
    if format == expected {
        return None;
    }
    let family = |f: &str| f.split('/').next().unwrap_or_default().to_string();
    let why = if family(format) == family(expected) {
        format!(": another version of the {what} format")
    } else if let Some(kind) = model_kind(format) {
        format!(": {kind}, not a {what}")
    } else {
        String::new()
    };
    Some(format!(
        "format is \"{format}\", expected \"{expected}\"{why}"
    ))
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

    #[cfg(unix)]
    #[test]
    fn a_link_to_a_file_stays_a_link_and_its_file_gets_the_bytes() {
        let d = scratch("link");
        let real = d.join("real.txt");
        std::fs::write(&real, b"old").unwrap();
        let link = d.join("link.txt");
        std::os::unix::fs::symlink("real.txt", &link).unwrap();
        write_atomic(&link, b"new").unwrap();
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read(&real).unwrap(), b"new");
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// A named pipe stands for every non-regular target (`/dev/null` is a character device; making one
    /// needs root, see the CLI test `an_output_that_is_a_device_stays_a_device`): it must stay what it
    /// is and get the bytes.
    #[cfg(unix)]
    #[test]
    fn a_named_pipe_stays_a_pipe_and_gets_the_bytes() {
        use std::os::unix::fs::FileTypeExt;
        let d = scratch("fifo");
        let fifo = d.join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            println!("skipped: mkfifo not available");
            return;
        }
        assert_eq!(destination(&fifo), Destination::InPlace);
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(&fifo).unwrap())
        };
        write_atomic(&fifo, b"through the pipe").unwrap();
        assert_eq!(reader.join().unwrap(), b"through the pipe");
        assert!(
            std::fs::symlink_metadata(&fifo)
                .unwrap()
                .file_type()
                .is_fifo()
        );
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn standard_output_and_null_are_written_in_place() {
        assert_eq!(destination(Path::new("/dev/null")), Destination::InPlace);
        assert_eq!(destination(Path::new("/dev/stdout")), Destination::InPlace);
        assert_eq!(destination(Path::new("/dev/fd/1")), Destination::InPlace);
        let d = scratch("dest");
        let f = d.join("x.txt");
        assert_eq!(destination(&f), Destination::Replace(f.clone()));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_path_without_a_file_name_is_refused() {
        let e = write_atomic(Path::new("/"), b"x").unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput);
    }
}
