//! All-or-nothing output files: [`OutputSet`].
//!
//! A command collects every file it will write (path and bytes) in one [`OutputSet`], then calls
//! [`OutputSet::commit`]. Nothing on disk changes unless every file can be written:
//!
//! 1. *check*: every path is checked before anything is written: it names a file (not a directory), its
//!    directory exists (or is declared with [`OutputSet::dir`] and its own parent exists), no two
//!    outputs name the same file (after links: a link and the file it points to are one file, as are
//!    two hard links), and no output lies inside a folder declared with [`OutputSet::folder`] unless it
//!    is that folder's own content ([`OutputSet::folder_file`]);
//! 2. *stage*: each file is written to a temporary beside its target (`.NAME.axcomp-tmp-PID-K`); declared
//!    directories are created first;
//! 3. *swap*: the temporaries are renamed over their targets, an existing target being kept aside
//!    (hard link) until every rename succeeded;
//! 4. *in place*: a target that is a device, FIFO or socket (`/dev/null`, `/dev/stdout`, a named pipe) is
//!    written into, after every swap and before the replaced files are let go, as
//!    [`axcomp_files::destination`] decides (a rename would put a regular file where the device was); a
//!    symbolic link to a regular file is followed, so the link stays and its file is replaced. Several
//!    outputs may go to the same device (`--json /dev/null --out /dev/null`).
//!
//! A *folder* ([`OutputSet::folder`], e.g. `--export DIR`, `--report DIR`) is written whole: it keeps a
//! list of the files the tool wrote into it ([`WRITTEN_LIST`]), and a later commit into the same folder
//! removes the files of that list it does not write again, so the folder never holds a mix of two runs.
//! Other files in the folder (the user's) are left alone.
//!
//! On any error the temporaries are removed, replaced targets are put back, directories created by the set
//! are removed again, and the error names the user's path (never a temporary). Commands should call
//! [`OutputSet::check`] right after parsing their arguments, so that a bad output path fails before a long
//! computation, and [`OutputSet::commit`] at the very end.

use std::collections::HashSet;
use std::ffi::OsString;
use std::path::{Path, PathBuf};

use axcomp_files::{Destination, destination};

/// One planned output file.
#[derive(Debug, Clone)]
struct Planned {
    path: PathBuf,
    /// `None`: declared with [`OutputSet::planned`] and not filled; checked but not written.
    bytes: Option<Vec<u8>>,
    /// The folder ([`OutputSet::folder`]) this file is the content of.
    folder: Option<PathBuf>,
}

/// The list of files the tool wrote into a folder ([`OutputSet::folder`]), one name a line.
pub const WRITTEN_LIST: &str = ".written-by-axcomp";

/// Output files written all together or not at all (see the module docs).
#[derive(Debug, Clone, Default)]
pub struct OutputSet {
    files: Vec<Planned>,
    dirs: Vec<PathBuf>,
    /// Folders written whole, with the option that names each (`--export`).
    folders: Vec<(PathBuf, String)>,
    /// Files the command reads ([`OutputSet::input`]); no output may be one of them.
    inputs: Vec<PathBuf>,
}

/// Why an output cannot be written; always names the user's path.
#[derive(Debug)]
pub enum OutputError {
    /// The path ends in `/`, `.` or `..`, or is empty.
    NotAFileName(PathBuf),
    /// The target exists and is a directory.
    IsADirectory(PathBuf),
    /// A declared output directory exists as a file.
    DirIsAFile(PathBuf),
    /// The directory the file should go into does not exist.
    NoSuchDirectory { path: PathBuf, dir: PathBuf },
    /// A declared output directory cannot be created: its parent is missing or not a directory.
    CannotCreateDir { dir: PathBuf, why: String },
    /// Two outputs name the same file.
    Duplicate { path: PathBuf, other: PathBuf },
    /// An output is a file the command reads (writing it would destroy the input).
    IsAnInput { path: PathBuf, input: PathBuf },
    /// An output lies inside a folder that another output writes whole.
    InsideFolder {
        path: PathBuf,
        folder: PathBuf,
        option: String,
    },
    /// Creating, writing or renaming failed.
    Io {
        path: PathBuf,
        cause: std::io::Error,
    },
}

impl std::fmt::Display for OutputError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            OutputError::NotAFileName(p) => {
                write!(f, "output {}: not a file name", p.display())
            }
            OutputError::IsADirectory(p) => write!(
                f,
                "output {}: is a directory (give a file name)",
                p.display()
            ),
            OutputError::DirIsAFile(p) => write!(
                f,
                "output directory {}: exists and is not a directory",
                p.display()
            ),
            OutputError::NoSuchDirectory { path, dir } => write!(
                f,
                "output {}: directory {} does not exist",
                path.display(),
                dir.display()
            ),
            OutputError::CannotCreateDir { dir, why } => {
                write!(f, "cannot create {}: {why}", dir.display())
            }
            OutputError::Duplicate { path, other } => write!(
                f,
                "output {} and {} name the same file",
                path.display(),
                other.display()
            ),
            OutputError::IsAnInput { path, input } => write!(
                f,
                "output {} is the input {} (it would be overwritten; give another output path)",
                path.display(),
                input.display()
            ),
            OutputError::InsideFolder {
                path,
                folder,
                option,
            } => write!(
                f,
                "output {} lies inside {} {}, a folder the command writes whole (give a path outside it)",
                path.display(),
                option,
                folder.display()
            ),
            OutputError::Io { path, cause } => {
                write!(f, "cannot write {}: {cause}", path.display())
            }
        }
    }
}

impl std::error::Error for OutputError {}

/// The directory a path's file lives in (`.` for a bare file name).
fn parent_of(path: &Path) -> PathBuf {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// A sibling of `path` named `.NAME.axcomp-KIND-PID-K`.
fn sibling(path: &Path, kind: &str, k: usize) -> PathBuf {
    let mut name = OsString::from(".");
    name.push(path.file_name().unwrap_or_default());
    name.push(format!(".axcomp-{kind}-{}-{k}", std::process::id()));
    parent_of(path).join(name)
}

/// A key that is equal for two spellings of the same file (`a/x` and `a/./x`), as far as the existing
/// directories allow.
fn identity(path: &Path) -> PathBuf {
    let dir = parent_of(path);
    let dir = std::fs::canonicalize(&dir).unwrap_or_else(|_| {
        dir.components().collect::<PathBuf>() // normalises `a/./b` and trailing separators
    });
    dir.join(path.file_name().unwrap_or_default())
}

impl OutputSet {
    pub fn new() -> Self {
        Self::default()
    }

    /// Declares a directory the outputs may be written into (e.g. `--report DIR`); it is created at
    /// commit when missing (its parent must exist) and removed again if the commit fails.
    pub fn dir(&mut self, dir: impl Into<PathBuf>) -> &mut Self {
        let dir = dir.into();
        if !self.dirs.contains(&dir) {
            self.dirs.push(dir);
        }
        self
    }

    /// Declares a folder written whole (see the module docs), named by `option` in messages: like
    /// [`OutputSet::dir`], and every other output inside it is refused; its files are given with
    /// [`OutputSet::folder_file`].
    pub fn folder(&mut self, dir: impl Into<PathBuf>, option: &str) -> &mut Self {
        let dir = dir.into();
        self.dir(dir.clone());
        if !self.folders.iter().any(|(d, _)| *d == dir) {
            self.folders.push((dir, option.to_string()));
        }
        self
    }

    /// Adds file `name` of folder `dir` (declared with [`OutputSet::folder`]).
    pub fn folder_file(&mut self, dir: &Path, name: &str, bytes: impl Into<Vec<u8>>) -> &mut Self {
        self.add(dir.join(name), Some(bytes.into()), Some(dir.to_path_buf()))
    }

    /// Adds a file: fills the first planned entry of that path still without content; a path that
    /// already has content is added again (and refused by the check as two outputs naming one file).
    pub fn file(&mut self, path: impl Into<PathBuf>, bytes: impl Into<Vec<u8>>) -> &mut Self {
        self.add(path.into(), Some(bytes.into()), None)
    }

    fn add(&mut self, path: PathBuf, bytes: Option<Vec<u8>>, folder: Option<PathBuf>) -> &mut Self {
        let at = self
            .files
            .iter()
            .position(|f| f.path == path && f.bytes.is_none() && f.folder == folder);
        match at {
            Some(k) if bytes.is_some() => self.files[k].bytes = bytes,
            _ => self.files.push(Planned {
                path,
                bytes,
                folder,
            }),
        }
        self
    }

    /// Declares a file the command reads: [`OutputSet::check`] refuses an output that is the same file
    /// (by any spelling, link or hard link), so that `--out` never overwrites an input.
    pub fn input(&mut self, path: impl Into<PathBuf>) -> &mut Self {
        self.inputs.push(path.into());
        self
    }

    /// Declares a file whose content is not known yet, so that [`OutputSet::check`] can test its path
    /// before the work; give the content later with [`OutputSet::file`]. A planned file that never gets
    /// content is not written (e.g. a table the guard refused). Planning one path twice (two options
    /// naming the same file, e.g. `--out x --csv x`) is an error at [`OutputSet::check`], as for two
    /// spellings of one file.
    pub fn planned(&mut self, path: impl Into<PathBuf>) -> &mut Self {
        let path = path.into();
        self.files.push(Planned {
            path,
            bytes: None,
            folder: None,
        });
        self
    }

    /// [`OutputSet::planned`] for file `name` of folder `dir` (declared with [`OutputSet::folder`]).
    pub fn planned_in(&mut self, dir: &Path, name: &str) -> &mut Self {
        self.add(dir.join(name), None, Some(dir.to_path_buf()))
    }

    /// Removes a planned file (e.g. a table the guard refused).
    pub fn remove(&mut self, path: &Path) -> &mut Self {
        self.files.retain(|f| f.path != path);
        self
    }

    /// Adds `value` as pretty JSON with a final newline.
    pub fn json<T: serde::Serialize>(
        &mut self,
        path: impl Into<PathBuf>,
        value: &T,
    ) -> anyhow::Result<&mut Self> {
        let mut text = serde_json::to_string_pretty(value)?;
        text.push('\n');
        Ok(self.file(path, text))
    }

    /// The files that will be written, in order.
    pub fn paths(&self) -> Vec<&Path> {
        self.files
            .iter()
            .filter(|f| f.bytes.is_some())
            .map(|f| f.path.as_path())
            .collect()
    }

    /// Checks every path without writing anything (step 1 of the module docs).
    pub fn check(&self) -> Result<(), OutputError> {
        let declared: HashSet<PathBuf> = self.dirs.iter().map(|d| identity_dir(d)).collect();
        for d in &self.dirs {
            if d.exists() && !d.is_dir() {
                return Err(OutputError::DirIsAFile(d.clone()));
            }
            if !d.exists() {
                let p = parent_of(d);
                if !p.is_dir() {
                    let why = if p.exists() {
                        format!("{} is not a directory", p.display())
                    } else {
                        format!("directory {} does not exist", p.display())
                    };
                    return Err(OutputError::CannotCreateDir {
                        dir: d.clone(),
                        why,
                    });
                }
            }
        }
        let mut seen: Vec<(PathBuf, &Path)> = Vec::new();
        for f in &self.files {
            let p = &f.path;
            let name_ok =
                p.file_name().is_some() && !p.as_os_str().to_string_lossy().ends_with(['/', '\\']);
            if !name_ok {
                return Err(OutputError::NotAFileName(p.clone()));
            }
            if p.is_dir() {
                return Err(OutputError::IsADirectory(p.clone()));
            }
            let dir = parent_of(p);
            if !dir.is_dir() && !declared.contains(&identity_dir(&dir)) {
                return Err(OutputError::NoSuchDirectory {
                    path: p.clone(),
                    dir,
                });
            }
            if declared.contains(&identity_dir(p)) {
                return Err(OutputError::Duplicate {
                    path: p.clone(),
                    other: p.clone(),
                });
            }
            let real = match destination(p) {
                Destination::InPlace => continue,
                Destination::Replace(real) => real,
            };
            self.check_folder(f, &real)?;
            if let Some(input) = self.inputs.iter().find(|i| same_file(p, i)) {
                return Err(OutputError::IsAnInput {
                    path: p.clone(),
                    input: input.clone(),
                });
            }
            let id = identity(&real);
            if let Some((_, other)) = seen
                .iter()
                .find(|(k, other)| *k == id || same_file(p, other))
            {
                return Err(OutputError::Duplicate {
                    path: p.clone(),
                    other: other.to_path_buf(),
                });
            }
            seen.push((id, p));
        }
        Ok(())
    }

    /// An output that is not the content of a folder must not lie inside one (`real`: where it is
    /// written, after links).
    fn check_folder(&self, f: &Planned, real: &Path) -> Result<(), OutputError> {
        if f.folder.is_some() {
            return Ok(());
        }
        let dir = identity_dir(&parent_of(real));
        match self
            .folders
            .iter()
            .find(|(d, _)| dir.starts_with(identity_dir(d)))
        {
            Some((folder, option)) => Err(OutputError::InsideFolder {
                path: f.path.clone(),
                folder: folder.clone(),
                option: option.clone(),
            }),
            None => Ok(()),
        }
    }

    /// Adds each folder's [`WRITTEN_LIST`] to the set and returns the files of the earlier lists that
    /// this commit does not write again (removed once everything is written).
    fn list_folders(&mut self) -> Vec<PathBuf> {
        let mut stale = Vec::new();
        for (dir, _) in self.folders.clone() {
            let names: Vec<String> = self
                .files
                .iter()
                .filter(|f| f.folder.as_ref() == Some(&dir) && f.bytes.is_some())
                .filter_map(|f| f.path.file_name())
                .map(|n| n.to_string_lossy().into_owned())
                .collect();
            let earlier = std::fs::read_to_string(dir.join(WRITTEN_LIST)).unwrap_or_default();
            for old in earlier.lines().filter(|l| !l.starts_with('#')) {
                // Only plain names of this folder: a list edited to name `../x` removes nothing.
                let plain = Path::new(old).file_name() == Some(std::ffi::OsStr::new(old));
                if plain && old != WRITTEN_LIST && !names.iter().any(|n| n == old) {
                    stale.push(dir.join(old));
                }
            }
            let mut list = String::from(
                "# files axcomp wrote here; the next run removes those it does not write again\n",
            );
            for n in &names {
                list.push_str(n);
                list.push('\n');
            }
            self.folder_file(&dir, WRITTEN_LIST, list);
        }
        stale
    }

    /// Writes every file or none (steps 1–3 of the module docs). Returns the paths written.
    pub fn commit(mut self) -> Result<Vec<PathBuf>, OutputError> {
        self.check()?;
        self.files.retain(|f| f.bytes.is_some());
        let stale = self.list_folders();
        // Directories, outermost first.
        let mut created: Vec<PathBuf> = Vec::new();
        let undo_dirs = |created: &[PathBuf]| {
            for d in created.iter().rev() {
                let _ = std::fs::remove_dir(d);
            }
        };
        for d in &self.dirs {
            if !d.is_dir() {
                if let Err(cause) = std::fs::create_dir(d) {
                    undo_dirs(&created);
                    return Err(OutputError::Io {
                        path: d.clone(),
                        cause,
                    });
                }
                created.push(d.clone());
            }
        }
        // Where each file goes: the regular file to replace (a link's file), or `None` for in place.
        let replaced: Vec<Option<PathBuf>> = self
            .files
            .iter()
            .map(|f| match destination(&f.path) {
                Destination::Replace(real) => Some(real),
                Destination::InPlace => None,
            })
            .collect();
        // Stage.
        let mut staged: Vec<Option<PathBuf>> = Vec::new();
        for (k, f) in self.files.iter().enumerate() {
            let Some(real) = &replaced[k] else {
                staged.push(None);
                continue;
            };
            let tmp = sibling(real, "tmp", k);
            let bytes = f.bytes.as_deref().unwrap_or_default();
            if let Err(cause) = std::fs::write(&tmp, bytes) {
                let _ = std::fs::remove_file(&tmp);
                for t in staged.iter().flatten() {
                    let _ = std::fs::remove_file(t);
                }
                undo_dirs(&created);
                return Err(OutputError::Io {
                    path: f.path.clone(),
                    cause,
                });
            }
            staged.push(Some(tmp));
        }
        // Puts the replaced files back and removes new ones (for the swaps in `done`), drops the
        // temporaries not yet renamed and the directories the set created.
        let roll_back = |done: &[(usize, Option<PathBuf>)], from: usize| {
            for (j, old) in done.iter().rev() {
                let Some(target) = &replaced[*j] else {
                    continue;
                };
                match old {
                    Some(old) => {
                        let _ = std::fs::rename(old, target);
                    }
                    None => {
                        let _ = std::fs::remove_file(target);
                    }
                }
            }
            for t in staged[from..].iter().flatten() {
                let _ = std::fs::remove_file(t);
            }
            undo_dirs(&created);
        };
        // Swap, keeping replaced targets aside until every rename succeeded.
        let mut done: Vec<(usize, Option<PathBuf>)> = Vec::new();
        for (k, f) in self.files.iter().enumerate() {
            let (Some(target), Some(tmp)) = (&replaced[k], &staged[k]) else {
                continue;
            };
            let mut kept = None;
            let mut failure = None;
            if target.exists() {
                let old = sibling(target, "old", k);
                let _ = std::fs::remove_file(&old);
                match std::fs::hard_link(target, &old)
                    .or_else(|_| std::fs::copy(target, &old).map(|_| ()))
                {
                    Ok(()) => kept = Some(old),
                    Err(cause) => failure = Some(cause),
                }
            }
            if failure.is_none() {
                if let Err(cause) = std::fs::rename(tmp, target) {
                    failure = Some(cause);
                    if let Some(old) = kept.take() {
                        let _ = std::fs::remove_file(old);
                    }
                }
            }
            if let Some(cause) = failure {
                roll_back(&done, k);
                return Err(OutputError::Io {
                    path: f.path.clone(),
                    cause,
                });
            }
            done.push((k, kept));
        }
        // In place, last: a device cannot be rolled back, so every replaced file is already in place.
        for (k, f) in self.files.iter().enumerate() {
            if replaced[k].is_some() {
                continue;
            }
            let bytes = f.bytes.as_deref().unwrap_or_default();
            if let Err(cause) = axcomp_files::write_in_place(&f.path, bytes) {
                roll_back(&done, self.files.len());
                return Err(OutputError::Io {
                    path: f.path.clone(),
                    cause,
                });
            }
        }
        for (_, old) in done {
            if let Some(old) = old {
                let _ = std::fs::remove_file(old);
            }
        }
        for f in stale {
            if std::fs::symlink_metadata(&f).is_ok_and(|m| m.is_file()) {
                let _ = std::fs::remove_file(f);
            }
        }
        Ok(self
            .files
            .into_iter()
            .filter(|f| f.path.file_name() != Some(std::ffi::OsStr::new(WRITTEN_LIST)))
            .map(|f| f.path)
            .collect())
    }
}

/// Like [`identity`] for a directory path itself.
/// Whether `a` and `b` are one existing file (the same path after links, or the same inode).
fn same_file(a: &Path, b: &Path) -> bool {
    let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        if ma.dev() == mb.dev() && ma.ino() == mb.ino() {
            return true;
        }
    }
    let _ = (ma, mb);
    matches!(
        (std::fs::canonicalize(a), std::fs::canonicalize(b)),
        (Ok(x), Ok(y)) if x == y
    )
}

fn identity_dir(dir: &Path) -> PathBuf {
    std::fs::canonicalize(dir).unwrap_or_else(|_| {
        if dir.file_name().is_some() {
            identity(dir)
        } else {
            dir.components().collect()
        }
    })
}

/// `, peak N MB` (the process's peak resident memory, Linux `VmHWM`) for progress lines; empty elsewhere.
pub fn peak_memory_note() -> String {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
        })
        .map_or(String::new(), |kb| format!(", peak {} MB", kb / 1024))
}

/// Writes one file through an [`OutputSet`] (for commands with a single output).
pub fn write_one(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    let mut set = OutputSet::new();
    set.file(path, bytes);
    set.commit().map(|_| ())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("axcomp-output-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn listing(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn writes_all_and_replaces_old_files() {
        let d = scratch("all");
        std::fs::write(d.join("a.txt"), "old a").unwrap();
        let mut s = OutputSet::new();
        s.file(d.join("a.txt"), "new a")
            .dir(d.join("rep"))
            .file(d.join("rep/r.md"), "report");
        let written = s.commit().unwrap();
        assert_eq!(written.len(), 2);
        assert_eq!(std::fs::read_to_string(d.join("a.txt")).unwrap(), "new a");
        assert_eq!(
            std::fs::read_to_string(d.join("rep/r.md")).unwrap(),
            "report"
        );
        assert_eq!(listing(&d), ["a.txt", "rep"]); // no temporary or kept-aside file left
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// A link to a regular file stays a link (its file replaced); a named pipe stays a pipe and gets its
    /// bytes; two outputs may name the same pipe or device.
    #[cfg(unix)]
    #[test]
    fn links_are_followed_and_pipes_written_in_place() {
        use std::os::unix::fs::FileTypeExt;
        let d = scratch("inplace");
        std::fs::write(d.join("real.json"), "old").unwrap();
        std::os::unix::fs::symlink("real.json", d.join("link.json")).unwrap();
        let fifo = d.join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            println!("skipped: mkfifo not available");
            return;
        }
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read_to_string(&fifo).unwrap())
        };
        // Two outputs naming the same pipe pass the check (a regular file twice does not).
        let mut twice = OutputSet::new();
        twice.file(&fifo, "one").file(d.join("./pipe"), "two");
        twice.check().unwrap();
        let mut s = OutputSet::new();
        s.file(d.join("link.json"), "new")
            .file(&fifo, "through the pipe");
        s.commit().unwrap();
        assert_eq!(reader.join().unwrap(), "through the pipe");
        assert!(
            std::fs::symlink_metadata(d.join("link.json"))
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(std::fs::read_to_string(d.join("real.json")).unwrap(), "new");
        assert!(
            std::fs::symlink_metadata(&fifo)
                .unwrap()
                .file_type()
                .is_fifo()
        );
        assert_eq!(listing(&d), ["link.json", "pipe", "real.json"]);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_bad_last_path_touches_nothing_and_names_the_user_path() {
        let d = scratch("bad");
        std::fs::write(d.join("t.json"), "old").unwrap();
        let mut s = OutputSet::new();
        s.file(d.join("t.json"), "new")
            .dir(d.join("report"))
            .file(d.join("report/x.md"), "x")
            .file(d.join("missing-dir/f.json"), "j");
        let e = s.clone().commit().unwrap_err().to_string();
        assert!(
            e.contains("missing-dir/f.json") && !e.contains("axcomp-tmp"),
            "{e}"
        );
        assert_eq!(std::fs::read_to_string(d.join("t.json")).unwrap(), "old");
        assert_eq!(listing(&d), ["t.json"]);
        // A directory where a file should go; duplicate paths.
        std::fs::create_dir(d.join("isdir")).unwrap();
        let mut s = OutputSet::new();
        s.file(d.join("t.json"), "new").file(d.join("isdir"), "x");
        assert!(matches!(s.commit(), Err(OutputError::IsADirectory(_))));
        let mut s = OutputSet::new();
        s.file(d.join("t.json"), "1")
            .file(d.join("isdir/../t.json"), "2");
        assert!(matches!(s.commit(), Err(OutputError::Duplicate { .. })));
        assert_eq!(std::fs::read_to_string(d.join("t.json")).unwrap(), "old");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[cfg(unix)]
    #[test]
    fn a_write_failure_after_the_check_rolls_back() {
        use std::os::unix::fs::PermissionsExt;
        let d = scratch("ro");
        std::fs::write(d.join("a.txt"), "old a").unwrap();
        let ro = d.join("ro");
        std::fs::create_dir(&ro).unwrap();
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o555)).unwrap();
        if std::fs::write(ro.join("probe"), "x").is_ok() {
            // Running as root: permissions do not stop writes; nothing to test here.
            println!("skipped: directory permissions are not enforced (root)");
            std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
            std::fs::remove_dir_all(&d).unwrap();
            return;
        }
        let mut s = OutputSet::new();
        s.file(d.join("a.txt"), "new a")
            .dir(d.join("newdir"))
            .file(d.join("newdir/n.txt"), "n")
            .file(ro.join("b.txt"), "b");
        let e = s.commit().unwrap_err().to_string();
        assert!(e.contains("ro/b.txt") && !e.contains("axcomp-tmp"), "{e}");
        assert_eq!(std::fs::read_to_string(d.join("a.txt")).unwrap(), "old a");
        assert_eq!(listing(&d), ["a.txt", "ro"]);
        std::fs::set_permissions(&ro, std::fs::Permissions::from_mode(0o755)).unwrap();
        std::fs::remove_dir_all(&d).unwrap();
    }
}
