//! Each format written from a known model, parsed back by the vendor's documented grammar (the readers in
//! the crate follow the pages cited in each module), and checked against the model.

use axcomp_export::{Format, heidenhain, linuxcnc, tf5280};
use axcomp_geometry::GeometryModel;
use axcomp_geometry::model::{ComponentModel, MODEL_FORMAT, MODEL_VERSION};
use axcomp_geometry::spline::AxisGrid;
use axcomp_kinematics::rotary::{MachineKind, N_LOCATION, location_unit};
use axcomp_kinematics::{Axis, Component, ComponentKind, Topology};
use axcomp_rtest::{ParamValue, RtestModel};

/// A geometry model with smooth, distinct values in every component (µm / µrad of a few units to tens);
/// `angular` false zeroes the angular components. ECZ is marked not identified.
fn geometry(topology: Topology, angular: bool) -> GeometryModel {
    let grids = [
        AxisGrid {
            lo: 0.0,
            hi: 800.0,
            intervals: 8,
        },
        AxisGrid {
            lo: 0.0,
            hi: 600.0,
            intervals: 6,
        },
        AxisGrid {
            lo: 0.0,
            hi: 500.0,
            intervals: 5,
        },
    ];
    let components = Component::ALL
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let n = c.axis().map_or(0, |a| grids[a.index()].n_basis());
            let on = angular || !matches!(c.kind(), ComponentKind::Angular { .. });
            let coefficients = (0..n)
                .map(|k| {
                    if on {
                        3.0 * ((i * 7 + k) as f64 * 0.37).sin()
                    } else {
                        0.0
                    }
                })
                .collect();
            ComponentModel {
                name: c.name().into(),
                identified: *c != Component::ECZ,
                reason: String::new(),
                unit: c.unit().into(),
                coefficients,
                value: if c.axis().is_none() {
                    4.0 + i as f64
                } else {
                    0.0
                },
                uncertainty: vec![],
            }
        })
        .collect();
    GeometryModel {
        format: MODEL_FORMAT.into(),
        version: MODEL_VERSION,
        topology,
        grids,
        components,
        method: "test".into(),
        smoothing_lambda: 0.0,
        sigma_um: 0.5,
        volume_min_mm: [0.0; 3],
        volume_max_mm: [800.0, 600.0, 500.0],
    }
}

fn file<'a>(files: &'a [axcomp_export::ExportFile], name: &str) -> &'a str {
    &files
        .iter()
        .find(|f| f.name == name)
        .unwrap_or_else(|| panic!("{name} not written"))
        .text
}

/// TF5280: the list names every file with format ISG_CSV and states the stacking (chain from the
/// workpiece, workpiece_axes); each component file has the header `X EXX EYX EZX EAX EBX ECX`, `//`
/// comments stating mm and rad, and values equal to the model's converted to mm / rad with the sign of the
/// axis's side. Tolerance: the written rounding, 5e-8 mm and 5e-11 rad.
#[test]
fn tf5280_files_follow_the_isg_grammar_and_the_model() {
    for (work, tool, chain) in [("YX", "Z", "XYZ"), ("", "XYZ", "XYZ"), ("Z", "YX", "ZYX")] {
        let m = geometry(Topology::parse(work, tool).unwrap(), true);
        let files = tf5280::export(&m, 50.0).unwrap();
        let list = tf5280::parse_list(file(&files, tf5280::LIST_FILE)).unwrap();
        let get = |k: &str| list.iter().find(|(a, _)| a == k).map(|(_, v)| v.as_str());
        assert_eq!(get("chain"), Some(chain));
        assert_eq!(get("workpiece_axes"), Some(work.len().to_string().as_str()));
        assert_eq!(
            (get("X"), get("Y"), get("Z")),
            (Some("1"), Some("2"), Some("3"))
        );
        let named: Vec<&str> = list
            .iter()
            .filter(|(k, _)| k.starts_with("file["))
            .map(|(_, v)| v.as_str())
            .collect();
        assert_eq!(named.len(), 4);
        for (j, name) in named.iter().enumerate() {
            assert_eq!(get(&format!("file_format[{j}]")), Some("ISG_CSV"));
            assert!(files.iter().any(|f| f.name == *name));
        }
        for a in Axis::ALL {
            let text = file(&files, &tf5280::component_file(a));
            assert!(
                text.contains("// Units: argument")
                    && text.contains("in mm")
                    && text.contains("in rad")
            );
            assert!(text.contains("// Sign:"));
            let blocks = tf5280::parse_isg_csv(text).unwrap();
            assert_eq!(blocks.len(), 1);
            let l = a.letter();
            let o = ['X', 'Y', 'Z', 'A', 'B', 'C'];
            let want: Vec<String> = std::iter::once(l.to_string())
                .chain(o.iter().map(|d| format!("E{d}{l}")))
                .collect();
            assert_eq!(blocks[0].header, want);
            let g = m.grids[a.index()];
            let rows = &blocks[0].rows;
            assert_eq!(rows[0][0], g.lo);
            assert_eq!(rows.last().unwrap()[0], g.hi);
            let sign = if m.topology.work.contains(&a) {
                -1.0
            } else {
                1.0
            };
            for row in rows {
                for (k, v) in row[1..].iter().enumerate() {
                    let c = Component::ALL[6 * a.index() + k];
                    let (unit, tol) = if k < 3 { (1e-3, 5e-8) } else { (1e-6, 5e-11) };
                    let expect = sign * unit * m.component_value(c, row[0]);
                    assert!(
                        (v - expect).abs() <= tol,
                        "{} at {}: {v} vs {expect}",
                        c.name(),
                        row[0]
                    );
                }
            }
        }
        let pos = tf5280::parse_isg_csv(file(&files, tf5280::POSITION_FILE)).unwrap();
        assert_eq!(pos[0].header, ["C0Y", "B0Z", "A0Z"]);
        for (k, c) in [Component::EC0Y, Component::EB0Z, Component::EA0Z]
            .iter()
            .enumerate()
        {
            assert!((pos[0].rows[0][k] - m.component_value(*c, 0.0) * 1e-6).abs() < 5e-11);
        }
        assert!(
            file(&files, &tf5280::component_file(Axis::Z)).contains("held at the prior 0): ECZ")
        );
    }
}

/// Heidenhain: `BEGIN X.COM MM`, columns NR AXISPOS X Y Z, entries numbered from 0, `[END]`; values (mm)
/// the model's error along each axis as a function of the table's axis, squareness folded in (tolerance:
/// the written rounding, 5e-7 mm). The .CMA assigns X.COM to column X etc. and marks line 0 active.
#[test]
fn heidenhain_tables_follow_the_tnc_grammar_and_the_model() {
    let m = geometry(Topology::default(), true);
    let (files, rem) = heidenhain::export(&m, 10.0).unwrap();
    for a in Axis::ALL {
        let t = heidenhain::parse_table(file(&files, &heidenhain::com_file(a))).unwrap();
        assert_eq!(t.name, heidenhain::com_file(a));
        assert_eq!(t.unit.as_deref(), Some("MM"));
        assert_eq!(t.columns, ["NR", "AXISPOS", "X", "Y", "Z"]);
        assert!(t.rows.len() <= heidenhain::MAX_ENTRIES);
        for (nr, row) in t.rows.iter().enumerate() {
            assert_eq!(row[0], nr.to_string());
            let q: f64 = row[1].parse().unwrap();
            for k in Axis::ALL {
                let v: f64 = row[2 + k.index()].parse().unwrap();
                let mut expect = m.component_value(Component::ALL[6 * a.index() + k.index()], q);
                // squareness: Y along (−EC0Y, 1, 0), Z along (EB0Z, −EA0Z, 1) (axcomp_kinematics)
                let sq = |c: Component| m.component_value(c, 0.0) * q * 1e-3;
                expect += match (a, k) {
                    (Axis::Y, Axis::X) => -sq(Component::EC0Y),
                    (Axis::Z, Axis::X) => sq(Component::EB0Z),
                    (Axis::Z, Axis::Y) => -sq(Component::EA0Z),
                    _ => 0.0,
                };
                assert!((v - expect * 1e-3).abs() <= 5e-7, "{a:?} {k:?} at {q}: {v}");
            }
        }
        assert_eq!(
            t.rows.last().unwrap()[1].parse::<f64>().unwrap(),
            m.grids[a.index()].hi
        );
    }
    let cma = heidenhain::parse_table(file(&files, heidenhain::CMA_FILE)).unwrap();
    assert_eq!(cma.columns, ["NR", "X", "Y", "Z", "ACTIVE"]);
    assert_eq!(cma.rows, [["0", "X.COM", "Y.COM", "Z.COM", "*"]]);
    let notes = file(&files, heidenhain::NOTES_FILE);
    assert!(notes.contains("Units: AXISPOS mm") && notes.contains("Sign:"));
    assert!(rem.after_rms_um > 0.0 && rem.after_rms_um < rem.before_rms_um);
    // Without angular components the tables take the whole model: nothing remains (float rounding only).
    let lin = geometry(Topology::default(), false);
    let (_, r) = heidenhain::export(&lin, 10.0).unwrap();
    assert!(r.before_rms_um > 1.0 && r.after_rms_um < 1e-9, "{r:?}");
    // A step giving more than 256 entries is refused, naming the step.
    let err = heidenhain::export(&m, 1.0).unwrap_err().to_string();
    assert!(err.contains("--step 1") && err.contains("256"), "{err}");
}

fn rotary(kind: MachineKind, le: [f64; N_LOCATION]) -> RtestModel {
    let names = kind.location_names();
    RtestModel {
        kind: "rtest".into(),
        machine: kind,
        pivot_mm: 0.0,
        location_errors: (0..N_LOCATION)
            .map(|k| {
                (
                    names[k].to_string(),
                    ParamValue {
                        value: le[k],
                        unit: location_unit(k).into(),
                        std: None,
                        identified: true,
                        reason: None,
                    },
                )
            })
            .collect(),
        setup_offsets_um: vec![("1".into(), [0.0; 6])],
        sign_convention: String::new(),
        effects: Vec::new(),
    }
}

/// LinuxCNC: with only the four offsets the kinematics takes, LinuxCNC's inverse (transcribed from
/// trtfuncs.c) with the exported values leaves nothing of the model's exact displacement (< 1e-6 µm over
/// the default K4 poses), against tens of µm with nominal kinematics: the values' meaning and signs match
/// the model. With tilts and squareness as well, what remains is what those alone give (first order: within
/// 5 % + 0.01 µm of the displacement of the untaken errors alone, nominal kinematics).
#[test]
fn linuxcnc_values_take_the_offsets_and_leave_the_rest() {
    for (kind, format, kins) in [
        (
            MachineKind::AcTrunnion,
            Format::LinuxCncXyzacTrt,
            "xyzac-trt-kins",
        ),
        (
            MachineKind::BcTrunnion,
            Format::LinuxCncXyzbcTrt,
            "xyzbc-trt-kins",
        ),
    ] {
        let offsets = [25.0, -18.0, 0.0, 0.0, 40.0, -30.0, 0.0, 0.0, 0.0, 0.0, 0.0];
        let m = rotary(kind, offsets);
        let poses = linuxcnc::default_poses(m.five_axis());
        let r = linuxcnc::remaining(&m, format, &poses, "default").unwrap();
        assert!(
            r.before_rms_um > 10.0 && r.after_rms_um < 1e-6,
            "{kind:?} {r:?}"
        );
        let tilts = [
            0.0, 0.0, 30.0, -20.0, 0.0, 0.0, 15.0, 25.0, 10.0, -12.0, 8.0,
        ];
        let both: Vec<f64> = offsets.iter().zip(&tilts).map(|(a, b)| a + b).collect();
        let all = rotary(kind, both.clone().try_into().unwrap());
        let r = linuxcnc::remaining(&all, format, &poses, "default").unwrap();
        let alone = linuxcnc::remaining(&rotary(kind, tilts), format, &poses, "default").unwrap();
        assert!(
            (r.after_rms_um - alone.before_rms_um).abs() <= 0.05 * alone.before_rms_um + 0.01,
            "{r:?} vs {alone:?}"
        );
        let (files, _) =
            linuxcnc::export(&all, format, [100.0, 50.0, 20.0], &poses, "default").unwrap();
        let hal = file(&files, &format!("{kins}.hal"));
        assert!(hal.contains("# Units: mm") && hal.contains("# Not taken") && hal.contains("EC0Y"));
        let pins = linuxcnc::parse_setp(hal).unwrap();
        let k = linuxcnc::kins_values(&all, format, [100.0, 50.0, 20.0]).unwrap();
        let expect = if kind == MachineKind::AcTrunnion {
            [("y-offset", k.y_offset), ("z-offset", k.z_offset)]
        } else {
            [("x-offset", k.x_offset), ("z-offset", k.z_offset)]
        };
        let want = [
            ("x-rot-point", 100.0 + both[0] * 1e-3),
            ("y-rot-point", 50.0 + both[1] * 1e-3),
            ("z-rot-point", 20.0),
            expect[0],
            expect[1],
        ];
        assert_eq!(pins.len(), 5);
        for ((pin, v), (name, w)) in pins.iter().zip(want) {
            assert_eq!(pin, &format!("{kins}.{name}"));
            assert!((v - w).abs() < 5e-7, "{pin} {v} {w}");
        }
        let ini = file(&files, &format!("{kins}.ini"));
        assert!(ini.contains(&format!("KINEMATICS = {kins}")));
    }
    let head = rotary(MachineKind::BcHead, [0.0; N_LOCATION]);
    let err = linuxcnc::kins_values(&head, Format::LinuxCncXyzbcTrt, [0.0; 3]).unwrap_err();
    assert!(err.to_string().contains("bc-head"), "{err}");
}
