//! Withheld-effect validation of the R-test diagnosis on the five-axis twin
//! (`axcomp validate-diagnosis --harness rtest`): many campaigns of a machine with random location
//! errors, each with one effect beyond them present in the twin (or none), diagnosed blind with the model
//! `location_errors`.
//!
//! Glossary:
//! - **plan** (the same for every case, whatever is withheld — the plan never tells the answer): sphere
//!   set-up 1 — K4 (72 poses, tilt 0 → −60° → 0), C circles at tilt 0° and −60° (36 poses each); sphere
//!   set-up 2 at another radius and height — the same two circles; then, **held out** (`run = 2`): a C
//!   circle at −30° and a second K4, measured last. 6 s per pose (32 min in all); the spindle temperature
//!   is logged (`spindle_degC`: a warm-up and the shop's air-conditioning cycle).
//! - **withheld**: one of the twin's effects beyond the location errors (`rotary_positioning`,
//!   `rotary_wobble`, `radial_runout` — a `rotary_wobble` in the contract's vocabulary —, `linear_geometry`,
//!   `setup_drift`, `thermal_drift`, `time_drift`) or none (every `null_every`-th case).
//! - **SNR**: the peak |contribution| of the withheld effect on the held-out rows — or, when smaller, of its
//!   part the location-error model cannot absorb (the residual of the model fitted to the effect alone on
//!   the training poses) — divided by the noise σ; the effect's magnitudes are scaled to it exactly.
//! - **oracle**: the linearised base model plus the true withheld contribution as one column, refitted on
//!   the training rows.
//! - **top-1**: the verdict is the withheld kind; **top-1 or tie**: the withheld kind is the verdict or
//!   one of its reported ties.
//! - machines cycle through `ac-trunnion` and `bc-trunnion` (and `bc-head` with `--machines`; on a head the
//!   sphere and the tool drift share the machine frame, so `setup_drift` and `time_drift` have the same
//!   signature and the diagnosis reports a tie).

use std::time::Instant;

use axcomp_diagnose::judge::DiagnoseOptions;
use axcomp_diagnose::rtest::{self as diag, RtestObservations};
use axcomp_effects::RotaryEffect;
use axcomp_kinematics::rotary::{FiveAxis, MachineKind, c_circle, k4_path};
use axcomp_rtest::RtestData;
use axcomp_twin::five_axis::{EffectParams, FiveAxisTwin, RtestCampaign, RtestPathSpec};
use serde::Serialize;

use crate::harness::{self, CaseOutcome, Unlisted};

/// The twin's effects that can be withheld, in the order cases cycle through them.
pub const WITHHELD: [&str; 7] = [
    "rotary_positioning",
    "rotary_wobble",
    "linear_geometry",
    "setup_drift",
    "thermal_drift",
    "time_drift",
    "radial_runout",
];

/// The contract kind of a twin effect (`radial_runout` is a `rotary_wobble`).
pub fn contract_kind(twin_effect: &str) -> RotaryEffect {
    match twin_effect {
        "radial_runout" => RotaryEffect::RotaryWobble,
        other => other
            .parse()
            .expect("a twin effect of the R-test vocabulary"),
    }
}

/// Settings of an R-test validation run.
#[derive(Debug, Clone)]
pub struct RtestValidateOptions {
    pub cases: usize,
    pub seed: u64,
    pub snrs: Vec<f64>,
    pub noise_um: f64,
    pub machines: Vec<MachineKind>,
    pub null_every: usize,
}

impl Default for RtestValidateOptions {
    fn default() -> Self {
        RtestValidateOptions {
            cases: 100,
            seed: 1,
            snrs: vec![3.0, 4.0, 6.0, 8.0],
            noise_um: 0.3,
            machines: vec![
                MachineKind::AcTrunnion,
                MachineKind::BcTrunnion,
                MachineKind::BcHead,
            ],
            null_every: 4,
        }
    }
}

impl RtestValidateOptions {
    pub fn build(self) -> Result<Self, String> {
        harness::check_common(self.cases, &self.snrs, self.noise_um, self.null_every)?;
        if self.machines.is_empty() {
            return Err("at least one machine kind".into());
        }
        Ok(self)
    }
}

/// Bc-head pivot length used by the harness, mm.
pub const HEAD_PIVOT_MM: f64 = 250.0;
/// Seconds per pose.
pub const DWELL_S: f64 = 6.0;

/// The fixed plan (see the module glossary); held out: `run == 2`.
pub fn plan(machine: &FiveAxis) -> Vec<RtestPathSpec> {
    let (s1, s2) = if machine.kind == MachineKind::BcHead {
        ([0.0, 0.0, 0.0], [100.0, 50.0, -60.0])
    } else {
        ([120.0, 80.0, 100.0], [60.0, -100.0, 180.0])
    };
    let spec = |path: &str, run, setup: &str, s: [f64; 3], poses| RtestPathSpec {
        path: path.into(),
        run,
        setup: setup.into(),
        sphere_mm: s,
        poses,
    };
    vec![
        spec("K4", 1, "1", s1, k4_path(machine, s1, -60.0, 72)),
        spec("C-circle@0", 1, "1", s1, c_circle(machine, s1, 0.0, 36)),
        spec("C-circle@-60", 1, "1", s1, c_circle(machine, s1, -60.0, 36)),
        spec("C-circle@0-s2", 1, "2", s2, c_circle(machine, s2, 0.0, 36)),
        spec(
            "C-circle@-60-s2",
            1,
            "2",
            s2,
            c_circle(machine, s2, -60.0, 36),
        ),
        spec("C-circle@-30", 2, "1", s1, c_circle(machine, s1, -30.0, 36)),
        spec("K4", 2, "1", s1, k4_path(machine, s1, -60.0, 72)),
    ]
}

/// R-test observations from a twin campaign (no CSV round trip); held out: `run == 2`.
pub fn observations(c: &RtestCampaign) -> RtestObservations {
    let mut setup_names: Vec<String> = Vec::new();
    let setup = c
        .rows
        .iter()
        .map(|r| match setup_names.iter().position(|s| *s == r.setup) {
            Some(k) => k,
            None => {
                setup_names.push(r.setup.clone());
                setup_names.len() - 1
            }
        })
        .collect();
    let data = RtestData {
        machine: c.machine,
        source: "twin".into(),
        poses: c.rows.iter().map(|r| r.pose).collect(),
        d_um: c.rows.iter().map(|r| r.d_um).collect(),
        path: c.rows.iter().map(|r| r.path.clone()).collect(),
        setup,
        setup_names,
        lines: (0..c.rows.len()).map(|i| i + 3).collect(),
        free_head_zero: false,
    };
    RtestObservations {
        data,
        held_out: c.rows.iter().map(|r| r.run == 2).collect(),
        run: c.rows.iter().map(|r| r.run.to_string()).collect(),
        time_s: Some(c.rows.iter().map(|r| r.time_s).collect()),
        temperatures: if c.temperature_sensor {
            vec![(
                "spindle".to_string(),
                c.rows.iter().map(|r| r.spindle_degc).collect(),
            )]
        } else {
            Vec::new()
        },
    }
}

/// Multiplies the magnitudes of one twin effect by `s`.
pub fn scale_effect(q: &mut EffectParams, effect: &str, s: f64) {
    match effect {
        "rotary_positioning" => {
            q.c_pos[0] *= s;
            q.c_pos[1] *= s;
            q.tilt_pos_urad_per_rad *= s;
        }
        "rotary_wobble" => q.wobble[0] *= s,
        "radial_runout" => q.runout[0] *= s,
        "linear_geometry" => q.linear.iter_mut().for_each(|v| *v *= s),
        "thermal_drift" => q.thermal_um_h.iter_mut().for_each(|v| *v *= s),
        "setup_drift" => q.setup_um_h.iter_mut().for_each(|v| *v *= s),
        "time_drift" => q.time_um_h.iter_mut().for_each(|v| *v *= s),
        other => panic!("unknown twin effect {other}"),
    }
}

/// One diagnosed case.
#[derive(Debug, Clone, Serialize)]
pub struct RtestCaseResult {
    pub index: usize,
    pub machine: String,
    /// Twin effect withheld (`none` for a null case).
    pub withheld: String,
    /// Its contract kind (`none` for a null case).
    pub withheld_kind: String,
    pub snr: Option<f64>,
    /// Held-out peak of the unabsorbed part / peak of the whole effect.
    pub unabsorbed_peak_ratio: Option<f64>,
    pub verdict: String,
    pub ties: Vec<String>,
    pub correct: bool,
    /// The withheld kind is the verdict or one of its ties.
    pub correct_or_tied: bool,
    pub holdout_rms_before_um: f64,
    pub shrink_pct: f64,
    pub oracle_shrink_pct: Option<f64>,
    pub seconds: f64,
}

/// The twin of case `index` (machine, truth, withheld effect scaled to its SNR).
pub struct RtestCase {
    pub twin: FiveAxisTwin,
    pub paths: Vec<RtestPathSpec>,
    pub withheld: Option<&'static str>,
    pub snr: Option<f64>,
    pub unabsorbed_peak_ratio: Option<f64>,
    /// The withheld effect's true contribution per pose (µm), noise-free.
    pub contribution: Vec<[f64; 3]>,
    pub noise_seed: u64,
}

fn held_out_peak(v: &[[f64; 3]], held: &[bool]) -> f64 {
    v.iter()
        .zip(held)
        .filter(|(_, h)| **h)
        .flat_map(|(d, _)| d.iter().map(|x| x.abs()))
        .fold(0.0, f64::max)
}

/// Builds case `index`: the machine kinds, withheld effects and SNRs cycle; every `null_every`-th case is
/// a null case.
pub fn make_case(opts: &RtestValidateOptions, index: usize) -> Result<RtestCase, String> {
    let seed = opts.seed.wrapping_mul(1_000_003).wrapping_add(index as u64);
    // Machines alternate across null and non-null cases alike.
    let kind = opts.machines[(index + index / opts.null_every) % opts.machines.len()];
    let machine = FiveAxis::new(kind, HEAD_PIVOT_MM);
    let mut twin = FiveAxisTwin::random(machine, seed);
    twin.noise_um = opts.noise_um;
    twin.dwell_s = DWELL_S;
    twin.temperature_sensor = true;
    let paths = plan(&machine);
    // Non-null cases cycle through the effects, then the SNRs.
    let scheduled = harness::schedule(index, opts.null_every, WITHHELD.len(), &opts.snrs);
    let withheld = scheduled.map(|(k, _)| WITHHELD[k]);
    let snr = scheduled.map(|(_, s)| s);
    let mut contribution = vec![[0.0; 3]; paths.iter().map(|p| p.poses.len()).sum()];
    let mut unabsorbed_peak_ratio = None;
    if let (Some(w), Some(snr)) = (withheld, snr) {
        let mut clean = twin.clone();
        clean.noise_um = 0.0;
        let mut on = clean.clone();
        on.effects.enable(w);
        let (a, b) = (on.measure(&paths, 0), clean.measure(&paths, 0));
        let contrib: Vec<[f64; 3]> = a
            .rows
            .iter()
            .zip(&b.rows)
            .map(|(x, y)| [0, 1, 2].map(|i| x.d_um[i] - y.d_um[i]))
            .collect();
        // The part the location-error model cannot absorb: the residual of the model fitted to the
        // effect alone on the training poses.
        let mut alone = a.clone();
        for (r, c) in alone.rows.iter_mut().zip(&contrib) {
            r.d_um = *c;
        }
        let obs = observations(&alone);
        let camp = diag::campaign(&obs, &[]).map_err(|e| e.to_string())?;
        let unabsorbed: Vec<[f64; 3]> = (0..contrib.len())
            .map(|i| [0, 1, 2].map(|c| camp.y[3 * i + c]))
            .collect();
        let raw = held_out_peak(&contrib, &obs.held_out);
        let un = held_out_peak(&unabsorbed, &obs.held_out);
        if raw.is_nan() || raw <= 0.0 {
            return Err(format!(
                "case {index}: withheld effect {w} is zero on the held-out poses"
            ));
        }
        let peak = raw.min(un.max(1e-12));
        let s = snr * opts.noise_um / peak;
        scale_effect(&mut twin.effect_params, w, s);
        twin.effects.enable(w);
        contribution = contrib.iter().map(|c| c.map(|x| x * s)).collect();
        unabsorbed_peak_ratio = Some(un / raw);
    }
    Ok(RtestCase {
        twin,
        paths,
        withheld,
        snr,
        unabsorbed_peak_ratio,
        contribution,
        noise_seed: seed ^ 0x006e_6f69_7365,
    })
}

/// Runs case `index`: measures, diagnoses blind (`--model location_errors`), compares with the oracle.
pub fn run_case(opts: &RtestValidateOptions, index: usize) -> Result<RtestCaseResult, String> {
    let case = make_case(opts, index)?;
    let campaign = case.twin.measure(&case.paths, case.noise_seed);
    let obs = observations(&campaign);
    let t0 = Instant::now();
    let dopts = DiagnoseOptions::default()
        .build()
        .map_err(|e| e.to_string())?;
    let (d, camp) = diag::diagnose(&obs, &[], &dopts).map_err(|e| e.to_string())?;
    let seconds = t0.elapsed().as_secs_f64();
    let dg = &d.diagnosis;
    let truth = case.withheld.map(contract_kind);
    let correct = match truth {
        Some(k) => dg.verdict == k.name(),
        None => dg.verdict == "none",
    };
    let correct_or_tied = correct || truth.is_some_and(|k| dg.ties.iter().any(|t| t == k.name()));
    let shrink_pct = dg
        .effects
        .iter()
        .find(|c| c.kind == dg.verdict)
        .map_or(0.0, |c| c.shrink_pct);
    let oracle_shrink_pct = truth.map(|_| {
        let col: Vec<f64> = case.contribution.iter().flat_map(|c| *c).collect();
        let mut cols: Vec<&[f64]> = camp.base_columns.iter().map(|c| c.as_slice()).collect();
        let ones = vec![1.0; camp.y.len()];
        cols.push(&ones);
        let b = harness::holdout_rms_after_fit(&cols, &camp.y, &camp.train, &camp.holdout);
        cols.push(&col);
        let a = harness::holdout_rms_after_fit(&cols, &camp.y, &camp.train, &camp.holdout);
        harness::shrink_pct(b, a)
    });
    Ok(RtestCaseResult {
        index,
        machine: case.twin.machine.kind.name().to_string(),
        withheld: case.withheld.unwrap_or("none").to_string(),
        withheld_kind: truth.map_or("none".to_string(), |k| k.name().to_string()),
        snr: case.snr,
        unabsorbed_peak_ratio: case.unabsorbed_peak_ratio,
        verdict: dg.verdict.clone(),
        ties: dg.ties.clone(),
        correct,
        correct_or_tied,
        holdout_rms_before_um: dg.gap.holdout_rms_um,
        shrink_pct,
        oracle_shrink_pct,
        seconds,
    })
}

/// Figures per SNR.
#[derive(Debug, Clone, Serialize)]
pub struct RtestSnrRow {
    pub snr: f64,
    pub cases: usize,
    pub detection_rate: f64,
    pub top1: f64,
    pub top1_or_tie: f64,
}

/// The summary (`--json` writes it with the cases).
#[derive(Debug, Clone, Serialize)]
pub struct RtestSummary {
    pub harness: &'static str,
    pub cases: usize,
    pub null_cases: usize,
    pub noise_um: f64,
    pub seed: u64,
    pub machines: Vec<String>,
    pub per_snr: Vec<RtestSnrRow>,
    pub false_alarm_rate: f64,
    pub top1_snr_ge_4: f64,
    pub top1_or_tie_snr_ge_4: f64,
    pub cases_snr_ge_4: usize,
    /// Per withheld twin effect at SNR ≥ 4: (effect, cases, top-1).
    pub per_effect_snr_ge_4: Vec<(String, usize, f64)>,
    pub median_seconds: f64,
    /// labels = `none` + the contract kinds; `confusion[withheld][verdict]`.
    pub labels: Vec<String>,
    pub confusion: Vec<Vec<usize>>,
    pub case_results: Vec<RtestCaseResult>,
}

harness::case_outcome!(RtestCaseResult, withheld_kind);

/// Summarises case results.
pub fn summarise(opts: &RtestValidateOptions, results: Vec<RtestCaseResult>) -> RtestSummary {
    let per_snr = harness::snr_levels(opts.snrs.iter().copied())
        .into_iter()
        .map(|s| {
            let cs = harness::at_snr(&results, s);
            RtestSnrRow {
                snr: s,
                cases: cs.len(),
                detection_rate: harness::share(cs.iter().map(|c| c.verdict != "none")),
                top1: harness::share(cs.iter().map(|c| c.correct)),
                top1_or_tie: harness::share(cs.iter().map(|c| c.correct_or_tied)),
            }
        })
        .collect();
    let ge4 = harness::at_snr_ge(&results, 4.0);
    let mut labels = vec!["none".to_string()];
    labels.extend(RotaryEffect::ALL.iter().map(|k| k.name().to_string()));
    let confusion = harness::confusion(&labels, &results, Unlisted::First);
    let per_effect_snr_ge_4 = WITHHELD
        .iter()
        .map(|w| {
            let cs: Vec<&&RtestCaseResult> = ge4.iter().filter(|c| c.withheld == *w).collect();
            (
                w.to_string(),
                cs.len(),
                harness::share(cs.iter().map(|c| c.correct)),
            )
        })
        .collect();
    let (mut secs, _) = harness::seconds(&results);
    RtestSummary {
        harness: "rtest",
        cases: results.len(),
        null_cases: results.iter().filter(|c| c.is_null()).count(),
        noise_um: opts.noise_um,
        seed: opts.seed,
        machines: opts.machines.iter().map(|m| m.name().to_string()).collect(),
        per_snr,
        false_alarm_rate: harness::false_alarm_rate(&results),
        top1_snr_ge_4: harness::share(ge4.iter().map(|c| c.correct)),
        top1_or_tie_snr_ge_4: harness::share(ge4.iter().map(|c| c.correct_or_tied)),
        cases_snr_ge_4: ge4.len(),
        per_effect_snr_ge_4,
        median_seconds: axcomp_numeric::stats::upper_median(&mut secs),
        labels,
        confusion,
        case_results: results,
    }
}

/// Runs every case, calling `progress` after each.
pub fn validate(
    opts: &RtestValidateOptions,
    mut progress: impl FnMut(&RtestCaseResult),
) -> Result<RtestSummary, String> {
    let results = harness::run_cases(opts.cases, |i| run_case(opts, i), &mut progress)?;
    Ok(summarise(opts, results))
}

impl RtestSummary {
    /// Markdown tables.
    pub fn to_markdown(&self) -> String {
        let mut s = format!(
            "Withheld-effect validation, rtest harness ({}): {} cases ({} null), noise σ {} µm, seed {}; plan: K4 + C circles at 0°/−60° on two sphere set-ups, held out: a C circle at −30° and a second K4 measured last.\n\n",
            self.machines.join(", "),
            self.cases,
            self.null_cases,
            self.noise_um,
            self.seed
        );
        s.push_str("| SNR | cases | detection | top-1 | top-1 or tie |\n|---|---|---|---|---|\n");
        for r in &self.per_snr {
            s.push_str(&format!(
                "| {} | {} | {:.1} % | {:.1} % | {:.1} % |\n",
                r.snr,
                r.cases,
                100.0 * r.detection_rate,
                100.0 * r.top1,
                100.0 * r.top1_or_tie
            ));
        }
        s.push_str(&format!(
            "\n| figure | value |\n|---|---|\n| top-1 at SNR ≥ 4 | {:.1} % ({} cases) |\n| top-1 or tie at SNR ≥ 4 | {:.1} % |\n| false alarms on nulls | {:.1} % ({} cases) |\n| diagnosis time per case (median) | {:.3} s |\n",
            100.0 * self.top1_snr_ge_4,
            self.cases_snr_ge_4,
            100.0 * self.top1_or_tie_snr_ge_4,
            100.0 * self.false_alarm_rate,
            self.null_cases,
            self.median_seconds
        ));
        s.push_str("\n| withheld (twin effect) | cases at SNR ≥ 4 | top-1 |\n|---|---|---|\n");
        for (w, n, t) in &self.per_effect_snr_ge_4 {
            s.push_str(&format!("| {w} | {n} | {:.1} % |\n", 100.0 * t));
        }
        s.push_str("\nConfusion matrix (rows: withheld kind, columns: verdict):\n\n");
        let rows: Vec<(String, &[usize])> = self
            .labels
            .iter()
            .cloned()
            .zip(self.confusion.iter().map(Vec::as_slice))
            .collect();
        s.push_str(&harness::counts_markdown(
            "withheld \\ verdict",
            &self.labels,
            &rows,
            true,
        ));
        s
    }
}
