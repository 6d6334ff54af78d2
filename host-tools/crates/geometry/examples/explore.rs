use axcomp_data::{Dataset, LoadOptions};
use axcomp_geometry::{FitOptions, Judge, LineData, Method, analyse};
use axcomp_kinematics::{Component, Topology};
use axcomp_twin::geometry::{GeometryTwin, plan_by_name};

fn main() {
    let plan = std::env::args().nth(1).unwrap_or("complete".into());
    let seed: u64 = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(1);
    let twin = GeometryTwin::random([800.0, 600.0, 500.0], Topology::default(), seed);
    let lines = plan_by_name(&plan, twin.stroke_mm, 21).unwrap();
    let camp = twin.measure(&lines, 2, 5);
    let ds = Dataset::from_csv_str("twin", &camp.to_csv_string(), &LoadOptions::default()).unwrap();
    let data = LineData::from_dataset(&ds, true).unwrap();
    for m in [Method::Auto, Method::Plain, Method::SevenLine] {
        let t = std::time::Instant::now();
        let a = analyse(
            &data,
            &Judge::None,
            &FitOptions {
                method: m,
                ..Default::default()
            },
        )
        .unwrap();
        println!(
            "{:?}: {:.3}s fit_rms {:.3} rank {} / {} cond {:.1} ns {:?} λcv {:?}",
            m,
            t.elapsed().as_secs_f64(),
            a.report.fit_rms_um,
            a.report.identifiability.rank,
            a.report.identifiability.parameters,
            a.report.identifiability.condition_number,
            a.report.identifiability.not_separable,
            a.report.model.lambda_cv_rms_um
        );
        for c in Component::ALL {
            let mc = &a.fit.model.components[c.index()];
            let (mut se, mut z2, mut k) = (0.0, 0.0, 0);
            for [q, u] in mc.uncertainty.iter().filter(|x| x[1] > 1e-6) {
                let e = a.fit.model.component_value(c, *q) - twin.component(c, *q);
                se += e * e;
                z2 += if *u > 0.0 { (e / u).powi(2) } else { 0.0 };
                k += 1;
            }
            print!(
                "{} {} err {:.2} z {:.2} | ",
                c.name(),
                mc.identified as u8,
                (se / k as f64).sqrt(),
                (z2 / k as f64).sqrt()
            );
        }
        println!();
    }
}
#[allow(dead_code)]
fn unused() {}
