//! The image pipeline from fits to a group image without traps: a table spans
//! exactly its measured stroke (so `image group --geometry` takes it), an axis without correction
//! (`image build --identity`) gets zero correction from the firmware library, `image build` and
//! `image inspect` report what the board would refuse (its own checks), `fit thermal` warns of a
//! model the firmware cannot take, and `inspect` names a schema-1 image's axis by its id.

mod common;

use std::path::Path;

use axcomp_core::group::{GroupEngine, GroupInput, GroupOutput, MAX_AXES};
use common::{axcomp_in, ok, scratch};

fn run_ok(args: &[&str], dir: &Path) -> String {
    ok(&axcomp_in(args, dir))
}

/// `sim --plan iso230 --end-mm END` → `fit positioning` → `image build --um-per-count 0.1`, axis id `id`.
fn axis_image(dir: &Path, name: &str, end_mm: &str, id: &str) -> String {
    let (csv, table, image) = (
        format!("{name}.csv"),
        format!("{name}.json"),
        format!("{name}.bin"),
    );
    run_ok(
        &[
            "sim", "--plan", "iso230", "--end-mm", end_mm, "--seed", id, "--out", &csv,
        ],
        dir,
    );
    run_ok(
        &["fit", "positioning", "--data", &csv, "--out", &table],
        dir,
    );
    run_ok(
        &[
            "image",
            "build",
            "--table",
            &table,
            "--axis-id",
            id,
            "--um-per-count",
            "0.1",
            "--out",
            &image,
        ],
        dir,
    );
    image
}

/// The 800 × 600 × 500 mm machine: each axis's table spans 0 … its stroke exactly in
/// counts (not 0 … 802.0194 mm for X), and the group with the geometry model fitted on that
/// volume builds; with Y as an identity axis too.
#[test]
fn the_800_600_500_chain_builds_a_group_image_with_geometry() {
    let dir = scratch("chain800");
    let x = axis_image(&dir, "x", "800", "1");
    let y = axis_image(&dir, "y", "600", "2");
    let z = axis_image(&dir, "z", "500", "3");
    for (image, counts) in [(&x, 8_000_000), (&y, 6_000_000), (&z, 5_000_000)] {
        let text = run_ok(&["image", "inspect", image], &dir);
        // Exact: the stroke is whole mm, 0.1 µm per count.
        assert!(
            text.contains(&format!(" 0 .. {counts} counts")),
            "{image} must span exactly 0 .. {counts} counts:\n{text}"
        );
        assert!(text.contains("board STM32G474: loads this image"), "{text}");
    }
    run_ok(
        &[
            "plan",
            "geometry",
            "--stroke",
            "800,600,500",
            "--simulate",
            "lines.csv",
        ],
        &dir,
    );
    run_ok(
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
    let axes = [format!("X={x}"), format!("Y={y}"), format!("Z={z}")];
    let out = run_ok(
        &[
            "image",
            "group",
            "--axis",
            &axes[0],
            "--axis",
            &axes[1],
            "--axis",
            &axes[2],
            "--geometry",
            "geo.json",
            "--exclude-geometric",
            "EXX,EYY,EZZ",
            "--out",
            "g.bin",
        ],
        &dir,
    );
    assert!(out.contains("geometric model: yes"), "{out}");
    let text = run_ok(&["image", "inspect", "g.bin"], &dir);
    for stroke in ["0 .. 8000000", "0 .. 6000000", "0 .. 5000000"] {
        assert!(text.contains(&format!("stroke {stroke} counts")), "{text}");
    }
    // Y without a table of its own: the geometry model's EYY stays in and corrects it.
    run_ok(
        &[
            "image",
            "build",
            "--identity",
            "--axis-id",
            "2",
            "--um-per-count",
            "0.1",
            "--out",
            "yid.bin",
        ],
        &dir,
    );
    run_ok(
        &[
            "image",
            "group",
            "--axis",
            &axes[0],
            "--axis",
            "Y=yid.bin",
            "--axis",
            &axes[2],
            "--geometry",
            "geo.json",
            "--exclude-geometric",
            "EXX,EZZ",
            "--out",
            "g2.bin",
        ],
        &dir,
    );
}

/// An identity axis in a group: the firmware library (`GroupEngine`, loaded from the image bytes)
/// applies exactly zero to it over its whole stroke, while the table axis beside it is corrected.
#[test]
fn an_identity_axis_gets_zero_correction_from_the_firmware_library() {
    let dir = scratch("identity");
    let x = axis_image(&dir, "x", "200", "1");
    let out = run_ok(
        &[
            "image",
            "build",
            "--identity",
            "--axis-id",
            "2",
            "--um-per-count",
            "0.1",
            "--out",
            "yid.bin",
        ],
        &dir,
    );
    assert!(
        out.contains("no table") && out.contains("identity"),
        "{out}"
    );
    run_ok(
        &[
            "image",
            "group",
            "--axis",
            &format!("X={x}"),
            "--axis",
            "Y=yid.bin",
            "--out",
            "g.bin",
        ],
        &dir,
    );
    let bytes = std::fs::read(dir.join("g.bin")).unwrap();
    let mut engine: Box<GroupEngine<4096>> = Box::new(GroupEngine::new());
    engine.load_image(&bytes).expect("the group loads");
    engine.reset(&[0; MAX_AXES]);
    let mut input = GroupInput::ZERO;
    let mut out = GroupOutput::ZERO;
    let (mut x_max, mut y_max) = (0.0f32, 0.0f32);
    // Both axes from 0 to 200 mm (2 000 000 counts) in 1 000-count steps (16-bit counters: well
    // within half a wrap per cycle), the scale following the command.
    for k in 0..=2000i64 {
        for a in 0..2 {
            input.axes[a].command_counts = k * 1000;
            input.axes[a].scale_raw = (k * 1000) as u32;
        }
        engine.cycle(&input, &mut out);
        x_max = x_max.max(out.axes[0].correction_um.abs());
        y_max = y_max.max(out.axes[1].correction_um.abs());
        assert_eq!(out.axes[1].correction_counts, 0, "Y at {} counts", k * 1000);
    }
    // Reference: zero exactly (no table, no thermo-force term); the table axis is corrected (the
    // twin's demo axis has deviations of tens of µm).
    assert_eq!(y_max, 0.0);
    assert!(x_max > 1.0, "X's table must correct: max {x_max} µm");
}

/// `image build` warns (and `inspect` prints) every refusal of the board, from the board's own
/// checks: an axis id it does not wire, more sensors than it has, a sensor named after no input;
/// `--board-inputs` naming the sensors lifts the last.
#[test]
fn image_build_and_inspect_report_every_board_refusal() {
    let dir = scratch("refusals");
    run_ok(&["sim", "--plan", "thermal", "--out", "t.csv"], &dir);
    run_ok(
        &[
            "fit",
            "thermal",
            "--data",
            "t.csv",
            "--target",
            "deviation_um",
            "--out",
            "t.json",
        ],
        &dir,
    );
    let o = axcomp_in(
        &[
            "image",
            "build",
            "--thermal",
            "t.json",
            "--axis-id",
            "4",
            "--um-per-count",
            "0.1",
            "--out",
            "t.bin",
        ],
        &dir,
    );
    ok(&o);
    let err = String::from_utf8_lossy(&o.stderr);
    for needle in [
        "image for axis 4, which this board does not wire",
        "temperature sensors, the board wires 2",
        "is not an input of this board",
    ] {
        assert!(err.contains(needle), "must warn `{needle}`:\n{err}");
    }
    let text = run_ok(&["image", "inspect", "t.bin"], &dir);
    assert!(
        text.contains("board STM32G474: REFUSES this image (3 reasons"),
        "{text}"
    );
    // A schema-1 image names no axis: its id, not "axis X".
    assert!(
        text.contains("axis id 4 sensors") && !text.contains("axis X"),
        "{text}"
    );
    // On a board whose inputs are the model's sensors, for a wired axis id: no refusal, no warning.
    let o = axcomp_in(
        &[
            "image",
            "build",
            "--thermal",
            "t.json",
            "--axis-id",
            "1",
            "--um-per-count",
            "0.1",
            "--board-inputs",
            "ambient:degC,motor:degC,scale:degC",
            "--out",
            "t1.bin",
        ],
        &dir,
    );
    ok(&o);
    assert!(
        o.stderr.is_empty(),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let text = run_ok(
        &[
            "image",
            "inspect",
            "t1.bin",
            "--board-inputs",
            "ambient:degC,motor:degC,scale:degC",
        ],
        &dir,
    );
    assert!(text.contains("board STM32G474: loads this image"), "{text}");
}

/// `fit thermal` on an absolute target (a position of 250 mm, not a deviation) writes the model but
/// warns that its b0 cannot be flashed; `image build` refuses it with the same reason.
#[test]
fn fit_thermal_warns_of_a_model_the_firmware_cannot_take() {
    let dir = scratch("b0");
    let mut csv = String::from("time_s,rtd0_degC,rtd1_degC,abs_um\n");
    for i in 0..300 {
        let t = i as f64 * 60.0;
        let a = 20.0 + 5.0 * (1.0 - (-t / 3000.0).exp());
        let b = 20.0 + 3.0 * (1.0 - (-t / 6000.0).exp()) + 0.3 * (i as f64 / 7.0).sin();
        let d = 250_000.0 + 2.0 * (a - 20.0) + 1.5 * (b - 20.0) + 0.05 * (i as f64 * 1.3).sin();
        csv.push_str(&format!("{t},{a:.4},{b:.4},{d:.4}\n"));
    }
    std::fs::write(dir.join("abs.csv"), csv).unwrap();
    let o = axcomp_in(
        &[
            "fit", "thermal", "--data", "abs.csv", "--target", "abs_um", "--out", "abs.json",
        ],
        &dir,
    );
    ok(&o);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("warning") && err.contains("b0") && err.contains("--zero-at-start"),
        "{err}"
    );
    let o = axcomp_in(
        &[
            "image",
            "build",
            "--thermal",
            "abs.json",
            "--axis-id",
            "1",
            "--um-per-count",
            "0.1",
            "--out",
            "abs.bin",
        ],
        &dir,
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("b0"));
    assert!(!dir.join("abs.bin").exists());
}
