//! `axcomp demo` end to end: no arguments, in a temporary directory; checks every output file and that the
//! before/after ISO 230-2 figures show a real improvement.

use std::process::{Command, Stdio};

mod common;
use common::scratch;

#[test]
fn demo_without_arguments_writes_report_plots_and_figures() {
    let dir = scratch("default");
    let o = Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .arg("demo")
        .current_dir(&dir)
        .output()
        .expect("running axcomp demo");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "demo failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        stdout.contains("before (uncompensated)") && stdout.contains("after (fitted table)"),
        "{stdout}"
    );

    let out = dir.join("axcomp-demo");
    for f in [
        "report.md",
        "demo.json",
        "measurement.csv",
        "measurement_compensated.csv",
        "table.json",
        "image.bin",
        "deviation_before.svg",
        "deviation_after.svg",
        "iso230_before_after.svg",
        "trace.bin",
        "replay.bin",
    ] {
        let p = out.join(f);
        assert!(
            p.is_file() && std::fs::metadata(&p).unwrap().len() > 0,
            "{f} missing or empty"
        );
        if f.ends_with(".svg") {
            let svg = std::fs::read_to_string(&p).unwrap();
            assert!(
                svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"),
                "{f} is not an SVG"
            );
            assert!(
                svg.contains("<circle") || svg.contains("<polyline") || svg.contains("<path"),
                "{f} is empty"
            );
        }
    }
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    for needle in [
        "deviation_before.svg",
        "iso230_before_after.svg",
        "| before (uncompensated) |",
        "CRC-32",
    ] {
        assert!(report.contains(needle), "report.md lacks {needle}");
    }

    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("demo.json")).unwrap()).unwrap();
    let fig = |which: &str, k: &str| {
        j[which][k]
            .as_f64()
            .unwrap_or_else(|| panic!("{which}.{k} missing"))
    };
    for which in ["iso230_2_before", "iso230_2_after", "iso230_2_ideal"] {
        for k in ["A_um", "E_um", "M_um", "R_um", "B_um"] {
            assert!(
                fig(which, k).is_finite() && fig(which, k) >= 0.0,
                "{which}.{k}"
            );
        }
    }
    // The twin's pitch error is ~20 µm peak to peak (axcomp_twin::Axis::linear_motor_demo), noise σ 0.5 µm:
    // the systematic deviation E must shrink at least 4× on the new, compensated campaign, and accuracy A
    // at least 2× (A keeps the ±2s noise band, ≈ 4σ = 2 µm, which no table can remove).
    let (a0, a1) = (
        fig("iso230_2_before", "A_um"),
        fig("iso230_2_after", "A_um"),
    );
    let (e0, e1) = (
        fig("iso230_2_before", "E_um"),
        fig("iso230_2_after", "E_um"),
    );
    assert!(e1 < e0 / 4.0, "E before {e0:.2} µm, after {e1:.2} µm");
    assert!(a1 < a0 / 2.0, "A before {a0:.2} µm, after {a1:.2} µm");
    // Reference floor: the table built from the known truth. The fitted table should come within 2 µm of
    // its accuracy (noise of two different campaigns; tolerance 2 µm ≈ 4σ).
    let a_ideal = fig("iso230_2_ideal", "A_um");
    assert!(
        a1 <= a_ideal + 2.0,
        "A after {a1:.2} µm vs ideal {a_ideal:.2} µm"
    );
    // The recorded trace replays bit for bit, and at every measured point the replayed correction equals
    // the one the twin applied through the same compensator (same table, same settled position; tolerance
    // 0.001 µm, far below one count of 0.05 µm).
    assert_eq!(j["replay"]["bit_for_bit"], serde_json::Value::Bool(true));
    let diff = j["replay"]["max_diff_to_twin_um"].as_f64().unwrap();
    assert!(
        diff <= 0.001,
        "replayed vs twin correction differ by {diff} µm"
    );
    // The replay output is whole 32-byte records, one per cycle.
    let n = std::fs::metadata(out.join("replay.bin")).unwrap().len() as usize;
    assert_eq!(n, 32 * j["replay"]["cycles"].as_u64().unwrap() as usize);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn demo_into_an_unwritable_place_fails_cleanly() {
    let dir = scratch("unwritable");
    std::fs::write(dir.join("file"), "x").unwrap();
    // `--out` below a regular file cannot be created.
    let o = Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(["demo", "--out", "file/sub"])
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot create file/sub"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The demo's table names its source: the SHA-256 of the `measurement.csv` written next to
/// it (reference: `sha256sum` when installed), its length, the tool version and the date.
#[test]
fn demo_table_carries_the_provenance_of_its_measurement() {
    let dir = scratch("provenance");
    let o = Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(["demo", "--out", "d"])
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let t = axcomp_positioning::TableFile::load(&dir.join("d/table.json")).unwrap();
    let p = t.provenance.expect("provenance");
    let csv = dir.join("d/measurement.csv");
    assert_eq!(p.source_bytes, std::fs::metadata(&csv).unwrap().len());
    assert_eq!(
        p.source_sha256,
        axcomp_data::provenance::file_sha256(&csv).unwrap().0
    );
    if let Ok(o) = Command::new("sha256sum").arg(&csv).output() {
        let want = String::from_utf8_lossy(&o.stdout);
        assert_eq!(
            Some(p.source_sha256.as_str()),
            want.split_whitespace().next()
        );
    }
    assert!(p.tool.starts_with("axcomp ") && p.created_utc.ends_with('Z'));
    // The demo's image names its table file and that file's data by their SHA-256 (every
    // image header names its sources), as `image build` does; `image inspect` shows them.
    let o = Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(["image", "inspect", "d/image.bin"])
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    let table_sha = axcomp_data::provenance::file_sha256(&dir.join("d/table.json"))
        .unwrap()
        .0;
    assert!(
        text.contains(&format!(
            "positioning table sha256 {table_sha}; data sha256 {}",
            p.source_sha256
        )),
        "{text}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `axcomp demo | true`: standard output closed before the demo prints anything. Reference: a process ended
/// by SIGPIPE, status 141, and nothing about a panic on stderr (it was status 101 with a panic message and a
/// backtrace: `println!` panics on a broken pipe).
#[test]
fn closed_standard_output_stops_quietly() {
    let dir = scratch("closed-stdout");
    let mut child = Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .arg("demo")
        .current_dir(&dir)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("running axcomp demo");
    // The reading end closed right away, long before the demo's first line (after its simulation).
    drop(child.stdout.take());
    let o = child.wait_with_output().expect("waiting for axcomp demo");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(141), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// `demo --all`: five rows, one per system, each with its before/after figure on data the fit never
/// saw; every chain but the probe's goes through the firmware library and gets smaller; the probe's
/// row says its calibration has no firmware stage; the report folder is written whole.
#[test]
fn demo_all_prints_a_row_per_system() {
    let dir = scratch("all");
    let o = Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(["demo", "--all", "--out", "rep"])
        .current_dir(&dir)
        .output()
        .expect("running axcomp demo --all");
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "demo --all failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("rep/demo_all.json")).unwrap())
            .unwrap();
    let rows = j["systems"].as_array().unwrap();
    let names: Vec<&str> = rows.iter().map(|r| r["system"].as_str().unwrap()).collect();
    assert_eq!(
        names,
        [
            "positioning",
            "thermo-force",
            "three-axis geometry",
            "five-axis rotary",
            "touch probe"
        ]
    );
    for r in rows {
        let name = r["system"].as_str().unwrap();
        assert!(
            stdout.lines().any(|l| l.starts_with(name)),
            "{name}:\n{stdout}"
        );
        let (b, a) = (r["before"].as_f64().unwrap(), r["after"].as_f64().unwrap());
        // Reference: the uncompensated figure on the same unseen data; the compensated one must be
        // smaller (each chain's own tests bound it more tightly).
        assert!(
            a.is_finite() && b.is_finite() && a < b,
            "{name}: {b} -> {a}"
        );
    }
    assert!(rows[4]["firmware"].as_str().unwrap().starts_with("none"));
    assert!(dir.join("rep/report.md").exists());
}
