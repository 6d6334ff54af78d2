//! The `axcomp` binary on bad input: a clear message naming file, line and column, a non-zero exit and no
//! output file; and the happy paths of `export`, `image build/inspect` and `replay` on hand-made inputs
//! whose expected numbers are worked out in the comments.

use std::path::Path;
use std::process::{Command, Output};

use axcomp_core::CycleInput;
use axcomp_core::trace::{OUTPUT_RECORD_LEN, OutputRecord, Record, Writer};

mod common;
use common::scratch;

fn axcomp(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("running axcomp")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Runs a command that must fail: non-zero exit, `want` in stderr, `out` not created.
fn fails(args: &[&str], dir: &Path, want: &str, out: &str) {
    let o = axcomp(args, dir);
    let err = stderr(&o);
    assert!(!o.status.success(), "{args:?} succeeded; stderr: {err}");
    assert!(
        err.contains(want),
        "{args:?}: stderr lacks `{want}`:\n{err}"
    );
    assert!(
        !dir.join(out).exists(),
        "{args:?} wrote {out} although it failed"
    );
    // No temporary file left behind either.
    let leftovers: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

const GOOD_HEADER: &str = "target_mm,run,direction,deviation_um\n";

#[test]
fn fit_positioning_names_the_bad_cell() {
    let dir = scratch("bad-cell");
    let text = format!("# campaign\n{GOOD_HEADER}0,1,+,1.0\n10,1,+,abc\n");
    std::fs::write(dir.join("bad.csv"), text).unwrap();
    fails(
        &["fit", "positioning", "--data", "bad.csv", "--out", "t.json"],
        &dir,
        "bad.csv:4:4 (column `deviation_um`): `abc` is not a number",
        "t.json",
    );
}

#[test]
fn ragged_row_duplicate_header_and_unterminated_quote() {
    let dir = scratch("structure");
    std::fs::write(
        dir.join("ragged.csv"),
        format!("{GOOD_HEADER}0,1,+,1\n10,1\n"),
    )
    .unwrap();
    fails(
        &[
            "fit",
            "positioning",
            "--data",
            "ragged.csv",
            "--out",
            "t.json",
        ],
        &dir,
        "ragged.csv:3:3: row has 2 fields but the header has 4",
        "t.json",
    );
    std::fs::write(dir.join("dup.csv"), "target_mm,run,target_mm\n0,1,2\n").unwrap();
    fails(
        &["fit", "positioning", "--data", "dup.csv", "--out", "t.json"],
        &dir,
        "dup.csv:1:3: duplicate column `target_mm` (first at column 1)",
        "t.json",
    );
    std::fs::write(dir.join("quote.csv"), format!("{GOOD_HEADER}0,1,\"+,1\n")).unwrap();
    fails(
        &[
            "fit",
            "positioning",
            "--data",
            "quote.csv",
            "--out",
            "t.json",
        ],
        &dir,
        "quote.csv:2:3: quoted field is never closed",
        "t.json",
    );
}

#[test]
fn missing_column_and_bad_options() {
    let dir = scratch("options");
    std::fs::write(dir.join("d.csv"), "position_mm,deviation_um\n0,1\n10,2\n").unwrap();
    fails(
        &["fit", "positioning", "--data", "d.csv", "--out", "t.json"],
        &dir,
        "d.csv: missing column `target_mm` (columns: position_mm, deviation_um)",
        "t.json",
    );
    fails(
        &[
            "fit",
            "positioning",
            "--data",
            "d.csv",
            "--where",
            "nope",
            "--out",
            "t.json",
        ],
        &dir,
        "--where `nope`: expected NAME=VALUE",
        "t.json",
    );
    fails(
        &[
            "fit",
            "positioning",
            "--data",
            "d.csv",
            "--scale",
            "deviation_um=x",
            "--out",
            "t.json",
        ],
        &dir,
        "--scale `deviation_um=x`: `x` is not a finite number",
        "t.json",
    );
    fails(
        &[
            "fit",
            "positioning",
            "--data",
            "missing.csv",
            "--out",
            "t.json",
        ],
        &dir,
        "missing.csv: cannot read",
        "t.json",
    );
}

/// A two-segment table over 0..20 mm: forward 10 + 2x µm, backward −5 µm (see export's unit test).
const TABLE: &str = r#"{
  "format": "axcomp-positioning-table/1", "axis": "X", "start_mm": 0.0, "segment_mm": 10.0,
  "forward": [[10.0, 20.0, 0.0, 0.0], [30.0, 20.0, 0.0, 0.0]],
  "backward": [[-5.0, 0.0, 0.0, 0.0], [-5.0, 0.0, 0.0, 0.0]],
  "model": "hand-made", "cv_rms_um": 0.0
}"#;

#[test]
fn export_linuxcnc_and_csv() {
    let dir = scratch("export");
    std::fs::write(dir.join("t.json"), TABLE).unwrap();
    let o = axcomp(
        &[
            "export",
            "--table",
            "t.json",
            "--format",
            "linuxcnc1",
            "--step",
            "5",
            "--out",
            "x.comp",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.join("x.comp")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    // 0, 5, 10, 15, 20 mm; at 5 mm forward deviation 20 µm → trim −0.020 mm, backward −5 µm → +0.005 mm.
    assert_eq!(lines.len(), 5);
    assert_eq!(lines[1], "5.000000 -0.0200000 0.0050000");
    let o = axcomp(
        &[
            "export", "--table", "t.json", "--format", "csv", "--step", "10", "--out", "x.csv",
        ],
        &dir,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.join("x.csv")).unwrap();
    assert_eq!(
        text.lines().next(),
        Some("position_mm,forward_um,backward_um")
    );
    assert_eq!(text.lines().nth(3), Some("20.000000,50.0000,-5.0000"));
    // Bad inputs.
    fails(
        &[
            "export",
            "--table",
            "t.json",
            "--format",
            "linuxcnc0",
            "--step",
            "0",
            "--out",
            "y.comp",
        ],
        &dir,
        "--step 0 mm",
        "y.comp",
    );
    fails(
        &[
            "export",
            "--table",
            "t.json",
            "--format",
            "linuxcnc0",
            "--step",
            "0.01",
            "--out",
            "y.comp",
        ],
        &dir,
        "linuxcnc0 takes at most 256",
        "y.comp",
    );
    std::fs::write(
        dir.join("bad.json"),
        TABLE.replace("axcomp-positioning-table/1", "other/9"),
    )
    .unwrap();
    fails(
        &[
            "export", "--table", "bad.json", "--format", "csv", "--step", "1", "--out", "y.csv",
        ],
        &dir,
        "format is \"other/9\"",
        "y.csv",
    );
}

fn trace_bytes(positions_counts: &[i64]) -> Vec<u8> {
    let mut buf = vec![0u8; 64 + 64 * positions_counts.len()];
    let mut w = Writer::new(&mut buf).unwrap();
    w.push(&Record::Reset {
        scale_raw: positions_counts[0] as u32,
    })
    .unwrap();
    for &p in positions_counts {
        w.push(&Record::Cycle(CycleInput {
            scale_raw: p as u32,
            command_counts: p,
            forces_n: [0.0; 3],
        }))
        .unwrap();
    }
    w.push(&Record::End).unwrap();
    let n = w.finish();
    buf.truncate(n);
    buf
}

#[test]
fn image_build_inspect_and_replay() {
    let dir = scratch("image");
    std::fs::write(dir.join("t.json"), TABLE).unwrap();
    // 0.1 µm per count: 10 mm = 100 000 counts (whole counts, so the table is copied, not resampled).
    let build = [
        "image",
        "build",
        "--table",
        "t.json",
        "--axis-id",
        "7",
        "--um-per-count",
        "0.1",
        "--max-slew-um",
        "100",
        "--out",
        "img.bin",
    ];
    let o = axcomp(&build, &dir);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = axcomp(&["image", "inspect", "img.bin"], &dir);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        out.contains("axis id: 7")
            && out.contains("CRC-32")
            && out.contains("2 segments per direction"),
        "{out}"
    );
    assert!(
        out.contains("forward: deviation at knots 10.000 .. 50.000 µm"),
        "{out}"
    );

    // Forward moves to 5 mm (50 000 counts), held there: correction 20 µm = 200 counts once the slew
    // limit (100 µm/cycle) allows, i.e. from the first cycle on.
    let positions: Vec<i64> = (0..=10).map(|k| k * 5_000).chain([50_000; 5]).collect();
    std::fs::write(dir.join("trace.bin"), trace_bytes(&positions)).unwrap();
    let o = axcomp(
        &[
            "replay",
            "--image",
            "img.bin",
            "--trace",
            "trace.bin",
            "--out",
            "out.bin",
            "--csv",
            "out.csv",
        ],
        &dir,
    );
    let summary = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        summary.contains(&format!("cycles: {}", positions.len())),
        "{summary}"
    );
    let bytes = std::fs::read(dir.join("out.bin")).unwrap();
    assert_eq!(bytes.len(), positions.len() * OUTPUT_RECORD_LEN);
    let last = OutputRecord::decode(&bytes[bytes.len() - OUTPUT_RECORD_LEN..]).unwrap();
    // Reference: forward table at 5 mm = 10 + 20·0.5 = 20 µm (f32 exact) → 200 counts, command 50 000 − 200.
    assert_eq!(last.correction_um(), 20.0);
    assert_eq!(last.correction_counts, 200);
    assert_eq!(last.corrected_command_counts, 49_800);
    let csv = std::fs::read_to_string(dir.join("out.csv")).unwrap();
    assert_eq!(csv.lines().count(), positions.len() + 1);

    // Bad inputs: a corrupted image is refused by inspect and replay, nothing is written.
    let mut img = std::fs::read(dir.join("img.bin")).unwrap();
    let k = img.len() / 2;
    img[k] ^= 0x55;
    std::fs::write(dir.join("bad.bin"), &img).unwrap();
    let o = axcomp(&["image", "inspect", "bad.bin"], &dir);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("bad.bin: invalid image: CRC-32 mismatch"),
        "{}",
        stderr(&o)
    );
    fails(
        &[
            "replay",
            "--image",
            "bad.bin",
            "--trace",
            "trace.bin",
            "--out",
            "out2.bin",
        ],
        &dir,
        "CRC-32 mismatch",
        "out2.bin",
    );
    std::fs::write(dir.join("notrace.bin"), b"hello").unwrap();
    fails(
        &[
            "replay",
            "--image",
            "img.bin",
            "--trace",
            "notrace.bin",
            "--out",
            "out3.bin",
        ],
        &dir,
        "not an axcomp trace",
        "out3.bin",
    );
    let mut bad_build = build.to_vec();
    bad_build[7] = "0"; // --um-per-count 0
    *bad_build.last_mut().unwrap() = "img2.bin";
    fails(&bad_build, &dir, "--um-per-count 0", "img2.bin");
    std::fs::write(dir.join("nan.json"), TABLE.replace("30.0", "1e999")).unwrap();
    let mut nan_build = build.to_vec();
    nan_build[3] = "nan.json";
    *nan_build.last_mut().unwrap() = "img3.bin";
    fails(&nan_build, &dir, "nan.json", "img3.bin");
}
