//! Bad laser line input: a clear error naming the line (or cell), or `identified: false` with the reason;
//! never a panic or a silent zero.

use axcomp_data::{Dataset, LoadOptions};
use axcomp_geometry::{FitOptions, Judge, LineData, analyse};
use axcomp_kinematics::Topology;
use axcomp_twin::geometry::{GeometryTwin, plan_by_name};

const HEADER: &str = "x_mm,y_mm,z_mm,line,deviation_um,beam_x,beam_y,beam_z\n";

fn parse(text: &str) -> Result<LineData, String> {
    let ds = Dataset::from_csv_str("lines.csv", text, &LoadOptions::default())
        .map_err(|e| e.to_string())?;
    LineData::from_dataset(&ds, true).map_err(|e| e.to_string())
}

fn x_line(name: &str, n: usize, beam: &str) -> String {
    (0..n)
        .map(|i| {
            format!(
                "{},0,0,{name},{:.2},{beam}\n",
                i as f64 * 100.0,
                i as f64 * 0.1
            )
        })
        .collect()
}

#[test]
fn line_with_fewer_than_three_targets_is_named() {
    let text = format!(
        "{HEADER}{}{}",
        x_line("A", 5, "1,0,0"),
        x_line("B", 2, "1,0,0")
    );
    let e = parse(&text).unwrap_err();
    assert!(
        e.contains("line B") && e.contains("2 distinct targets"),
        "{e}"
    );
}

#[test]
fn beam_not_a_unit_vector_is_named() {
    let text = format!("{HEADER}{}", x_line("A", 5, "0.9,0,0"));
    let e = parse(&text).unwrap_err();
    assert!(
        e.contains("line A") && e.contains("lines.csv:2") && e.contains("not a unit vector"),
        "{e}"
    );
}

/// A row's beam is taken as given, whatever the line's direction (contract: rows whose beam is given are
/// judged along it): a straightness reading across an X line (beam +Y), and points each read along its
/// own beam from a station (a tracking interferometer). Before: "the beam is 90° off the line's
/// direction".
#[test]
fn a_beam_across_the_line_or_per_point_is_taken_as_given() {
    let text = format!("{HEADER}{}", x_line("A", 5, "0,1,0"));
    let d = parse(&text).unwrap();
    assert!(d.readings.iter().all(|r| r.beam == [0.0, 1.0, 0.0]));
    // Five points, each with the unit beam from a station at (0, -500, 0) (exact to 1e-12).
    let mut text = String::from(HEADER);
    for i in 0..5 {
        let p = [100.0 * i as f64, 50.0, 20.0];
        let v = [p[0], p[1] + 500.0, p[2]];
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        text += &format!(
            "{},{},{},P,{:.2},{},{},{}\n",
            p[0],
            p[1],
            p[2],
            0.1 * i as f64,
            v[0] / n,
            v[1] / n,
            v[2] / n
        );
    }
    let d = parse(&text).unwrap();
    for (i, r) in d.readings.iter().enumerate() {
        let v = [100.0 * i as f64, 550.0, 20.0];
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        for k in 0..3 {
            assert!(
                (r.beam[k] - v[k] / n).abs() < 1e-12,
                "row {i}: {:?}",
                r.beam
            );
        }
    }
}

#[test]
fn nan_and_empty_cells_are_named() {
    let mut text = format!("{HEADER}{}", x_line("A", 5, "1,0,0"));
    text = text.replacen("0.20", "NaN", 1);
    let e = parse(&text).unwrap_err();
    assert!(
        e.contains("lines.csv:4") && e.contains("deviation_um"),
        "{e}"
    );
    let text = format!("{HEADER}{}", x_line("A", 5, "1,0,0")).replacen(",0.30,", ",,", 1);
    let e = parse(&text).unwrap_err();
    assert!(e.contains("deviation_um"), "{e}");
}

#[test]
fn missing_beam_is_taken_from_the_line() {
    let text: String = format!(
        "x_mm,y_mm,z_mm,line,deviation_um\n{}",
        (0..5)
            .map(|i| format!("0,{},0,Y1,0.1\n", i * 50))
            .collect::<String>()
    );
    let d = parse(&text).unwrap();
    assert_eq!(d.readings[0].beam, [0.0, 1.0, 0.0]);
}

/// A rank-deficient set (axis lines only, no offsets): what cannot be separated is reported
/// `identified: false` with its reason, fixed at 0, and listed in `not_separable`; nothing is invented.
#[test]
fn rank_deficient_set_reports_what_it_cannot_identify() {
    let stroke = [500.0, 400.0, 300.0];
    let twin = GeometryTwin::random(stroke, Topology::default(), 4);
    // X, Y, Z lines through the origin only
    let lines: Vec<_> = plan_by_name("axis-lines", stroke, 9)
        .unwrap()
        .into_iter()
        .filter(|l| l.name.ends_with('1'))
        .collect();
    assert_eq!(lines.len(), 3);
    let camp = twin.measure(&lines, 1, 3);
    let ds =
        Dataset::from_csv_str("axes.csv", &camp.to_csv_string(), &LoadOptions::default()).unwrap();
    let data = LineData::from_dataset(&ds, true).unwrap();
    let an = analyse(&data, &Judge::None, &FitOptions::default()).unwrap();
    let mut identified = Vec::new();
    for (name, e) in &an.report.errors {
        if e.identified {
            identified.push(name.clone());
        } else {
            assert!(!e.reason.is_empty(), "{name}");
            if let Some(s) = &e.samples {
                assert!(
                    s.iter().all(|[_, v]| *v == 0.0),
                    "{name} not identified but not 0"
                );
            }
        }
    }
    identified.sort();
    // axis lines through the origin see only the three positioning errors
    assert_eq!(identified, vec!["EXX", "EYY", "EZZ"]);
    assert!(
        an.report.errors["EBX"]
            .reason
            .contains("no reading is sensitive")
    );
    assert!(!an.report.identifiability.not_separable.is_empty());
}
