//! Host file I/O over ARM semihosting (QEMU `-semihosting-config enable=on,target=native`).
//!
//! Glossary:
//! - **Semihosting**: the target executes `bkpt 0xAB` with an operation number in r0; the debugger or QEMU
//!   performs the operation (open/read/write a host file, exit) on the host and returns the result.
//! - **Command line**: `SYS_GET_CMDLINE` returns the arguments QEMU was given with
//!   `-semihosting-config arg=...` (or `-append`), the first being the program name.

use cortex_m_semihosting::{debug, nr, syscall};

/// A semihosting operation failed; `op` names it, `errno` is the host's errno (SYS_ERRNO).
#[derive(Clone, Copy)]
pub struct HostError {
    pub op: &'static str,
    pub errno: usize,
}

/// `OP (errno N)`: the replay errors print their byte source's error with `{:?}`; a derived `Debug`
/// would link `core::fmt`'s struct builders and the `str` escaping (Unicode tables) for this one struct.
impl core::fmt::Debug for HostError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.op)?;
        write!(f, " (errno {})", self.errno)
    }
}

fn last_error(op: &'static str) -> HostError {
    // SAFETY: SYS_ERRNO takes no argument and only reads the host's errno.
    let errno = unsafe { syscall!(ERRNO) };
    HostError { op, errno }
}

/// An open host file.
pub struct HostFile {
    handle: usize,
}

impl HostFile {
    /// Opens `path` (no NUL needed; at most 255 bytes) for binary reading.
    pub fn open_read(path: &str) -> Result<HostFile, HostError> {
        Self::open(path, nr::open::R_BINARY, "open for reading")
    }

    /// Creates or truncates `path` for binary writing.
    pub fn create(path: &str) -> Result<HostFile, HostError> {
        Self::open(path, nr::open::W_TRUNC_BINARY, "create")
    }

    // One copy for both modes (inlined, each would carry its own NUL scan).
    #[inline(never)]
    fn open(path: &str, mode: usize, op: &'static str) -> Result<HostFile, HostError> {
        let mut name = [0u8; 256];
        let bytes = path.as_bytes();
        if bytes.len() >= name.len() || bytes.contains(&0) {
            return Err(HostError { op, errno: 0 });
        }
        name[..bytes.len()].copy_from_slice(bytes);
        // SAFETY: SYS_OPEN reads `len` bytes of a NUL-terminated name from a live buffer.
        let handle = unsafe { syscall!(OPEN, name.as_ptr(), mode, bytes.len()) } as isize;
        if handle < 0 {
            return Err(last_error(op));
        }
        Ok(HostFile {
            handle: handle as usize,
        })
    }

    /// Length of the file in bytes.
    pub fn length(&self) -> Result<usize, HostError> {
        // SAFETY: SYS_FLEN takes the handle only.
        let n = unsafe { syscall!(FLEN, self.handle) } as isize;
        if n < 0 {
            return Err(last_error("file length"));
        }
        Ok(n as usize)
    }

    /// Reads up to `buf.len()` bytes; returns how many were read (0 at end of file).
    pub fn read(&mut self, buf: &mut [u8]) -> Result<usize, HostError> {
        if buf.is_empty() {
            return Ok(0);
        }
        // SAFETY: SYS_READ writes at most `buf.len()` bytes into `buf`; returns the count NOT read.
        let not_read = unsafe { syscall!(READ, self.handle, buf.as_mut_ptr(), buf.len()) };
        if not_read > buf.len() {
            return Err(last_error("read"));
        }
        Ok(buf.len() - not_read)
    }

    /// Fills `buf` as far as the file allows; returns the count (< `buf.len()` only at end of file).
    pub fn read_full(&mut self, buf: &mut [u8]) -> Result<usize, HostError> {
        let mut done = 0;
        while done < buf.len() {
            let n = self.read(&mut buf[done..])?;
            if n == 0 {
                break;
            }
            done += n;
        }
        Ok(done)
    }

    /// Writes all of `data`.
    pub fn write_all(&mut self, mut data: &[u8]) -> Result<(), HostError> {
        while !data.is_empty() {
            // SAFETY: SYS_WRITE reads `data.len()` bytes from `data`; returns the count NOT written.
            let not_written = unsafe { syscall!(WRITE, self.handle, data.as_ptr(), data.len()) };
            if not_written == data.len() {
                return Err(last_error("write"));
            }
            if not_written > data.len() {
                return Err(last_error("write"));
            }
            data = &data[data.len() - not_written..];
        }
        Ok(())
    }

    /// Closes the file (also done on drop, ignoring errors).
    pub fn close(self) -> Result<(), HostError> {
        let handle = self.handle;
        core::mem::forget(self);
        // SAFETY: SYS_CLOSE takes the handle only.
        if unsafe { syscall!(CLOSE, handle) } != 0 {
            return Err(last_error("close"));
        }
        Ok(())
    }
}

impl Drop for HostFile {
    fn drop(&mut self) {
        // SAFETY: as in `close`.
        unsafe { syscall!(CLOSE, self.handle) };
    }
}

/// Output bytes collected into a RAM block before each semihosting write (one host call per block
/// instead of one per record); the file's bytes are the same for any block size.
pub struct OutBlock<'a> {
    file: HostFile,
    buf: &'a mut [u8],
    len: usize,
    error: Option<HostError>,
}

impl<'a> OutBlock<'a> {
    pub fn new(file: HostFile, buf: &'a mut [u8]) -> Self {
        OutBlock {
            file,
            buf,
            len: 0,
            error: None,
        }
    }

    /// Appends `bytes` (at most the block's size), writing the block out first when they do not fit.
    /// After a failed write nothing more is written; [`OutBlock::finish`] reports it.
    pub fn push(&mut self, bytes: &[u8]) {
        if self.len + bytes.len() > self.buf.len() {
            self.flush();
        }
        let n = bytes.len().min(self.buf.len() - self.len);
        self.buf[self.len..self.len + n].copy_from_slice(&bytes[..n]);
        self.len += n;
    }

    fn flush(&mut self) {
        if self.len > 0 && self.error.is_none() {
            self.error = self.file.write_all(&self.buf[..self.len]).err();
        }
        self.len = 0;
    }

    /// Writes what is left and closes the file: `Err(("writing", e))` for the first failed write,
    /// `Err(("closing", e))` when the close fails.
    pub fn finish(mut self) -> Result<(), (&'static str, HostError)> {
        self.flush();
        if let Some(e) = self.error {
            return Err(("writing", e));
        }
        self.file.close().map_err(|e| ("closing", e))
    }
}

/// Trace file name when the command line gives none.
pub const DEFAULT_TRACE_PATH: &str = "axcomp-trace.bin";
/// Output file name when the command line gives none.
pub const DEFAULT_OUT_PATH: &str = "axcomp-out.bin";

/// The trace and output file names from the semihosting command line `PROGRAM TRACE OUT` (words
/// separated by ASCII white space or NULs), read into `buf`; a missing word (or one that is not
/// UTF-8) is [`DEFAULT_TRACE_PATH`] / [`DEFAULT_OUT_PATH`]. Split by bytes: `str::split_ascii_whitespace`
/// and `str::trim` cost about 1.5 KiB of code flash for these two words.
pub fn trace_and_output_paths(buf: &mut [u8]) -> (&str, &str) {
    let mut paths = [DEFAULT_TRACE_PATH, DEFAULT_OUT_PATH];
    let block = [buf.as_mut_ptr() as usize, buf.len()];
    // SAFETY: r1 points at the parameter block {buffer, length}; the host writes at most `length` bytes
    // into `buf` and the used length back into block[1] (read volatile below).
    let r = unsafe { cortex_m_semihosting::syscall(nr::GET_CMDLINE, &block) };
    if r != 0 {
        return (paths[0], paths[1]);
    }
    // SAFETY: reading our own initialised local after the host may have written it.
    let len = unsafe { core::ptr::read_volatile(&block[1]) }.min(buf.len());
    let line = &buf[..len];
    let (mut at, mut word) = (0, 0);
    while word <= paths.len() {
        while at < line.len() && line[at] <= b' ' {
            at += 1;
        }
        let start = at;
        while at < line.len() && line[at] > b' ' {
            at += 1;
        }
        if start == at {
            break;
        }
        // Word 0 is the program's name.
        if word > 0 {
            if let Ok(p) = core::str::from_utf8(&line[start..at]) {
                paths[word - 1] = p;
            }
        }
        word += 1;
    }
    (paths[0], paths[1])
}

/// Exits QEMU with status 0.
pub fn exit_success() -> ! {
    debug::exit(debug::EXIT_SUCCESS);
    #[allow(clippy::empty_loop)]
    loop {}
}

/// Exits QEMU with status `code`. On 32-bit ARM, SYS_EXIT (0x18) only distinguishes success from failure;
/// SYS_EXIT_EXTENDED (0x20) takes a {reason, subcode} block and QEMU exits with the subcode when the reason
/// is ADP_Stopped_ApplicationExit (0x20026). Falls back to a plain failure exit if the host ignores it.
pub fn exit_code(code: u32) -> ! {
    if code == 0 {
        exit_success()
    }
    let block = [0x20026usize, code as usize];
    // SAFETY: r1 points at the {reason, subcode} block; the host terminates the program.
    unsafe { cortex_m_semihosting::syscall(0x20, &block) };
    exit_failure()
}

/// Exits QEMU with a non-zero status.
pub fn exit_failure() -> ! {
    debug::exit(debug::EXIT_FAILURE);
    #[allow(clippy::empty_loop)]
    loop {}
}

/// Writes `program: panic at FILE:LINE:COLUMN` to the host's stdout and exits with status 1.
///
/// The location only: a handler that formats the whole `PanicInfo` (or even asks its message for a
/// plain string) keeps every panic site's message arguments alive, linking `core::fmt`'s `Debug`
/// builders, `str` escaping and the Unicode tables (about 3 to 8 KiB of code flash in
/// `axcomp-qemu-group`); the location says which check failed.
pub fn report_panic(program: &str, info: &core::panic::PanicInfo) -> ! {
    match info.location() {
        Some(at) => cortex_m_semihosting::hprintln!(
            "{}: panic at {}:{}:{}",
            program,
            at.file(),
            at.line(),
            at.column()
        ),
        None => cortex_m_semihosting::hprintln!("{}: panic", program),
    }
    exit_failure()
}
