//! A `fit geometry` model in the firmware: `axcomp image group --geometry
//! MODEL.json [--tool-offset-mm x,y,z]` converts it into the group image's geometric section, and
//! the core's f32 stage reproduces the host's f64 prediction (`GeometryModel::error_at`, the
//! `axcomp-kinematics` linearised chain that `axcomp predict` uses) at random positions.

mod common;
use common::scratch;
use std::path::{Path, PathBuf};

use axcomp::commands::image_group::{GroupArgs, group_bytes};
use axcomp_core::group::Group;
use axcomp_core::group_image;
use axcomp_core::{ImageSpec, LimitSpec, OutsideStroke, TableSpec, image_len, write_image};
use axcomp_geometry::GeometryModel;
use axcomp_geometry::model::{ComponentModel, MODEL_FORMAT};
use axcomp_geometry::spline::AxisGrid;
use axcomp_image::{describe_any, exclude_geometric_components, geometric_from_model};
use axcomp_kinematics::{Component, Topology};

/// µm per count of every axis (as the axis images store it, f32).
const UPC: f32 = 0.1;

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
    fn sym(&mut self, a: f64) -> f64 {
        a * (2.0 * self.next() - 1.0)
    }
}

fn grids() -> [AxisGrid; 3] {
    [
        AxisGrid {
            lo: 0.0,
            hi: 600.0,
            intervals: 6,
        },
        AxisGrid {
            lo: -100.0,
            hi: 400.0,
            intervals: 5,
        },
        AxisGrid {
            lo: -300.0,
            hi: 0.0,
            intervals: 4,
        },
    ]
}

/// A model as `fit geometry` writes it: B-spline coefficients of the specified magnitudes
/// (positioning/straightness a few µm, angles tens of µrad, squareness tens of µrad); the four
/// components the seven-line method cannot see are `identified: false` and hold zeros (fixed at
/// 0, as the fit writes them).
fn model(topology: Topology, rng: &mut Lcg) -> GeometryModel {
    let g = grids();
    let unseen = [
        Component::ECY,
        Component::EAZ,
        Component::EBZ,
        Component::ECZ,
    ];
    let components = Component::ALL
        .iter()
        .map(|c| {
            let identified = !unseen.contains(c);
            let held = if identified { 1.0 } else { 0.0 };
            let (coefficients, value) = match c.axis() {
                Some(a) => {
                    let amp = if c.unit() == "um" { 8.0 } else { 25.0 };
                    let n = g[a.index()].n_basis();
                    ((0..n).map(|_| held * rng.sym(amp)).collect(), 0.0)
                }
                None => (Vec::new(), held * rng.sym(40.0)),
            };
            ComponentModel {
                name: c.name().to_string(),
                identified,
                reason: if identified {
                    "identified".into()
                } else {
                    "no reading is sensitive to it; fixed at 0".into()
                },
                unit: c.unit().into(),
                coefficients,
                value,
                uncertainty: vec![],
            }
        })
        .collect();
    GeometryModel {
        format: MODEL_FORMAT.into(),
        version: 1,
        topology,
        grids: g,
        components,
        method: "test".into(),
        smoothing_lambda: 0.0,
        sigma_um: 0.5,
        volume_min_mm: [0.0, -100.0, -300.0],
        volume_max_mm: [600.0, 400.0, 0.0],
    }
}

/// `m` with ECX and EB0Z marked not separable as `fit geometry` (auto) marks them: `identified:
/// false`, their non-zero values the minimum-norm share of a combination the lines measure (which
/// `axcomp predict` uses, so the image must carry them).
fn with_not_separable(m: &GeometryModel) -> GeometryModel {
    let mut m = m.clone();
    for c in [Component::ECX, Component::EB0Z] {
        let cm = &mut m.components[c.index()];
        cm.identified = false;
        cm.reason = "not separable from EYX with these lines; its value is the minimum-norm share \
                     of what the lines determine (not its own value)"
            .into();
    }
    m
}

/// An axis image with a zero table over the model's grid of axis `k` and loose limits, so the
/// group's X, Y, Z corrections are the geometric stage's alone.
fn axis_image(k: usize, table_start_counts: i64) -> Vec<u8> {
    axis_image_correcting(k, table_start_counts, 0.0)
}

/// An axis image whose table corrects a constant `offset_um` over the model's grid of axis `k`
/// (0: a zero table, which corrects nothing).
fn axis_image_correcting(k: usize, table_start_counts: i64, offset_um: f32) -> Vec<u8> {
    let g = grids()[k];
    let seg = ((g.hi - g.lo) * 1000.0 / UPC as f64 / g.intervals as f64).round() as u32;
    let zeros = vec![[offset_um, 0.0, 0.0, 0.0]; g.intervals];
    let spec = ImageSpec {
        axis_id: k as u16 + 1,
        um_per_count: UPC,
        counter_bits: 32,
        table: Some(TableSpec {
            start_counts: table_start_counts,
            segment_counts: seg,
            forward: &zeros,
            backward: &[],
            outside: OutsideStroke::Hold,
        }),
        thermo: None,
        limits: LimitSpec {
            max_correction_um: 1.0e4,
            max_slew_um_per_cycle: 1.0e4,
            direction_hysteresis_counts: 0,
        },
    };
    let mut buf = vec![0u8; image_len(&spec)];
    write_image(&spec, &mut buf).unwrap();
    buf
}

fn start_counts(k: usize) -> i64 {
    (grids()[k].lo * 1000.0 / UPC as f64).round() as i64
}

/// Writes the model and X, Y, Z images into `dir`; the `--axis` arguments in slot order `order`.
fn files(dir: &Path, m: &GeometryModel, order: &str) -> (PathBuf, Vec<String>) {
    let model_path = dir.join("model.json");
    std::fs::write(&model_path, m.to_json()).unwrap();
    let mut axes = Vec::new();
    for c in order.chars() {
        let k = "XYZ".find(c).unwrap();
        let p = dir.join(format!("{c}.bin"));
        std::fs::write(&p, axis_image(k, start_counts(k))).unwrap();
        axes.push(format!("{c}={}", p.display()));
    }
    (model_path, axes)
}

fn args(
    axes: Vec<String>,
    geometry: Option<PathBuf>,
    tool: Option<&str>,
    out: PathBuf,
) -> GroupArgs {
    GroupArgs {
        axes,
        sensor_names: vec![],
        rotary: None,
        pivot_counts: None,
        tool_length_mm: None,
        geometry,
        tool_offset_mm: tool.map(str::to_string),
        probe: None,
        exclude_geometric: vec![],
        out,
    }
}

/// Reference: `GeometryModel::error_at` (f64, `axcomp_kinematics::linear_error`) at the
/// position the counts stand for (counts × the image's f32 µm per count). Tolerance 0.01 µm
/// (the required one); the core's f32 arithmetic on errors of ≤ ~100 µm and positions ≤ 600 mm gives
/// about 4e-6 µm (the figure printed). Four stackings, with and without a tool offset, slots in
/// two orders, 500 random positions each within the measured volume.
#[test]
fn core_stage_matches_host_prediction() {
    let mut rng = Lcg(0x0a0c_0010);
    let dir = scratch("equiv");
    let mut worst = 0.0f64;
    for (work, tool_axes, order) in [
        ("YX", "Z", "XYZ"),
        ("", "XYZ", "ZXY"),
        ("X", "YZ", "YZX"),
        ("ZYX", "", "XYZ"),
    ] {
        let topo = Topology::parse(work, tool_axes).unwrap();
        let m = with_not_separable(&model(topo.clone(), &mut rng));
        // What the host predicts with: every value the model holds, identified or not.
        let reference = m.clone();
        for tool in [None, Some("35.5,-60,-120")] {
            let t_mm: [f64; 3] = tool.map_or([0.0; 3], |s| {
                let v: Vec<f64> = s.split(',').map(|x| x.parse().unwrap()).collect();
                [v[0], v[1], v[2]]
            });
            let (model_path, axes) = files(&dir, &m, order);
            let bytes =
                group_bytes(&args(axes, Some(model_path), tool, dir.join("g.bin"))).unwrap();
            let mut g = Box::new(Group::<256>::new());
            g.load_image(&bytes).unwrap();
            assert!(g.has_geometric_stage());
            let upc = UPC as f64;
            for _ in 0..500 {
                let counts: [i64; 3] = std::array::from_fn(|k| {
                    let gr = grids()[k];
                    ((gr.lo + (gr.hi - gr.lo) * rng.next()) * 1000.0 / upc).round() as i64
                });
                let q = counts.map(|c| c as f64 * upc / 1000.0);
                let want = reference.error_at(q, t_mm).expect("inside the model");
                let got = g.geometric_error_um(counts).unwrap();
                for d in 0..3 {
                    let diff = (got[d] as f64 - want[d]).abs();
                    worst = worst.max(diff);
                    assert!(
                        diff <= 0.01,
                        "{} tool {tool:?} at {q:?} mm: axis {d}: core {} host {}",
                        topo.label(),
                        got[d],
                        want[d]
                    );
                }
            }
        }
    }
    eprintln!("largest |core f32 stage − host f64 prediction|: {worst:.2e} µm");
}

/// `image inspect` lists the geometric section: stacking, tool offset, grids, each component,
/// which are not separable (stored at their minimum-norm share) and which are not identified
/// (stored as zero).
#[test]
fn inspect_lists_the_geometric_section() {
    let mut rng = Lcg(5);
    let dir = scratch("inspect");
    let m = with_not_separable(&model(Topology::default(), &mut rng));
    let (model_path, axes) = files(&dir, &m, "XYZ");
    let out = dir.join("g.bin");
    axcomp::run([
        "axcomp",
        "image",
        "group",
        "--axis",
        &axes[0],
        "--axis",
        &axes[1],
        "--axis",
        &axes[2],
        "--geometry",
        &model_path.display().to_string(),
        "--tool-offset-mm",
        "0,0,-100",
        "--out",
        &out.display().to_string(),
    ])
    .unwrap();
    let text = describe_any(&std::fs::read(&out).unwrap()).unwrap();
    for want in [
        "geometric model (21 ISO 230-1 components, volumetric stage): stacking YX/Z",
        "tool offset (0, 0, -100000) µm, 15 of 21 components identified, 2 not separable \
         stored at their minimum-norm share (only their combination is measured)",
        "ECX  ",
        "µrad, NOT separable: only its combination with others is measured; stored at its \
         minimum-norm share",
        "grid X: 6 segments of 1000000 counts from 0 counts (7 knots)",
        "grid Y: 5 segments of 1000000 counts from -1000000 counts",
        "ECY  0.000 .. 0.000 µrad, NOT identified: stored as zero (the model's prior)",
        "EBZ  0.000 .. 0.000 µrad, NOT identified",
        "EC0Y",
        "--- axis Z (linear, stroke -3000000 .. 0 counts) ---",
    ] {
        assert!(text.contains(want), "missing {want:?} in:\n{text}");
    }
    // the provenance names the geometry model file by its hash
    let model_sha = axcomp_data::provenance::file_sha256(&model_path).unwrap().0;
    let trust = axcomp_image::describe_trust(&std::fs::read(&out).unwrap(), &[]).unwrap();
    assert!(
        trust.contains(&format!("geometry model sha256 {model_sha}")),
        "no geometry model record in:\n{trust}"
    );
    assert!(
        text.contains("EXX ") && text.contains(", identified"),
        "{text}"
    );
    let bytes = std::fs::read(&out).unwrap();
    let view = group_image::parse(&bytes).unwrap();
    let g = view.geometric.unwrap();
    assert_eq!(g.identified.count_ones(), 15);
    for (c, status) in [
        (Component::ECX, "NOT separable"),
        (Component::EB0Z, "NOT separable"),
        (Component::ECY, "NOT identified: stored as zero"),
    ] {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("  {:<4} ", c.name())))
            .unwrap();
        assert!(line.contains(status), "{line}");
    }
}

/// Bad input is a clear error naming what is wrong, and nothing is written.
#[test]
fn bad_geometry_arguments_are_named() {
    let mut rng = Lcg(11);
    let dir = scratch("bad");
    let m = model(Topology::default(), &mut rng);
    let (model_path, axes) = files(&dir, &m, "XYZ");
    let out = dir.join("never.bin");
    let err = |a: GroupArgs| format!("{:#}", group_bytes(&a).unwrap_err());
    // No Z axis in the group.
    let e = err(args(
        axes[..2].to_vec(),
        Some(model_path.clone()),
        None,
        out.clone(),
    ));
    assert!(e.contains("needs axis Z in the group"), "{e}");
    // An axis table over another stroke than the model's grid.
    let shifted = dir.join("Yshift.bin");
    std::fs::write(&shifted, axis_image(1, start_counts(1) + 10)).unwrap();
    let mut a = axes.clone();
    a[1] = format!("Y={}", shifted.display());
    let e = err(args(a, Some(model_path.clone()), None, out.clone()));
    assert!(
        e.contains("axis Y's positioning table spans -999990 .. 4000010 counts"),
        "{e}"
    );
    // Tool offset not three numbers.
    let e = err(args(
        axes.clone(),
        Some(model_path.clone()),
        Some("1,2"),
        out.clone(),
    ));
    assert!(
        e.contains("--tool-offset-mm 1,2: expected three finite numbers"),
        "{e}"
    );
    // A grid that does not fall on whole counts.
    let e = format!(
        "{:#}",
        geometric_from_model(&m, [0.3, 0.1, 0.1], [0.0; 3]).unwrap_err()
    );
    assert!(
        e.contains("the X grid (0 .. 600 mm, 6 intervals) does not fall on whole counts"),
        "{e}"
    );
    // Not a geometry model.
    let junk = dir.join("junk.json");
    std::fs::write(&junk, "{\"format\": \"other\"}").unwrap();
    let e = err(args(axes.clone(), Some(junk), None, out.clone()));
    assert!(e.contains("not a geometry model"), "{e}");
    // The CLI run with a bad argument writes nothing.
    let r = axcomp::run([
        "axcomp",
        "image",
        "group",
        "--axis",
        &axes[0],
        "--axis",
        &axes[1],
        "--geometry",
        &model_path.display().to_string(),
        "--out",
        &out.display().to_string(),
    ]);
    assert!(r.is_err());
    assert!(!out.exists(), "nothing written");
}

/// An axis table that corrects X's positioning and a geometric model whose
/// EXX does too would correct the same error twice: `image group` refuses it, naming both sources
/// and the way out, and writes nothing; `--exclude-geometric EXX` builds the image with EXX stored as
/// zero (identified bit kept), which `image inspect` lists as excluded, and the geometric stage then
/// applies nothing for EXX (the other 16 identified components are unchanged).
#[test]
fn double_positioning_correction_is_refused_unless_excluded() {
    let mut rng = Lcg(23);
    let dir = scratch("double");
    let m = model(Topology::default(), &mut rng);
    let (model_path, mut axes) = files(&dir, &m, "XYZ");
    let x_table = dir.join("Xtable.bin");
    std::fs::write(&x_table, axis_image_correcting(0, start_counts(0), 2.5)).unwrap();
    axes[0] = format!("X={}", x_table.display());
    let out = dir.join("g.bin");
    let run = |extra: &[&str]| {
        let mut argv: Vec<String> = ["axcomp", "image", "group"].map(String::from).to_vec();
        for a in &axes {
            argv.extend(["--axis".to_string(), a.clone()]);
        }
        argv.extend(["--geometry".into(), model_path.display().to_string()]);
        argv.extend(extra.iter().map(|s| s.to_string()));
        argv.extend(["--out".into(), out.display().to_string()]);
        axcomp::run(argv)
    };
    // Refused: both sources named, the way out given, nothing written.
    let e = format!("{:#}", run(&[]).unwrap_err());
    for want in [
        "would correct the same error twice (nothing written)",
        &format!(
            "axis X's positioning table (--axis X={})",
            x_table.display()
        ),
        &format!(
            "the geometry model's EXX (--geometry {}) both correct X's positioning error",
            model_path.display()
        ),
        "`--exclude-geometric EXX`",
    ] {
        assert!(e.contains(want), "missing {want:?} in: {e}");
    }
    assert!(
        !e.contains("EYY") && !e.contains("EZZ"),
        "zero tables correct nothing: {e}"
    );
    assert!(!out.exists(), "nothing written on refusal");
    // The way out: EXX left out of the geometric section.
    run(&["--exclude-geometric", "EXX"]).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    let g = group_image::parse(&bytes).unwrap().geometric.unwrap();
    assert_eq!(
        g.identified.count_ones(),
        17,
        "the identified bits are kept"
    );
    for seg in 0..g.grids[0].n_segments as usize {
        assert_eq!(g.segment(0, seg, 0), [0.0; 4], "EXX stored as zero");
        assert_ne!(g.segment(0, seg, 1), [0.0; 4], "EYX kept");
    }
    let text = describe_any(&bytes).unwrap();
    for want in [
        "17 of 21 components identified, 1 of them excluded from this image (stored as zero)",
        "EXX  0.000 .. 0.000 µm, identified by the fit, EXCLUDED from this image",
        "ECY  0.000 .. 0.000 µrad, NOT identified: stored as zero (the model's prior)",
    ] {
        assert!(text.contains(want), "missing {want:?} in:\n{text}");
    }
    // The same image as the conversion with EXX excluded by hand (nothing else changed).
    let mut by_hand = geometric_from_model(&m, [0.1; 3], [0.0; 3]).unwrap();
    exclude_geometric_components(&mut by_hand, &["EXX".into()]).unwrap();
    let want = by_hand.spec();
    assert_eq!(
        (g.identified, g.squareness_urad, g.grids),
        (want.identified, want.squareness_urad, want.grids)
    );
    for k in 0..3 {
        for seg in 0..g.grids[k].n_segments as usize {
            for f in 0..6 {
                assert_eq!(g.segment(k, seg, f), want.segment(k, seg, f));
            }
        }
    }
    // Excluding what the model did not identify, or an unknown name, is refused and writes nothing.
    std::fs::remove_file(&out).unwrap();
    let e = format!(
        "{:#}",
        run(&["--exclude-geometric", "EXX,ECY"]).unwrap_err()
    );
    assert!(
        e.contains("--exclude-geometric ECY: the geometry model did not identify ECY"),
        "{e}"
    );
    let e = format!("{:#}", run(&["--exclude-geometric", "EXQ"]).unwrap_err());
    assert!(
        e.contains("--exclude-geometric EXQ: not an ISO 230-1 component name"),
        "{e}"
    );
    assert!(!out.exists(), "nothing written");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Compensated three-axis twin runs driven through the core's
/// geometric stage. The twin (known truth, σ = 0.5 µm, seeds 1–3) is measured on a line set
/// that `plan geometry` calls complete plus the seven lines (2 runs, 11 targets), fitted with the
/// default `fit geometry`, the model put into a group image (`image group --geometry` conversion)
/// and every point of an 11³ grid of the measured volume commanded through `Group::cycle` (zero
/// axis tables: the geometric stage alone, the corrected commands rounded to 0.1 µm counts); the
/// twin's exact HTM chain gives where the tool lands. Reference in the same run: the same
/// correction from the host's f64 model (`GeometryModel::error_at`, no rounding). Pass: the
/// volumetric max error falls ≥ 90 % (the required figure), at tool offset 0 and at a 150 mm tool
/// along Z (the Abbe arm the lines with tool offsets identify); the core's residual is within
/// 0.1 µm of the host model's (0.05 µm count rounding per axis, √3 · 0.05 ≈ 0.09 µm).
#[test]
fn twin_compensated_through_the_core_stage() {
    use axcomp_core::group::{GroupInput, GroupOutput, GroupState};
    use axcomp_data::{Dataset, LoadOptions};
    use axcomp_geometry::plan::{PlanOptions, plan};
    use axcomp_geometry::{FitOptions, Judge, LineData, analyse};
    use axcomp_twin::geometry::{GeometryTwin, plan_by_name};

    const STROKE: [f64; 3] = [800.0, 600.0, 500.0];
    let p = plan(&PlanOptions {
        stroke_mm: STROKE,
        max_lines: Some(20),
        tool_offsets: vec![
            [0.0; 3],
            [150.0, 0.0, 0.0],
            [0.0, 150.0, 0.0],
            [0.0, 0.0, 150.0],
        ],
        sigma_um: 0.5,
        targets: 11,
        topology: Topology::default(),
    })
    .unwrap();
    assert!(p.complete);
    let mut lines = plan_by_name("seven-line", STROKE, 11).unwrap();
    lines.extend(p.lines.iter().cloned());
    for seed in [1u64, 2, 3] {
        let twin = GeometryTwin::random(STROKE, Topology::default(), seed);
        let camp = twin.measure(&lines, 2, seed + 100);
        let ds =
            Dataset::from_csv_str("twin", &camp.to_csv_string(), &LoadOptions::default()).unwrap();
        let data = LineData::from_dataset(&ds, true).unwrap();
        let model = analyse(&data, &Judge::None, &FitOptions::default())
            .unwrap()
            .fit
            .model;
        let (lo, hi) = (model.volume_min_mm, model.volume_max_mm);
        for tool in [[0.0; 3], [0.0, 0.0, 150.0]] {
            let section = geometric_from_model(&model, [0.1; 3], tool).unwrap();
            let images: Vec<Vec<u8>> = (0..3)
                .map(|k| {
                    let g = section.grids[k];
                    let zeros = vec![[0.0f32; 4]; g.n_segments as usize];
                    let spec = ImageSpec {
                        axis_id: k as u16 + 1,
                        um_per_count: UPC,
                        counter_bits: 32,
                        table: Some(TableSpec {
                            start_counts: g.start_counts,
                            segment_counts: g.segment_counts,
                            forward: &zeros,
                            backward: &[],
                            outside: OutsideStroke::Hold,
                        }),
                        thermo: None,
                        limits: LimitSpec {
                            max_correction_um: 1.0e4,
                            max_slew_um_per_cycle: 1.0e4,
                            direction_hysteresis_counts: 0,
                        },
                    };
                    let mut buf = vec![0u8; image_len(&spec)];
                    write_image(&spec, &mut buf).unwrap();
                    buf
                })
                .collect();
            let axes: Vec<axcomp_core::group::GroupAxisImage> = (0..3)
                .map(|k| axcomp_core::group::GroupAxisImage {
                    name: axcomp_core::group::AxisName::ALL[k],
                    counts_per_rev: 0,
                    image: &images[k],
                })
                .collect();
            let mut g = Box::new(Group::<1024>::new());
            g.load_stages(&axes, None, Some(&section.spec())).unwrap();
            let mut st = GroupState::new();
            let per_mm = 1000.0 / UPC as f64;
            let core = twin.compensated_volume(lo, hi, 11, tool, |q| {
                let mut input = GroupInput::ZERO;
                #[allow(clippy::needless_range_loop)] // parallel arrays indexed together
                for k in 0..3 {
                    let c = (q[k] * per_mm).round() as i64;
                    input.axes[k].command_counts = c;
                    input.axes[k].scale_raw = c as u32;
                }
                let mut out = GroupOutput::ZERO;
                g.cycle(&mut st, &input, &mut out);
                std::array::from_fn(|k| out.axes[k].corrected_command_counts as f64 / per_mm)
            });
            let host = twin.compensated_volume(lo, hi, 11, tool, |q| {
                let e = model.error_at(q, tool).unwrap();
                std::array::from_fn(|k| q[k] - e[k] * 1e-3)
            });
            eprintln!(
                "seed {seed} tool {tool:?} mm: volumetric max {:.2} µm → core stage {:.3} µm ({:.1} % less; rms {:.2} → {:.3} µm), host f64 model {:.3} µm",
                core.before_max_um,
                core.after_max_um,
                100.0 * (1.0 - core.after_max_um / core.before_max_um),
                core.before_rms_um,
                core.after_rms_um,
                host.after_max_um
            );
            assert!(
                core.after_max_um <= 0.1 * core.before_max_um,
                "seed {seed} tool {tool:?}: {core:?}"
            );
            assert!(
                (core.after_max_um - host.after_max_um).abs() <= 0.1,
                "seed {seed}: core {core:?} host {host:?}"
            );
        }
    }
}

/// Reads a CSV written by `axcomp predict` into its header and rows of fields.
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    (header, rows)
}

/// Host = image on a real fit with not-separable sets: the twin's twelve axis lines (four per
/// axis, at the stroke's corners) leave the squareness and several straightness and angular
/// components not separable (estimated at the damped minimum norm, `identified: false`) and ECY,
/// EAZ, EBZ, ECZ without data (zero). `fit geometry` (default) on them, the seven-line set held out;
/// `axcomp predict` on every row; `image group --geometry` with identity axis images. At every
/// held-out row (the seven lines, other positions than the training lines, zero tool offset) the
/// firmware library's geometric stage (`Group::geometric_error_um`, f32 Horner) gives
/// `pred_ex_um, pred_ey_um, pred_ez_um`. Tolerance 1e-3 µm: the f32 Horner form of errors of up to
/// ~100 µm (f32 relative precision 6e-8, a few operations: ~1e-5 µm; the figure printed). Reference
/// for why they are stored: the same image with the not-separable components zeroed
/// misses the host by the printed amount at the same rows.
#[test]
fn fitted_not_separable_components_reach_the_image() {
    use axcomp_data::{Dataset, LoadOptions};
    use axcomp_twin::geometry::{GeometryTwin, plan_by_name};

    const STROKE: [f64; 3] = [800.0, 600.0, 500.0];
    let dir = scratch("fitted-min-norm");
    let mut lines = plan_by_name("axis-lines", STROKE, 11).unwrap();
    lines.extend(plan_by_name("seven-line", STROKE, 11).unwrap());
    let twin = GeometryTwin::random(STROKE, Topology::default(), 7);
    let csv = twin.measure(&lines, 2, 107).to_csv_string();
    Dataset::from_csv_str("twin", &csv, &LoadOptions::default()).unwrap();
    let p = |name: &str| dir.join(name).display().to_string();
    std::fs::write(p("lines.csv"), csv).unwrap();
    let (data, model, pred, group) = (
        p("lines.csv"),
        p("geometry.json"),
        p("pred.csv"),
        p("group.bin"),
    );
    cli(&format!(
        "fit geometry --data {data} --holdout line=L1,L2,L3,L4,L5,L6,L7 --out {model}"
    ));
    cli(&format!(
        "predict --model {model} --data {data} --out {pred}"
    ));
    let axes = identity_axes(&dir);
    cli(&format!(
        "image group {axes} --geometry {model} --out {group}"
    ));

    let m = GeometryModel::from_json(&std::fs::read_to_string(&model).unwrap(), "fit").unwrap();
    let shared: Vec<usize> = (0..21)
        .filter(|&i| {
            let c = &m.components[i];
            !c.identified && (c.value != 0.0 || c.coefficients.iter().any(|v| *v != 0.0))
        })
        .collect();
    assert!(
        shared.len() >= 3,
        "the axis lines leave sets not separable, estimated at the minimum norm: {shared:?}"
    );
    let bytes = std::fs::read(&group).unwrap();
    let text = describe_any(&bytes).unwrap();
    for i in &shared {
        let line = text
            .lines()
            .find(|l| l.starts_with(&format!("  {:<4} ", m.components[*i].name)))
            .unwrap();
        assert!(line.contains("NOT separable"), "{line}");
    }
    let ecy = text.lines().find(|l| l.starts_with("  ECY  ")).unwrap();
    assert!(ecy.contains("NOT identified: stored as zero"), "{ecy}");
    // The image as it was stored before: not-separable components at zero.
    let mut old = m.clone();
    for i in &shared {
        old.components[*i]
            .coefficients
            .iter_mut()
            .for_each(|v| *v = 0.0);
        old.components[*i].value = 0.0;
    }

    let mut g = Box::new(Group::<1024>::new());
    g.load_image(&bytes).unwrap();
    let (header, rows) = read_csv(Path::new(&pred));
    let col = |n: &str| header.iter().position(|h| h == n).unwrap();
    let (cx, cl) = (col("x_mm"), col("line"));
    let tools = [col("tool_x_mm"), col("tool_y_mm"), col("tool_z_mm")];
    let preds = [col("pred_ex_um"), col("pred_ey_um"), col("pred_ez_um")];
    let (mut n, mut worst, mut worst_old) = (0, 0.0f64, 0.0f64);
    for r in rows.iter().filter(|r| r[cl].starts_with('L')) {
        assert!(tools.iter().all(|&t| r[t].parse::<f64>().unwrap() == 0.0));
        let q: [f64; 3] = std::array::from_fn(|k| r[cx + k].parse().unwrap());
        let counts = q.map(|v| (v * 1e4).round() as i64);
        assert!((0..3).all(|k| (counts[k] as f64 - q[k] * 1e4).abs() < 1e-6));
        let host: [f64; 3] = preds.map(|c| r[c].parse().unwrap());
        let core = g.geometric_error_um(counts).unwrap();
        let before = old.error_at(q, [0.0; 3]).unwrap();
        for d in 0..3 {
            let diff = (core[d] as f64 - host[d]).abs();
            worst = worst.max(diff);
            worst_old = worst_old.max((before[d] - host[d]).abs());
            assert!(
                diff <= 1e-3,
                "held-out {} at {q:?}: axis {d}: image {} predict {}",
                r[cl],
                core[d],
                host[d]
            );
        }
        n += 1;
    }
    assert!(n >= 7 * 11, "held-out rows compared: {n}");
    eprintln!(
        "{n} held-out points: max |image − predict| {worst:.2e} µm; with the {} not-separable \
         components stored as zero (before): {worst_old:.2} µm",
        shared.len()
    );
    assert!(
        worst_old > 100.0 * worst.max(1e-6),
        "the old image differed from the host"
    );

    // --exclude-geometric: a not-separable component may be left out (then zero), one without
    // data (stored as zero already) is an error naming it.
    let name = m.components[shared[0]].name.clone();
    let excluded = p("excluded.bin");
    cli(&format!(
        "image group {axes} --geometry {model} --exclude-geometric {name} --out {excluded}"
    ));
    let ex_bytes = std::fs::read(&excluded).unwrap();
    let ex = group_image::parse(&ex_bytes).unwrap().geometric.unwrap();
    assert!(!axcomp_image::geometric::geometric_component_nonzero(
        &ex, shared[0]
    ));
    let no = p("no.bin");
    let args =
        format!("axcomp image group {axes} --geometry {model} --exclude-geometric ECY --out {no}");
    let e = axcomp::run(args.split_whitespace()).unwrap_err();
    assert!(format!("{e:#}").contains("ECY"), "{e:#}");
    assert!(!dir.join("no.bin").exists());
}

/// Runs `axcomp` with the whitespace-separated arguments `args` (scratch paths hold no spaces).
fn cli(args: &str) {
    axcomp::run(std::iter::once("axcomp").chain(args.split_whitespace()))
        .unwrap_or_else(|e| panic!("axcomp {args}: {e:#}"));
}

/// Identity X, Y, Z images at 0.1 µm per count in `dir`, as `--axis` arguments of `image group`.
fn identity_axes(dir: &Path) -> String {
    let mut axes = Vec::new();
    for (k, c) in ["X", "Y", "Z"].into_iter().enumerate() {
        let img = dir.join(format!("{c}.bin")).display().to_string();
        cli(&format!(
            "image build --identity --axis-id {} --um-per-count 0.1 --out {img}",
            k + 1
        ));
        axes.push(format!("--axis {c}={img}"));
    }
    axes.join(" ")
}
