//! Throughput of the measurement CSV reader: prints rows/s and MB/s (no assertion; a figure to read).
//!
//! Run: `cargo bench -p axcomp-data`. Inputs: a synthetic ISO 230-2 style file (200 000 rows, 9 columns,
//! quoted text cells, `#` comments) built in memory, and the real ESS file from `../shared` when present.

use std::path::Path;
use std::time::Instant;

use axcomp_data::{Dataset, LoadOptions, shared_dir};

fn synthetic(rows: usize) -> String {
    let mut s = String::from("# synthetic campaign\n# axis X\n");
    s.push_str("target_mm,run,direction,deviation_um,time_s,motor_degC,scale_degC,force_N,note\n");
    for i in 0..rows {
        let x = (i % 21) as f64 * 10.0;
        s.push_str(&format!(
            "{x},{},{},{:.4},{:.3},{:.3},{:.3},{:.2},\"cell {i}, quoted\"\n",
            i / 42 + 1,
            if (i / 21) % 2 == 0 { "+" } else { "-" },
            (x * 0.1).sin() * 5.0,
            i as f64 * 0.5,
            20.0 + (i as f64 * 1e-4).sin(),
            21.0 + (i as f64 * 2e-4).cos(),
            (i % 100) as f64 * 0.5,
        ));
    }
    s
}

fn measure(name: &str, text: &str, opts: &LoadOptions, repeats: usize) {
    // Warm-up, then the best of `repeats` runs.
    let ds = Dataset::from_csv_str(name, text, opts).expect("parses");
    let kept = ds.n_rows();
    // Input data rows: lines that are neither blank, `#` comments nor the header.
    let rows = text
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .count()
        - 1;
    let mut best = f64::INFINITY;
    for _ in 0..repeats {
        let t = Instant::now();
        let ds = Dataset::from_csv_str(name, text, opts).expect("parses");
        std::hint::black_box(ds.numeric("target_mm").ok());
        best = best.min(t.elapsed().as_secs_f64());
    }
    println!(
        "{name}: {rows} rows ({kept} kept), {:.2} MB in {:.2} ms (best of {repeats}) = {:.2} M rows/s, {:.1} MB/s",
        text.len() as f64 / 1e6,
        best * 1e3,
        rows as f64 / best / 1e6,
        text.len() as f64 / best / 1e6
    );
}

fn main() {
    let text = synthetic(200_000);
    measure("synthetic 200k rows", &text, &LoadOptions::default(), 5);
    let filtered = LoadOptions::from_args(
        &["run=7".into()],
        &["force_N=load_N".into()],
        &["deviation_um=0.001".into()],
    )
    .expect("options");
    measure(
        "synthetic 200k rows with --rename/--scale/--where",
        &text,
        &filtered,
        5,
    );
    let root = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../../.."));
    match shared_dir(root) {
        Some(sh) => {
            let p = sh.join("data/real/ess-linear-axes-iso230/tidy/iso230_2_runs_long.csv");
            let text = std::fs::read_to_string(&p).expect("ESS file");
            measure(
                "ESS iso230_2_runs_long.csv",
                &text,
                &LoadOptions::default(),
                50,
            );
        }
        None => println!("skipped: ../shared not found"),
    }
}
