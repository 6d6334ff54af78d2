//! Hostile inputs to the R-test system (`fit rtest`, `predict` and `image group --rotary` on its model
//! file; contract: `shared/spec/interfaces.md`, "Location errors of a five-axis machine's rotary axes").
//! Each test failed before its fix. The data are the twin's (`axcomp sim --machine`).

use std::path::Path;

use proptest::prelude::*;
use serde_json::Value;

mod common;
use common::{axcomp_in, fails_untouched_naming, ok, read_json, scratch};

/// The twin's AC-trunnion R-test rows (`dir/rt.csv`) and the fit's model (`dir/rm.json`).
fn rows_and_model(dir: &Path) {
    ok(&axcomp_in(
        &["sim", "--machine", "ac-trunnion", "--out", "rt.csv"],
        dir,
    ));
    ok(&axcomp_in(
        &["fit", "rtest", "--data", "rt.csv", "--out", "rm.json"],
        dir,
    ));
}

fn write_json(path: &Path, v: &Value) {
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap()).unwrap();
}

fn entry(model: &Value, name: &str) -> usize {
    model["location_errors"]
        .as_array()
        .unwrap()
        .iter()
        .position(|e| e[0] == name)
        .unwrap()
}

/// Two location errors swapped, each keeping its name with its value: `predict` must not take
/// them by position (EY0C's value as EX0C's, predictions off by tens of µm) and exit 0. The
/// prediction is the unswapped model's, to the byte.
#[test]
fn swapped_location_errors_are_read_by_name() {
    let dir = scratch("swap");
    rows_and_model(&dir);
    let mut m = read_json(&dir.join("rm.json"));
    let (a, b) = (entry(&m, "EX0C"), entry(&m, "EA0C"));
    m["location_errors"].as_array_mut().unwrap().swap(a, b);
    write_json(&dir.join("swapped.json"), &m);
    for (model, out) in [("rm.json", "p0.csv"), ("swapped.json", "p1.csv")] {
        ok(&axcomp_in(
            &[
                "predict", "--model", model, "--data", "rt.csv", "--out", out,
            ],
            &dir,
        ));
    }
    let p0 = std::fs::read(dir.join("p0.csv")).unwrap();
    let p1 = std::fs::read(dir.join("p1.csv")).unwrap();
    assert!(p0 == p1, "the swapped model predicts differently");
}

/// A name twice, a name of another machine kind (EX0B on an AC trunnion), a 1e300 value, a missing
/// entry and a kind the reader does not know: `predict` must accept none (the first two
/// would be taken by position, 1e300 as a prediction of 1e300). Exit 2 naming the file and the entry.
#[test]
fn malformed_location_errors_are_refused_naming_the_entry() {
    let dir = scratch("entries");
    rows_and_model(&dir);
    let m = read_json(&dir.join("rm.json"));
    let a = entry(&m, "EX0C");
    let b = entry(&m, "EY0C");
    let mut twice = m.clone();
    twice["location_errors"][a] = m["location_errors"][b].clone();
    let mut other = m.clone();
    other["location_errors"][a][0] = "EX0B".into();
    let mut huge = m.clone();
    huge["location_errors"][a][1]["value"] = serde_json::json!(1e300);
    let mut missing = m.clone();
    missing["location_errors"].as_array_mut().unwrap().remove(a);
    let mut kind = m.clone();
    kind["kind"] = "rtest2".into();
    let cases = [
        ("twice.json", twice, vec!["EY0C", "twice"]),
        ("other.json", other, vec!["EX0B", "ac-trunnion"]),
        ("huge.json", huge, vec!["EX0C", "1e300"]),
        ("missing.json", missing, vec!["missing EX0C"]),
        ("kind.json", kind, vec!["rtest2"]),
    ];
    for (name, v, mut needles) in cases {
        write_json(&dir.join(name), &v);
        needles.push(name);
        fails_untouched_naming(
            &[
                "predict", "--model", name, "--data", "rt.csv", "--out", "p.csv",
            ],
            &dir,
            &needles,
        );
    }
}

/// A mutation of a model file's `location_errors`.
#[derive(Debug, Clone)]
enum Mutation {
    Swap(usize, usize),
    Duplicate(usize, usize),
    Drop(usize),
    Poison(usize, f64),
    Rename(usize, usize),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    let i = 0usize..11;
    prop_oneof![
        (i.clone(), i.clone()).prop_map(|(a, b)| Mutation::Swap(a, b)),
        (i.clone(), i.clone()).prop_map(|(a, b)| Mutation::Duplicate(a, b)),
        i.clone().prop_map(Mutation::Drop),
        (
            i.clone(),
            prop_oneof![Just(1e300), Just(-1e300), Just(1e12), Just(f64::NAN)]
        )
            .prop_map(|(a, v)| Mutation::Poison(a, v)),
        (i.clone(), i).prop_map(|(a, b)| Mutation::Rename(a, b)),
    ]
}

/// Applies `m` (indices wrap round the entries left); true when the result is a pure reordering.
fn apply(model: &mut Value, m: &Mutation) -> bool {
    let e = model["location_errors"].as_array_mut().unwrap();
    let n = e.len();
    match *m {
        Mutation::Swap(a, b) => {
            e.swap(a % n, b % n);
            true
        }
        Mutation::Duplicate(a, b) => {
            e[b % n] = e[a % n].clone();
            a % n == b % n
        }
        Mutation::Drop(a) => {
            e.remove(a % n);
            false
        }
        Mutation::Poison(a, v) => {
            e[a % n][1]["value"] = if v.is_nan() {
                Value::Null
            } else {
                serde_json::json!(v)
            };
            false
        }
        Mutation::Rename(a, b) => {
            let name = e[b % n][0].clone();
            e[a % n][0] = name;
            a % n == b % n
        }
    }
}

fn predictions(text: &str, rows: &axcomp_data::Dataset) -> Option<Vec<[f64; 3]>> {
    let model = axcomp_rtest::RtestModel::from_json(text, "rm.json").ok()?;
    Some(axcomp_rtest::predict_rows(&model, rows).expect("the rows predict"))
}

/// Model files mutated (location errors swapped, duplicated, dropped, renamed; 1e300, 1e12 or null
/// values): the reader never panics, and a model it accepts predicts exactly what the unmutated one
/// does (only a pure reordering may be accepted): a swap must not change the predictions.
#[test]
fn mutated_models_never_panic_nor_predict_differently() {
    let dir = scratch("prop");
    rows_and_model(&dir);
    let text = std::fs::read_to_string(dir.join("rm.json")).unwrap();
    let original: Value = serde_json::from_str(&text).unwrap();
    let rows = axcomp_data::Dataset::load(&dir.join("rt.csv"), &Default::default()).unwrap();
    let reference = predictions(&text, &rows).expect("the fitted model reads");
    let config = ProptestConfig {
        cases: 128,
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

/// `fit rtest --report r --out r/report.md`: the report's page must not overwrite the model (or
/// the reverse) with exit 0. Exit 2 naming the output and `--report`, nothing written.
#[test]
fn an_output_inside_the_report_folder_is_refused() {
    let dir = scratch("inside");
    rows_and_model(&dir);
    fails_untouched_naming(
        &[
            "fit",
            "rtest",
            "--data",
            "rt.csv",
            "--report",
            "r",
            "--out",
            "r/report.md",
        ],
        &dir,
        &["r/report.md", "--report"],
    );
}

/// `--out m.json --json fit.json` with m.json a link to fit.json: must not exit 0 with fit.json
/// holding the model. Exit 2 naming both.
#[cfg(unix)]
#[test]
fn two_outputs_that_are_one_file_through_a_link_are_refused() {
    let dir = scratch("link");
    rows_and_model(&dir);
    std::fs::write(dir.join("fit.json"), "{}\n").unwrap();
    std::os::unix::fs::symlink("fit.json", dir.join("m.json")).unwrap();
    fails_untouched_naming(
        &[
            "fit", "rtest", "--data", "rt.csv", "--out", "m.json", "--json", "fit.json",
        ],
        &dir,
        &["m.json", "fit.json", "same file"],
    );
}

/// Copies `dir/FROM` to `dir/TO` with each cell of `cols` replaced by `f(row index, value)`, comment
/// lines kept.
fn rewrite(dir: &Path, from: &str, to: &str, cols: &[&str], f: impl Fn(usize, f64) -> f64) {
    let text = std::fs::read_to_string(dir.join(from)).unwrap();
    let mut lines = text.lines();
    let mut out = String::new();
    let mut header: Vec<String> = Vec::new();
    for l in lines.by_ref() {
        out.push_str(l);
        out.push('\n');
        if !l.starts_with('#') {
            header = l.split(',').map(str::to_string).collect();
            break;
        }
    }
    let idx: Vec<usize> = cols
        .iter()
        .map(|c| header.iter().position(|h| h == c).unwrap())
        .collect();
    for (k, l) in lines.enumerate() {
        let mut cells: Vec<String> = l.split(',').map(str::to_string).collect();
        for &i in &idx {
            cells[i] = f(k, cells[i].parse().unwrap()).to_string();
        }
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    std::fs::write(dir.join(to), out).unwrap();
}

/// R-test data whose own header names its machine kind (`# … machine bc-head`) fitted as another
/// (`--machine bc-trunnion`), angles in radians, displacements ×1000 (nm for µm): none may
/// be fitted silently. A warning naming the file (and the header's line), and `--strict`
/// refuses (exit 2, nothing written). The twin's own data raise none.
#[test]
fn implausible_rtest_data_warns_and_strict_refuses() {
    let dir = scratch("plausible");
    rows_and_model(&dir);
    ok(&axcomp_in(
        &[
            "sim",
            "--machine",
            "bc-head",
            "--pivot-mm",
            "200",
            "--out",
            "bh.csv",
        ],
        &dir,
    ));
    let rad = std::f64::consts::PI / 180.0;
    rewrite(&dir, "rt.csv", "rad.csv", &["a_deg", "c_deg"], |_, v| {
        v * rad
    });
    rewrite(
        &dir,
        "rt.csv",
        "nm.csv",
        &["dx_um", "dy_um", "dz_um"],
        |_, v| v * 1000.0,
    );
    let cases: [(&[&str], &[&str]); 3] = [
        (
            &["--data", "bh.csv", "--machine", "bc-trunnion"],
            &["bh.csv:1", "bc-head", "bc-trunnion"],
        ),
        (&["--data", "rad.csv"], &["rad.csv", "radians", "c_deg"]),
        (&["--data", "nm.csv"], &["nm.csv", "dx_um", "nm"]),
    ];
    for (extra, needles) in cases {
        let mut args = vec!["fit", "rtest"];
        args.extend_from_slice(extra);
        let o = axcomp_in(&args, &dir);
        let err = String::from_utf8_lossy(&o.stderr);
        for n in needles {
            assert!(
                err.contains("warning") && err.contains(n),
                "{extra:?}: must name {n}: {err}"
            );
        }
        args.extend_from_slice(&["--strict", "--out", "s.json"]);
        let mut needles = needles.to_vec();
        needles.push("--strict");
        fails_untouched_naming(&args, &dir, &needles);
    }
    for (data, machine) in [("rt.csv", "ac-trunnion"), ("bh.csv", "bc-head")] {
        let mut args = vec!["fit", "rtest", "--data", data, "--machine", machine];
        if machine == "bc-head" {
            args.extend_from_slice(&["--pivot-mm", "200"]);
        }
        let o = axcomp_in(&args, &dir);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            o.status.success() && !err.contains("warning"),
            "{data}: {err}"
        );
    }
}

/// A 1e300 displacement: must not be fitted into a model of 1e299 values. Exit 2 naming file,
/// line and column.
#[test]
fn an_absurd_reading_is_an_error_naming_the_cell() {
    let dir = scratch("absurd");
    rows_and_model(&dir);
    rewrite(&dir, "rt.csv", "huge.csv", &["dy_um"], |k, v| {
        if k == 5 { 1e300 } else { v }
    });
    // Row 5 is on line 8: a comment line, the header, then rows 0 … 5.
    fails_untouched_naming(
        &["fit", "rtest", "--data", "huge.csv", "--out", "m.json"],
        &dir,
        &["huge.csv:8:", "dy_um"],
    );
}

/// Options: `plan rtest --circle-poses 1000000000` (unchecked: the process aborts when memory runs out),
/// `--pivot-mm 1e300` (unchecked: a bc-head of 1e300 mm fitted and planned), one column scaled twice
/// (unchecked: the last factor silently wins) and a repeated `--machine` (refused by the parser: kept as
/// a guard): each is exit 2 naming the option, nothing written.
#[test]
fn out_of_range_and_repeated_options_are_refused() {
    let dir = scratch("options");
    rows_and_model(&dir);
    let cases: [(&[&str], &[&str]); 5] = [
        (
            &["plan", "rtest", "--circle-poses", "1000000000"],
            &["--circle-poses"],
        ),
        (
            &[
                "plan",
                "rtest",
                "--machine",
                "bc-head",
                "--pivot-mm",
                "1e300",
            ],
            &["--pivot-mm"],
        ),
        (
            &[
                "fit",
                "rtest",
                "--data",
                "rt.csv",
                "--machine",
                "bc-head",
                "--pivot-mm",
                "1e300",
            ],
            &["--pivot-mm"],
        ),
        (
            &[
                "fit", "rtest", "--data", "rt.csv", "--scale", "dx_um=2", "--scale", "dx_um=3",
            ],
            &["--scale", "dx_um", "twice"],
        ),
        (
            &[
                "fit",
                "rtest",
                "--data",
                "rt.csv",
                "--machine",
                "ac-trunnion",
                "--machine",
                "bc-head",
            ],
            &["--machine"],
        ),
    ];
    for (args, needles) in cases {
        let mut args = args.to_vec();
        args.extend_from_slice(&["--json", "out.json"]);
        fails_untouched_naming(&args, &dir, needles);
    }
}
