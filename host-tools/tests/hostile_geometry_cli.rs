//! Hostile inputs to the geometry system (`fit geometry`, `predict` and `image group --geometry` on its
//! model file; contract: `shared/spec/interfaces.md`, "Geometric errors of a three-axis machine"). Each
//! test failed before its fix. The data are the twin's (`axcomp plan geometry --simulate`).

use std::path::Path;

use proptest::prelude::*;
use serde_json::Value;

mod common;
use common::{axcomp_in, fails_untouched_naming, ok, read_json, scratch};

/// The twin's laser lines (`dir/lines.csv`) and the plain fit's model (`dir/model.json`).
fn lines_and_model(dir: &Path) {
    ok(&axcomp_in(
        &[
            "plan",
            "geometry",
            "--stroke",
            "800,600,500",
            "--simulate",
            "lines.csv",
        ],
        dir,
    ));
    ok(&axcomp_in(
        &[
            "fit",
            "geometry",
            "--data",
            "lines.csv",
            "--method",
            "plain",
            "--out",
            "model.json",
        ],
        dir,
    ));
}

fn write_json(path: &Path, v: &Value) {
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap()).unwrap();
}

/// Index of component `name` in the model's `components`.
fn entry(model: &Value, name: &str) -> usize {
    model["components"]
        .as_array()
        .unwrap()
        .iter()
        .position(|c| c["name"] == name)
        .unwrap()
}

/// Two entries of `components` swapped, each keeping its name with its data: the file still says which
/// values are EXX's. A reader taking the entries by position would use EYX's values as EXX's in
/// `predict` (predictions moved by µm) and exit 0. The prediction is the unswapped
/// model's, to the byte.
#[test]
fn swapped_components_are_read_by_name() {
    let dir = scratch("swap");
    lines_and_model(&dir);
    let mut m = read_json(&dir.join("model.json"));
    let (a, b) = (entry(&m, "EXX"), entry(&m, "EYX"));
    m["components"].as_array_mut().unwrap().swap(a, b);
    write_json(&dir.join("swapped.json"), &m);
    for (model, out) in [("model.json", "p0.csv"), ("swapped.json", "p1.csv")] {
        ok(&axcomp_in(
            &[
                "predict",
                "--model",
                model,
                "--data",
                "lines.csv",
                "--out",
                out,
            ],
            &dir,
        ));
    }
    let p0 = std::fs::read(dir.join("p0.csv")).unwrap();
    let p1 = std::fs::read(dir.join("p1.csv")).unwrap();
    assert!(p0 == p1, "the swapped model predicts differently");
}

/// Two `EXY` entries and no `EXX`: must not be accepted (EXX read from the first entry, which is
/// EXY's). Exit 2 naming the file, the duplicated name and the missing one is not reached.
#[test]
fn a_duplicated_component_is_refused_naming_it() {
    let dir = scratch("dup");
    lines_and_model(&dir);
    let mut m = read_json(&dir.join("model.json"));
    let (a, b) = (entry(&m, "EXX"), entry(&m, "EXY"));
    m["components"][a] = m["components"][b].clone();
    write_json(&dir.join("dup.json"), &m);
    fails_untouched_naming(
        &[
            "predict",
            "--model",
            "dup.json",
            "--data",
            "lines.csv",
            "--out",
            "p.csv",
        ],
        &dir,
        &["dup.json", "EXY", "twice"],
    );
    // Dropped instead of duplicated: the missing name is said.
    m["components"].as_array_mut().unwrap().remove(a);
    write_json(&dir.join("short.json"), &m);
    fails_untouched_naming(
        &[
            "predict",
            "--model",
            "short.json",
            "--data",
            "lines.csv",
            "--out",
            "p.csv",
        ],
        &dir,
        &["short.json", "missing", "EXX"],
    );
}

/// A short coefficient array (unchecked: a panic, exit 101, indexing past its end), a 1e300 coefficient
/// (unchecked: predictions of 1e299), an unknown component name and a version the reader does not know:
/// each exit 2 naming the file and the entry.
#[test]
fn malformed_entries_are_refused_naming_the_entry() {
    let dir = scratch("entries");
    lines_and_model(&dir);
    let m = read_json(&dir.join("model.json"));
    let i = entry(&m, "EYY");
    let mut short = m.clone();
    short["components"][i]["coefficients"]
        .as_array_mut()
        .unwrap()
        .truncate(3);
    let mut huge = m.clone();
    huge["components"][i]["coefficients"][2] = serde_json::json!(1e300);
    let mut unknown = m.clone();
    unknown["components"][i]["name"] = "EQQ".into();
    let mut version = m.clone();
    version["version"] = 7.into();
    let cases = [
        ("short.json", short, vec!["EYY", "3 coefficients"]),
        ("huge.json", huge, vec!["EYY", "1e300"]),
        ("unknown.json", unknown, vec!["EQQ", "unknown component"]),
        ("version.json", version, vec!["version 7"]),
    ];
    for (name, v, needles) in cases {
        write_json(&dir.join(name), &v);
        let mut needles = needles;
        needles.push(name);
        fails_untouched_naming(
            &[
                "predict",
                "--model",
                name,
                "--data",
                "lines.csv",
                "--out",
                "p.csv",
            ],
            &dir,
            &needles,
        );
    }
}

/// A mutation of a model file's `components`.
#[derive(Debug, Clone)]
enum Mutation {
    Swap(usize, usize),
    Duplicate(usize, usize),
    Drop(usize),
    Truncate(usize, usize),
    Poison(usize, usize, f64),
    Rename(usize, usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let i = 0usize..21;
    prop_oneof![
        (i.clone(), i.clone()).prop_map(|(a, b)| Mutation::Swap(a, b)),
        (i.clone(), i.clone()).prop_map(|(a, b)| Mutation::Duplicate(a, b)),
        i.clone().prop_map(Mutation::Drop),
        (i.clone(), 0usize..12).prop_map(|(a, n)| Mutation::Truncate(a, n)),
        (
            i.clone(),
            0usize..12,
            prop_oneof![Just(1e300), Just(-1e300), Just(1e12), Just(f64::NAN)]
        )
            .prop_map(|(a, k, v)| Mutation::Poison(a, k, v)),
        (i.clone(), i).prop_map(|(a, b)| Mutation::Rename(a, b)),
    ]
}

/// Applies `m`; true when the result is a pure reordering (read by name, it must predict the same).
fn apply(model: &mut Value, m: &Mutation) -> bool {
    let c = model["components"].as_array_mut().unwrap();
    // Indices wrap round the entries left after earlier drops.
    let n = c.len();
    let m = match *m {
        Mutation::Swap(a, b) => Mutation::Swap(a % n, b % n),
        Mutation::Duplicate(a, b) => Mutation::Duplicate(a % n, b % n),
        Mutation::Drop(a) => Mutation::Drop(a % n),
        Mutation::Truncate(a, k) => Mutation::Truncate(a % n, k),
        Mutation::Poison(a, k, v) => Mutation::Poison(a % n, k, v),
        Mutation::Rename(a, b) => Mutation::Rename(a % n, b % n),
    };
    match m {
        Mutation::Swap(a, b) => {
            c.swap(a, b);
            true
        }
        Mutation::Duplicate(a, b) => {
            c[b] = c[a].clone();
            a == b
        }
        Mutation::Drop(a) => {
            c.remove(a);
            false
        }
        Mutation::Truncate(a, n) => {
            let k = c[a]["coefficients"].as_array_mut().unwrap();
            let same = n >= k.len();
            k.truncate(n);
            same
        }
        Mutation::Poison(a, k, v) => {
            // NaN is not JSON: serde_json writes it as null, as a careless writer would.
            let v = if v.is_nan() {
                Value::Null
            } else {
                serde_json::json!(v)
            };
            match c[a]["coefficients"].as_array_mut().unwrap().get_mut(k) {
                Some(x) => *x = v,
                None => c[a]["value"] = v,
            }
            false
        }
        Mutation::Rename(a, b) => {
            let name = c[b]["name"].clone();
            c[a]["name"] = name;
            a == b
        }
    }
}

fn predictions(text: &str, rows: &axcomp_data::Dataset) -> Option<Vec<[f64; 3]>> {
    let model = axcomp_geometry::GeometryModel::from_json(text, "m.json").ok()?;
    let p = axcomp_geometry::predict_rows(&model, rows).expect("rows inside the grid");
    Some(p.iter().map(|r| r.e_um).collect())
}

/// Model files mutated as the image parser's tests mutate images (entries swapped, duplicated,
/// dropped, renamed; coefficient arrays truncated; 1e300, 1e12 or null put in): the reader never
/// panics, and a model it accepts predicts exactly what the unmutated one does (only a pure
/// reordering may be accepted): a swap must not change predictions, nor a truncation panic.
#[test]
fn mutated_models_never_panic_nor_predict_differently() {
    let dir = scratch("prop");
    lines_and_model(&dir);
    let text = std::fs::read_to_string(dir.join("model.json")).unwrap();
    let original: Value = serde_json::from_str(&text).unwrap();
    let rows = axcomp_data::Dataset::load(&dir.join("lines.csv"), &Default::default()).unwrap();
    let reference = predictions(&text, &rows).expect("the fitted model reads");
    let config = ProptestConfig {
        cases: 96,
        failure_persistence: None,
        ..ProptestConfig::default()
    };
    proptest!(config, |(ms in proptest::collection::vec(mutation(), 1..4))| {
        let mut v = original.clone();
        let mut reordering = true;
        for m in &ms {
            reordering &= apply(&mut v, m);
        }
        match predictions(&v.to_string(), &rows) {
            Some(p) => prop_assert!(p == reference, "{ms:?} accepted with other predictions"),
            None => prop_assert!(!reordering, "{ms:?} is a reordering and was refused"),
        }
    });
}

/// `--out model.json --json fit.json` where model.json is a link to fit.json: both outputs
/// pass a check by name (different names) and fit.json would end up holding the model, exit 0. Instead
/// exit 2 naming both, nothing written.
#[cfg(unix)]
#[test]
fn two_outputs_that_are_one_file_through_a_link_are_refused() {
    let dir = scratch("link");
    lines_and_model(&dir);
    std::fs::write(dir.join("fit.json"), "{}\n").unwrap();
    std::os::unix::fs::symlink("fit.json", dir.join("m.json")).unwrap();
    fails_untouched_naming(
        &[
            "fit",
            "geometry",
            "--data",
            "lines.csv",
            "--out",
            "m.json",
            "--json",
            "fit.json",
        ],
        &dir,
        &["m.json", "fit.json", "same file"],
    );
}

/// An output inside a folder the command writes whole: `--report rep --out rep/report.md` (the
/// report would overwrite the model, exit 0), `--export tab --json tab/EXX.csv` (the table would
/// overwrite the JSON) and an output reaching the folder through a link: exit 2 naming the output and the
/// folder's option, nothing written.
#[cfg(unix)]
#[test]
fn an_output_inside_a_folder_the_command_writes_is_refused() {
    let dir = scratch("inside");
    lines_and_model(&dir);
    std::fs::create_dir(dir.join("tab")).unwrap();
    std::os::unix::fs::symlink("tab", dir.join("alias")).unwrap();
    let cases: [(&[&str], &str); 3] = [
        (
            &["--report", "rep", "--out", "rep/report.md"],
            "rep/report.md",
        ),
        (&["--export", "tab", "--json", "tab/EXX.csv"], "tab/EXX.csv"),
        (
            &["--export", "tab", "--out", "alias/m.json"],
            "alias/m.json",
        ),
    ];
    for (extra, path) in cases {
        let mut args = vec!["fit", "geometry", "--data", "lines.csv"];
        args.extend_from_slice(extra);
        fails_untouched_naming(&args, &dir, &[path, extra[0]]);
    }
}

/// A second `--export` into the same folder: the first fit's component tables that the
/// second fit does not write (the four components the seven-line plan cannot identify) must not stay,
/// or the folder holds a mix of two models. The folder holds the second export only; a file of the
/// user's in it stays.
#[test]
fn a_second_export_leaves_no_table_of_the_first() {
    let dir = scratch("stale");
    lines_and_model(&dir);
    ok(&axcomp_in(
        &[
            "fit",
            "geometry",
            "--data",
            "lines.csv",
            "--method",
            "plain",
            "--export",
            "tables",
        ],
        &dir,
    ));
    assert!(
        dir.join("tables/ECZ.csv").is_file(),
        "the full plan identifies ECZ"
    );
    std::fs::write(dir.join("tables/notes.txt"), "mine").unwrap();
    ok(&axcomp_in(
        &[
            "plan",
            "geometry",
            "--stroke",
            "800,600,500",
            "--simulate",
            "seven.csv",
            "--twin-plan",
            "seven-line",
        ],
        &dir,
    ));
    ok(&axcomp_in(
        &[
            "fit",
            "geometry",
            "--data",
            "seven.csv",
            "--method",
            "plain",
            "--export",
            "tables",
        ],
        &dir,
    ));
    for gone in ["ECY.csv", "EAZ.csv", "EBZ.csv", "ECZ.csv"] {
        assert!(
            !dir.join("tables").join(gone).exists(),
            "{gone} of the first export left"
        );
    }
    assert!(dir.join("tables/EXX.csv").is_file());
    assert_eq!(
        std::fs::read_to_string(dir.join("tables/notes.txt")).unwrap(),
        "mine"
    );
}

/// Rewrites `dir/lines.csv` into `dir/NAME` with `f(row index, deviation)` as each deviation.
fn rewrite_deviations(dir: &Path, name: &str, f: impl Fn(usize, f64) -> String) {
    let (header, mut rows) = common::table(&dir.join("lines.csv"));
    let i = header.iter().position(|h| h == "deviation_um").unwrap();
    for (k, r) in rows.iter_mut().enumerate() {
        r[i] = f(k, r[i].parse().unwrap());
    }
    common::write_table(&dir.join(name), &header, &rows);
}

/// One typed-in 5000 µm reading among laser lines, and every reading ×1000 (nm taken for µm): neither
/// may be fitted silently (volumetric error ×8, "after" figures worse than before): a
/// warning naming the file and the line of the reading (the fit goes on), and `--strict` refuses the
/// data (exit 2, nothing written).
#[test]
fn implausible_readings_warn_and_strict_refuses() {
    let dir = scratch("plausible");
    lines_and_model(&dir);
    rewrite_deviations(&dir, "typo.csv", |k, v| {
        if k == 40 {
            "5000".into()
        } else {
            v.to_string()
        }
    });
    rewrite_deviations(&dir, "nm.csv", |_, v| (v * 1000.0).to_string());
    // Row 40 is on file line 42 (the header is line 1).
    let cases = [
        ("typo.csv", vec!["typo.csv", "line 42", "neighbours"]),
        ("nm.csv", vec!["nm.csv", "nm"]),
    ];
    for (file, needles) in cases {
        let o = axcomp_in(
            &[
                "fit", "geometry", "--data", file, "--method", "plain", "--json", "w.json",
            ],
            &dir,
        );
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        for n in &needles {
            assert!(
                err.contains("warning") && err.contains(n),
                "{file}: must name {n}: {err}"
            );
        }
        // The same findings are in the JSON (`warnings`: kind, column, message, lines).
        let v: Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("w.json")).unwrap()).unwrap();
        let w = v["warnings"].as_array().expect("warnings in the JSON");
        assert!(
            !w.is_empty() && w.iter().all(|w| w["column"] == "deviation_um"),
            "{w:?}"
        );
        if file == "typo.csv" {
            assert!(
                w.iter()
                    .any(|w| w["lines"].as_array().unwrap().contains(&42.into()))
            );
        }
        fails_untouched_naming(
            &[
                "fit", "geometry", "--data", file, "--method", "plain", "--strict", "--out",
                "s.json",
            ],
            &dir,
            &[file, "--strict"],
        );
    }
    // The twin's own lines raise no warning.
    let o = axcomp_in(
        &[
            "fit",
            "geometry",
            "--data",
            "lines.csv",
            "--method",
            "plain",
        ],
        &dir,
    );
    assert!(!String::from_utf8_lossy(&o.stderr).contains("warning"));
}

/// The R-test and probe fits carry their data warnings in the JSON too (`warnings`, `[]` when none).
#[test]
fn rtest_and_probe_json_carry_warnings() {
    let dir = scratch("json-warnings");
    for (sim, fit) in [
        (
            vec!["sim", "--machine", "ac-trunnion", "--out", "r.csv"],
            vec!["fit", "rtest", "--data", "r.csv", "--json", "r.json"],
        ),
        (
            vec!["sim-probe", "--plan", "probe-cal", "--out", "p.csv"],
            vec![
                "fit",
                "probe",
                "--data",
                "p.csv",
                "--sphere-diameter-mm",
                "25",
                "--json",
                "p.json",
            ],
        ),
    ] {
        let o = axcomp_in(&sim, &dir);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let o = axcomp_in(&fit, &dir);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let j = dir.join(fit.last().unwrap());
        let v: Value = serde_json::from_str(&std::fs::read_to_string(j).unwrap()).unwrap();
        assert_eq!(v["warnings"], serde_json::json!([]), "{}", fit[1]);
    }
}

/// A single 1e300 reading: must not be fitted (the model would hold 1e299 and `null`s, and then the
/// tool would refuse its own model). Exit 2 naming file, line and column.
#[test]
fn an_absurd_reading_is_an_error_naming_the_cell() {
    let dir = scratch("absurd");
    lines_and_model(&dir);
    rewrite_deviations(&dir, "huge.csv", |k, v| {
        if k == 7 {
            "1e300".into()
        } else {
            v.to_string()
        }
    });
    fails_untouched_naming(
        &["fit", "geometry", "--data", "huge.csv", "--out", "m.json"],
        &dir,
        &["huge.csv:9:", "deviation_um"],
    );
}

/// Numeric options out of range: `--export-step 1e-9` (unchecked: the export exhausts the memory and
/// the process aborts), `--export-step NaN` (unchecked: accepted), `plan geometry --stroke 1e300,…`
/// (unchecked: a plan over 1e300 mm) and `--runs 1000000000` (unchecked: runs until memory runs out):
/// each is exit 2 naming the option, nothing written.
#[test]
fn out_of_range_options_are_refused_naming_them() {
    let dir = scratch("options");
    lines_and_model(&dir);
    let fit = [
        "fit",
        "geometry",
        "--data",
        "lines.csv",
        "--method",
        "plain",
        "--export",
        "t",
    ];
    for step in ["1e-9", "NaN"] {
        let mut args = fit.to_vec();
        args.extend_from_slice(&["--export-step", step]);
        fails_untouched_naming(&args, &dir, &["--export-step"]);
    }
    for order in ["0", "5", "cubic"] {
        let mut args = fit.to_vec();
        args.extend_from_slice(&["--roughness-order", order]);
        fails_untouched_naming(&args, &dir, &["--roughness-order"]);
    }
    let plan = ["plan", "geometry", "--simulate", "s.csv"];
    let cases: [(&[&str], &str); 2] = [
        (&["--stroke", "1e300,600,500"], "--stroke"),
        (
            &["--stroke", "800,600,500", "--runs", "1000000000"],
            "--runs",
        ),
    ];
    for (extra, needle) in cases {
        let mut args = plan.to_vec();
        args.extend_from_slice(extra);
        fails_untouched_naming(&args, &dir, &[needle]);
    }
}
