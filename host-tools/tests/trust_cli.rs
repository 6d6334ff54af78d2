//! Traceability through the CLI: every fit command's model file carries its provenance
//! (the data file's SHA-256, the filters, the tool version, the command, the UTC date); `image build` and
//! `image group` put the model files' hashes, the tool and the build date into the image, with the sensor
//! names; `image inspect` shows them and which board input feeds each sensor (a warm-up sensor
//! on the STM32G474 board: refused).

use std::path::Path;

use axcomp_kinematics::rotary::{FiveAxis, MachineKind};
use axcomp_twin::five_axis::{FiveAxisTwin, standard_paths};
use axcomp_twin::synth::{SynthConfig, generate};

mod common;
use common::{axcomp_in, ok_in as ok, read_json, scratch};

fn sha(path: &Path) -> String {
    axcomp_data::provenance::file_sha256(path).unwrap().0
}

/// The model file's provenance names `data`'s SHA-256 and length, `command`, this tool's version and a
/// UTC date; returns it.
fn stamped(model: &Path, data: &Path, command: &str) -> serde_json::Value {
    let v = read_json(model);
    let p = &v["provenance"];
    assert_eq!(
        p["source_sha256"].as_str(),
        Some(sha(data).as_str()),
        "{}: {v}",
        model.display()
    );
    assert_eq!(
        p["source_bytes"].as_u64(),
        Some(std::fs::metadata(data).unwrap().len())
    );
    assert_eq!(p["command"], command);
    assert_eq!(
        p["tool"].as_str(),
        Some(concat!("axcomp ", env!("CARGO_PKG_VERSION")))
    );
    let date = p["created_utc"].as_str().unwrap();
    assert!(
        date.len() == 20 && date.ends_with('Z') && date.as_bytes()[10] == b'T',
        "{date}"
    );
    p.clone()
}

fn positioning_csv(path: &Path) {
    let mut s = String::from("target_mm,run,direction,deviation_um,test_id\n");
    for run in 1..=6 {
        for (d, sign) in [("+", 1.0), ("-", -1.0)] {
            for k in 0..21 {
                let x = 10.0 * k as f64;
                let noise = ((run * 31 + k * 17) % 13) as f64 / 13.0 - 0.5;
                let y = 12.0 * (x / 40.0).sin() + 2.0 * sign + noise;
                s.push_str(&format!("{x},{run},{d},{y:.4},A\n"));
            }
        }
    }
    std::fs::write(path, s).unwrap();
}

/// F = 900·ap·fz^0.75·n^0.05 on a grid (no noise), the contract's power-law columns.
fn force_csv(path: &Path) {
    let mut s = String::from("ap_mm,fz_mm,n_rpm,Fc_N\n");
    for ap in [0.5, 1.0, 2.0, 3.0] {
        for fz in [0.05, 0.1, 0.15, 0.2] {
            for n in [2000.0, 4000.0, 6000.0f64] {
                let f = 900.0 * ap * f64::powf(fz, 0.75) * n.powf(0.05);
                s.push_str(&format!("{ap},{fz},{n},{f:.4}\n"));
            }
        }
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn every_fit_command_stamps_its_model_file() {
    let dir = scratch("stamps");
    // positioning (the table carried it already), with a filter.
    positioning_csv(&dir.join("pos.csv"));
    ok(
        &[
            "fit",
            "positioning",
            "--data",
            "pos.csv",
            "--where",
            "test_id=A",
            "--out",
            "t.json",
        ],
        &dir,
    );
    let p = stamped(&dir.join("t.json"), &dir.join("pos.csv"), "fit positioning");
    assert_eq!(p["where_"][0], "test_id=A");
    // thermal, with --holdout and --cv recorded.
    let d = generate(&SynthConfig {
        seed: 5,
        ..SynthConfig::default()
    });
    d.write_csv(&dir.join("th.csv")).unwrap();
    ok(
        &[
            "fit",
            "thermal",
            "--data",
            "th.csv",
            "--target",
            "error_um",
            "--holdout",
            "condition=2",
            "--select",
            "all",
            "--sensors",
            "s01,s02",
            "--out",
            "m.json",
        ],
        &dir,
    );
    let p = stamped(&dir.join("m.json"), &dir.join("th.csv"), "fit thermal");
    assert_eq!(
        (p["holdout"].as_str(), p["target"].as_str()),
        (Some("condition=2"), Some("error_um"))
    );
    // The stamped file still reads as a thermal model.
    axcomp_thermal::model_file::ThermalModelFile::load(&dir.join("m.json")).unwrap();
    // force (power law), with --rename recorded.
    force_csv(&dir.join("f.csv"));
    ok(
        &[
            "fit", "force", "--data", "f.csv", "--rename", "Fc_N=F_N", "--out", "law.json",
        ],
        &dir,
    );
    let p = stamped(&dir.join("law.json"), &dir.join("f.csv"), "fit force");
    assert_eq!(p["rename"][0], "Fc_N=F_N");
    // probe calibration.
    ok(
        &["sim-probe", "--plan", "probe-cal", "--out", "touches.csv"],
        &dir,
    );
    ok(
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
        &dir,
    );
    stamped(&dir.join("cal.json"), &dir.join("touches.csv"), "fit probe");
    // geometry.
    ok(
        &[
            "plan",
            "geometry",
            "--stroke",
            "800,600,500",
            "--lines",
            "20",
            "--sigma-um",
            "0.5",
            "--simulate",
            "lines.csv",
        ],
        &dir,
    );
    ok(
        &[
            "fit",
            "geometry",
            "--data",
            "lines.csv",
            "--out",
            "geo.json",
        ],
        &dir,
    );
    stamped(
        &dir.join("geo.json"),
        &dir.join("lines.csv"),
        "fit geometry",
    );
    // rtest (as in rtest_cli.rs: AC trunnion twin, seed 3).
    let m = FiveAxis::new(MachineKind::AcTrunnion, 0.0);
    let twin = FiveAxisTwin::random(m, 3);
    let paths = standard_paths(&m, [150.0, 0.0, 100.0], -60.0, 72, &[0.0, -60.0], 36, None);
    std::fs::write(
        dir.join("rtest.csv"),
        twin.measure(&paths, 3).to_csv_string(),
    )
    .unwrap();
    ok(
        &["fit", "rtest", "--data", "rtest.csv", "--out", "rt.json"],
        &dir,
    );
    stamped(&dir.join("rt.json"), &dir.join("rtest.csv"), "fit rtest");
    // predict still reads every stamped model.
    ok(
        &[
            "predict",
            "--model",
            "rt.json",
            "--data",
            "rtest.csv",
            "--out",
            "p.csv",
        ],
        &dir,
    );
    ok(
        &[
            "predict", "--model", "m.json", "--data", "th.csv", "--out", "p2.csv",
        ],
        &dir,
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

fn inspect(dir: &Path, img: &str) -> String {
    let o = axcomp_in(&["image", "inspect", img], dir);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn images_carry_provenance_and_names_and_inspect_shows_the_wiring() {
    let dir = scratch("image");
    positioning_csv(&dir.join("pos.csv"));
    ok(
        &["fit", "positioning", "--data", "pos.csv", "--out", "t.json"],
        &dir,
    );
    let d = generate(&SynthConfig {
        seed: 5,
        ..SynthConfig::default()
    });
    d.write_csv(&dir.join("th.csv")).unwrap();
    ok(
        &[
            "fit",
            "thermal",
            "--data",
            "th.csv",
            "--target",
            "error_um",
            "--select",
            "all",
            "--sensors",
            "s01,s02",
            "--sensor-period-ms",
            "100",
            "--out",
            "m.json",
        ],
        &dir,
    );
    let build = |extra: &[&str], out: &str| {
        let mut a = vec![
            "image",
            "build",
            "--table",
            "t.json",
            "--thermal",
            "m.json",
            "--axis-id",
            "1",
            "--um-per-count",
            "0.1",
            "--out",
            out,
        ];
        a.extend_from_slice(extra);
        ok(&a, &dir);
    };
    // The model's own sensor names: the board (rtd0, rtd1) has neither, so inspect says it is refused.
    build(&[], "own.img");
    let text = inspect(&dir, "own.img");
    let (ts, ms, ds) = (
        sha(&dir.join("t.json")),
        sha(&dir.join("m.json")),
        sha(&dir.join("th.csv")),
    );
    assert!(
        text.contains(&format!(
            "positioning table sha256 {ts}; data sha256 {}",
            sha(&dir.join("pos.csv"))
        )) && text.contains(&format!("thermal model sha256 {ms}; data sha256 {ds}")),
        "{text}"
    );
    assert!(
        text.contains(concat!("by axcomp ", env!("CARGO_PKG_VERSION"))),
        "{text}"
    );
    assert!(
        text.contains("REFUSED by this board") && text.contains("sensor 0 s01 -> no board input"),
        "{text}"
    );
    // Named after the board's inputs (crossed): every sensor wired, by name.
    build(
        &["--sensor-input", "s01=rtd1", "--sensor-input", "s02=rtd0"],
        "wired.img",
    );
    let text = inspect(&dir, "wired.img");
    assert!(
        text.contains("every sensor has its input")
            && text.contains("sensor 0 rtd1 -> board input 1 rtd1 (°C)")
            && text.contains("sensor 1 rtd0 -> board input 0 rtd0 (°C)"),
        "{text}"
    );
    // A group of that axis: the records re-labelled with the axis, the names carried over.
    ok(
        &["image", "group", "--axis", "X=wired.img", "--out", "g.img"],
        &dir,
    );
    let text = inspect(&dir, "g.img");
    assert!(
        text.contains(&format!("axis X: positioning table sha256 {ts}"))
            && text.contains(&format!("axis X: thermal model sha256 {ms}"))
            && text.contains("sensor 1 name: rtd0")
            && text.contains("every sensor has its input"),
        "{text}"
    );
    // A warm-up input (a drift model as `fit positioning --drift-model` writes it): refused on
    // the STM32G474 board, accepted on a board that declares a `warmup` input.
    std::fs::write(
        dir.join("drift.json"),
        r#"{"format":"axcomp-thermal-model/1","target":"deviation_um","sensor_period_ms":100,"b0_um":4.43,
           "sensors":[{"name":"warmup","reference_degc":0.0,"tau_s":1960.0,"coef_um_per_k":-10.3,
           "min_degc":-0.5,"max_degc":1.5,"max_rate_degc_per_s":1000000.0,"stale_timeout_ms":10000}],
           "forces":[],"raw_rms_um":32.97,"holdout_rms_um":2.54}"#,
    )
    .unwrap();
    ok(
        &[
            "image",
            "build",
            "--thermal",
            "drift.json",
            "--axis-id",
            "1",
            "--um-per-count",
            "0.1",
            "--out",
            "drift.img",
        ],
        &dir,
    );
    let text = inspect(&dir, "drift.img");
    assert!(
        text.contains("sensor 0 warmup -> no board input")
            && text.contains("REFUSED by this board")
            && text.contains("thermal model sha256")
            && text.contains("data sha256 not recorded"),
        "{text}"
    );
    let o = axcomp_in(
        &[
            "image",
            "inspect",
            "drift.img",
            "--board-inputs",
            "rtd0:degC,warmup:warmup",
        ],
        &dir,
    );
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("sensor 0 warmup -> board input 1 warmup (warm-up state (0..1))"),
        "{text}"
    );
    // A model sensor name that is not in the model is an error naming it; nothing written.
    let o = axcomp_in(
        &[
            "image",
            "build",
            "--thermal",
            "drift.json",
            "--axis-id",
            "1",
            "--um-per-count",
            "0.1",
            "--sensor-input",
            "motor=rtd0",
            "--out",
            "x.img",
        ],
        &dir,
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("`motor` is not a sensor"));
    assert!(!dir.join("x.img").exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
