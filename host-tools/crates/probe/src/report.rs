//! The report of `axcomp fit probe`: the JSON result (contract: "Touch probe: calibration and correction")
//! and the report folder's `report.md` with its figures (residual maps, pretravel versus speed, diameter
//! error by speed).

use std::collections::BTreeMap;
use std::fmt::Write as _;

use axcomp_plot::{Figure, markdown_table};
use serde_json::{Value, json};

use crate::evaluate::Evaluation;
use crate::poses::PoseCentre;
use crate::{
    Calibration, CalibrationResult, DirSpeed, SharedCentreError, Sphere, Structure, Touch,
    measured_diameter_mm,
};

/// Everything the report describes.
pub struct ProbeReport<'a> {
    pub result: &'a CalibrationResult,
    pub sphere_diameter_mm: f64,
    /// The calibration touches (before outlier removal).
    pub calibration_touches: &'a [Touch],
    pub evaluation: &'a Evaluation,
    /// Rows of the file, of the calibration and held out.
    pub rows: [usize; 3],
    /// Number of `--group` columns (the leading values of each pose's `values`).
    pub group_columns: usize,
    pub poses: &'a [PoseCentre],
    pub shared: Option<&'a SharedCentreError>,
    /// The machine kind whose probe frame the directions were taken in, when given.
    pub machine: Option<&'a str>,
}

fn sphere_json(s: &Sphere) -> Value {
    json!({ "center_mm": s.center_mm, "radius_mm": s.radius_mm, "rms_um": s.rms_um })
}

fn shared_zero_json(z: &SharedCentreError) -> Value {
    json!({
        "columns": (1..=z.components()).map(|k| format!("zero{k}_dx_um, zero{k}_dy_um, zero{k}_dz_um")).collect::<Vec<_>>(),
        "std_um": z.std_um,
        "captured_share": z.captured_share,
        "definition": "error every pose's fitted centre shares through the one probe calibration (its coefficients' covariance from the calibration fit, propagated through each pose's centre fit); each column triplet is one independent standard-uncertainty component (µm); `fit rtest` propagates it",
    })
}

/// The pretravel at the calibrated elevations (a bilinear grid's, else 0/30/60/90°), every 30° of azimuth,
/// at zero speed and the calibrated speeds.
fn pretravel_table(cal: &Calibration) -> Vec<Value> {
    let mut v = Vec::new();
    let els: Vec<f64> = match &cal.structure {
        Structure::Bilinear {
            elevation_nodes_deg,
            ..
        } => elevation_nodes_deg.clone(),
        _ => vec![0.0, 30.0, 60.0, 90.0],
    };
    let feeds = if cal.feed_range_mm_min[1] > cal.feed_range_mm_min[0] {
        vec![0.0, cal.feed_range_mm_min[0], cal.feed_range_mm_min[1]]
    } else {
        vec![cal.feed_range_mm_min[0]]
    };
    for &el in &els {
        for k in 0..12 {
            let az = 30.0 * k as f64;
            if el >= 89.9 && k > 0 {
                break;
            }
            for &f in &feeds {
                let d = DirSpeed {
                    t: el.to_radians().sin(),
                    theta: az.to_radians(),
                    v: f / 60.0,
                };
                v.push(
                    json!({ "azimuth_deg": az, "elevation_deg": el, "feed_mm_min": f,
                               "pretravel_um": cal.pretravel_um(d) }),
                );
            }
        }
    }
    v
}

/// Speed slope of the pretravel at a mid-elevation direction, µm per mm/s.
fn speed_slope(c: &Calibration) -> f64 {
    let d = DirSpeed {
        t: 0.5f64.sqrt(),
        theta: 0.0,
        v: 1.0,
    };
    -c.structure.speed_part(&c.coef_mm, d) * 1000.0
}

/// One pose's JSON entry.
fn pose_json(p: &PoseCentre, group_columns: usize) -> Value {
    let d = p.displacement_um();
    json!({
        "group": &p.values[..group_columns], "touches": p.kept.len(), "outliers": p.outliers,
        "commanded_mm": p.commanded_mm, "center_mm": p.sphere.center_mm, "rms_um": p.sphere.rms_um,
        "dx_um": d.map(|d| d[0]), "dy_um": d.map(|d| d[1]), "dz_um": d.map(|d| d[2]),
    })
}

impl ProbeReport<'_> {
    /// The console summary of `fit probe` (two lines): touches, outliers, model, centre and stylus
    /// radius; fit RMS, repeatability and the diameter error before / after of `report` (the JSON
    /// result, [`ProbeReport::json`]).
    pub fn summary(&self, report: &Value) -> String {
        let res = self.result;
        let cal = &res.calibration;
        let de = &report["diameter_error_um"];
        let f = |v: &Value| v.as_f64().map_or("–".to_string(), |x| format!("{x:+.3}"));
        let mut s = String::new();
        let _ = writeln!(
            s,
            "fit probe: {} touches ({} outliers), model {}; centre [{:.4}, {:.4}, {:.4}] mm, stylus radius {:.4} mm",
            self.rows[1],
            res.outliers.len(),
            cal.structure.name(),
            cal.sphere_center_mm[0],
            cal.sphere_center_mm[1],
            cal.sphere_center_mm[2],
            cal.stylus_radius_mm
        );
        let _ = writeln!(
            s,
            "  fit RMS {:.3} µm; repeatability 2σ {}; diameter error on {}: before {} µm, after {} µm{}",
            cal.fit_rms_um,
            res.repeatability_2sigma_um
                .map_or("–".into(), |r| format!("{r:.3} µm")),
            self.evaluation.on,
            f(&de["before"]),
            f(&de["after"]),
            self.evaluation
                .holdout_rms_um
                .map_or(String::new(), |r| format!("; holdout RMS {:.3} µm", r[0]))
        );
        s
    }

    /// The JSON result.
    pub fn json(&self) -> Value {
        let mut v = self.calibration_json();
        if let (Some(m), Some(o)) = (self.machine, v.as_object_mut()) {
            o.insert("probe_frame".into(), json!({
                "machine": m,
                "definition": "each touch's position and approach taken into the probe's frame by the nominal kinematics of its pose before the calibration (made at the reference pose) corrects it; directions, pretravel and sphere_center_mm are in that frame, each pose's center_mm in the machine frame",
            }));
        }
        v
    }

    fn calibration_json(&self) -> Value {
        let res = self.result;
        let cal = &res.calibration;
        let ev = self.evaluation;
        let h = ev.holdout_rms_um;
        json!({
            "sphere_center_mm": cal.sphere_center_mm,
            "sphere_diameter_mm": self.sphere_diameter_mm,
            "stylus_radius_mm": cal.stylus_radius_mm,
            "pretravel": {
                "model": cal.structure.name(),
                "structure": cal.structure,
                "coefficients_mm": cal.coef_mm,
                "speed_um_per_mm_s": speed_slope(cal),
                "definition": "pretravel_um = (stylus_radius_mm − r_eff(n, v))·1000; direction = surface normal n = −approach (azimuth, elevation); v = feed_mm_min/60",
                "table": pretravel_table(cal),
                "cv": res.candidates,
                "chosen_why": res.why,
            },
            "repeatability_2sigma_um": res.repeatability_2sigma_um,
            "repeatability_note": if res.repeatability_2sigma_um.is_some() {
                "pooled standard deviation of the radial distance over repeated touches (same direction and speed) \
                 of the calibration rows, times 2"
            } else {
                "null: no repeated touches (same direction and speed) among the calibration rows; the data cannot \
                 determine the repeatability (held-out rows are not used for it)"
            },
            "repeat_groups": res.repeat_groups,
            "fit_rms_um": cal.fit_rms_um,
            "holdout_rms_um": h.map(|v| v[0]),
            "holdout_rms_before_um": h.map(|v| v[1]),
            "holdout_rms_reference_um": h.map(|v| v[2]),
            "diameter_error_um": {
                "before": ev.diameter_error_um(&ev.before),
                "after": ev.diameter_error_um(cal),
                "reference_bilinear": ev.diameter_error_um(&res.reference),
                "plain_one_radius": ev.diameter_error_um(&res.plain),
                "on": ev.on,
                "artefact_diameter_mm": ev.diameter_mm,
                "before_method": ev.before_method,
            },
            "outliers": res.outliers,
            "holdout_outliers": ev.flagged.iter().map(|(row, e)| json!({ "row": row, "residual_um": e })).collect::<Vec<_>>(),
            "fit": {
                "algebraic": sphere_json(&res.algebraic),
                "geometric_free_radius": sphere_json(&res.geometric_free),
                "reference_bilinear_fit_rms_um": res.reference.fit_rms_um,
                "plain_fit_rms_um": res.plain.fit_rms_um,
            },
            "touches": self.rows[0],
            "calibration_touches": self.rows[1],
            "holdout_touches": self.rows[2],
            "shared_zero": self.shared.map(shared_zero_json),
            "groups": self.poses.iter().map(|p| pose_json(p, self.group_columns)).collect::<Vec<_>>(),
        })
    }

    /// The report folder's files (name, content): the figures and `report.md`; `report` is [`Self::json`].
    pub fn files(&self, report: &Value) -> Vec<(String, String)> {
        let (after, before) = self.residual_maps();
        let (dfig, rows_md) = self.diameter_by_speed(report);
        let md = self.markdown(report, &rows_md);
        vec![
            ("residual_map.svg".into(), after),
            ("residual_map_plain.svg".into(), before),
            ("pretravel_speed.svg".into(), self.pretravel_figure()),
            ("diameter_error.svg".into(), dfig),
            ("report.md".into(), md),
        ]
    }

    /// The calibration inliers, each with its index.
    fn inliers(&self) -> impl Iterator<Item = (usize, &Touch)> {
        let out: Vec<usize> = self.result.outliers.iter().map(|o| o.index).collect();
        self.calibration_touches
            .iter()
            .enumerate()
            .filter(move |(i, _)| !out.contains(i))
    }

    /// Radial residual over the sphere (azimuth on x, one series per elevation ring): after correction, and
    /// with one effective radius (the plain method).
    fn residual_maps(&self) -> (String, String) {
        let res = self.result;
        let cal = &res.calibration;
        // Per elevation ring (0.1°): azimuths, residuals after, residuals with one radius.
        type Ring = (Vec<f64>, Vec<f64>, Vec<f64>);
        let mut rings: BTreeMap<i64, Ring> = BTreeMap::new();
        let radius = cal.sphere_diameter_mm / 2.0;
        let plain_c = res.plain.sphere_center_mm;
        for (i, t) in self.inliers() {
            let d = t.dir_speed();
            let e = rings
                .entry((d.elevation_deg() * 10.0).round() as i64)
                .or_default();
            e.0.push(d.azimuth_deg());
            e.1.push(res.residual_um[i]);
            let dist = (0..3)
                .map(|k| (t.position_mm[k] - plain_c[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            e.2.push((dist - radius - res.plain.effective_radius_mm(t)) * 1000.0);
        }
        let mut after = Figure::new(
            &format!(
                "Radial residual of each touch over the sphere after correction (chosen model: {}), one series per elevation ring",
                cal.structure.name()
            ),
            &axcomp_plot::label("azimuth of the surface normal", "°"),
            &axcomp_plot::label("radial residual", "µm"),
        );
        let mut before = Figure::new(
            "Radial residual of each touch over the sphere with one effective radius (plain method), one series per elevation ring",
            &axcomp_plot::label("azimuth of the surface normal", "°"),
            &axcomp_plot::label("radial residual", "µm"),
        );
        for (el, (az, r_after, r_plain)) in &rings {
            let name = format!("elevation {:.1}°", *el as f64 / 10.0);
            after.points(&name, az, r_after);
            before.points(&name, az, r_plain);
        }
        after.hline(0.0, "");
        before.hline(0.0, "");
        (after.to_svg(), before.to_svg())
    }

    /// Pretravel versus speed: measured (stylus radius − |p − C| + R) per touch, and the model averaged over
    /// the same touches' directions, one colour per elevation ring of the surface normal.
    fn pretravel_figure(&self) -> String {
        let cal = &self.result.calibration;
        let radius = cal.sphere_diameter_mm / 2.0;
        let c = cal.sphere_center_mm;
        let mut classes: BTreeMap<i64, Vec<&Touch>> = BTreeMap::new();
        for (_, t) in self.inliers() {
            classes
                .entry((t.dir_speed().elevation_deg() * 10.0).round() as i64)
                .or_default()
                .push(t);
        }
        let fmax = cal.feed_range_mm_min[1].max(1.0) * 1.5;
        let feeds: Vec<f64> = (0..=20).map(|k| fmax * k as f64 / 20.0).collect();
        let mut pv = Figure::new(
            &format!(
                "Pretravel of each touch vs probing speed, by approach elevation, and the calibrated model ({}), fit RMS {:.2} µm",
                cal.structure.name(),
                cal.fit_rms_um
            ),
            &axcomp_plot::label("feed", "mm/min"),
            &axcomp_plot::label("pretravel", "µm"),
        );
        for (el, ts) in &classes {
            let (fx, fy): (Vec<f64>, Vec<f64>) = ts
                .iter()
                .map(|t| {
                    let dist = (0..3)
                        .map(|k| (t.position_mm[k] - c[k]).powi(2))
                        .sum::<f64>()
                        .sqrt();
                    (
                        t.feed_mm_min,
                        (cal.stylus_radius_mm - (dist - radius)) * 1000.0,
                    )
                })
                .unzip();
            let model: Vec<f64> = feeds
                .iter()
                .map(|f| {
                    let sum: f64 = ts
                        .iter()
                        .map(|t| {
                            let mut d = t.dir_speed();
                            d.v = f / 60.0;
                            cal.pretravel_um(d)
                        })
                        .sum();
                    sum / ts.len() as f64
                })
                .collect();
            let name = format!(
                "elevation {}°",
                axcomp_plot::style::fmt_fixed(*el as f64 / 10.0, 1)
            );
            pv.points(&format!("touches, {name}"), &fx, &fy);
            pv.dashed(&format!("model, {name}"), &feeds, &model)
                .like_previous();
        }
        pv.to_svg()
    }

    /// Diameter error by speed on the evaluation rows (before, reference, after): the figure and the
    /// markdown table's rows.
    fn diameter_by_speed(&self, report: &Value) -> (String, Vec<Vec<String>>) {
        let res = self.result;
        let cal = &res.calibration;
        let ev = self.evaluation;
        let mut speeds: Vec<f64> = ev.touches.iter().map(|t| t.feed_mm_min).collect();
        speeds.sort_by(f64::total_cmp);
        speeds.dedup();
        let mut dfig = Figure::new(
            "",
            &axcomp_plot::label("feed", "mm/min"),
            &axcomp_plot::label("diameter error", "µm"),
        );
        let mut rows_md = Vec::new();
        let mut series: [(String, Vec<f64>); 3] = [
            ("before".into(), Vec::new()),
            ("bilinear reference".into(), Vec::new()),
            ("after".into(), Vec::new()),
        ];
        let mut xs = Vec::new();
        for &f in &speeds {
            let ts: Vec<Touch> = ev
                .touches
                .iter()
                .copied()
                .filter(|t| t.feed_mm_min == f)
                .collect();
            let vals: Vec<Option<f64>> = [&ev.before, &res.reference, cal]
                .iter()
                .map(|c| {
                    measured_diameter_mm(&ts, |t| c.effective_radius_mm(t))
                        .ok()
                        .map(|s| (2.0 * s.radius_mm - ev.diameter_mm) * 1000.0)
                })
                .collect();
            if let [Some(a), Some(b), Some(c)] = vals[..] {
                xs.push(f);
                for (k, v) in [a, b, c].into_iter().enumerate() {
                    series[k].1.push(v);
                }
                rows_md.push(vec![
                    format!("{f}"),
                    format!("{}", ts.len()),
                    format!("{a:+.3}"),
                    format!("{b:+.3}"),
                    format!("{c:+.3}"),
                ]);
            }
        }
        for (name, ys) in &series {
            dfig.line(name, &xs, ys);
        }
        let worst = |k: usize| series[k].1.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        dfig.set_title(&format!(
            "Diameter error of the {} evaluation touches ({}) by probing speed: worst |error| {:.2} µm before, {:.2} µm after the chosen model ({})",
            ev.touches.len(),
            report["diameter_error_um"]["on"].as_str().unwrap_or("?"),
            worst(0),
            worst(2),
            cal.structure.name()
        ));
        dfig.hline(0.0, "");
        (dfig.to_svg(), rows_md)
    }

    /// `report.md`.
    fn markdown(&self, report: &Value, rows_md: &[Vec<String>]) -> String {
        let res = self.result;
        let cal = &res.calibration;
        let de = &report["diameter_error_um"];
        let num = |v: &Value| v.as_f64().map_or("–".to_string(), |x| format!("{x:+.3}"));
        let mut md = String::new();
        let _ = writeln!(md, "# Probe calibration\n");
        let _ = writeln!(
            md,
            "Sphere centre [{:.4}, {:.4}, {:.4}] mm, Ø{} mm; stylus (effective) radius {:.4} mm at zero speed.\n",
            cal.sphere_center_mm[0],
            cal.sphere_center_mm[1],
            cal.sphere_center_mm[2],
            cal.sphere_diameter_mm,
            cal.stylus_radius_mm
        );
        if let Some(m) = self.machine {
            let _ = writeln!(
                md,
                "Directions in the probe's frame (--machine {m}): each touch turned by its pose's nominal \
                 kinematics before the correction; each pose's centre turned back into the machine frame.\n"
            );
        }
        let _ = writeln!(md, "Model: **{}** — {}.\n", cal.structure.name(), res.why);
        let cand: Vec<Vec<String>> = res
            .candidates
            .iter()
            .map(|c| {
                vec![
                    c.model.clone(),
                    c.coefficients.to_string(),
                    format!("{:.3}", c.cv_rms_um),
                ]
            })
            .collect();
        let _ = writeln!(
            md,
            "{}",
            markdown_table(&["candidate", "coefficients", "CV RMS / µm"], &cand)
        );
        let _ = writeln!(
            md,
            "\nFit RMS {:.3} µm; repeatability 2σ {}; {} outliers (listed in the JSON).\n",
            cal.fit_rms_um,
            res.repeatability_2sigma_um
                .map_or("– (no repeated touches)".into(), |r| format!("{r:.3} µm")),
            res.outliers.len()
        );
        let _ = writeln!(
            md,
            "## Diameter error (on the {} rows, Ø{} mm)\n",
            de["on"].as_str().unwrap_or(""),
            self.evaluation.diameter_mm
        );
        let _ = writeln!(
            md,
            "{}",
            markdown_table(
                &[
                    "before",
                    "bilinear reference",
                    "plain (one radius)",
                    "after"
                ],
                &[vec![
                    num(&de["before"]),
                    num(&de["reference_bilinear"]),
                    num(&de["plain_one_radius"]),
                    num(&de["after"]),
                ]]
            )
        );
        let _ = writeln!(
            md,
            "\n\"before\" = {}.\n",
            de["before_method"].as_str().unwrap_or("")
        );
        let _ = writeln!(
            md,
            "{}",
            markdown_table(
                &[
                    "feed / mm/min",
                    "touches",
                    "before / µm",
                    "bilinear / µm",
                    "after / µm"
                ],
                rows_md
            )
        );
        let _ = writeln!(
            md,
            "\n![diameter error](diameter_error.svg)\n\n## Radial residual over the sphere\n\nEach point is a touch at \
             the azimuth of its surface normal, one series per elevation ring.\n\n![after](residual_map.svg)\n\n\
             ![plain](residual_map_plain.svg)\n\n## Pretravel versus speed\n\n![pretravel](pretravel_speed.svg)"
        );
        md
    }
}
