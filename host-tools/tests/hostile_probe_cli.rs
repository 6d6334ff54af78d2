//! Hostile inputs to the touch-probe system (`fit probe`, `predict` on its calibration file) and to the
//! outputs of the other fits that share its output handling (`fit positioning`, `replay`); contract:
//! `shared/spec/interfaces.md`, "Touch probe". Each test failed before its fix. The touches are the
//! twin's (`axcomp sim-probe`).

use std::path::Path;

use serde_json::Value;

mod common;
use common::{axcomp_in, fails_untouched_naming, ok, read_json, scratch};

/// The twin's calibration touches (`dir/touches.csv`) and their calibration (`dir/cal.json`).
fn touches_and_calibration(dir: &Path) {
    ok(&axcomp_in(
        &["sim-probe", "--plan", "probe-cal", "--out", "touches.csv"],
        dir,
    ));
    ok(&axcomp_in(
        &[
            "fit",
            "probe",
            "--data",
            "touches.csv",
            "--sphere-diameter-mm",
            "25",
            "--out",
            "cal.json",
        ],
        dir,
    ));
}

/// `--out m.json --json fit.json` with m.json a link to fit.json: must not exit 0 with fit.json
/// holding the calibration. Exit 2 naming both, nothing written.
#[cfg(unix)]
#[test]
fn two_outputs_that_are_one_file_through_a_link_are_refused() {
    let dir = scratch("link");
    touches_and_calibration(&dir);
    std::fs::write(dir.join("fit.json"), "{}\n").unwrap();
    std::os::unix::fs::symlink("fit.json", dir.join("m.json")).unwrap();
    fails_untouched_naming(
        &[
            "fit",
            "probe",
            "--data",
            "touches.csv",
            "--sphere-diameter-mm",
            "25",
            "--out",
            "m.json",
            "--json",
            "fit.json",
        ],
        &dir,
        &["m.json", "fit.json", "same file"],
    );
    // A hard link is one file too.
    std::fs::hard_link(dir.join("fit.json"), dir.join("hard.json")).unwrap();
    fails_untouched_naming(
        &[
            "fit",
            "probe",
            "--data",
            "touches.csv",
            "--sphere-diameter-mm",
            "25",
            "--out",
            "hard.json",
            "--json",
            "fit.json",
        ],
        &dir,
        &["hard.json", "fit.json", "same file"],
    );
}

/// `--report rep --out rep/notes.json`: an output inside the folder the report writes whole; must
/// not exit 0 (the next report run could not tell it from its own files). Exit 2.
#[test]
fn an_output_inside_the_report_folder_is_refused() {
    let dir = scratch("inside");
    touches_and_calibration(&dir);
    fails_untouched_naming(
        &[
            "fit",
            "probe",
            "--data",
            "touches.csv",
            "--sphere-diameter-mm",
            "25",
            "--report",
            "rep",
            "--out",
            "rep/notes.json",
        ],
        &dir,
        &["rep/notes.json", "--report"],
    );
}

/// A calibration whose sphere centre is 1e300 mm or whose feed range is upside down: `predict`
/// must not accept it (contact points of 1e300). Exit 2 naming the file and the entry.
#[test]
fn an_absurd_calibration_is_refused_naming_the_entry() {
    let dir = scratch("absurd");
    touches_and_calibration(&dir);
    let cal = read_json(&dir.join("cal.json"));
    let mut huge = cal.clone();
    huge["sphere_center_mm"][1] = serde_json::json!(1e300);
    let mut upside = cal.clone();
    upside["elevation_range_deg"] = serde_json::json!([80.0, -10.0]);
    let cases: [(&str, Value, &[&str]); 2] = [
        ("huge.json", huge, &["sphere_center_mm[1]", "1e300"]),
        ("upside.json", upside, &["elevation_range_deg"]),
    ];
    for (name, v, needles) in cases {
        std::fs::write(dir.join(name), v.to_string()).unwrap();
        let mut needles = needles.to_vec();
        needles.push(name);
        fails_untouched_naming(
            &[
                "predict",
                "--model",
                name,
                "--data",
                "touches.csv",
                "--out",
                "p.csv",
            ],
            &dir,
            &needles,
        );
    }
}

/// `fit positioning --out table.json --json fit.json` and `replay --out o.bin --csv c.csv` with the
/// second a link to the first: both pass a check by name (exit 0 for the fit, the JSON
/// holding the table), which is not enough. Exit 2 naming both, before any input is read.
#[cfg(unix)]
#[test]
fn positioning_and_replay_outputs_that_are_one_file_are_refused() {
    let dir = scratch("others");
    std::fs::write(dir.join("table.json"), "{}\n").unwrap();
    std::os::unix::fs::symlink("table.json", dir.join("fit.json")).unwrap();
    std::fs::write(dir.join("pos.csv"), "target_mm,deviation_um\n0,1\n10,2\n").unwrap();
    fails_untouched_naming(
        &[
            "fit",
            "positioning",
            "--data",
            "pos.csv",
            "--out",
            "table.json",
            "--json",
            "fit.json",
        ],
        &dir,
        &["table.json", "fit.json", "same file"],
    );
    std::fs::write(dir.join("img.bin"), b"x").unwrap();
    std::fs::write(dir.join("trace.bin"), b"x").unwrap();
    fails_untouched_naming(
        &[
            "replay",
            "--image",
            "img.bin",
            "--trace",
            "trace.bin",
            "--out",
            "table.json",
            "--csv",
            "fit.json",
        ],
        &dir,
        &["table.json", "fit.json", "same file"],
    );
}

/// Touch positions logged in µm (×1000) and a 1e300 position: the first must not be fitted
/// silently, nor the second give contact points of 1e300. The first warns naming the columns and
/// `--strict` refuses it; the second is an error naming file, line and column (exit 2).
#[test]
fn implausible_touches_warn_or_fail() {
    let dir = scratch("plausible");
    touches_and_calibration(&dir);
    let (header, rows) = common::table(&dir.join("touches.csv"));
    let cols: Vec<usize> = (0..3).collect(); // x_mm, y_mm, z_mm
    assert_eq!(&header[..3], ["x_mm", "y_mm", "z_mm"]);
    let mut um = rows.clone();
    for r in &mut um {
        for &c in &cols {
            r[c] = (r[c].parse::<f64>().unwrap() * 1000.0).to_string();
        }
    }
    common::write_table(&dir.join("um.csv"), &header, &um);
    let fit = |data: &str, strict: bool| {
        let mut a = vec!["fit", "probe", "--data", data, "--sphere-diameter-mm", "25"];
        if strict {
            a.extend_from_slice(&["--strict", "--out", "s.json"]);
        }
        a.into_iter().map(str::to_string).collect::<Vec<_>>()
    };
    let args = fit("um.csv", false);
    let o = axcomp_in(&args.iter().map(String::as_str).collect::<Vec<_>>(), &dir);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("warning") && err.contains("x_mm") && err.contains("µm?"),
        "{err}"
    );
    let args = fit("um.csv", true);
    fails_untouched_naming(
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
        &dir,
        &["um.csv", "--strict"],
    );
    let mut huge = rows.clone();
    huge[3][1] = "1e300".into();
    common::write_table(&dir.join("huge.csv"), &header, &huge);
    let args = fit("huge.csv", false);
    fails_untouched_naming(
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
        &dir,
        &["huge.csv:5:2", "y_mm"],
    );
}

/// `sim-probe --feed NaN` and `--feed 1e300`: neither may write touches (feed_mm_min NaN or
/// 1e300). Exit 2 naming the option, nothing written.
#[test]
fn an_absurd_feed_is_refused() {
    let dir = scratch("feed");
    for feed in ["NaN", "1e300"] {
        fails_untouched_naming(
            &[
                "sim-probe",
                "--plan",
                "probe-measure",
                "--feed",
                feed,
                "--out",
                "t.csv",
            ],
            &dir,
            &["--feed"],
        );
    }
}
