//! `axcomp export` of geometry and rotary models end to end: twin data → fit → export; the files parsed
//! back by the documented grammars (`axcomp_export`'s readers) and compared with the model file; the folder
//! written whole; a format for another model kind refused, nothing written.

use std::path::Path;
use std::process::{Command, Output};

use axcomp_export::{Format, heidenhain, linuxcnc, tf5280};
use axcomp_kinematics::rotary::{FiveAxis, MachineKind};
use axcomp_kinematics::{Axis, Component};
use axcomp_twin::five_axis::{FiveAxisTwin, standard_paths};

mod common;
use common::scratch;

fn axcomp(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("running axcomp")
}

fn ok(o: &Output) -> String {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Geometry twin (800 × 600 × 500, σ 0.5 µm) → fit geometry → export tf5280, then heidenhain into the same
/// folder: the TF5280 files are gone, the user's note stays; values equal the model file's (tolerance: the
/// written rounding, 5e-8 mm, 5e-11 rad, 5e-7 mm).
#[test]
fn geometry_exports_follow_the_formats_and_replace_each_other_whole() {
    let d = scratch("export-geometry");
    ok(&axcomp(
        &[
            "plan",
            "geometry",
            "--stroke",
            "800,600,500",
            "--lines",
            "20",
            "--sigma-um",
            "0.5",
            "--twin-plan",
            "seven-line+plan",
            "--simulate",
            "lines.csv",
        ],
        &d,
    ));
    ok(&axcomp(
        &[
            "fit",
            "geometry",
            "--data",
            "lines.csv",
            "--out",
            "model.json",
        ],
        &d,
    ));
    let model = axcomp_geometry::GeometryModel::from_json(
        &std::fs::read_to_string(d.join("model.json")).unwrap(),
        "model.json",
    )
    .unwrap();
    let out = ok(&axcomp(
        &[
            "export",
            "--model",
            "model.json",
            "--format",
            "tf5280",
            "--out",
            "cnc",
        ],
        &d,
    ));
    assert!(out.contains("chain XYZ (workpiece_axes 2)"), "{out}");
    std::fs::write(d.join("cnc/my-notes.txt"), "mine").unwrap();
    let list =
        tf5280::parse_list(&std::fs::read_to_string(d.join("cnc/volcomp.lis")).unwrap()).unwrap();
    assert!(list.contains(&("workpiece_axes".into(), "2".into())));
    let x = std::fs::read_to_string(d.join("cnc").join(tf5280::component_file(Axis::X))).unwrap();
    let rows = &tf5280::parse_isg_csv(&x).unwrap()[0].rows;
    for row in rows {
        // X carries the workpiece (YX/Z): the file holds the carriage's own motion, −model.
        let exx = -model.component_value(Component::EXX, row[0]) * 1e-3;
        let ebx = -model.component_value(Component::EBX, row[0]) * 1e-6;
        assert!(
            (row[1] - exx).abs() <= 5e-8 && (row[5] - ebx).abs() <= 5e-11,
            "{row:?}"
        );
    }
    let out = ok(&axcomp(
        &[
            "export",
            "--model",
            "model.json",
            "--format",
            "heidenhain",
            "--out",
            "cnc",
            "--step",
            "25",
        ],
        &d,
    ));
    assert!(out.contains("remaining |e| RMS"), "{out}");
    assert_eq!(
        names(&d.join("cnc")),
        [
            ".written-by-axcomp",
            "AXCOMP.CMA",
            "README.txt",
            "X.COM",
            "Y.COM",
            "Z.COM",
            "my-notes.txt"
        ]
    );
    let z =
        heidenhain::parse_table(&std::fs::read_to_string(d.join("cnc/Z.COM")).unwrap()).unwrap();
    assert_eq!(z.columns, ["NR", "AXISPOS", "X", "Y", "Z"]);
    for row in &z.rows {
        let q: f64 = row[1].parse().unwrap();
        let ezz: f64 = row[4].parse().unwrap();
        assert!((ezz - model.component_value(Component::EZZ, q) * 1e-3).abs() <= 5e-7);
    }
}

/// AC-trunnion twin → fit rtest → export linuxcnc-xyzac-trt over the fitted poses: the HAL pins are the
/// model's values (trtfuncs.c names), and the stated remaining error is the library's over the same poses
/// (same arithmetic, 1e-3 µm: printed with 3 decimals); the bc format on this model is refused, nothing
/// written.
#[test]
fn rotary_export_states_what_remains() {
    let d = scratch("export-rotary");
    let m = FiveAxis::new(MachineKind::AcTrunnion, 0.0);
    let paths = standard_paths(&m, [150.0, 0.0, 100.0], -60.0, 72, &[0.0, -60.0], 36, None);
    let csv = FiveAxisTwin::random(m, 3)
        .measure(&paths, 3)
        .to_csv_string();
    std::fs::write(d.join("rtest.csv"), csv).unwrap();
    ok(&axcomp(
        &["fit", "rtest", "--data", "rtest.csv", "--out", "model.json"],
        &d,
    ));
    let out = ok(&axcomp(
        &[
            "export",
            "--model",
            "model.json",
            "--format",
            "linuxcnc-xyzac-trt",
            "--poses",
            "rtest.csv",
            "--out",
            "kins",
        ],
        &d,
    ));
    let model = axcomp_rtest::RtestModel::from_json(
        &std::fs::read_to_string(d.join("model.json")).unwrap(),
        "model.json",
    )
    .unwrap();
    let ds = axcomp_data::Dataset::load(&d.join("rtest.csv"), &Default::default()).unwrap();
    let poses = axcomp_rtest::RtestData::from_dataset(&ds, m, false)
        .unwrap()
        .poses;
    let r = linuxcnc::remaining(&model, Format::LinuxCncXyzacTrt, &poses, "x").unwrap();
    assert!(r.after_rms_um < r.before_rms_um, "{r:?}");
    assert!(
        out.contains(&format!(
            "remaining RMS |d| {:.3} µm over {} poses",
            r.after_rms_um,
            poses.len()
        )),
        "{out} vs {r:?}"
    );
    let hal = std::fs::read_to_string(d.join("kins/xyzac-trt-kins.hal")).unwrap();
    let k = linuxcnc::kins_values(&model, Format::LinuxCncXyzacTrt, [0.0; 3]).unwrap();
    let pins = linuxcnc::parse_setp(&hal).unwrap();
    assert_eq!(pins[0].0, "xyzac-trt-kins.x-rot-point");
    assert!((pins[0].1 - k.x_rot_point).abs() < 5e-7 && (pins[4].1 - k.z_offset).abs() < 5e-7);
    let o = axcomp(
        &[
            "export",
            "--model",
            "model.json",
            "--format",
            "linuxcnc-xyzbc-trt",
            "--out",
            "bc",
        ],
        &d,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success() && err.contains("ac-trunnion"), "{err}");
    assert!(!d.join("bc").exists());
    let o = axcomp(
        &[
            "export",
            "--model",
            "model.json",
            "--format",
            "tf5280",
            "--out",
            "tf",
        ],
        &d,
    );
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains("takes a geometry model"),
        "{err}"
    );
    assert!(!d.join("tf").exists());
}
