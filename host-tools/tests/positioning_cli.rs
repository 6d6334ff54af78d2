//! End-to-end tests of `axcomp fit positioning` through the built binary: the required figures
//! (real ESS runs, the do-no-harm guard on the MUTS runs, synthetic data with known truth), JSON fields
//! per the contract, and bad input. Real data is read from `../shared` (override: `AXCOMP_SHARED`); when
//! it is absent these tests print `skipped: ../shared not found` and return, except under `CI`.

use std::path::Path;
use std::process::Command;

use serde_json::{Value, json};

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

/// The contract's ISO 230-2 fields are present: a finite number, or (figures the judged runs
/// cannot define, e.g. A and R of single-run CV folds, are never invented) `null` with a reason.
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
    // pooled within-point s = 3.17 µm. The target ≤ 3.5 µm is reached with the warm-up drift
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
    // Pooled after-figures. The chosen table passes through every target (9 targets, natural spline per
    // direction), so each held-out residual is (x_i − mean)·n/(n−1): reference for R↑ and R↓ after is
    // 1.25 × the figure before (n = 5), tolerance 1e-6 µm; the target means are equal by construction,
    // which the JSON says beside E, M and B.
    let (before, after) = (&j["iso230_2_before"], &j["iso230_2_after"]);
    for k in ["R_up_um", "R_down_um"] {
        let want = 1.25 * num(before, k);
        assert!(
            (num(after, k) - want).abs() < 1e-6,
            "{k}: {} vs {want}",
            after[k]
        );
    }
    assert!(
        j["iso230_2_after_caveats"]["B_um"].is_string(),
        "{}",
        j["iso230_2_after_caveats"]
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
    // Target: ≤ 3.5 µm leave-one-cycle-out. Measured 2.541 µm.
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
    // ISO 230-2 after the correction, pooled over the five held-out cycles (each corrected by the model of
    // the fold that held it out): a campaign of 5 runs per target and direction, so every figure is a number
    // and A falls (before 135.3 µm, measured after 22.3 µm). E, M and B are flagged: each fold's table took
    // every target from the other cycles, which makes the pooled target means equal by construction.
    let (before, after) = (&j["iso230_2_before"], &j["iso230_2_after"]);
    for k in [
        "A_um",
        "E_um",
        "M_um",
        "R_um",
        "B_um",
        "A_up_um",
        "A_down_um",
        "R_up_um",
        "R_down_um",
    ] {
        assert!(
            after[k].as_f64().is_some_and(f64::is_finite),
            "after {k}: {after}"
        );
    }
    assert_eq!(after["min_runs_per_target"], 5);
    assert!(
        num(after, "A_um") < num(before, "A_um"),
        "A after ≥ A before"
    );
    assert!(j["iso230_2_after_caveats"]["E_um"].is_string());
    assert!(j["iso230_2_after_fold_mean"]["E_um"].is_number());
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
use axcomp_numeric::noise::TestNoise as Rng;

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

// ---------------------------------------------------------------------------------------------
// Honest figures, after-figures from a compensated campaign, data sanity,
// traceability, grouped folds.

/// One-direction data: unidirectional ISO 230-2 figures, `null` + reason for every bidirectional one
/// (`A_down_um == A_up_um`, `B_um: 0` would be invented), and no "bidirectional" heading.
#[test]
fn one_direction_data_gets_unidirectional_figures_only() {
    let dir = scratch("onedir");
    let (csv, json, report) = (dir.join("u.csv"), dir.join("j.json"), dir.join("rep"));
    let mut rng = Rng(11);
    let mut s = String::from("target_mm,run,direction,deviation_um\n");
    for run in 1..=5 {
        for k in 0..21 {
            let x = 20.0 * k as f64;
            s.push_str(&format!(
                "{x},{run},+,{:.4}\n",
                truth(x, 1) + 0.5 * rng.normal()
            ));
        }
    }
    std::fs::write(&csv, s).unwrap();
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let j = read_json(&json);
    for part in ["iso230_2_before", "iso230_2_after"] {
        let f = &j[part];
        assert_eq!(f["directions"], "positive only", "{f}");
        assert_eq!(f["bidirectional"], false);
        for k in [
            "A_um",
            "E_um",
            "M_um",
            "R_um",
            "B_um",
            "A_down_um",
            "E_down_um",
            "R_down_um",
        ] {
            assert!(f[k].is_null(), "{part}.{k} = {}", f[k]);
            assert!(f["null_reasons"][k].is_string(), "{part}.{k}: no reason");
        }
        assert!(
            f["null_reasons"]["B_um"]
                .as_str()
                .unwrap()
                .contains("one approach direction")
        );
    }
    // Before: the ↑ figures of the raw data are defined (5 runs per target).
    for k in ["A_up_um", "E_up_um", "R_up_um"] {
        assert!(j["iso230_2_before"][k].as_f64().is_some(), "{k}");
    }
    let md = std::fs::read_to_string(report.join("report.md")).unwrap();
    assert!(!md.contains("(bidirectional)"), "{md}");
    assert!(md.contains("unidirectional") && md.contains("A_up_um"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// `--holdout cycle=5` (one held-out cycle): the contract's `A_um … B_um` are all present; E, M, B (from
/// the per-target means) are numbers, A and R (which need s, i.e. ≥ 2 runs) are `null` with the reason.
/// Reference for E, M, B: computed here from the CSV rows of cycle 5 (max − min of the per-target
/// means, tolerance 1e-9 µm).
#[test]
fn holdout_of_one_cycle_keeps_every_computable_figure() {
    let Some(shared) = shared() else { return };
    let csv = shared.join(ESS_CSV);
    let dir = scratch("holdout5");
    let json = dir.join("j.json");
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--where",
        &format!("test_id={B02}"),
        "--holdout",
        "cycle=5",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let j = read_json(&json);
    let b = &j["iso230_2_before"];
    for k in ["A_um", "E_um", "M_um", "R_um", "B_um"] {
        assert!(b.get(k).is_some(), "{k} dropped: {b}");
    }
    for k in ["A_um", "R_um"] {
        assert!(b[k].is_null());
        assert!(
            b["null_reasons"][k]
                .as_str()
                .unwrap()
                .contains("at least 2 runs")
        );
    }
    // Independent reference from the raw rows of cycle 5.
    let ds = axcomp_data::Dataset::load(
        &csv,
        &axcomp_data::LoadOptions::from_args(
            &[format!("test_id={B02}"), "cycle=5".into()],
            &[],
            &[],
        )
        .unwrap(),
    )
    .unwrap();
    let (x, d, dir_) = (
        ds.numeric("target_mm").unwrap(),
        ds.numeric("deviation_um").unwrap(),
        ds.direction().unwrap().unwrap(),
    );
    let mut up = std::collections::BTreeMap::new();
    let mut down = std::collections::BTreeMap::new();
    for i in 0..x.len() {
        let m = if dir_[i] > 0 { &mut up } else { &mut down };
        m.insert((x[i] * 1000.0).round() as i64, d[i]);
    }
    let all: Vec<f64> = up.values().chain(down.values()).copied().collect();
    let e_ref =
        all.iter().copied().fold(f64::MIN, f64::max) - all.iter().copied().fold(f64::MAX, f64::min);
    let mids: Vec<f64> = up.iter().map(|(t, u)| 0.5 * (u + down[t])).collect();
    let m_ref = mids.iter().copied().fold(f64::MIN, f64::max)
        - mids.iter().copied().fold(f64::MAX, f64::min);
    let b_ref = up
        .iter()
        .map(|(t, u)| (u - down[t]).abs())
        .fold(0.0, f64::max);
    for (k, want) in [("E_um", e_ref), ("M_um", m_ref), ("B_um", b_ref)] {
        let got = num(b, k);
        assert!((got - want).abs() < 1e-9, "{k}: {got} vs {want}");
    }
    for k in ["E_um", "M_um", "B_um"] {
        assert!(j["iso230_2_after"][k].as_f64().is_some(), "after {k}");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// On the twin: `iso230_2_after` of `--holdout` equals the ISO 230-2 figures of the truly
/// compensated campaign — the same held-out runs simulated with the written table loaded into the core's
/// compensator (same noise seed) — within 0.05 µm (the required tolerance; the differences are the
/// firmware's f32 table and count rounding, and the error evaluated at the compensated position).
/// The axis is the demo's linear-motor axis without its interpolation error: that error has a 20 µm period,
/// so the compensated axis, sitting a correction (~10 µm) away from the target, reads it at another phase
/// (±0.15 µm) — a real difference no position table can predict, not an error of the after-figures.
#[test]
fn twin_after_figures_equal_the_truly_compensated_campaign() {
    use axcomp_twin::{Axis, EffectKind, Iso230Plan, Plan, simulate};
    let dir = scratch("twin-after");
    let (csv, json, table) = (dir.join("m.csv"), dir.join("j.json"), dir.join("t.json"));
    let axis = Axis::typical(
        "linear_motor_demo_without_interpolation_error",
        0.0,
        200.0,
        &[
            EffectKind::PitchError,
            EffectKind::Reversal,
            EffectKind::Cogging,
            EffectKind::ScaleExpansion,
        ],
    );
    let mut iso_plan = Iso230Plan::standard(axis.start_mm, axis.end_mm);
    iso_plan.cycles = 10;
    let plan = Plan::from(iso_plan);
    let seed = 7;
    let measured = simulate(&axis, &plan, None, seed).unwrap();
    std::fs::write(&csv, measured.to_csv_string()).unwrap();
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--holdout",
        "run=6,7,8,9,10",
        "--out",
        table.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let j = read_json(&json);
    // The truly compensated campaign: the written table in a firmware image, driven by the twin.
    let t = axcomp_positioning::TableFile::load(&table).unwrap();
    let core = t.try_to_core(axis.scale_um_per_count).unwrap();
    let spec = axcomp_core::ImageSpec {
        axis_id: 1,
        um_per_count: axis.scale_um_per_count as f32,
        counter_bits: 32,
        table: Some(core.spec()),
        thermo: None,
        limits: axcomp_twin::ideal::default_limits(&axis),
    };
    let mut image = vec![0u8; axcomp_core::image_len(&spec)];
    let n = axcomp_core::write_image(&spec, &mut image).unwrap();
    image.truncate(n);
    let mut comp = axcomp_core::Compensator::IDENTITY;
    comp.load(&image).unwrap();
    let compensated = simulate(&axis, &plan, Some(&comp), seed).unwrap();
    let pts: Vec<axcomp_positioning::iso230::Point> = compensated
        .rows
        .iter()
        .filter(|r| r.run >= 6)
        .map(|r| axcomp_positioning::iso230::Point {
            target_mm: r.target_mm,
            run: r.run,
            direction: r.direction,
            deviation_um: r.deviation_um,
        })
        .collect();
    let truly = axcomp_positioning::iso230::evaluate(&pts).unwrap();
    let truly = serde_json::to_value(&truly).unwrap();
    let after = &j["iso230_2_after"];
    for k in [
        "A_um",
        "E_um",
        "M_um",
        "R_um",
        "B_um",
        "A_up_um",
        "A_down_um",
        "R_up_um",
        "R_down_um",
    ] {
        let (got, want) = (num(after, k), num(&truly, k));
        println!("twin after {k}: CLI {got:.4} µm, truly compensated {want:.4} µm");
        assert!((got - want).abs() <= 0.05, "{k}: {got} vs {want}");
    }
    // And compensation did something: A after well below A before.
    assert!(num(after, "A_um") < 0.5 * num(&j["iso230_2_before"], "A_um"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// On the real ESS runs: with the last two cycles held out, no after-figure is an
/// artefact. Where the guard writes a table, A after ≤ A before. R after is consistent with the held-out
/// runs' own repeatability: a static table subtracts the same value from every run at a target, so the
/// unidirectional R↑ and R↓ after (4s of the residuals) equal R↑ and R↓ before (4s of the held-out
/// deviations) — reference: the before figures, tolerance 1e-9 µm — and the bidirectional R after is at most
/// R before plus what the reversal after adds (R_i = 2s↑ + 2s↓ + |B_i|).
#[test]
fn ess_after_figures_are_not_artefacts() {
    let Some(shared) = shared() else { return };
    let csv = shared.join(ESS_CSV);
    let dir = scratch("ess-after");
    let ids = [B02].into_iter().chain(MUTS.iter().map(|m| m.0));
    let mut tables = 0;
    for id in ids {
        let json = dir.join(format!("{id}.json"));
        let r = axcomp(&[
            "fit",
            "positioning",
            "--data",
            csv.to_str().unwrap(),
            "--where",
            &format!("test_id={id}"),
            "--holdout",
            "cycle=4,5",
            "--json",
            json.to_str().unwrap(),
        ]);
        assert!(r.code == 0 || r.code == 3, "{id}: {}", r.stderr);
        let j = read_json(&json);
        let (b, a) = (&j["iso230_2_before"], &j["iso230_2_after"]);
        let passed = j["guard"]["passed"] == true;
        println!(
            "{id}: A {:.2} → {:.2} µm, R {:.2} → {:.2} µm, R↑ {:.3} → {:.3}, guard {}",
            num(b, "A_um"),
            num(a, "A_um"),
            num(b, "R_um"),
            num(a, "R_um"),
            num(b, "R_up_um"),
            num(a, "R_up_um"),
            if passed { "passed" } else { "refused" }
        );
        for k in ["R_up_um", "R_down_um"] {
            assert!((num(a, k) - num(b, k)).abs() < 1e-9, "{id} {k}");
        }
        let rev_after = num(a, "B_um");
        assert!(
            num(a, "R_um") <= num(b, "R_um") + rev_after + 1e-9,
            "{id} R"
        );
        if passed {
            tables += 1;
            assert!(num(a, "A_um") <= num(b, "A_um"), "{id}: A after > A before");
        }
    }
    assert!(tables >= 2, "at least B02 and one MUTS run get a table");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Writes the B02 rows of the ESS file with `edit(row, cycle, deviation)` applied to `deviation_um`.
fn b02_edited(shared: &Path, out: &Path, edit: impl Fn(usize, f64, f64) -> f64) {
    let ds = axcomp_data::Dataset::load(
        &shared.join(ESS_CSV),
        &axcomp_data::LoadOptions::from_args(&[format!("test_id={B02}")], &[], &[]).unwrap(),
    )
    .unwrap();
    let (x, c, d, v) = (
        ds.numeric("target_mm").unwrap(),
        ds.numeric("cycle").unwrap(),
        ds.direction().unwrap().unwrap(),
        ds.numeric("deviation_um").unwrap(),
    );
    let mut s = String::from("test_id,target_mm,cycle,direction,deviation_um\n");
    for i in 0..x.len() {
        s.push_str(&format!(
            "{B02},{},{},{},{}\n",
            x[i],
            c[i],
            d[i],
            edit(i, c[i], v[i])
        ));
    }
    std::fs::write(out, s).unwrap();
}

/// A value mistyped ×10 must not be fitted silently (it would move the table by 9.9 µm): it is a
/// warning on stderr and in the JSON naming its line; `--strict` refuses the data with exit code 2 and
/// writes nothing.
#[test]
fn a_value_mistyped_ten_times_is_flagged_and_strict_refuses_it() {
    let Some(shared) = shared() else { return };
    let dir = scratch("typo");
    let (csv, json, table) = (dir.join("b02.csv"), dir.join("j.json"), dir.join("t.json"));
    b02_edited(&shared, &csv, |i, _, v| if i == 40 { v * 10.0 } else { v });
    let args = [
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--out",
        table.to_str().unwrap(),
    ];
    let r = axcomp(&args);
    assert!(r.code == 0 || r.code == 3, "{}", r.stderr);
    assert!(
        r.stderr.contains("warning") && r.stderr.contains("line 42"),
        "{}",
        r.stderr
    );
    let j = read_json(&json);
    let w = j["warnings"].as_array().unwrap();
    assert_eq!(w.len(), 1, "{w:?}");
    assert_eq!(w[0]["kind"], "outlier");
    assert_eq!(w[0]["lines"], json!([42]));
    std::fs::remove_file(&json).unwrap();
    let _ = std::fs::remove_file(&table);
    let strict: Vec<&str> = args.iter().copied().chain(["--strict"]).collect();
    let r = axcomp(&strict);
    assert_eq!(r.code, 2, "{}", r.stderr);
    assert!(r.stderr.contains("--strict"), "{}", r.stderr);
    assert!(
        !json.exists() && !table.exists(),
        "--strict wrote something"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Half the rows in mm instead of µm must not be fitted silently: a `unit_mix` warning.
#[test]
fn half_the_rows_in_mm_is_a_unit_warning() {
    let Some(shared) = shared() else { return };
    let dir = scratch("units");
    let (csv, json) = (dir.join("b02.csv"), dir.join("j.json"));
    // Cycles 3–5 logged in mm.
    b02_edited(
        &shared,
        &csv,
        |_, c, v| if c >= 3.0 { v / 1000.0 } else { v },
    );
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
        "--strict",
    ]);
    assert_eq!(r.code, 2, "{}", r.stderr);
    assert!(r.stderr.contains("mm mixed with µm"), "{}", r.stderr);
    assert!(!json.exists());
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(r.code == 0 || r.code == 3, "{}", r.stderr);
    let j = read_json(&json);
    assert_eq!(j["warnings"][0]["kind"], "unit_mix", "{}", j["warnings"]);
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The ESS file holds nine `test_id`s; without `--where` they must not be fitted as one axis: a
/// clear error (exit 2) listing them, and nothing written.
#[test]
fn several_test_ids_without_where_are_an_error_listing_them() {
    let Some(shared) = shared() else { return };
    let dir = scratch("nine");
    let json = dir.join("j.json");
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        shared.join(ESS_CSV).to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 2, "{}", r.stderr);
    assert!(
        r.stderr.contains("holds 9 different values"),
        "{}",
        r.stderr
    );
    for (id, _) in MUTS {
        assert!(r.stderr.contains(id), "{id} not listed: {}", r.stderr);
    }
    assert!(r.stderr.contains("--where test_id="), "{}", r.stderr);
    assert!(!json.exists());
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The table file names its source (SHA-256 of the file's bytes, length), the filters,
/// the tool version and the date. Reference for the digest: `sha256sum` when installed.
#[test]
fn the_table_file_carries_its_provenance() {
    let dir = scratch("provenance");
    let (csv, table) = (dir.join("s.csv"), dir.join("t.json"));
    synthetic_csv(&csv, 6, 1.0, 5);
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--holdout",
        "run=6",
        "--scale",
        "deviation_um=1",
        "--out",
        table.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let t = axcomp_positioning::TableFile::load(&table).unwrap();
    let p = t.provenance.expect("provenance in the table file");
    assert_eq!(p.source_bytes, std::fs::metadata(&csv).unwrap().len());
    assert_eq!(p.source_sha256.len(), 64);
    if let Ok(o) = Command::new("sha256sum").arg(&csv).output() {
        let want = String::from_utf8_lossy(&o.stdout);
        assert_eq!(
            Some(p.source_sha256.as_str()),
            want.split_whitespace().next()
        );
    }
    assert_eq!(p.holdout.as_deref(), Some("run=6"));
    assert_eq!(p.scale, vec!["deviation_um=1".to_string()]);
    assert_eq!(p.tool, concat!("axcomp ", env!("CARGO_PKG_VERSION")));
    assert!(
        p.created_utc.len() == 20 && p.created_utc.ends_with('Z'),
        "{}",
        p.created_utc
    );
    let line = p.header_line();
    assert!(
        line.contains("holdout=run=6") && line.contains(&p.source_sha256[..16]),
        "{line}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A campaign of many runs is cross-validated in at most `--max-folds` (default 20)
/// folds of consecutive runs, and the JSON says so.
#[test]
fn many_runs_are_grouped_into_at_most_twenty_folds() {
    let dir = scratch("folds");
    let (csv, json) = (dir.join("s.csv"), dir.join("j.json"));
    synthetic_csv(&csv, 50, 1.0, 9);
    let r = axcomp(&[
        "fit",
        "positioning",
        "--data",
        csv.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let j = read_json(&json);
    assert_eq!(j["cv"]["method"], "leave-runs-out");
    assert_eq!(j["cv"]["folds"], 20);
    assert_eq!(j["cv"]["grouped"], true);
    assert!(
        j["cv"]["note"]
            .as_str()
            .unwrap()
            .contains("50 runs grouped into 20 folds")
    );
    // Folds of 2–3 runs: every after-figure is defined (s from ≥ 2 runs per fold).
    check_iso(&j);
    assert_eq!(j["iso230_2_per_fold"].as_array().unwrap().len(), 20);
    assert!(j["iso230_2_after"]["A_um"].as_f64().is_some());
    // Close to σ = 1 µm (the generator's noise) on unseen runs.
    assert!(num(&j, "cv_rms_um") < 1.1, "{}", j["cv_rms_um"]);
    std::fs::remove_dir_all(&dir).unwrap();
}
