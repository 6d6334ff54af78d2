//! Unit tests: one per rule of the module docs, then the real files of `../shared` (skipped when absent).

use super::*;

fn none() -> LoadOptions {
    LoadOptions::default()
}

fn opts(w: &[&str], r: &[&str], s: &[&str]) -> LoadOptions {
    let v = |x: &[&str]| x.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    LoadOptions::from_args(&v(w), &v(r), &v(s)).unwrap()
}

const ISO: &str = "\
# campaign: demo
# axis X
target_mm,cycle,approach_direction,deviation_um,note
0,1,positive,1.5,\"a, b\"
0,1,negative,-0.5,x
10,2,+,2.0,
10,2,-,abc,y
";

#[test]
fn loads_header_after_comments_and_keeps_line_numbers() {
    let ds = Dataset::from_csv_str("iso.csv", ISO, &none()).unwrap();
    assert_eq!(ds.n_rows(), 4);
    assert_eq!(
        ds.column_names(),
        vec![
            "target_mm",
            "cycle",
            "approach_direction",
            "deviation_um",
            "note"
        ]
    );
    assert_eq!(ds.line_of_row(0), 4);
    assert_eq!(ds.text("note").unwrap(), vec!["a, b", "x", "", "y"]);
    assert_eq!(ds.numeric("target_mm").unwrap(), &[0.0, 0.0, 10.0, 10.0]);
}

#[test]
fn non_numeric_cell_names_file_line_column() {
    let ds = Dataset::from_csv_str("iso.csv", ISO, &none()).unwrap();
    let e = ds.numeric("deviation_um").unwrap_err().to_string();
    assert_eq!(
        e,
        "iso.csv:7:4 (column `deviation_um`): `abc` is not a number"
    );
}

#[test]
fn empty_cell_is_not_a_number_but_numeric_or_nan_reads_it() {
    let ds = Dataset::from_csv_str("f.csv", "a,b\n1,2\n,3\n", &none()).unwrap();
    let e = ds.numeric("a").unwrap_err().to_string();
    assert_eq!(
        e,
        "f.csv:3:1 (column `a`): empty cell where a number is required"
    );
    let v = ds.numeric_or_nan("a").unwrap();
    assert_eq!(v[0], 1.0);
    assert!(v[1].is_nan());
}

#[test]
fn explicit_nan_is_a_number() {
    let ds = Dataset::from_csv_str("f.csv", "a\n1\nNaN\n", &none()).unwrap();
    assert!(ds.numeric("a").unwrap()[1].is_nan());
}

#[test]
fn aliases_cycle_and_approach_direction() {
    let ds = Dataset::from_csv_str("iso.csv", ISO, &none()).unwrap();
    assert!(ds.has("run") && ds.has("direction") && ds.has("cycle"));
    assert_eq!(ds.run().unwrap(), vec!["1", "1", "2", "2"]);
    assert_eq!(ds.direction().unwrap().unwrap(), vec![1, -1, 1, -1]);
}

#[test]
fn direction_forms_and_error() {
    let ds = Dataset::from_csv_str(
        "d.csv",
        "direction\n+\n-\n1\n-1\nPositive\nnegative\n",
        &none(),
    )
    .unwrap();
    assert_eq!(ds.direction().unwrap().unwrap(), vec![1, -1, 1, -1, 1, -1]);
    let ds = Dataset::from_csv_str("d.csv", "x,direction\n0,+\n0,up\n", &none()).unwrap();
    let e = ds.direction().unwrap_err().to_string();
    assert!(
        e.starts_with("d.csv:3:2 (column `direction`): `up` is not a direction"),
        "{e}"
    );
    let ds = Dataset::from_csv_str("d.csv", "x\n0\n", &none()).unwrap();
    assert_eq!(ds.direction().unwrap(), None);
}

#[test]
fn duplicate_header_is_an_error_with_position() {
    let e = Dataset::from_csv_str("d.csv", "# c\na,b,a\n1,2,3\n", &none())
        .unwrap_err()
        .to_string();
    assert_eq!(e, "d.csv:2:3: duplicate column `a` (first at column 1)");
}

#[test]
fn ragged_rows_are_errors_with_position() {
    let e = Dataset::from_csv_str("r.csv", "a,b,c\n1,2,3\n4,5\n", &none())
        .unwrap_err()
        .to_string();
    assert_eq!(e, "r.csv:3:3: row has 2 fields but the header has 3");
    let e = Dataset::from_csv_str("r.csv", "a,b\n1,2,3\n", &none())
        .unwrap_err()
        .to_string();
    assert_eq!(e, "r.csv:2:3: row has 3 fields but the header has 2");
}

#[test]
fn unterminated_quote_is_an_error() {
    let e = Dataset::from_csv_str("q.csv", "a,b\n1,\"x\n", &none())
        .unwrap_err()
        .to_string();
    assert_eq!(e, "q.csv:2:2: quoted field is never closed");
}

#[test]
fn empty_and_header_only_files_are_errors() {
    assert!(matches!(
        Dataset::from_csv_str("e.csv", "# only\n\n", &none()),
        Err(DataError::NoHeader { .. })
    ));
    assert!(matches!(
        Dataset::from_csv_str("e.csv", "a,b\n", &none()),
        Err(DataError::NoRows { .. })
    ));
}

#[test]
fn missing_column_lists_the_available_ones() {
    let ds = Dataset::from_csv_str("m.csv", "a,b\n1,2\n", &none()).unwrap();
    let e = ds.numeric("target_mm").unwrap_err().to_string();
    assert_eq!(e, "m.csv: missing column `target_mm` (columns: a, b)");
}

#[test]
fn rename_then_scale_then_where() {
    // Rename mcu_pos_z → z_um, scale microsteps by 2.5 µm, keep sample 1 (by number: `1.0` matches `1`).
    let text = "sample,mcu_pos_z,frame_t\n0,-4,20\n1,-2,21\n1,-3,22\n";
    let o = opts(
        &["sample=1.0"],
        &["mcu_pos_z=z_um", "frame_t=frame_degC"],
        &["z_um=2.5"],
    );
    let ds = Dataset::from_csv_str("v.csv", text, &o).unwrap();
    assert_eq!(ds.n_rows(), 2);
    assert_eq!(ds.numeric("z_um").unwrap(), &[-5.0, -7.5]);
    assert_eq!(ds.sensors(), vec!["frame"]);
    assert_eq!(ds.error_channels(), vec!["z_um"]);
    assert_eq!(ds.line_of_row(0), 3);
}

#[test]
fn rename_can_resolve_a_duplicate_and_unknown_names_are_errors() {
    assert!(Dataset::from_csv_str("d.csv", "a,a\n1,2\n", &opts(&[], &["a=b"], &[])).is_ok());
    let e = Dataset::from_csv_str("d.csv", "a\n1\n", &opts(&[], &["z=b"], &[]))
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "d.csv: missing column `z` (named by --rename) (columns: a)"
    );
    let e = Dataset::from_csv_str("d.csv", "a\n1\n", &opts(&["z=1"], &[], &[]))
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "d.csv: missing column `z` (named by --where) (columns: a)"
    );
}

#[test]
fn scale_of_a_text_column_names_the_cell() {
    let e = Dataset::from_csv_str("s.csv", "a\n1\nx\n", &opts(&[], &[], &["a=2"]))
        .unwrap_err()
        .to_string();
    assert_eq!(e, "s.csv:3:1 (column `a`): `x` is not a number");
}

#[test]
fn where_matching_nothing_is_an_error() {
    let e = Dataset::from_csv_str("w.csv", "a\n1\n", &opts(&["a=2"], &[], &[]))
        .unwrap_err()
        .to_string();
    assert_eq!(e, "w.csv: no data rows match --where a=2");
}

#[test]
fn bad_option_syntax() {
    let e = LoadOptions::from_args(&["nope".into()], &[], &[])
        .unwrap_err()
        .to_string();
    assert_eq!(e, "--where `nope`: expected NAME=VALUE");
    let e = LoadOptions::from_args(&[], &[], &["a=x".into()])
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "--scale `a=x`: `x` is not a finite number (a non-zero factor below 1e12 expected)"
    );
    for bad in ["a=1e300", "a=0"] {
        assert!(
            LoadOptions::from_args(&[], &[], &[bad.into()]).is_err(),
            "{bad}"
        );
    }
    // One column scaled (or renamed) twice: the last must not win silently.
    let e = LoadOptions::from_args(&[], &[], &["a=2".into(), "a=3".into()])
        .unwrap_err()
        .to_string();
    assert_eq!(e, "--scale `a=3`: column `a` is named by --scale twice");
    let e = LoadOptions::from_args(&[], &["a=b".into(), "a=c".into()], &[])
        .unwrap_err()
        .to_string();
    assert_eq!(e, "--rename `a=c`: column `a` is named by --rename twice");
}

#[test]
fn time_column_becomes_time_s_from_first_row() {
    let text = "time,z\n2021/06/13-05:42:16,1\n2021-06-13 05:42:20,2\n2021-06-13T05:43:16.5,3\n";
    let ds = Dataset::from_csv_str("t.csv", text, &none()).unwrap();
    assert_eq!(ds.time_s().unwrap(), &[0.0, 4.0, 60.5]);
    assert!(ds.has("time_s"));
    // Relative to the file's first row even when --where drops it.
    let ds = Dataset::from_csv_str("t.csv", text, &opts(&["z=2"], &[], &[])).unwrap();
    assert_eq!(ds.time_s().unwrap(), &[4.0]);
}

#[test]
fn time_s_column_wins_and_bad_timestamps_are_named() {
    let ds =
        Dataset::from_csv_str("t.csv", "time,time_s\n2021-06-13 05:42:16,7\n", &none()).unwrap();
    assert_eq!(ds.time_s().unwrap(), &[7.0]);
    let e = Dataset::from_csv_str("t.csv", "z,time\n1,2021-06-13 05:42:16\n2,later\n", &none())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("t.csv:3:2 (column `time`): `later` is not a timestamp"),
        "{e}"
    );
    // A numeric `time` column is carried along, not converted.
    let ds = Dataset::from_csv_str("t.csv", "time\n1\n2\n", &none()).unwrap();
    assert!(ds.time_s().is_none());
}

#[test]
fn select_rows_and_csv_round_trip() {
    let ds = Dataset::from_csv_str("iso.csv", ISO, &opts(&[], &[], &["target_mm=0.001"])).unwrap();
    let text = ds.to_csv_string();
    let back = Dataset::from_csv_str("back.csv", &text, &none()).unwrap();
    assert_eq!(back.column_names(), ds.column_names());
    for c in ds.column_names() {
        assert_eq!(back.text(c).unwrap(), ds.text(c).unwrap(), "column {c}");
    }
    assert_eq!(back.numeric("target_mm").unwrap(), &[0.0, 0.0, 0.01, 0.01]);
    let sub = ds.select_rows(&[false, true, true, false]);
    assert_eq!(sub.n_rows(), 2);
    assert_eq!(sub.text("note").unwrap(), vec!["x", ""]);
    assert_eq!(sub.line_of_row(1), 6);
    // The non-numeric cell was dropped, so the column is numeric in the subset.
    assert_eq!(sub.numeric("deviation_um").unwrap(), &[-0.5, 2.0]);
}

#[test]
fn in_memory_columns() {
    let mut ds =
        Dataset::from_numeric_columns("twin", vec![("target_mm".into(), vec![0.0, 1.0])]).unwrap();
    ds.add_text_column("direction", vec!["+".into(), "-".into()])
        .unwrap();
    assert_eq!(ds.direction().unwrap().unwrap(), vec![1, -1]);
    assert!(ds.add_numeric_column("x_um", vec![1.0]).is_err());
    let back = Dataset::from_csv_str("b", &ds.to_csv_string(), &none()).unwrap();
    assert_eq!(back.numeric("target_mm").unwrap(), &[0.0, 1.0]);
}

/// `--holdout line=FD1,X2` without a line FD1 held out X2 alone, and the JSON said FD1 was held out too.
#[test]
fn a_holdout_value_that_matches_no_row_is_an_error_naming_it() {
    let ds = Dataset::from_csv_str("iso.csv", ISO, &none()).unwrap();
    let e = HoldoutSpec::parse("run=2,7")
        .unwrap()
        .mask(&ds)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("7 is in no row of iso.csv") && e.contains("column `run` has 1, 2"),
        "{e}"
    );
    // Numerically equal spellings still match (`2.0` is run 2).
    let m = HoldoutSpec::parse("run=2.0").unwrap().mask(&ds).unwrap();
    assert_eq!(m, vec![false, false, true, true]);
}

#[test]
fn holdout_specs() {
    let ds = Dataset::from_csv_str("iso.csv", ISO, &none()).unwrap();
    let m = HoldoutSpec::parse("run=2").unwrap().mask(&ds).unwrap();
    assert_eq!(m, vec![false, false, true, true]);
    let m = HoldoutSpec::parse("target_mm>=5")
        .unwrap()
        .mask(&ds)
        .unwrap();
    assert_eq!(m, vec![false, false, true, true]);
    let m = HoldoutSpec::parse("target_mm<5")
        .unwrap()
        .mask(&ds)
        .unwrap();
    assert_eq!(m, vec![true, true, false, false]);
    let m = HoldoutSpec::parse("target_mm<=10").unwrap();
    assert!(
        m.mask(&ds)
            .unwrap_err()
            .to_string()
            .contains("selects every row")
    );
    let m = HoldoutSpec::parse("target_mm>10").unwrap();
    assert!(
        m.mask(&ds)
            .unwrap_err()
            .to_string()
            .contains("selects no rows")
    );
    let m = HoldoutSpec::parse("note=x,y").unwrap().mask(&ds).unwrap();
    assert_eq!(m, vec![false, true, false, true]);
    let e = HoldoutSpec::parse("deviation_um>0")
        .unwrap()
        .mask(&ds)
        .unwrap_err()
        .to_string();
    assert_eq!(
        e,
        "iso.csv:7:4 (column `deviation_um`): `abc` is not a number"
    );
    assert!(HoldoutSpec::parse("run").is_err());
    assert!(HoldoutSpec::parse("=3").is_err());
    assert!(HoldoutSpec::parse("t>=x").is_err());
    assert!(HoldoutSpec::parse("t=1,,2").is_err());
    let e = HoldoutSpec::parse("zz=1")
        .unwrap()
        .mask(&ds)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("missing column `zz` (named by --holdout)"),
        "{e}"
    );
}

#[test]
fn split_from_args() {
    assert_eq!(Split::from_args(None, None).unwrap(), None);
    assert_eq!(
        Split::from_args(None, Some("run")).unwrap(),
        Some(Split::Cv("run".into()))
    );
    assert!(matches!(
        Split::from_args(Some("run=1"), None).unwrap(),
        Some(Split::Holdout(_))
    ));
    assert!(Split::from_args(Some("run=1"), Some("run")).is_err());
}

#[test]
fn groups_by_first_appearance() {
    let ds = Dataset::from_csv_str("g.csv", "run\n2\n1\n2.0\n3\n1\n", &none()).unwrap();
    let (ids, labels) = groups(&ds, "run").unwrap();
    assert_eq!(ids, vec![0, 1, 0, 2, 1]);
    assert_eq!(labels, vec!["2", "1", "3"]);
}

// ---- real files in ../shared (skipped when absent, failure under CI) ----

fn shared() -> Option<std::path::PathBuf> {
    shared_dir_for_test(Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../..")))
}

#[test]
fn real_ess_iso230_long_file() {
    let Some(sh) = shared() else { return };
    let path = sh.join("data/real/ess-linear-axes-iso230/tidy/iso230_2_runs_long.csv");
    let ds = Dataset::load(&path, &none()).unwrap();
    // PROVENANCE.md: 490 rows; 9 tests.
    assert_eq!(ds.n_rows(), 490);
    assert!(
        ds.text("system").unwrap()[0].contains("(TDU), B02"),
        "quoted field with commas"
    );
    let b02 = Dataset::load(
        &path,
        &opts(&["test_id=ESS_TDU_B02_X_2022-04-06"], &[], &[]),
    )
    .unwrap();
    // 9 targets × 5 cycles × 2 directions.
    assert_eq!(b02.n_rows(), 90);
    let dir = b02.direction().unwrap().unwrap();
    assert_eq!(dir.iter().filter(|d| **d == 1).count(), 45);
    let (_, runs) = groups(&b02, "run").unwrap();
    assert_eq!(runs, vec!["1", "2", "3", "4", "5"]);
    let dev = b02.numeric("deviation_um").unwrap();
    // First row of the file: -49.226 µm.
    assert_eq!(dev[0], -49.226);
    assert_eq!(b02.numeric("target_mm").unwrap()[0], -20.0);
    let back = Dataset::from_csv_str("rt", &b02.to_csv_string(), &none()).unwrap();
    assert_eq!(back.text("system").unwrap(), b02.text("system").unwrap());
}

#[test]
fn real_voron_thermal_files() {
    let Some(sh) = shared() else { return };
    let dir = sh.join("data/real/thermal-voron-frame-z");
    // (file, data rows per PROVENANCE.md)
    let files = [
        ("frame_temp_v_pos_2021-06-05_13-24-32.csv", 570),
        (
            "frame_exp_quant_v3_2021-06-12_12-54-36-mvieleers_V2.1253.csv",
            1083,
        ),
        ("frame_exp_quant_v3_2021-06-13_05-41-53.csv", 1203),
        (
            "expansion_quant_whoppingpochard_2514_2021-06-13_20-04-43.csv",
            990,
        ),
    ];
    for (name, rows) in files {
        let o = opts(
            &[],
            &["frame_t=frame_degC", "mcu_pos_z=z_um"],
            &["z_um=2.5"],
        );
        let ds = Dataset::load(&dir.join(name), &o).unwrap();
        assert_eq!(ds.n_rows(), rows, "{name}");
        let t = ds.time_s().expect("time → time_s");
        assert_eq!(t[0], 0.0);
        assert!(t.windows(2).all(|w| w[1] >= w[0]), "{name}: time increases");
        // Durations 3.2 h … 6.7 h per PROVENANCE.md.
        let hours = t[t.len() - 1] / 3600.0;
        assert!((3.0..7.0).contains(&hours), "{name}: {hours} h");
        assert_eq!(ds.sensors(), vec!["frame"]);
        assert!(ds.numeric("z_um").unwrap().iter().all(|v| v.is_finite()));
    }
    // 2021-06-13 05:42:16 → 05:42:20 in the first rows of the v3 file: 4 s.
    let ds = Dataset::load(&dir.join(files[2].0), &none()).unwrap();
    assert_eq!(&ds.time_s().unwrap()[..2], &[0.0, 4.0]);
}

#[test]
fn real_bifrost_files_keep_out_of_range_cells_as_text() {
    let Some(sh) = shared() else { return };
    let path = sh.join("data/real/ess-linear-axes-iso230/tidy/bifrost_slits_accuracy_12pos.csv");
    let ds = Dataset::load(&path, &none()).unwrap();
    assert_eq!(ds.n_rows(), 144);
    let e = ds.numeric("ild2300_mm").unwrap_err().to_string();
    assert!(e.ends_with("bifrost_slits_accuracy_12pos.csv:2:8 (column `ild2300_mm`): `Out of range` is not a number"), "{e}");
    assert!(ds.numeric_or_nan("ild2300_mm").unwrap()[0].is_nan());
    let path = sh.join(
        "data/real/ess-linear-axes-iso230/tidy/bifrost_slit11360_iso230_sequences_2021-10.csv",
    );
    let ds = Dataset::load(&path, &none()).unwrap();
    assert_eq!(ds.n_rows(), 325);
    assert!(ds.numeric("deviation_ref_minus_target_um").is_ok());
}

/// The streaming file reader and the in-memory parser agree cell for cell and line for line on a file with
/// a byte-order mark, comments, CRLF line ends, blank lines, a quoted field spanning lines and doubled
/// quotes; a `--where` applied while reading keeps the same rows (and `time_s` stays relative to the
/// file's first row) as one applied afterwards.
#[test]
fn streaming_load_equals_parsing_the_whole_text() {
    let text = "\u{feff}# meta, with comma\r\n\r\ntime,test_id,x,note\r\n2021-06-13 05:42:16,A,1,\"two\r\nlines\"\r\n\r\n2021-06-13 05:42:18,B,2,\"say \"\"hi\"\"\"\r\n2021-06-13 05:42:21,A,3,plain\r\n";
    let p = std::env::temp_dir().join(format!("axcomp-stream-{}.csv", std::process::id()));
    std::fs::write(&p, text).unwrap();
    for opts in [
        LoadOptions::default(),
        LoadOptions::from_args(&["test_id=A".into()], &[], &[]).unwrap(),
        LoadOptions::from_args(&["x=2".into()], &[], &["x=1".into()]).unwrap(),
    ] {
        let a = Dataset::load(&p, &opts).unwrap();
        let b = Dataset::from_csv_str(&p.display().to_string(), text, &opts).unwrap();
        assert_eq!(a.column_names(), b.column_names());
        assert_eq!(a.n_rows(), b.n_rows());
        for r in 0..a.n_rows() {
            assert_eq!(a.line_of_row(r), b.line_of_row(r));
        }
        for c in a.column_names() {
            assert_eq!(a.text(c).unwrap(), b.text(c).unwrap(), "{c}");
        }
    }
    let a = Dataset::load(
        &p,
        &LoadOptions::from_args(&["test_id=A".into()], &[], &[]).unwrap(),
    )
    .unwrap();
    // Rows on lines 4 and 8; time_s from the file's first row (05:42:16): 0 and 5 s.
    assert_eq!((a.line_of_row(0), a.line_of_row(1)), (4, 8));
    assert_eq!(a.numeric("time_s").unwrap(), &[0.0, 5.0]);
    assert_eq!(a.text("note").unwrap(), vec!["two\r\nlines", "plain"]);
    std::fs::remove_file(&p).unwrap();
}

// ---- format details of other tools' files (robustness audit) ----

#[test]
fn either_alias_name_finds_the_column() {
    // `--cv cycle` / `--holdout cycle=2` on a file with `run`, `approach_direction` on one with `direction`.
    let ds =
        Dataset::from_csv_str("r.csv", "target_mm,run,direction\n0,1,+\n0,2,-\n", &none()).unwrap();
    assert!(ds.has("cycle") && ds.has("approach_direction"));
    assert_eq!(ds.text("cycle").unwrap(), vec!["1", "2"]);
    let (ids, labels) = groups(&ds, "cycle").unwrap();
    assert_eq!((ids, labels), (vec![0, 1], vec!["1".into(), "2".into()]));
    let h = HoldoutSpec::parse("cycle=2").unwrap();
    assert_eq!(h.mask(&ds).unwrap(), vec![false, true]);
    let kept = Dataset::from_csv_str(
        "r.csv",
        "target_mm,run\n0,1\n0,2\n",
        &opts(&["cycle=2"], &[], &[]),
    )
    .unwrap();
    assert_eq!(kept.n_rows(), 1);
    // A column of the asked name wins over the alias.
    let both = Dataset::from_csv_str("b.csv", "run,cycle\n1,7\n", &none()).unwrap();
    assert_eq!(both.text("cycle").unwrap(), vec!["7"]);
    assert_eq!(both.text("run").unwrap(), vec!["1"]);
}

#[test]
fn a_separator_at_the_end_of_every_line_adds_no_column() {
    let with = Dataset::from_csv_str("t.csv", "target_mm,deviation_um,\n0,1.5,\n10,2,\n", &none())
        .unwrap();
    assert_eq!(with.column_names(), vec!["target_mm", "deviation_um"]);
    assert_eq!(with.numeric("deviation_um").unwrap(), &[1.5, 2.0]);
    // Only in the rows, or only in the header: the same.
    let rows_only =
        Dataset::from_csv_str("t.csv", "target_mm,deviation_um\n0,1.5,\n10,2, \n", &none())
            .unwrap();
    assert_eq!(rows_only.numeric("deviation_um").unwrap(), &[1.5, 2.0]);
    let header_only =
        Dataset::from_csv_str("t.csv", "target_mm,deviation_um,\n0,1.5\n", &none()).unwrap();
    assert_eq!(
        header_only.column_names(),
        vec!["target_mm", "deviation_um"]
    );
    // A value past the header's last column is still a ragged row, and an empty name inside the header
    // still an error.
    let e = Dataset::from_csv_str("t.csv", "a,b\n1,2,3\n", &none())
        .unwrap_err()
        .to_string();
    assert_eq!(e, "t.csv:2:3: row has 3 fields but the header has 2");
    let e = Dataset::from_csv_str("t.csv", "a,,b\n1,2,3\n", &none())
        .unwrap_err()
        .to_string();
    assert_eq!(e, "t.csv:1:2: empty column name in the header");
}

#[test]
fn semicolon_tab_and_cr_only_files_are_named_as_such() {
    let e = Dataset::from_csv_str("s.csv", "target_mm;deviation_um\n0;1,5\n", &none())
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("s.csv:1: the header is one column `target_mm;deviation_um` holding `;`"),
        "{e}"
    );
    let e = Dataset::from_csv_str("t.csv", "# x\ntarget_mm\tdeviation_um\n0\t1.5\n", &none())
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("t.csv:2: the header is one column"), "{e}");
    assert!(e.contains("tab-separated"), "{e}");
    let e = Dataset::from_csv_str("c.csv", "target_mm,deviation_um\r0,1.5\r10,2\r", &none())
        .unwrap_err()
        .to_string();
    assert!(e.contains("CR alone"), "{e}");
    // A genuine one-column file is fine.
    let one = Dataset::from_csv_str("o.csv", "target_mm\n0\n5\n", &none()).unwrap();
    assert_eq!(one.numeric("target_mm").unwrap(), &[0.0, 5.0]);
}

#[test]
fn excel_separator_line_is_skipped() {
    let ds =
        Dataset::from_csv_str("x.csv", "sep=,\ntarget_mm,deviation_um\n0,1.5\n", &none()).unwrap();
    assert_eq!(ds.column_names(), vec!["target_mm", "deviation_um"]);
    assert_eq!(ds.line_of_row(0), 3);
}

#[test]
fn utf16_file_is_refused_naming_the_encoding() {
    let p = std::env::temp_dir().join(format!("axcomp-utf16-{}.csv", std::process::id()));
    let mut bytes = vec![0xff, 0xfe];
    for u in "target_mm,deviation_um\r\n0,1.5\r\n".encode_utf16() {
        bytes.extend(u.to_le_bytes());
    }
    std::fs::write(&p, bytes).unwrap();
    let e = Dataset::load(&p, &none()).unwrap_err().to_string();
    std::fs::remove_file(&p).unwrap();
    assert!(
        e.contains("UTF-16") && e.contains("save the file as UTF-8"),
        "{e}"
    );
}

/// The contract lets a file spell the approach direction `+`/`-`, `1`/`-1` or `positive`/`negative`; a
/// `--where` or `--holdout` on the direction column takes any spelling of the same direction (comparing the
/// text, `direction=+` would keep none of the `positive` rows). Other columns still compare as
/// numbers, then as text.
#[test]
fn where_and_holdout_on_the_direction_take_any_spelling() {
    // ISO's approach_direction cells: positive, negative, +, -.
    for (want, rows) in [("+", 2), ("positive", 2), ("1", 2), ("-1.0", 2), ("NEG", 2)] {
        let o = opts(&[&format!("direction={want}")], &[], &[]);
        let ds = Dataset::from_csv_str("iso.csv", ISO, &o).unwrap();
        assert_eq!(ds.n_rows(), rows, "direction={want}");
        let signs = ds.direction().unwrap().unwrap();
        let sign = if want.starts_with('-') || want == "NEG" {
            -1
        } else {
            1
        };
        assert!(
            signs.iter().all(|s| *s == sign),
            "direction={want}: {signs:?}"
        );
    }
    let ds = Dataset::from_csv_str("iso.csv", ISO, &none()).unwrap();
    let m = HoldoutSpec::parse("approach_direction=-")
        .unwrap()
        .mask(&ds)
        .unwrap();
    assert_eq!(m, vec![false, true, false, true]);
    // A note column holding `+` is text: it does not match `positive`.
    let text = "note,v\n+,1\npositive,2\n";
    let ds = Dataset::from_csv_str("n.csv", text, &opts(&["note=+"], &[], &[])).unwrap();
    assert_eq!(ds.n_rows(), 1);
}
