//! Workspace-level system tests live in `tests/tests/`; helpers shared by them live here.
//!
//! Glossary:
//! - **Workspace root**: the directory of the root `Cargo.toml` (parent of this package).
//! - **Shared data**: `../shared` next to the workspace root (override: env `AXCOMP_SHARED`).
//! - **CI mode**: env `CI` set; a missing prerequisite (shared data, QEMU) is then a failure, not a skip.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// The workspace root.
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .expect("tests/ has a parent")
        .to_path_buf()
}

/// True when running in CI (env `CI` set).
pub fn in_ci() -> bool {
    std::env::var_os("CI").is_some()
}

/// The shared directory (`AXCOMP_SHARED` or `../shared` from the workspace root), `None` when absent
/// outside CI (after printing `skipped: ../shared not found`); panics when absent in CI.
pub fn shared_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("AXCOMP_SHARED") {
        Some(p) => PathBuf::from(p),
        None => workspace_root().join("../shared"),
    };
    if dir.is_dir() {
        return Some(dir);
    }
    if in_ci() {
        panic!(
            "{} not found (CI is set, so this is a failure)",
            dir.display()
        );
    }
    println!("skipped: ../shared not found");
    None
}

/// True when `program --version` runs; otherwise prints `skipped: {program} not found` and returns false,
/// or panics in CI.
pub fn require_tool(program: &str) -> bool {
    let ok = Command::new(program)
        .arg("--version")
        .output()
        .map(|o| o.status.success())
        .unwrap_or(false);
    if !ok {
        if in_ci() {
            panic!("{program} not found (CI is set, so this is a failure)");
        }
        println!("skipped: {program} not found");
    }
    ok
}

/// Waits for `child` at most `timeout`; kills it and returns `None` on timeout.
pub fn wait_timeout(child: &mut Child, timeout: Duration) -> std::io::Result<Option<ExitStatus>> {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(st) = child.try_wait()? {
            return Ok(Some(st));
        }
        if Instant::now() >= deadline {
            let _ = child.kill();
            let _ = child.wait();
            return Ok(None);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// A fresh scratch directory under the system temp dir, unique to this process and `tag`.
pub fn scratch_dir(tag: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("axcomp-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("creating a scratch dir");
    d
}

/// Builds a firmware bin for QEMU (release, thumbv7em-none-eabihf, feature `qemu`) in its own target dir so
/// the nested cargo does not wait on the outer one's lock; returns the ELF path.
///
/// Builds run one at a time within a test binary, and each bin is built once per test binary: the tests
/// of a file run on parallel threads and several ask for the same bin. The nested cargo gets `/dev/null`
/// as standard input and none of the outer cargo's jobserver variables.
pub fn build_qemu_firmware(bin: &str) -> PathBuf {
    static BUILT: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
    let root = workspace_root();
    let target_dir = match std::env::var_os("AXCOMP_QEMU_TARGET_DIR") {
        Some(d) => PathBuf::from(d),
        None => root.join("target/qemu-equivalence"),
    };
    let elf = target_dir.join("thumbv7em-none-eabihf/release").join(bin);
    // A test that panicked while holding the lock leaves nothing half-done here: a bin is only listed
    // after a successful build.
    let mut built = BUILT
        .lock()
        .unwrap_or_else(|poisoned| poisoned.into_inner());
    if built.iter().any(|b| b == bin) {
        return elf;
    }
    let out = cargo_build_qemu(&root, &target_dir, bin);
    assert!(
        out.status.success(),
        "building {bin} for QEMU failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    built.push(bin.to_string());
    elf
}

/// One `cargo build` of a QEMU firmware bin into `target_dir`, with its output captured.
fn cargo_build_qemu(root: &Path, target_dir: &Path, bin: &str) -> std::process::Output {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    Command::new(cargo)
        .current_dir(root)
        .env("CARGO_TARGET_DIR", target_dir)
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_MAKEFLAGS")
        .env_remove("MAKEFLAGS")
        .env_remove("MFLAGS")
        .stdin(Stdio::null())
        .args([
            "build",
            "--release",
            "--target",
            "thumbv7em-none-eabihf",
            "-p",
            "axcomp-firmware",
            "--features",
            "qemu",
            "--bin",
            bin,
        ])
        .output()
        .expect("running cargo to build the QEMU firmware")
}

/// QEMU's command line for an ELF on netduinoplus2 with semihosting and deterministic instruction counting;
/// `args` become the semihosting command line after the program name.
pub fn qemu_command(elf: &Path, args: &[&str]) -> Command {
    let mut sh = String::from("enable=on,target=native,arg=firmware");
    for a in args {
        assert!(
            !a.contains(',') && !a.contains(' '),
            "semihosting argument {a:?} must not contain , or space"
        );
        sh.push_str(",arg=");
        sh.push_str(a);
    }
    let mut c = Command::new("qemu-system-arm");
    c.args([
        "-machine",
        "netduinoplus2",
        "-nographic",
        "-monitor",
        "none",
        "-serial",
        "none",
    ])
    .args(["-semihosting-config", &sh])
    .args(["-icount", "shift=0"])
    .arg("-kernel")
    .arg(elf);
    c
}

/// How long one QEMU replay may take before the test fails.
pub const QEMU_TIMEOUT: Duration = Duration::from_secs(300);

/// Runs the firmware `elf` in QEMU on `trace` (written as `trace.bin` into a scratch directory named
/// after `tag`) and returns its exit status, its standard output (also printed, for `--nocapture`) and
/// the `out.bin` it wrote (empty if none). A QEMU that does not finish within [`QEMU_TIMEOUT`] fails
/// the test with its output.
pub fn qemu_replay(elf: &Path, tag: &str, trace: &[u8]) -> (ExitStatus, String, Vec<u8>) {
    let dir = scratch_dir(tag);
    std::fs::write(dir.join("trace.bin"), trace).unwrap();
    let mut child = qemu_command(elf, &["trace.bin", "out.bin"])
        .current_dir(&dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("starting qemu-system-arm");
    let status = wait_timeout(&mut child, QEMU_TIMEOUT).expect("waiting for QEMU");
    let out = child.wait_with_output().expect("QEMU output");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    let stderr = String::from_utf8_lossy(&out.stderr);
    let status = status.unwrap_or_else(|| {
        panic!("QEMU timed out after {QEMU_TIMEOUT:?}\nstdout:\n{stdout}\nstderr:\n{stderr}")
    });
    println!("{stdout}");
    let got = std::fs::read(dir.join("out.bin")).unwrap_or_default();
    let _ = std::fs::remove_dir_all(&dir);
    (status, stdout, got)
}

/// Coefficient pool of the group firmware `axcomp-qemu-group` (segments per slot).
pub const GROUP_POOL: usize = 1024;

/// The host's replay of a group trace through the same core as the firmware (`axcomp_firmware::replay`):
/// the encoded output records, the number of cycles and of errors.
pub fn host_group_replay(trace: &[u8]) -> (Vec<u8>, u32, u32) {
    use axcomp_core::group::GroupEngine;
    use axcomp_firmware::replay;
    let mut engine: Box<GroupEngine<GROUP_POOL>> = Box::new(GroupEngine::new());
    let mut buf = vec![0u8; 24 * 1024];
    let mut stream = replay::TraceStream::new(trace, &mut buf).expect("trace header");
    let mut out = Vec::new();
    let sum = replay::replay_group(
        &mut engine,
        &mut stream,
        |o| out.extend_from_slice(&o.encode()),
        |_| {},
    );
    (out, sum.cycles, sum.errors)
}
