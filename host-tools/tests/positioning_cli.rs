//! End-to-end tests of `axcomp fit positioning` through the built binary: the figures the issue asks for
//! (real ESS runs, the do-no-harm guard on the MUTS runs, synthetic data with known truth), JSON fields
//! per the contract, and bad input. Real data is read from `../shared` (override: `AXCOMP_SHARED`); when
//! it is absent these tests print `skipped: ../shared not found` and return, except under `CI`.

use std::path::Path;
use std::process::Command;

use serde_json::Value;

mod common;
use common::{read_json, scratch, shared};

const ESS_CSV: &str = "data/real/ess-linear-axes-iso230/tidy/iso230_2_runs_long.csv";
const B02: &str = "ESS_TDU_B02_X_2022-04-06";

struct Run {
    code: i32,
    stdout: String,
    stderr: String,
}

fn axcomp(args: &[&str]) -> Run {
    let out = Command::new(env!("CARGO_BIN_EXE_axcomp"))
        .args(args)
        .output()
        .expect("run axcomp");
    Run {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn num(j: &Value, key: &str) -> f64 {
    j[key]
        .as_f64()
        .unwrap_or_else(|| panic!("JSON field {key} missing or not a number: {j}"))
}

/// The contract's ISO 230-2 fields are present: a finite number, or (issue 14: figures the judged runs
/// cannot define, e.g. A and R of single-run CV folds, are no longer invented) `null` with a reason.
/// Before is always fully defined on these bidirectional multi-run campaigns.
fn check_iso(j: &Value) {
    for part in ["iso230_2_before", "iso230_2_after"] {
        for k in ["A_um", "E_um", "M_um", "R_um", "B_um"] {
            let v = &j[part][k];
            let ok = v.as_f64().is_some_and(f64::is_finite)
                || (part == "iso230_2_after"
                    && v.is_null()
                    && j[part]["null_reasons"][k]
                        .as_str()
                        .is_some_and(|r| !r.is_empty()));
            assert!(ok, "{part}.{k} missing: {}", j[part]);
        }
    }
}

/// Reference for B02: leave-one-cycle-out RMS of the per-(target, direction) mean of the other cycles,
/// computed here directly from the CSV, independent of the crate's code.
fn loo_of_means(csv: &Path, test_id: &str) -> (f64, f64) {
    let text = std::fs::read_to_string(csv).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |n: &str| header.iter().position(|h| *h == n).unwrap();
    let (ci, ct, cc, cd, cv) = (
        col("test_id"),
        col("target_mm"),
        col("cycle"),
        col("approach_direction"),
        col("deviation_um"),
    );
    let mut rows = Vec::new();
    for l in lines {
        // Quoted fields contain commas: split on commas outside quotes.
        let mut f = Vec::new();
        let (mut cur, mut q) = (String::new(), false);
        for ch in l.chars() {
            match ch {
                '"' => q = !q,
                ',' if !q => f.push(std::mem::take(&mut cur)),
                c => cur.push(c),
            }
        }
        f.push(cur);
        if f[ci] == test_id {
            rows.push((
                f[ct].clone(),
                f[cc].clone(),
                f[cd].clone(),
                f[cv].parse::<f64>().unwrap(),
            ));
        }
    }
    let (mut se, mut raw) = (0.0, 0.0);
    for r in &rows {
        let others: Vec<f64> = rows
            .iter()
            .filter(|o| o.0 == r.0 && o.2 == r.2 && o.1 != r.1)
            .map(|o| o.3)
            .collect();
        let m = others.iter().sum::<f64>() / others.len() as f64;
        se += (r.3 - m).powi(2);
        raw += r.3 * r.3;
    }
    (
        (raw / rows.len() as f64).sqrt(),
        (se / rows.len() as f64).sqrt(),
    )
}

#[test]
fn ess_b02_x_leave_one_cycle_out() {
    let Some(shared) = shared() else { return };
    let csv = shared.join(ESS_CSV);
    let dir = scratch("b02");
    let (table, json, report) = (
        dir.join("table.json"),
        dir.join("fit.json"),
        dir.join("report"),
    );
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--where",
        &format!("test_id={B02}"),
        "--cv",
        "cycle",
        "--out",
        table.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "stdout {}\nstderr {}", r.stdout, r.stderr);
    let j = read_json(&json);
    let (raw_ref, loo_ref) = loo_of_means(&csv, B02);
    let raw = num(&j, "raw_rms_um");
    let cv = num(&j, "cv_rms_um");
    println!(
        "B02 X: raw {raw:.3} µm, leave-one-cycle-out {cv:.3} µm (LOO of per-target means {loo_ref:.3} µm)"
    );
    // Raw RMS: reference = direct computation from the CSV, tolerance 1e-9 µm.
    assert!((raw - raw_ref).abs() < 1e-9, "raw {raw} vs {raw_ref}");
    // A static table alone: 3.539 µm, the floor for any table fitted on the other cycles here. The runs
    // drift ≈ −1.4 µm per cycle (per-run mean residual +3.9 … −3.1 µm, see `cv.per_run`) as the motor warms,
    // and the per-target mean of n − 1 = 4 cycles has a leave-one-out RMS of exactly s·√(n/(n−1)) with the
    // pooled within-point s = 3.17 µm. The issue's ≤ 3.5 µm is reached with the warm-up drift
    // (`ess_b02_x_with_warmup_drift`, 2.541 µm). Bound here: the measured static figure with 0.3 % margin,
    // and no worse than the reference model (LOO of per-target means, 3.539 µm) + 1e-9.
    assert!(cv <= 3.55, "leave-one-cycle-out RMS {cv}");
    assert!(
        cv <= loo_ref + 1e-9,
        "cv {cv} worse than the per-target-mean reference {loo_ref}"
    );
    assert_eq!(j["cv"]["method"], "leave-one-run-out");
    assert_eq!(j["cv"]["column"], "cycle");
    assert_eq!(j["cv"]["folds"], 5);
    assert_eq!(j["cv"]["per_run"].as_array().unwrap().len(), 5);
    check_iso(&j);
    // Before: ISO 230-2 figures of the raw data (B = max |reversal| ≈ 34 µm per PROVENANCE: −16…−34 µm).
    let b_before = j["iso230_2_before"]["B_um"].as_f64().unwrap();
    assert!((30.0..40.0).contains(&b_before), "B before {b_before}");
    assert!(
        j["iso230_2_after"]["E_um"].as_f64().unwrap()
            < j["iso230_2_before"]["E_um"].as_f64().unwrap() / 10.0
    );
    // Model: chosen + every candidate with its CV figure; the chosen one's figure is the reported one.
    let chosen = j["model"]["chosen"].as_str().unwrap();
    let cands = j["model"]["candidates"].as_array().unwrap();
    assert!(cands.len() >= 10, "{cands:?}");
    let c = cands
        .iter()
        .find(|c| c["name"] == chosen)
        .expect("chosen among candidates");
    assert!((c["cv_rms_um"].as_f64().unwrap() - cv).abs() < 1e-12);
    assert!(cands.iter().all(|c| c["cv_rms_um"].as_f64().is_some()));
    assert!(!j["model"]["reason"].as_str().unwrap().is_empty());
    // Guard passed, table written and readable; it reproduces the chosen spline (resampling ≤ 1e-6 µm).
    assert_eq!(j["guard"]["passed"], true);
    assert_eq!(j["table_written"], true);
    assert!(num(&j["table"], "resampling_max_um") < 1e-6);
    let t = axcomp_positioning::TableFile::load(&table).unwrap();
    assert_eq!(t.format, "axcomp-positioning-table/1");
    assert_eq!(
        (t.start_mm, t.forward.len(), t.backward.len()),
        (-20.0, 32, 32)
    );
    assert!(t.to_core(0.1).spec().forward.len() == 32);
    for f in ["report.md", "positioning.svg", "residual.svg"] {
        assert!(report.join(f).is_file(), "{f} missing");
    }
    let md = std::fs::read_to_string(report.join("report.md")).unwrap();
    assert!(md.contains(chosen) && md.contains("A_um"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// MUTS week-42 runs (slipping axis, bad reference sensor; PROVENANCE.md). Measured outcome per run:
/// `true` = the guard refuses (cross-validated RMS not clearly below raw), `false` = the table helps on
/// unseen cycles in every cycle (Y 10-19: 38.2 → 22.2 µm, Z ILD-below: 14.0 → 6.0 µm) and is written.
const MUTS: [(&str, bool); 8] = [
    ("ESS_TDU_MUTS_X_2022-10-19", true),
    ("ESS_TDU_MUTS_X_2022-10-20_8A", true),
    ("ESS_TDU_MUTS_X_2022-10-20a", true),
    ("ESS_TDU_MUTS_X_2022-10-21_ILD50", true),
    ("ESS_TDU_MUTS_Y_2022-10-19", false),
    ("ESS_TDU_MUTS_Y_2022-10-21_ILD50", true),
    ("ESS_TDU_MUTS_Z_2022-10-20", true),
    ("ESS_TDU_MUTS_Z_2022-10-20_ILDbelow", false),
];

#[test]
fn ess_muts_runs_not_clearly_improved_trigger_the_guard() {
    let Some(shared) = shared() else { return };
    let csv = shared.join(ESS_CSV);
    let dir = scratch("muts");
    // The same outcomes with a warm-up drift allowed: the drifts these runs show (slip, a moving reference)
    // exceed their raw RMS and are not kept, or do not lower the CV RMS.
    for (id, expect_refused, drift) in MUTS
        .iter()
        .flat_map(|&(id, e)| [(id, e, false), (id, e, true)])
    {
        let (table, json) = (
            dir.join(format!("{id}.{drift}.table.json")),
            dir.join(format!("{id}.{drift}.json")),
        );
        let filter = format!("test_id={id}");
        let mut args = vec![
            "fit",
            "positioning",
            "--data",
            csv.to_str().unwrap(),
            "--where",
            &filter,
            "--cv",
            "cycle",
            "--out",
            table.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ];
        if drift {
            args.extend(["--drift", "cycle", "--run-period-s", "490"]);
        }
        let r = axcomp(&args);
        let j = read_json(&json);
        let (raw, cv) = (num(&j, "raw_rms_um"), num(&j, "cv_rms_um"));
        println!(
            "{id}{}: raw {raw:.3} µm, cv {cv:.3} µm, exit {}",
            if drift { " --drift" } else { "" },
            r.code
        );
        if drift && expect_refused {
            assert_eq!(
                j["model"]["warmup"]["kept"], false,
                "{id}: {}",
                j["model"]["warmup"]
            );
        }
        check_iso(&j);
        // The rule (guard module): cv ≤ 0.8·raw and improvement in ≥ 80 % of the cycles.
        let not_clearly_below = cv > 0.8 * raw;
        assert_eq!(
            not_clearly_below || !j["guard"]["passed"].as_bool().unwrap(),
            expect_refused,
            "{id}"
        );
        if expect_refused {
            assert_eq!(
                r.code, 3,
                "{id}: guard must refuse with exit code 3\n{}",
                r.stderr
            );
            assert_eq!(j["table_written"], false, "{id}");
            assert_eq!(j["guard"]["refused"], true, "{id}");
            assert!(
                !j["guard"]["reasons"].as_array().unwrap().is_empty(),
                "{id}"
            );
            assert!(
                !table.exists(),
                "{id}: a table was written despite the guard"
            );
            assert!(
                r.stderr.contains("do-no-harm guard refused"),
                "{id}: {}",
                r.stderr
            );
        } else {
            assert_eq!(r.code, 0, "{id}: {}", r.stderr);
            assert!(cv <= 0.8 * raw);
            assert_eq!(j["table_written"], true);
            assert!(table.is_file());
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// B02 X with a warm-up drift (`--drift cycle`): the runs were measured back to back, 490 s per cycle
/// (TestNumber 1101 at 12:48:40, 1201 at 12:56:50 in the raw log `x_230_2.log`), while the motor warmed
/// from 28 to 48 °C (PROVENANCE.md). The drift is judged by leave-one-cycle-out with τ re-chosen in every
/// fold, then carried into a firmware image and applied by the core's thermo-force term.
#[test]
fn ess_b02_x_with_warmup_drift() {
    let Some(shared) = shared() else { return };
    let csv = shared.join(ESS_CSV);
    let dir = scratch("b02-drift");
    let (table, json, model, image) = (
        dir.join("table.json"),
        dir.join("fit.json"),
        dir.join("drift.json"),
        dir.join("b02.axci"),
    );
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--where",
        &format!("test_id={B02}"),
        "--cv",
        "cycle",
        "--drift",
        "cycle",
        "--run-period-s",
        "490",
        "--out",
        table.to_str().unwrap(),
        "--drift-model",
        model.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "stdout {}\nstderr {}", r.stdout, r.stderr);
    let j = read_json(&json);
    let w = &j["model"]["warmup"];
    let (cv, static_cv) = (num(&j, "cv_rms_um"), num(w, "cv_rms_um_static"));
    let (_, loo_ref) = loo_of_means(&csv, B02);
    println!(
        "B02 X: leave-one-cycle-out {cv:.3} µm with the warm-up drift, {static_cv:.3} µm static; τ {:.0} s, drift {:.3} µm",
        num(w, "tau_s"),
        num(w, "drift_um")
    );
    // Issue target: ≤ 3.5 µm leave-one-cycle-out. Measured 2.541 µm.
    assert!(cv <= 3.5, "leave-one-cycle-out RMS {cv}");
    assert_eq!(w["kept"], true, "{w}");
    assert!((cv - num(w, "cv_rms_um_with_drift")).abs() < 1e-12);
    // The static figure is the one of the plain fit (reference: LOO of per-target means, 3.539 µm).
    assert!(
        static_cv <= loo_ref + 1e-9 && static_cv > 3.4,
        "static {static_cv}"
    );
    // Nested choice: one τ per held-out cycle, all on the candidate grid (> 0, finite).
    let taus = w["tau_per_fold_s"].as_array().unwrap();
    assert_eq!(taus.len(), 5);
    assert!(taus.iter().all(|t| t.as_f64().is_some_and(|t| t > 0.0)));
    // The drift removes the run-to-run trend: per-cycle mean residuals within ±2 µm (static: +3.9 … −3.1).
    for p in j["cv"]["per_run"].as_array().unwrap() {
        let m = num(p, "mean_residual_um");
        assert!(m.abs() < 2.0, "cycle {}: mean residual {m}", p["run"]);
    }
    assert_eq!(j["guard"]["passed"], true);
    assert_eq!(j["drift_model_written"], true);
    // The drift model goes into a firmware image with the table…
    let r = axcomp(&[
        "image",
        "build",
        "--table",
        table.to_str().unwrap(),
        "--thermal",
        model.to_str().unwrap(),
        "--axis-id",
        "1",
        "--um-per-count",
        "0.001",
        "--max-slew-um",
        "1000",
        "--out",
        image.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    // …and the core applies it: with the `warmup` input 0 at t = 0 and 1 every 100 ms after, the correction
    // at a fixed position changes by drift_um·(1 − exp(−t/τ)). Reference: that closed form in f64;
    // tolerance 0.02 µm (f32 lag state over up to 36 000 updates, table in f32).
    let bytes = std::fs::read(&image).unwrap();
    let mut comp = axcomp_core::Compensator::IDENTITY;
    comp.load(&bytes).unwrap();
    let mut st = axcomp_core::State::new();
    let (tau, k) = (num(w, "tau_s"), num(w, "drift_um"));
    let input = axcomp_core::CycleInput {
        scale_raw: 5_000_000,
        command_counts: 5_000_000,
        forces_n: [0.0; axcomp_core::MAX_FORCES],
    };
    comp.update_temperatures(&mut st, 0, &[0.0]);
    let cold = f64::from(comp.cycle(&mut st, &input).correction_um);
    let mut worst: f64 = 0.0;
    for n in 1..=36_000u32 {
        comp.update_temperatures(&mut st, n * 100, &[1.0]);
        if n % 600 == 0 {
            let now = f64::from(comp.cycle(&mut st, &input).correction_um);
            let t = f64::from(n) * 0.1;
            let want = k * (1.0 - (-t / tau).exp());
            worst = worst.max((now - cold - want).abs());
        }
    }
    println!("firmware drift vs closed form: worst {worst:.4} µm over 1 h");
    assert!(worst < 0.02, "worst {worst}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn drift_options_are_checked_and_nothing_is_written() {
    let Some(shared) = shared() else { return };
    let csv = shared.join(ESS_CSV);
    let dir = scratch("drift-bad");
    let table = dir.join("t.json");
    let base = [
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--where",
        "test_id=ESS_TDU_B02_X_2022-04-06",
        "--out",
        table.to_str().unwrap(),
    ];
    let cases: [(&[&str], &str); 4] = [
        (&["--drift", "cycle"], "--run-period-s"),
        (
            &["--drift", "cycle", "--run-period-s", "0"],
            "must be a finite number",
        ),
        (&["--drift", "time_s"], "time_s"),
        (&["--drift-model", "m.json"], "--drift"),
    ];
    for (extra, needle) in cases {
        let args: Vec<&str> = base.iter().chain(extra.iter()).copied().collect();
        let r = axcomp(&args);
        assert_ne!(r.code, 0, "{extra:?} was accepted");
        assert!(r.stderr.contains(needle), "{extra:?}: {}", r.stderr);
        assert!(!table.exists(), "{extra:?}: a table was written");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn force_writes_a_refused_table_and_says_so() {
    let Some(shared) = shared() else { return };
    let csv = shared.join(ESS_CSV);
    let dir = scratch("force");
    let (table, json) = (dir.join("t.json"), dir.join("j.json"));
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--where",
        "test_id=ESS_TDU_MUTS_X_2022-10-19",
        "--out",
        table.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--force",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let j = read_json(&json);
    assert_eq!(j["guard"]["passed"], false);
    assert_eq!(j["guard"]["forced"], true);
    assert_eq!(j["table_written"], true);
    // Without --cv the `cycle` column (alias of `run`) is used for leave-one-run-out.
    assert_eq!(j["cv"]["method"], "leave-one-run-out");
    assert!(table.is_file());
    std::fs::remove_dir_all(&dir).unwrap();
}

// ---------------------------------------------------------------------------------------------
// Synthetic data with known truth.

/// Deterministic uniform (64-bit LCG) and normal (Box–Muller) numbers.
struct Rng(u64);
impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// Truth: smooth pitch error (µm) along 0…400 mm plus a reversal growing from 6 to 8 µm.
fn truth(x: f64, d: i8) -> f64 {
    let pitch = 15.0 * (std::f64::consts::TAU * x / 300.0).sin()
        + 5.0 * (std::f64::consts::TAU * x / 70.0).sin()
        + 0.02 * x;
    let reversal = 6.0 + 2.0 * x / 400.0;
    pitch + 0.5 * d as f64 * reversal
}

/// ISO 230-2 style campaign: 41 targets every 10 mm, `runs` cycles, both directions, noise σ.
fn synthetic_csv(path: &Path, runs: usize, sigma: f64, seed: u64) {
    let mut rng = Rng(seed);
    let mut s = String::from(
        "# synthetic: smooth pitch error + reversal + Gaussian noise\ntarget_mm,run,direction,deviation_um\n",
    );
    for run in 1..=runs {
        for (d, order) in [(1i8, false), (-1i8, true)] {
            for k in 0..41 {
                let k = if order { 40 - k } else { k };
                let x = 10.0 * k as f64;
                let y = truth(x, d) + sigma * rng.normal();
                s.push_str(&format!(
                    "{x},{run},{},{y:.6}\n",
                    if d > 0 { "+" } else { "-" }
                ));
            }
        }
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn synthetic_holdout_residual_is_within_1_1_of_the_noise_floor() {
    // Noise floor: σ of the generator's Gaussian noise — the RMS a perfect table would leave on unseen runs
    // (ISO-style, the standard uncertainty of one reading). Cycles 21–25 are held out; cycles 1–20 fit.
    let dir = scratch("synthetic");
    let (csv, json, table) = (
        dir.join("synth.csv"),
        dir.join("j.json"),
        dir.join("t.json"),
    );
    let sigma = 1.0;
    synthetic_csv(&csv, 25, sigma, 42);
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--holdout",
        "run=21,22,23,24,25",
        "--json",
        json.to_str().unwrap(),
        "--out",
        table.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let j = read_json(&json);
    let hold = num(&j, "holdout_rms_um");
    let raw = num(&j, "raw_rms_um");
    println!(
        "synthetic: raw {raw:.3} µm, held-out {hold:.3} µm, σ = {sigma}, model {}",
        j["model"]["chosen"]
    );
    assert!(
        j.get("cv_rms_um").is_none(),
        "with --holdout the contract field is holdout_rms_um"
    );
    assert_eq!(j["rows_judged"], 5 * 82);
    assert!(hold <= 1.1 * sigma, "held-out RMS {hold} > 1.1 σ");
    check_iso(&j);
    // The written table is close to the truth (reference: truth(); tolerance 0.5 µm RMS over the targets,
    // ≈ 2.5× the standard error σ/√20 of a per-target mean).
    let t = axcomp_positioning::TableFile::load(&table).unwrap();
    let mut se = 0.0;
    for k in 0..41 {
        for d in [1i8, -1] {
            let x = 10.0 * k as f64;
            se += (t.deviation_um(x, d) - truth(x, d)).powi(2);
        }
    }
    let err = (se / 82.0).sqrt();
    assert!(err < 0.5, "table vs truth RMS {err}");
    // The reversal was found: backward and forward tables differ by ≈ the true reversal (6…8 µm).
    let rev = t.deviation_um(200.0, 1) - t.deviation_um(200.0, -1);
    assert!((rev - 7.0).abs() < 0.5, "reversal at 200 mm {rev}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn unidirectional_data_without_runs_uses_row_folds_and_one_table() {
    let dir = scratch("unidir");
    let (csv, json, table) = (dir.join("u.csv"), dir.join("j.json"), dir.join("t.json"));
    let mut rng = Rng(3);
    let mut s = String::from("target_mm,deviation_um\n");
    for _ in 0..300 {
        let x = 100.0 * rng.uniform();
        s.push_str(&format!("{x},{}\n", truth(x * 4.0, 0) + 0.5 * rng.normal()));
    }
    std::fs::write(&csv, s).unwrap();
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--out",
        table.to_str().unwrap(),
        "--segments",
        "50",
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let j = read_json(&json);
    assert_eq!(j["cv"]["method"], "k-fold-by-row");
    assert!(num(&j, "cv_rms_um") < 0.6, "{}", j["cv_rms_um"]);
    let t = axcomp_positioning::TableFile::load(&table).unwrap();
    assert_eq!((t.forward.len(), t.backward.len()), (50, 0));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn bad_input_names_file_line_and_column_and_writes_nothing() {
    let dir = scratch("bad");
    let (csv, json, table) = (dir.join("bad.csv"), dir.join("j.json"), dir.join("t.json"));
    std::fs::write(
        &csv,
        "target_mm,run,direction,deviation_um\n0,1,+,1.0\n10,1,+,oops\n20,1,+,2.0\n",
    )
    .unwrap();
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--out",
        table.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 2);
    assert!(
        r.stderr.contains("bad.csv:3:4"),
        "message must name file:line:column: {}",
        r.stderr
    );
    assert!(
        !json.exists() && !table.exists(),
        "nothing may be written on bad input"
    );

    std::fs::write(&csv, "position,deviation_um\n0,1\n1,2\n").unwrap();
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 2);
    assert!(r.stderr.contains("target_mm"), "{}", r.stderr);
    assert!(!json.exists());

    synthetic_csv(&csv, 3, 1.0, 1);
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--segments",
        "2000",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 2);
    assert!(r.stderr.contains("segments"), "{}", r.stderr);
    assert!(!json.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}
