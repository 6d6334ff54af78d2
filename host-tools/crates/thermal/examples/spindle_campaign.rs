//! Writes the twin spindle campaign (nine speeds + a variable-speed block, 16 sensors, 5 channels) as CSV:
//! `cargo run --release -p axcomp-thermal --example spindle_campaign OUT.csv [SEED]`.

fn main() {
    let mut args = std::env::args().skip(1);
    let out = args.next().expect("usage: spindle_campaign OUT.csv [SEED]");
    let seed: u64 = args.next().and_then(|s| s.parse().ok()).unwrap_or(1);
    let c = axcomp_twin::synth::spindle_campaign(seed, 60.0);
    std::fs::write(&out, c.to_csv()).expect("write the CSV");
    println!(
        "{} rows, {} channels → {out}",
        c.data.time_s.len(),
        c.channels.len()
    );
}
