use axcomp_kinematics::rotary::{FiveAxis, MachineKind};
use axcomp_rtest::plan::{PlanGeometry, plan};
fn main() {
    for kind in [
        MachineKind::AcTrunnion,
        MachineKind::BcTrunnion,
        MachineKind::BcHead,
    ] {
        for free in [false, true] {
            let mut g = PlanGeometry::default_for(FiveAxis::new(kind, 250.0));
            g.free_head_zero = free;
            let p = plan(&g, 0.3);
            println!("{} free_head {free}", kind.name());
            for c in &p.candidates {
                println!(
                    "  {:?} poses {} rank {} cond {:.1} not {:?}",
                    c.paths, c.poses, c.rank, c.condition_number, c.not_identified
                );
                println!(
                    "     {:?}",
                    c.std
                        .iter()
                        .map(|(n, s)| format!("{n}:{:.2}", s.unwrap_or(f64::NAN)))
                        .collect::<Vec<_>>()
                );
            }
        }
    }
}
