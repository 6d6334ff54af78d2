//! Robustness of `image build`, `image inspect`, `trace`, `replay` and `export` on inputs an outside
//! evaluation may send: model files of other spellings, the wrong kind or out of range, repeated or
//! conflicting flags, outputs that name an input or each other. Refusals: exit 2, a message naming the file
//! (or option) and what is wrong, nothing written (`common::fails_untouched_naming`). Each test names the
//! input that once failed.

use std::path::{Path, PathBuf};

mod common;
use common::{axcomp_in, fails_untouched_naming, ok_in, scratch};

/// A positioning table file (`fit positioning --out` form) over 0..100 mm in 10 segments: forward
/// deviation c0 = 2·i µm rising linearly inside each segment, backward 1 µm below it.
fn table_json() -> serde_json::Value {
    let fwd: Vec<[f64; 4]> = (0..10).map(|i| [2.0 * i as f64, 2.0, 0.0, 0.0]).collect();
    let bwd: Vec<[f64; 4]> = fwd.iter().map(|c| [c[0] - 1.0, c[1], 0.0, 0.0]).collect();
    serde_json::json!({
        "format": "axcomp-positioning-table/1",
        "axis": "X",
        "start_mm": 0.0,
        "segment_mm": 10.0,
        "forward": fwd,
        "backward": bwd,
        "model": "hand-written",
        "cv_rms_um": 0.5,
        "raw_rms_um": 5.0,
        "cv_method": "leave-one-run-out"
    })
}

/// A thermal model file (`fit thermal --out` form) with two sensors, `frame` and `motor`.
fn thermal_json() -> serde_json::Value {
    let sensor = |name: &str, coef: f64| {
        serde_json::json!({
            "name": name, "reference_degc": 20.0, "tau_s": 0.0, "coef_um_per_k": coef,
            "min_degc": 0.0, "max_degc": 60.0, "max_rate_degc_per_s": 1.0, "stale_timeout_ms": 10000
        })
    };
    serde_json::json!({
        "format": "axcomp-thermal-model/1",
        "target": "deviation_um",
        "sensor_period_ms": 1000,
        "b0_um": 1.5,
        "sensors": [sensor("frame", 0.8), sensor("motor", -0.2)],
        "forces": [],
        "raw_rms_um": 3.0,
        "holdout_rms_um": null
    })
}

fn write_json(dir: &Path, name: &str, v: &serde_json::Value) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, serde_json::to_string_pretty(v).unwrap()).unwrap();
    p
}

fn build_args<'a>(extra: &[&'a str], out: &'a str) -> Vec<&'a str> {
    let mut a = vec!["image", "build", "--axis-id", "1", "--um-per-count", "0.1"];
    a.extend_from_slice(extra);
    a.extend_from_slice(&["--out", out]);
    a
}

/// `image build --out T` with `--table T` would replace the fitted table with the image; `export --out`
/// the table it read, `replay --out` the trace, `trace --out` the `--image`: an output that is an input is
/// refused (by any spelling), the input left as it was.
#[test]
fn an_output_that_is_an_input_is_refused() {
    let dir = scratch("out-is-input");
    write_json(&dir, "table.json", &table_json());
    fails_untouched_naming(
        &build_args(&["--table", "table.json"], "table.json"),
        &dir,
        &["table.json", "input"],
    );
    fails_untouched_naming(
        &[
            "export",
            "--table",
            "table.json",
            "--format",
            "linuxcnc1",
            "--step",
            "10",
            "--out",
            "./table.json",
        ],
        &dir,
        &["./table.json", "input"],
    );
    ok_in(&build_args(&["--table", "table.json"], "image.bin"), &dir);
    fails_untouched_naming(
        &["trace", "--image", "image.bin", "--out", "image.bin"],
        &dir,
        &["image.bin", "input"],
    );
    ok_in(
        &[
            "trace",
            "--scenario",
            "group3",
            "--cycles",
            "6000",
            "--out",
            "trace.bin",
        ],
        &dir,
    );
    fails_untouched_naming(
        &["replay", "--trace", "trace.bin", "--out", "trace.bin"],
        &dir,
        &["trace.bin", "input"],
    );
    fails_untouched_naming(
        &[
            "replay",
            "--trace",
            "trace.bin",
            "--image",
            "image.bin",
            "--out",
            "out.bin",
            "--csv",
            "image.bin",
        ],
        &dir,
        &["image.bin", "input"],
    );
}

/// `replay --out x --csv x` wrote the CSV alone into `x` and said it wrote the records there: two outputs
/// spelled the same are refused, as two spellings of one file were.
#[test]
fn two_outputs_spelled_alike_are_refused() {
    let dir = scratch("same-spelling");
    ok_in(
        &[
            "trace",
            "--scenario",
            "group3",
            "--cycles",
            "6000",
            "--out",
            "trace.bin",
        ],
        &dir,
    );
    fails_untouched_naming(
        &[
            "replay",
            "--trace",
            "trace.bin",
            "--out",
            "x.bin",
            "--csv",
            "x.bin",
        ],
        &dir,
        &["x.bin", "same file"],
    );
    // Two spellings of one device still both go there.
    ok_in(
        &[
            "replay",
            "--trace",
            "trace.bin",
            "--out",
            "/dev/null",
            "--csv",
            "/dev/null",
        ],
        &dir,
    );
}

/// A table or thermal model whose value is beyond what the image holds (a coefficient of 5e6 µm, 1e300
/// µm/K, a reference temperature of 1e6 °C) was refused as "the image spec is not valid:
/// table.forward[0] is out of range", naming neither the file nor the limit; an option out of range named
/// `counter_bits[0]` instead of the option.
#[test]
fn an_out_of_range_value_names_its_file_or_option_and_the_limit() {
    let dir = scratch("out-of-range");
    let mut t = table_json();
    t["forward"][3][0] = serde_json::json!(5.0e6);
    write_json(&dir, "big table.json", &t);
    fails_untouched_naming(
        &build_args(&["--table", "big table.json"], "x.bin"),
        &dir,
        &["big table.json", "10 000 µm"],
    );
    let mut m = thermal_json();
    m["sensors"][1]["coef_um_per_k"] = serde_json::json!(1.0e300);
    write_json(&dir, "modèle.json", &m);
    fails_untouched_naming(
        &build_args(&["--thermal", "modèle.json"], "x.bin"),
        &dir,
        &["modèle.json", "sensors[1]", "motor", "1e4 µm/K"],
    );
    let mut m = thermal_json();
    m["sensors"][0]["reference_degc"] = serde_json::json!(1.0e6);
    write_json(&dir, "hot.json", &m);
    fails_untouched_naming(
        &build_args(&["--thermal", "hot.json"], "x.bin"),
        &dir,
        &["hot.json", "frame", "2000] °C"],
    );
    write_json(&dir, "table.json", &table_json());
    fails_untouched_naming(
        &build_args(&["--table", "table.json", "--counter-bits", "8"], "x.bin"),
        &dir,
        &["--counter-bits 8", "16 to 32"],
    );
    fails_untouched_naming(
        &build_args(&["--table", "table.json", "--max-slew-um", "0"], "x.bin"),
        &dir,
        &["--max-slew-um 0", "100000"],
    );
}

/// The image wires each sensor to the board input of its name. Two sensors given one input
/// (`--sensor-input frame=rtd0 --sensor-input motor=rtd0`, or a rename onto another sensor's name, or a
/// model with two sensors of one name) were built into an image whose two coefficients read one
/// temperature; one sensor given two inputs silently took the last. Both are refused.
#[test]
fn sensors_sharing_an_input_or_one_sensor_given_two_are_refused() {
    let dir = scratch("sensor-inputs");
    write_json(&dir, "thermal.json", &thermal_json());
    let th = ["--thermal", "thermal.json"];
    let with = |extra: &[&'static str]| {
        let mut a: Vec<&str> = th.to_vec();
        a.extend_from_slice(extra);
        a
    };
    fails_untouched_naming(
        &build_args(
            &with(&[
                "--sensor-input",
                "frame=rtd0",
                "--sensor-input",
                "motor=rtd0",
            ]),
            "x.bin",
        ),
        &dir,
        &["frame", "motor", "rtd0"],
    );
    fails_untouched_naming(
        &build_args(&with(&["--sensor-input", "frame=motor"]), "x.bin"),
        &dir,
        &["frame", "motor", "thermal.json"],
    );
    fails_untouched_naming(
        &build_args(
            &with(&[
                "--sensor-input",
                "frame=rtd0",
                "--sensor-input",
                "frame=rtd1",
            ]),
            "x.bin",
        ),
        &dir,
        &["frame=rtd1", "rtd0"],
    );
    let mut m = thermal_json();
    m["sensors"][1]["name"] = serde_json::json!("frame");
    write_json(&dir, "twice.json", &m);
    fails_untouched_naming(
        &build_args(&["--thermal", "twice.json"], "x.bin"),
        &dir,
        &["twice.json", "sensors[0]", "sensors[1]", "frame"],
    );
    // The same pair given twice, and a swap of two names, are fine; the image names the inputs.
    ok_in(
        &build_args(
            &with(&[
                "--sensor-input",
                "frame=rtd0",
                "--sensor-input",
                "frame=rtd0",
                "--sensor-input",
                "motor=rtd1",
            ]),
            "ok.bin",
        ),
        &dir,
    );
    let o = axcomp_in(&["image", "inspect", "ok.bin"], &dir);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{text}");
    assert!(
        text.contains("sensor 0 rtd0 -> board input 0 rtd0")
            && text.contains("sensor 1 rtd1 -> board input 1 rtd1"),
        "{text}"
    );
}

/// A model file of the wrong kind failed on serde's first missing field (`missing field `axis``), a binary
/// image or trace given as a model on "stream did not contain valid UTF-8": the message now says what the
/// file is. Nothing is written.
#[test]
fn a_model_of_the_wrong_kind_says_what_it_is() {
    let dir = scratch("wrong-kind");
    write_json(&dir, "table.json", &table_json());
    write_json(&dir, "thermal.json", &thermal_json());
    ok_in(&build_args(&["--table", "table.json"], "image.bin"), &dir);
    ok_in(
        &[
            "trace",
            "--scenario",
            "group3",
            "--cycles",
            "6000",
            "--out",
            "trace.bin",
        ],
        &dir,
    );
    fails_untouched_naming(
        &build_args(&["--table", "thermal.json"], "x.bin"),
        &dir,
        &["thermal.json", "a thermal model", "not a positioning table"],
    );
    fails_untouched_naming(
        &build_args(&["--thermal", "table.json"], "x.bin"),
        &dir,
        &["table.json", "a positioning table", "not a thermal model"],
    );
    fails_untouched_naming(
        &build_args(&["--table", "image.bin"], "x.bin"),
        &dir,
        &["image.bin", "firmware image"],
    );
    fails_untouched_naming(
        &build_args(&["--thermal", "trace.bin"], "x.bin"),
        &dir,
        &["trace.bin", "firmware trace"],
    );
    fails_untouched_naming(
        &[
            "export",
            "--table",
            "image.bin",
            "--format",
            "csv",
            "--step",
            "1",
            "--out",
            "x.csv",
        ],
        &dir,
        &["image.bin", "firmware image"],
    );
    let mut t = table_json();
    t["format"] = serde_json::json!("axcomp-positioning-table/2");
    write_json(&dir, "v2.json", &t);
    fails_untouched_naming(
        &build_args(&["--table", "v2.json"], "x.bin"),
        &dir,
        &["v2.json", "another version"],
    );
}

/// Model files as other tools and editors write them: keys in another order with extra keys, a UTF-8
/// byte-order mark (Windows editors; was "expected value at line 1 column 1"), a thermal model without the
/// optional `forces` and `raw_rms_um` (was "missing field `forces`"). Each builds, and `image inspect`
/// reports what was put in (reference: the hand-written files above; the table's knots are exact in f32).
#[test]
fn other_spellings_of_model_files_build_and_inspect_reports_them() {
    let dir = scratch("spellings");
    // Keys reversed, extra keys, BOM.
    let t = table_json();
    let mut rev = serde_json::Map::new();
    for (k, v) in t.as_object().unwrap().iter().rev() {
        rev.insert(k.clone(), v.clone());
    }
    rev.insert("comment".into(), serde_json::json!({"by": "another tool"}));
    let text = format!(
        "\u{feff}{}",
        serde_json::to_string(&serde_json::Value::Object(rev)).unwrap()
    );
    std::fs::write(dir.join("tablé bom.json"), text).unwrap();
    let mut m = thermal_json();
    let o = m.as_object_mut().unwrap();
    o.remove("forces");
    o.remove("raw_rms_um");
    o.remove("holdout_rms_um");
    o.insert("fitted_by".into(), serde_json::json!("spreadsheet"));
    write_json(&dir, "thermal min.json", &m);
    ok_in(
        &build_args(
            &[
                "--table",
                "tablé bom.json",
                "--thermal",
                "thermal min.json",
                "--sensor-input",
                "frame=rtd0",
                "--sensor-input",
                "motor=rtd1",
            ],
            "image ü.bin",
        ),
        &dir,
    );
    let o = axcomp_in(&["image", "inspect", "image ü.bin"], &dir);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{text}");
    for needle in [
        "axis id: 1",
        "scale: 0.1 µm/count",
        "table: 10 segments per direction of 100000 counts (10.0000 mm), 0 .. 1000000 counts (0.0000 .. 100.0000 mm)",
        "forward: deviation at knots 0.000 .. 20.000 µm",
        "backward: deviation at knots -1.000 .. 19.000 µm",
        "thermo-force: 2 sensors (period 1000 ms), b0 = 1.5 µm, 0 force terms",
        "sensor 0: ref 20 °C, range 0 .. 60 °C, b = 0.8 µm/K, lag τ = 0 s",
        "sensor 1: ref 20 °C, range 0 .. 60 °C, b = -0.2 µm/K, lag τ = 0 s",
        "sensor 0 rtd0 -> board input 0 rtd0",
        "sensor 1 rtd1 -> board input 1 rtd1",
    ] {
        assert!(
            text.contains(needle),
            "inspect must report `{needle}`:\n{text}"
        );
    }
}

/// `image group --axis X=FILE` with a table JSON, a group image or a trace was refused as "the group is not
/// valid: bad magic" / "unsupported image schema version 2", naming neither the option nor the file;
/// `--rotary` given a geometry model said the hand-written form carries its pivot itself.
#[test]
fn image_group_names_the_axis_file_that_is_no_axis_image() {
    let dir = scratch("group-kind");
    write_json(&dir, "table.json", &table_json());
    ok_in(
        &build_args(&["--table", "table.json", "--counter-bits", "32"], "x.bin"),
        &dir,
    );
    ok_in(
        &["image", "group", "--axis", "X=x.bin", "--out", "group.bin"],
        &dir,
    );
    fails_untouched_naming(
        &["image", "group", "--axis", "X=table.json", "--out", "g.bin"],
        &dir,
        &["--axis X=table.json", "not a firmware image"],
    );
    fails_untouched_naming(
        &["image", "group", "--axis", "Y=group.bin", "--out", "g.bin"],
        &dir,
        &["--axis Y=group.bin", "group image", "single-axis"],
    );
    let mut bytes = std::fs::read(dir.join("x.bin")).unwrap();
    bytes.extend_from_slice(&[0; 8]);
    std::fs::write(dir.join("long.bin"), bytes).unwrap();
    fails_untouched_naming(
        &["image", "group", "--axis", "X=long.bin", "--out", "g.bin"],
        &dir,
        &["--axis X=long.bin", "bytes follow"],
    );
    let mut geo = serde_json::json!({"format": "axcomp-geometry-model", "version": 1});
    geo["note"] = serde_json::json!("a geometry model, cut short");
    write_json(&dir, "geo.json", &geo);
    fails_untouched_naming(
        &[
            "image",
            "group",
            "--axis",
            "X=x.bin",
            "--rotary",
            "geo.json",
            "--pivot-counts",
            "0,0,0",
            "--tool-length-mm",
            "100",
            "--out",
            "g.bin",
        ],
        &dir,
        &[
            "--rotary geo.json",
            "geometry model",
            "not a rotary-axis model",
        ],
    );
}

/// `image group --sensor-names X=rtd0,rtd0,rtd1` built a group whose two sensors read one input, a
/// second `--sensor-names X=...` was silently ignored, and a wrong count was "the group is not valid:
/// axis X: sensor names must be one non-empty UTF-8 name per sensor" without the option or the count.
#[test]
fn image_group_sensor_names_one_per_sensor_none_twice() {
    let dir = scratch("group-names");
    write_json(&dir, "thermal.json", &thermal_json());
    ok_in(
        &build_args(
            &["--thermal", "thermal.json", "--counter-bits", "32"],
            "x.bin",
        ),
        &dir,
    );
    fails_untouched_naming(
        &[
            "image",
            "group",
            "--axis",
            "X=x.bin",
            "--sensor-names",
            "X=rtd0,rtd0",
            "--out",
            "g.bin",
        ],
        &dir,
        &["--axis X=x.bin", "rtd0", "two sensors"],
    );
    fails_untouched_naming(
        &[
            "image",
            "group",
            "--axis",
            "X=x.bin",
            "--sensor-names",
            "X=rtd0,rtd1",
            "--sensor-names",
            "X=a,b",
            "--out",
            "g.bin",
        ],
        &dir,
        &["X=a,b", "twice"],
    );
    fails_untouched_naming(
        &[
            "image",
            "group",
            "--axis",
            "X=x.bin",
            "--sensor-names",
            "X=rtd0",
            "--out",
            "g.bin",
        ],
        &dir,
        &["--sensor-names X=rtd0", "1 names", "2 sensors"],
    );
    ok_in(
        &[
            "image",
            "group",
            "--axis",
            "X=x.bin",
            "--sensor-names",
            "X=rtd1,rtd0",
            "--out",
            "g.bin",
        ],
        &dir,
    );
    let o = axcomp_in(&["image", "inspect", "g.bin"], &dir);
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{text}");
    assert!(
        text.contains("sensor 0 rtd1 -> board input 1 rtd1")
            && text.contains("sensor 1 rtd0 -> board input 0 rtd0"),
        "{text}"
    );
}

/// The nominal positions of an exported LinuxCNC file, parsed as LinuxCNC's `usrmotLoadComp` reads them
/// (`%lf %lf %lf` per line, stopping at the first line that is not three numbers).
fn linuxcnc_rows(text: &str) -> Vec<[f64; 3]> {
    let mut rows = Vec::new();
    for line in text.lines() {
        let v: Vec<f64> = line
            .split_whitespace()
            .map_while(|w| w.parse().ok())
            .collect();
        if v.len() < 3 {
            break;
        }
        rows.push([v[0], v[1], v[2]]);
    }
    rows
}

/// A table ending a fraction of a nanometre-scale beyond a whole number of steps (data max 200.0000004 mm,
/// `--step 20`) was exported with a last regular entry and the end both printed as `200.000000`;
/// LinuxCNC refuses a nominal that does not increase ("compensation values must increase", motion's
/// `EMCMOT_SET_JOINT_COMP`). The end now takes the last regular entry's place; every exported line is
/// read back (LinuxCNC's reading) with increasing nominals and the table's values (reference: the
/// hand-written table, deviation 2·x/10 µm forward; tolerance 1e-7 mm, the file's printed resolution).
/// A table shorter than the printed resolution is refused, naming the file.
#[test]
fn linuxcnc_nominals_increase_when_the_stroke_ends_just_past_a_step() {
    let dir = scratch("linuxcnc-nominals");
    let mut t = table_json();
    t["segment_mm"] = serde_json::json!(20.00000004);
    write_json(&dir, "table.json", &t);
    for (format, kind) in [("linuxcnc0", 0), ("linuxcnc1", 1)] {
        let out = format!("{format}.comp");
        ok_in(
            &[
                "export",
                "--table",
                "table.json",
                "--format",
                format,
                "--step",
                "20",
                "--out",
                &out,
            ],
            &dir,
        );
        let rows = linuxcnc_rows(&std::fs::read_to_string(dir.join(&out)).unwrap());
        assert_eq!(rows.len(), 11, "{format}: {rows:?}");
        for w in rows.windows(2) {
            assert!(
                w[1][0] > w[0][0],
                "{format}: nominals must increase: {rows:?}"
            );
        }
        assert!((rows[10][0] - 200.0).abs() < 1e-6, "{rows:?}");
        for r in &rows {
            // Forward deviation of the hand-written table at x: c0 + c1·s = 2·x/segment µm.
            let dev_mm = 2.0 * r[0] / 20.00000004 / 1000.0;
            let trim = if kind == 0 { r[0] - r[1] } else { r[1] };
            assert!((trim + dev_mm).abs() < 1e-7, "{format}: {r:?}");
        }
    }
    let mut t = table_json();
    t["segment_mm"] = serde_json::json!(1e-8);
    write_json(&dir, "tiny.json", &t);
    fails_untouched_naming(
        &[
            "export",
            "--table",
            "tiny.json",
            "--format",
            "linuxcnc1",
            "--step",
            "1",
            "--out",
            "t.comp",
        ],
        &dir,
        &["tiny.json", "resolution"],
    );
}

/// `image inspect --board-inputs rtd0:degC,rtd0:degC` described a board with two inputs of one name (the
/// firmware wires a sensor to the input of its name, so such a board cannot be wired): refused.
#[test]
fn inspect_refuses_a_board_input_named_twice() {
    let dir = scratch("board-inputs");
    write_json(&dir, "thermal.json", &thermal_json());
    ok_in(&build_args(&["--thermal", "thermal.json"], "x.bin"), &dir);
    fails_untouched_naming(
        &[
            "image",
            "inspect",
            "x.bin",
            "--board-inputs",
            "rtd0:degC,rtd0:degC",
        ],
        &dir,
        &["--board-inputs", "rtd0", "twice"],
    );
}

/// `predict` reads a model file with a UTF-8 byte-order mark as `image build` does (it said "not a JSON
/// model file"). Reference: the hand-written table is 0 µm at 0 mm and 20 µm at 100 mm forward with knots
/// every 10 mm; at a knot (10 mm) the prediction is the knot's value within 1e-9 µm.
#[test]
fn predict_reads_a_model_with_a_byte_order_mark() {
    let dir = scratch("predict-bom");
    let text = format!("\u{feff}{}", serde_json::to_string(&table_json()).unwrap());
    std::fs::write(dir.join("bom.json"), text).unwrap();
    std::fs::write(dir.join("d.csv"), "target_mm,direction\n10,+\n").unwrap();
    ok_in(
        &[
            "predict", "--model", "bom.json", "--data", "d.csv", "--out", "p.csv",
        ],
        &dir,
    );
    let out = std::fs::read_to_string(dir.join("p.csv")).unwrap();
    let row = out.lines().nth(1).unwrap();
    let pred: f64 = row.rsplit(',').next().unwrap().parse().unwrap();
    let knot = table_json()["forward"].as_array().unwrap()[1]
        .as_array()
        .unwrap()[0]
        .as_f64()
        .unwrap();
    assert!((pred - knot).abs() < 1e-9, "{out}");
}
