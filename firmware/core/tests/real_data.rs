//! Real ISO 230-2 data through the whole core: table image, load, direction detection, sign.
//!
//! Data: `../shared/data/real/ess-linear-axes-iso230/tidy/iso230_2_runs_long.csv`, test
//! `ESS_TDU_B02_X_2022-04-06` (9 targets −20…20 mm, 5 cycles, both directions; see its
//! PROVENANCE.md). Override the shared directory with `AXCOMP_SHARED`.

mod common;
use axcomp_core::*;
use common::*;
use std::collections::BTreeMap;
use std::path::PathBuf;

fn shared_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("AXCOMP_SHARED") {
        Some(d) => PathBuf::from(d),
        None => PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../..")).join("../shared"),
    };
    if dir.is_dir() {
        Some(dir)
    } else if std::env::var_os("CI").is_some() {
        panic!("../shared not found at {} (CI is set)", dir.display());
    } else {
        println!("skipped: ../shared not found");
        None
    }
}

/// Split one CSV line, honouring double quotes.
fn split_csv(line: &str) -> Vec<String> {
    let mut out = vec![String::new()];
    let mut quoted = false;
    for ch in line.chars() {
        match ch {
            '"' => quoted = !quoted,
            ',' if !quoted => out.push(String::new()),
            _ => out.last_mut().unwrap().push(ch),
        }
    }
    out
}

#[test]
fn iso230_b02_x_table_reproduces_the_measured_means() {
    let Some(shared) = shared_dir() else { return };
    let path = shared.join("data/real/ess-linear-axes-iso230/tidy/iso230_2_runs_long.csv");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header = split_csv(lines.next().expect("header"));
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("{}: no column {name}", path.display()))
    };
    let (c_id, c_t, c_dir, c_dev) = (
        col("test_id"),
        col("target_mm"),
        col("approach_direction"),
        col("deviation_um"),
    );
    // (target in µm as integer, positive?) -> measured deviations
    let mut points: BTreeMap<(i64, bool), Vec<f64>> = BTreeMap::new();
    for (k, line) in lines.enumerate() {
        let f = split_csv(line);
        if f[c_id] != "ESS_TDU_B02_X_2022-04-06" {
            continue;
        }
        let num = |c: usize| -> f64 {
            f[c].parse().unwrap_or_else(|_| {
                panic!("{}: line {}: bad number {:?}", path.display(), k + 2, f[c])
            })
        };
        let target_um = (num(c_t) * 1000.0).round() as i64;
        let positive = f[c_dir] == "positive";
        points
            .entry((target_um, positive))
            .or_default()
            .push(num(c_dev));
    }
    let targets: Vec<i64> = points.keys().filter(|k| k.1).map(|k| k.0).collect();
    assert_eq!(targets.len(), 9, "B02 X has 9 targets");
    let step = targets[1] - targets[0];
    assert!(
        targets.windows(2).all(|w| w[1] - w[0] == step),
        "uniform targets"
    );

    // Mean deviation per target and direction; natural splines through them (f64 reference).
    let mean = |t: i64, pos: bool| {
        let v = &points[&(t, pos)];
        v.iter().sum::<f64>() / v.len() as f64
    };
    let fwd_y: Vec<f64> = targets.iter().map(|&t| mean(t, true)).collect();
    let bwd_y: Vec<f64> = targets.iter().map(|&t| mean(t, false)).collect();
    let fwd = to_f32(&natural_spline(&fwd_y));
    let bwd = to_f32(&natural_spline(&bwd_y));
    let upc = 0.1f32; // 0.1 µm per count
    let to_counts = |um: i64| um * 10;
    let spec = ImageSpec {
        axis_id: 1,
        um_per_count: upc,
        counter_bits: 32,
        table: Some(TableSpec {
            start_counts: to_counts(targets[0]),
            segment_counts: to_counts(step) as u32,
            forward: &fwd,
            backward: &bwd,
            outside: OutsideStroke::Hold,
        }),
        thermo: None,
        limits: LimitSpec {
            max_correction_um: 1000.0,
            max_slew_um_per_cycle: 1000.0,
            direction_hysteresis_counts: 50,
        },
    };
    let comp = load(&spec);

    // Replay the ISO 230-2 cycle: each target approached from 500 counts (50 µm) before it,
    // upwards in the positive run, downwards in the negative run.
    let mut st = State::new();
    let (mut raw_sq, mut res_sq, mut n) = (0.0f64, 0.0f64, 0usize);
    let mut max_table_err = 0.0f64;
    for positive in [true, false] {
        let order: Vec<i64> = if positive {
            targets.clone()
        } else {
            targets.iter().rev().copied().collect()
        };
        for &t in &order {
            let x = to_counts(t);
            let pre = if positive { x - 500 } else { x + 500 };
            comp.cycle(&mut st, &input(pre as u32, pre));
            let o = comp.cycle(&mut st, &input(x as u32, x));
            assert_eq!(
                st.direction(),
                if positive {
                    Direction::Forward
                } else {
                    Direction::Backward
                }
            );
            // Reference: the measured mean; tolerance 1e-3 µm (f32 on values ≤ 100 µm).
            let want = mean(t, positive);
            max_table_err = max_table_err.max((o.correction_um as f64 - want).abs());
            assert!(
                (o.correction_um as f64 - want).abs() < 1e-3,
                "target {t} µm {}: {} vs {want}",
                if positive { "+" } else { "-" },
                o.correction_um
            );
            // Sign: the deviation is subtracted from the command.
            assert_eq!(o.corrected_command_counts, x - (want / 0.1).round() as i64);
            for d in &points[&(t, positive)] {
                raw_sq += d * d;
                res_sq += (d - o.correction_um as f64).powi(2);
                n += 1;
            }
        }
    }
    let (raw, res) = ((raw_sq / n as f64).sqrt(), (res_sq / n as f64).sqrt());
    println!(
        "B02 X in-sample: raw RMS {raw:.2} µm, after table {res:.2} µm, max table error {max_table_err:.2e} µm ({n} points)"
    );
    assert!(res < raw, "compensation must reduce the in-sample RMS");
}
