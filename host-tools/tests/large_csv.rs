//! A large campaign through `axcomp fit positioning`: 2,222 bidirectional cycles of
//! 1,000 targets (4.4 M rows, ~158 MB). Peak memory ≤ 4× the file, at most 20 grouped CV folds stated in
//! the JSON, progress on stderr, SVGs of at most a few MB. Slow in a debug build (minutes), so ignored by
//! default; run it with
//!
//!     cargo test --release -p axcomp --test large_csv -- --ignored --nocapture
//!
//! Peak memory is the child's `VmHWM` (Linux `/proc`), polled every 20 ms while it runs.

use std::io::Write as _;
use std::process::{Command, Stdio};

mod common;
use common::{read_json, scratch};

#[test]
#[ignore]
fn a_2222_cycle_campaign_in_bounded_memory() {
    let dir = scratch("large");
    let csv = dir.join("big.csv");
    {
        let mut f = std::io::BufWriter::new(std::fs::File::create(&csv).unwrap());
        writeln!(f, "target_mm,run,direction,deviation_um,time_s,motor_degC").unwrap();
        let mut state: u64 = 1;
        let mut t = 0.0f64;
        for run in 1..=2222 {
            for sign in [1.0f64, -1.0] {
                for k in 0..1000 {
                    let k = if sign > 0.0 { k } else { 999 - k };
                    let x = 0.4 * k as f64;
                    state = state
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let u = ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64;
                    let y =
                        15.0 * (x / 47.0).sin() + 5.0 * (x / 13.0).sin() + 2.0 * sign + (u - 0.5);
                    t += 0.05;
                    writeln!(
                        f,
                        "{x:.1},{run},{},{y:.3},{t:.2},{:.3}",
                        if sign > 0.0 { "+" } else { "-" },
                        20.0 + 3.0 * (1.0 - (-t / 3000.0).exp())
                    )
                    .unwrap();
                }
            }
        }
    }
    let size = std::fs::metadata(&csv).unwrap().len();
    let (json, report) = (dir.join("j.json"), dir.join("rep"));
    let mut child = Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(["fit", "positioning", "--data"])
        .arg(&csv)
        .arg("--json")
        .arg(&json)
        .arg("--report")
        .arg(&report)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let status_path = format!("/proc/{}/status", child.id());
    let mut peak_kb = 0u64;
    let started = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if let Ok(s) = std::fs::read_to_string(&status_path) {
            if let Some(kb) = s
                .lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            {
                peak_kb = peak_kb.max(kb);
            }
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    let peak = peak_kb as f64 * 1024.0;
    println!(
        "{:.0} MB file: {:.1} s, peak {:.0} MB = {:.2}× the file\n{stderr}",
        size as f64 / 1e6,
        started.elapsed().as_secs_f64(),
        peak / 1e6,
        peak / size as f64
    );
    assert!(peak <= 4.0 * size as f64, "peak {peak} B > 4 × {size} B");
    assert!(stderr.contains("read 4444000 rows") && stderr.contains("cross-validated in 20 folds"));
    let j = read_json(&json);
    assert_eq!(j["cv"]["folds"], 20);
    assert_eq!(j["cv"]["grouped"], true);
    for f in ["positioning.svg", "residual.svg"] {
        let n = std::fs::metadata(report.join(f)).unwrap().len();
        println!("{f}: {n} bytes");
        assert!(n < 3_000_000, "{f}: {n} bytes");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
