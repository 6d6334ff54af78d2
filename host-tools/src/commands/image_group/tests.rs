//! `image group` from per-axis images, then `inspect`.

use super::*;
use axcomp_image::describe_any;

/// `image group` from per-axis images, then `inspect`: the view lists every axis, the sensor
/// names and the rotary model; bad axis specs are clear errors.
#[test]
fn group_image_build_and_inspect() {
    let dir = std::env::temp_dir().join(format!("axcomp-image-group-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let g = axcomp_scenario::group_image(5, false).unwrap();
    let view = group_image::parse(&g).unwrap();
    let mut axis_args = Vec::new();
    for a in view.axes() {
        let p = dir.join(format!("{}.bin", a.axis.name.letter()));
        std::fs::write(&p, a.axis.image).unwrap();
        axis_args.push(if a.axis.name.is_rotary() {
            format!(
                "{}:{}={}",
                a.axis.name.letter(),
                a.axis.counts_per_rev,
                p.display()
            )
        } else {
            format!("{}={}", a.axis.name.letter(), p.display())
        });
    }
    let rot = dir.join("rotary.json");
    std::fs::write(
        &rot,
        r#"{"ex0c_um": 12, "ey0c_um": -7, "ea0c_urad": 25, "eb0c_urad": -15, "ey0a_um": 9,
            "ez0a_um": -20, "eb0a_urad": 18, "ec0a_urad": -10,
            "pivot_counts": [500000, 500000, 500000], "tool_length_um": 100000}"#,
    )
    .unwrap();
    let args = GroupArgs {
        axes: axis_args.clone(),
        sensor_names: vec!["X=spindle,column".into()],
        rotary: Some(rot.clone()),
        pivot_counts: None,
        tool_length_mm: None,
        geometry: None,
        tool_offset_mm: None,
        probe: None,
        exclude_geometric: vec![],
        out: dir.join("g.bin"),
    };
    // The same group the scenario builds, byte for byte.
    assert_eq!(group_bytes(&args).unwrap(), g);
    group(args).unwrap();
    let text = describe_any(&std::fs::read(dir.join("g.bin")).unwrap()).unwrap();
    assert!(
        text.contains("5 axes")
            && text.contains("--- axis C (rotary, 3600000 counts per revolution) ---"),
        "{text}"
    );
    assert!(
        text.contains("sensor 1 name: column") && text.contains("EB0A 18 µrad"),
        "{text}"
    );
    // With probe settings (section kind 4): parsed back by the core, shown by inspect.
    let probed = group_bytes(&GroupArgs {
        axes: axis_args.clone(),
        sensor_names: vec!["X=spindle,column".into()],
        rotary: Some(rot.clone()),
        pivot_counts: None,
        tool_length_mm: None,
        geometry: None,
        tool_offset_mm: None,
        probe: Some("latency_us=850, lockout_ms=25".into()),
        exclude_geometric: vec![],
        out: dir.join("never.bin"),
    })
    .unwrap();
    let p = group_image::parse(&probed).unwrap().probe.unwrap();
    assert_eq!(
        p,
        ProbeSettings {
            latency_ns: 850_000,
            lockout_us: 25_000,
            ..ProbeSettings::RECOMMENDED
        }
    );
    let text = describe_any(&probed).unwrap();
    assert!(
        text.contains("probe settings: minimum pulse 2000 µs, latency 850 µs, lockout 25 ms"),
        "{text}"
    );
    assert!(describe_any(&g).unwrap().contains("probe settings: none"));
    assert_eq!(
        args::parse_probe_settings("recommended").unwrap(),
        ProbeSettings::RECOMMENDED
    );
    for (bad, want) in [
        ("latency=3", "unknown key `latency`"),
        ("lockout_ms=-1", "must be a number >= 0"),
        ("min_pulse_us=2000,lockout_ms=1", "--probe"),
        ("fast", "expected KEY=VALUE"),
    ] {
        let e = args::parse_probe_settings(bad).unwrap_err();
        assert!(format!("{e:#}").contains(want), "{bad}: {e:#}");
    }
    // Errors name what is wrong.
    for (bad, want) in [
        ("Q=x.bin", "axis name must be one of"),
        ("A=x.bin", "rotary axis needs"),
        ("X:100=x.bin", "linear axis has no counts"),
        ("X", "expected NAME[:CPR]=IMAGE"),
    ] {
        let e = group_bytes(&GroupArgs {
            axes: vec![bad.into()],
            sensor_names: vec![],
            rotary: None,
            pivot_counts: None,
            tool_length_mm: None,
            geometry: None,
            tool_offset_mm: None,
            probe: None,
            exclude_geometric: vec![],
            out: dir.join("never.bin"),
        })
        .unwrap_err();
        assert!(format!("{e:#}").contains(want), "{bad}: {e:#}");
    }
    // Trailing bytes after a schema-1 image are refused by inspect.
    let mut long = std::fs::read(dir.join("X.bin")).unwrap();
    long.extend_from_slice(&[0; 100]);
    let e = describe_any(&long).unwrap_err();
    assert!(format!("{e:#}").contains("bytes follow the end"), "{e:#}");
    let _ = std::fs::remove_dir_all(&dir);
}
