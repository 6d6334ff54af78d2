//! All-or-nothing outputs: for every command of `fit positioning`, `fit force`, `demo` and
//! `export`, an output path that cannot be written — the last one given — fails with exit code 2 before
//! anything is written: existing outputs keep their old bytes, no new file appears, no temporary is left,
//! and the message names the user's path, never a temporary.

use std::path::Path;
use std::process::{Command, Output};

mod common;
use common::scratch;

fn axcomp(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run axcomp")
}

/// Every file under `dir` (relative path → bytes), sorted.
fn snapshot(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                out.push((
                    p.strip_prefix(dir).unwrap().display().to_string() + "/",
                    vec![],
                ));
                stack.push(p);
            } else {
                out.push((
                    p.strip_prefix(dir).unwrap().display().to_string(),
                    std::fs::read(&p).unwrap(),
                ));
            }
        }
    }
    out.sort();
    out
}

/// Runs `args` in `dir` and checks the failure: exit 2, `needle` (the bad path) in the message, no
/// temporary named, and the directory exactly as before.
fn fails_untouched(args: &[&str], dir: &Path, needle: &str) {
    let before = snapshot(dir);
    let o = axcomp(args, dir);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(
        err.contains(needle),
        "{args:?}: message must name {needle}: {err}"
    );
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

/// 21 targets × 6 bidirectional runs of a smooth error with a little noise.
fn positioning_csv(path: &Path) {
    let mut s = String::from("target_mm,run,direction,deviation_um\n");
    for run in 1..=6 {
        for (d, sign) in [("+", 1.0), ("-", -1.0)] {
            for k in 0..21 {
                let x = 10.0 * k as f64;
                let noise = ((run * 31 + k * 17) % 13) as f64 / 13.0 - 0.5;
                let y = 12.0 * (x / 40.0).sin() + 2.0 * sign + noise;
                s.push_str(&format!("{x},{run},{d},{y:.4}\n"));
            }
        }
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn fit_positioning_bad_last_output_touches_nothing() {
    let dir = scratch("positioning");
    positioning_csv(&dir.join("d.csv"));
    std::fs::write(dir.join("t.json"), "old table").unwrap();
    std::fs::create_dir(dir.join("rep")).unwrap();
    std::fs::write(dir.join("rep/report.md"), "old report").unwrap();
    // The tester's case: --out t.json --json missing-dir/f.json.
    let base = [
        "fit",
        "positioning",
        "--data",
        "d.csv",
        "--out",
        "t.json",
        "--report",
        "rep",
    ];
    let with =
        |extra: &[&'static str]| -> Vec<&str> { base.iter().chain(extra).copied().collect() };
    fails_untouched(
        &with(&["--json", "missing-dir/f.json"]),
        &dir,
        "missing-dir/f.json",
    );
    // A directory where a file goes, a report folder below a missing one, the same file twice.
    fails_untouched(&with(&["--json", "rep"]), &dir, "rep");
    fails_untouched(
        &[
            "fit",
            "positioning",
            "--data",
            "d.csv",
            "--out",
            "t.json",
            "--report",
            "no/rep",
        ],
        &dir,
        "no/rep",
    );
    fails_untouched(&with(&["--json", "./t.json"]), &dir, "t.json");
    // The drift model path is checked with the others.
    fails_untouched(
        &with(&[
            "--drift",
            "run",
            "--run-period-s",
            "60",
            "--drift-model",
            "missing-dir/m.json",
        ]),
        &dir,
        "missing-dir/m.json",
    );
    // And the same command with good paths writes every output.
    let o = axcomp(&with(&["--json", "f.json"]), &dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_ne!(std::fs::read(dir.join("t.json")).unwrap(), b"old table");
    for f in [
        "f.json",
        "rep/report.md",
        "rep/positioning.svg",
        "rep/residual.svg",
    ] {
        assert!(dir.join(f).is_file(), "{f}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn fit_force_bad_last_output_touches_nothing() {
    let dir = scratch("force");
    // F = 1500·ap·fz^0.8 (Kienzle-like, n fixed) with ±1 % deterministic scatter.
    let mut s = String::from("ap_mm,fz_mm,n_rpm,F_N\n");
    for (i, ap) in [0.5, 1.0, 1.5, 2.0].iter().enumerate() {
        for (k, fz) in [0.05, 0.1, 0.15, 0.2, 0.3].iter().enumerate() {
            let f =
                1500.0 * ap * f64::powf(*fz, 0.8) * (1.0 + 0.01 * (((i * 5 + k) % 3) as f64 - 1.0));
            s.push_str(&format!("{ap},{fz},1000,{f:.3}\n"));
        }
    }
    std::fs::write(dir.join("f.csv"), s).unwrap();
    std::fs::write(dir.join("law.json"), "old law").unwrap();
    let args = [
        "fit",
        "force",
        "--data",
        "f.csv",
        "--fix",
        "z_n=0",
        "--out",
        "law.json",
        "--report",
        "rep",
        "--json",
        "missing-dir/j.json",
    ];
    fails_untouched(&args, &dir, "missing-dir/j.json");
    let mut good = args;
    good[11] = "j.json";
    let o = axcomp(&good, &dir);
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert_ne!(std::fs::read(dir.join("law.json")).unwrap(), b"old law");
    assert!(dir.join("rep/force_fit.svg").is_file() && dir.join("j.json").is_file());
    // The report folder is written whole: the JSON inside it is refused (written into it,
    // the next report would mix with it), nothing touched; the folder records what it holds.
    good[11] = "rep/j.json";
    fails_untouched(&good, &dir, "a folder the command writes whole");
    assert!(dir.join("rep/.written-by-axcomp").is_file());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn demo_bad_output_touches_nothing() {
    let dir = scratch("demo");
    std::fs::create_dir(dir.join("d")).unwrap();
    std::fs::write(dir.join("d/measurement.csv"), "old").unwrap();
    // The last file the demo writes (report.md) cannot be written: it is a directory.
    std::fs::create_dir(dir.join("d/report.md")).unwrap();
    fails_untouched(&["demo", "--out", "d"], &dir, "report.md");
    fails_untouched(&["demo", "--out", "missing/d"], &dir, "missing/d");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn export_bad_output_touches_nothing() {
    let dir = scratch("export");
    positioning_csv(&dir.join("d.csv"));
    let o = axcomp(
        &["fit", "positioning", "--data", "d.csv", "--out", "t.json"],
        &dir,
    );
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    std::fs::write(dir.join("x.csv"), "old export").unwrap();
    fails_untouched(
        &[
            "export",
            "--table",
            "t.json",
            "--format",
            "csv",
            "--step",
            "5",
            "--out",
            "missing/x.csv",
        ],
        &dir,
        "missing/x.csv",
    );
    // A bad table leaves the old export as it was.
    std::fs::write(dir.join("bad.json"), "{").unwrap();
    fails_untouched(
        &[
            "export", "--table", "bad.json", "--format", "csv", "--step", "5", "--out", "x.csv",
        ],
        &dir,
        "bad.json",
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--help` states the exit codes.
#[test]
fn help_documents_exit_codes() {
    let o = Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .arg("--help")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(0));
    for needle in [
        "Exit codes",
        "0  success",
        "2  bad input",
        "3  refused by a guard",
    ] {
        assert!(text.contains(needle), "{needle}: {text}");
    }
}

/// `--json /dev/null` run as root must not rename a regular file over `/dev/null` (the all-or-nothing
/// swap): that turns the machine's `/dev/null` into a file that every later `> /dev/null` writes into and every
/// read of it returns (seen: a CI run whose nested cargo read a compiler message from its "empty" standard
/// input). Here a character device 1,3 (the same device as `/dev/null`) is made in the scratch directory,
/// so the test never touches the real one: every output given as that device must leave it a device, and
/// the other outputs must be written as usual. Making a device needs root (CI runs as root); elsewhere the
/// test says it is skipped. The same path without root is covered by a named pipe in `output.rs`.
#[cfg(target_os = "linux")]
#[test]
fn an_output_that_is_a_device_stays_a_device() {
    use std::os::unix::fs::FileTypeExt;
    let dir = scratch("device");
    let null = dir.join("null");
    let made = Command::new("mknod")
        .args(["-m", "666"])
        .arg(&null)
        .args(["c", "1", "3"])
        .output();
    if !made.is_ok_and(|o| o.status.success()) {
        if std::env::var_os("CI").is_some() {
            panic!("CI runs as root, where mknod must work");
        }
        println!("skipped: mknod needs root");
        return;
    }
    positioning_csv(&dir.join("d.csv"));
    let o = axcomp(
        &[
            "fit",
            "positioning",
            "--data",
            "d.csv",
            "--out",
            "null",
            "--json",
            "./null",
            "--report",
            "rep",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let kind = std::fs::symlink_metadata(&null).unwrap().file_type();
    assert!(kind.is_char_device(), "the device became {kind:?}");
    assert!(dir.join("rep/report.md").is_file());
    let names: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("axcomp-"))
        .collect();
    assert!(names.is_empty(), "temporaries left: {names:?}");
}

/// A fit or predict output that names its own data or model is refused before anything is
/// written (otherwise `fit positioning --data d.csv --out d.csv` would replace the measurements by the table).
#[test]
fn an_output_that_is_the_data_or_the_model_is_refused() {
    let dir = scratch("own-input");
    positioning_csv(&dir.join("d.csv"));
    let o = axcomp(
        &["fit", "positioning", "--data", "d.csv", "--out", "t.json"],
        &dir,
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    fails_untouched(
        &["fit", "positioning", "--data", "d.csv", "--out", "./d.csv"],
        &dir,
        "d.csv",
    );
    fails_untouched(
        &["fit", "positioning", "--data", "d.csv", "--json", "d.csv"],
        &dir,
        "d.csv",
    );
    fails_untouched(
        &[
            "predict", "--model", "t.json", "--data", "d.csv", "--out", "t.json",
        ],
        &dir,
        "t.json",
    );
    fails_untouched(
        &[
            "predict", "--model", "t.json", "--data", "d.csv", "--out", "d.csv",
        ],
        &dir,
        "d.csv",
    );
}
