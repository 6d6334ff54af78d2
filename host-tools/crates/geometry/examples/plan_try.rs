use axcomp_geometry::plan::{PlanOptions, plan};
use axcomp_kinematics::Topology;
fn main() {
    let t = std::time::Instant::now();
    let p = plan(&PlanOptions {
        stroke_mm: [800.0, 600.0, 500.0],
        max_lines: None,
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
    println!(
        "{:.2}s {} lines complete {} {:?}",
        t.elapsed().as_secs_f64(),
        p.lines.len(),
        p.complete,
        p.not_identifiable
    );
    for l in &p.lines {
        println!(
            "{} {:?}->{:?} step {} tool {:?}",
            l.name, l.start, l.end, l.stepwise, l.tool
        );
    }
    for u in &p.uncertainty {
        println!("{:?}", u);
    }
}
