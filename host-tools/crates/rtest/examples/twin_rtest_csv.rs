//! Writes a five-axis twin R-test campaign (K4 run 1, C circles at 0° and −60°, K4 run 2) as contract CSV
//! and the truth as JSON: `cargo run -p axcomp-rtest --example twin_rtest_csv -- OUT.csv [SEED] [MACHINE]`.
use axcomp_kinematics::rotary::{FiveAxis, MachineKind};
use axcomp_twin::five_axis::{FiveAxisTwin, standard_paths};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let out = args.get(1).cloned().unwrap_or_else(|| "rtest.csv".into());
    let seed: u64 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1);
    let kind = args
        .get(3)
        .and_then(|s| MachineKind::parse(s))
        .unwrap_or(MachineKind::AcTrunnion);
    let m = FiveAxis::new(kind, 250.0);
    let mut twin = FiveAxisTwin::random(m, seed);
    for e in args.iter().skip(4) {
        assert!(twin.effects.enable(e), "unknown effect {e}");
    }
    let sphere = if kind == MachineKind::BcHead {
        [0.0, 0.0, 0.0]
    } else {
        [150.0, 0.0, 100.0]
    };
    let paths = standard_paths(&m, sphere, -60.0, 72, &[0.0, -60.0], 36, None);
    let c = twin.measure(&paths, seed);
    std::fs::write(&out, c.to_csv_string()).expect("write csv");
    println!(
        "truth {:?} location {:?}",
        m.kind.location_names(),
        twin.location
    );
    println!("setup {:?}", twin.setup_offsets_um[0]);
}
