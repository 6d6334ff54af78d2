//! Withheld-effect validation of the diagnosis on touch-probe data: twin campaigns of touches
//! in which one probe effect is present but left out of the model told to the diagnosis (or none: null
//! cases), diagnosed blind.
//!
//! # Glossary
//! - **survey** ([`survey_plan`]): one plan for every case, so the plan never tells which effect was
//!   withheld. Training: a Ø25 mm calibration sphere at (100, 50, 20) mm (rings at 0°, 22.5°, 45°, 67.5° and
//!   the top, 18 azimuths, at 100, 300 and 600 mm/min, two runs), a plane grid (5 × 5 touches over
//!   160 × 120 mm at z = 2 mm), a Ø50 mm ring gauge (24 touches) and a ball plate of five Ø10 mm spheres
//!   spread over the volume ([`BALL_PLATE`]; 17 touches each) — the machine's error at several places with
//!   the same probe. Held out, last: a Ø19.05 mm sphere at (130, 100, 15) mm (rings at 10°, 35°, 60°, 80°,
//!   16 azimuths offset from the calibration's, at 200 and 450 mm/min: speeds between the calibration's).
//!   Touches are 3 s apart; the frame warms up by 2 K with τ = 30 min in every case (sensor `frame_degC`).
//! - **held out**: `artefact=sphere2`, fixed before any case is drawn.
//! - **probe without the withheld effect**: one isotropic pretravel (3 µm), no lobes, no speed term, no
//!   latency, no bending, no machine error, no thermal drift; noise σ along the approach.
//! - **withheld effects** (each at unit size, then scaled): `lobing` (three lobes, random orientation),
//!   `speed_pretravel` (lateral speed term with an axial one 0–30 % of it: direction-dependent),
//!   `stylus_bending` (∝ cos of the elevation), `latch_latency` (v·latency along the approach),
//!   `machine_geometry` (a random polynomial error field of degree ≤ 2 over the machine's volume),
//!   `thermal_drift` (the tip drifting relative to the artefacts ∝ the frame's temperature rise, random
//!   direction).
//! - **SNR**: held-out peak of the withheld effect's radial contribution once the held-out sphere's own
//!   placement is projected out (nobody can see that part), or of its part the told model cannot absorb
//!   when that is smaller, / noise σ.
//! - **oracle**: the base model plus the true withheld contribution as one column, refitted on the
//!   training rows.

use axcomp_diagnose::DiagnoseOptions;
use axcomp_diagnose::lsq;
use axcomp_diagnose::probe::{self as dprobe, ProbeData, ProbeModelSpec};
use axcomp_effects::ProbeEffect;
use axcomp_twin::probe::{
    Artefact, DisturbedTouch, MachineErrorField, PlannedTouch, ProbeModel, ProbePlan,
    TouchDisturbances, simulate_disturbed_touches,
};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;

use crate::harness::{self, CaseOutcome};

/// The held-out artefact of the survey.
pub const HOLDOUT_ARTEFACT: &str = "sphere2";

/// The kinds withheld in turn.
pub const WITHHELD: [ProbeEffect; 6] = [
    ProbeEffect::Lobing,
    ProbeEffect::SpeedPretravel,
    ProbeEffect::StylusBending,
    ProbeEffect::LatchLatency,
    ProbeEffect::MachineGeometry,
    ProbeEffect::ThermalDrift,
];

/// Settings of the probe validation.
#[derive(Debug, Clone)]
pub struct ProbeValidateOptions {
    pub cases: usize,
    pub seed: u64,
    /// SNRs cycled through by the non-null cases.
    pub snrs: Vec<f64>,
    /// Noise σ of the trigger point along the approach, µm.
    pub noise_um: f64,
    /// Every `null_every`-th case is a null case.
    pub null_every: usize,
    /// The hard profile: a probe with lobes and latch latency that the model is told about (those not
    /// withheld), withheld effects whose form lies outside the candidate's columns (speed pretravel ∝
    /// v^0.6…1, bending ∝ cos^1…2 φ, a machine error with cubic terms, a frame sensor lagging by 0–10 min).
    pub hard: bool,
}

impl Default for ProbeValidateOptions {
    fn default() -> Self {
        ProbeValidateOptions {
            cases: 100,
            seed: 1,
            snrs: vec![3.0, 4.0, 6.0, 8.0],
            noise_um: 0.5,
            null_every: 4,
            hard: false,
        }
    }
}

impl ProbeValidateOptions {
    pub fn build(self) -> Result<Self, String> {
        harness::check_common(self.cases, &self.snrs, self.noise_um, self.null_every)?;
        Ok(self)
    }
}

/// Centres of the ball plate's spheres, mm.
pub const BALL_PLATE: [[f64; 3]; 5] = [
    [30.0, 30.0, 5.0],
    [190.0, 30.0, 30.0],
    [30.0, 150.0, 30.0],
    [190.0, 150.0, 5.0],
    [110.0, 150.0, 15.0],
];

/// The survey plan (see the module glossary).
pub fn survey_plan() -> ProbePlan {
    let mut plan = ProbePlan::calibration(
        [100.0, 50.0, 20.0],
        25.0,
        &[0.0, 22.5, 45.0, 67.5, 90.0],
        18,
        &[100.0, 300.0, 600.0],
        2,
    );
    plan.artefacts
        .push(("plane".into(), Artefact::Plane { z_mm: 2.0 }));
    plan.artefacts.push((
        "ring".into(),
        Artefact::Ring {
            centre_mm: [60.0, 120.0, 5.0],
            diameter_mm: 50.0,
        },
    ));
    plan.artefacts.push((
        HOLDOUT_ARTEFACT.into(),
        Artefact::Sphere {
            centre_mm: [130.0, 100.0, 15.0],
            diameter_mm: 19.05,
        },
    ));
    let touch = |artefact, az, el, xy, feed| PlannedTouch {
        artefact,
        azimuth_deg: az,
        elevation_deg: el,
        at_xy_mm: xy,
        feed_mm_min: feed,
        run: 1,
    };
    for i in 0..5 {
        for j in 0..5 {
            let xy = [20.0 + 40.0 * i as f64, 20.0 + 30.0 * j as f64];
            plan.touches.push(touch(1, 0.0, 90.0, xy, 300.0));
        }
    }
    for k in 0..24 {
        plan.touches
            .push(touch(2, 3.0 + 15.0 * k as f64, 0.0, [0.0; 2], 300.0));
    }
    // A ball plate: five Ø10 mm spheres over the working volume (the machine's error where the probe's is
    // the same), each a ring at 0° and 45° of 8 touches and the top, 300 mm/min.
    for (k, c) in BALL_PLATE.iter().enumerate() {
        plan.artefacts.push((
            format!("ball{}", k + 1),
            Artefact::Sphere {
                centre_mm: *c,
                diameter_mm: 10.0,
            },
        ));
        let a = plan.artefacts.len() - 1;
        for &el in &[0.0, 45.0] {
            for m in 0..8 {
                plan.touches
                    .push(touch(a, 45.0 * m as f64 + el / 2.0, el, [0.0; 2], 300.0));
            }
        }
        plan.touches.push(touch(a, 0.0, 90.0, [0.0; 2], 300.0));
    }
    for &feed in &[200.0, 450.0] {
        for &el in &[10.0, 35.0, 60.0, 80.0] {
            for k in 0..16 {
                plan.touches
                    .push(touch(3, 7.0 + 22.5 * k as f64, el, [0.0; 2], feed));
            }
        }
    }
    plan
}

/// The probe without any withheld effect (isotropic 3 µm pretravel, noise σ, no glitches).
pub fn plain_probe(noise_um: f64) -> ProbeModel {
    ProbeModel {
        stylus_radius_mm: 1.5,
        lateral_base_um: 3.0,
        lobe_um: 0.0,
        lobe_phase_deg: 0.0,
        axial_um: 3.0,
        speed_um_per_mm_s: 0.0,
        latency_ms: 0.0,
        noise_um,
        bounce_prob: 0.0,
        bounce_um: (0.0, 0.0),
        false_trigger_prob: 0.0,
        false_trigger_mm: (0.0, 0.0),
    }
}

/// The probe and further effects with the withheld kind at unit size (random shape).
pub fn with_unit_effect(
    kind: ProbeEffect,
    probe: &ProbeModel,
    rng: &mut StdRng,
    hard: bool,
) -> (ProbeModel, TouchDisturbances, serde_json::Value) {
    let mut p = probe.clone();
    let mut d = TouchDisturbances::default();
    let truth = match kind {
        ProbeEffect::Lobing => {
            p.lobe_um = 1.0;
            p.lobe_phase_deg = rng.gen_range(0.0..120.0);
            serde_json::json!({"lobe_phase_deg": p.lobe_phase_deg})
        }
        ProbeEffect::SpeedPretravel => {
            d.speed_lateral_um_per_mm_s = 1.0;
            d.speed_axial_um_per_mm_s = rng.gen_range(0.0..0.3);
            if hard {
                d.speed_exponent = rng.gen_range(0.6..1.0);
            }
            serde_json::json!({"axial_over_lateral": d.speed_axial_um_per_mm_s, "speed_exponent": d.speed_exponent})
        }
        ProbeEffect::StylusBending => {
            d.stylus_bending_um = 1.0;
            if hard {
                d.stylus_bending_exponent = rng.gen_range(1.0..2.0);
            }
            serde_json::json!({"form": "cos(elevation)^k", "k": d.stylus_bending_exponent})
        }
        ProbeEffect::LatchLatency => {
            p.latency_ms = 1.0;
            serde_json::json!({})
        }
        ProbeEffect::MachineGeometry => {
            let mut m = || {
                let mut a = [[0.0; 3]; 3];
                for r in a.iter_mut() {
                    for x in r.iter_mut() {
                        *x = rng.gen_range(-1.0..1.0);
                    }
                }
                a
            };
            let (linear, square, cross) = (m(), m(), m());
            let cubic = if hard {
                m().map(|r| r.map(|x| 0.5 * x))
            } else {
                [[0.0; 3]; 3]
            };
            let f = MachineErrorField {
                origin_mm: [100.0, 80.0, 10.0],
                scale_mm: 100.0,
                linear,
                square,
                cross,
                cubic,
            };
            d.machine_error = Some(f);
            serde_json::json!({"degree": if hard { 3 } else { 2 }})
        }
        ProbeEffect::ThermalDrift => {
            let g: [f64; 3] = [0, 1, 2].map(|_| rng.gen_range(-1.0..1.0));
            let l = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt().max(1e-6);
            d.drift_um_per_k = g.map(|x| x / l);
            if hard {
                d.sensor_lag_s = rng.gen_range(0.0..600.0);
            }
            serde_json::json!({"direction": d.drift_um_per_k, "sensor_lag_s": d.sensor_lag_s})
        }
    };
    (p, d, truth)
}

/// Probe data from disturbed touches (`artefact=sphere2` held out).
pub fn probe_data(t: &[DisturbedTouch]) -> ProbeData {
    ProbeData {
        touches: t
            .iter()
            .map(|d| axcomp_probe::Touch {
                position_mm: d.touch.latched_mm,
                approach: d.touch.approach,
                feed_mm_min: d.touch.feed_mm_min,
            })
            .collect(),
        artefact: t.iter().map(|d| d.touch.artefact.clone()).collect(),
        run: Some(t.iter().map(|d| d.touch.run.to_string()).collect()),
        time_s: Some(t.iter().map(|d| d.time_s).collect()),
        temperatures: vec![("frame".into(), t.iter().map(|d| d.frame_degc).collect())],
        held_out: t
            .iter()
            .map(|d| d.touch.artefact == HOLDOUT_ARTEFACT)
            .collect(),
        labels: (0..t.len()).map(|i| format!("touch {i}")).collect(),
    }
}

/// One simulated case with its truth.
pub struct ProbeCase {
    pub index: usize,
    pub seed: u64,
    pub withheld: Option<ProbeEffect>,
    pub snr: Option<f64>,
    pub model: ProbeModelSpec,
    pub data: ProbeData,
    /// The scaled withheld contribution to the (linearised, placement-projected) radial residual, µm.
    pub truth_um: Vec<f64>,
    pub truth_params: serde_json::Value,
}

/// Training residual of `v` after the base model of `c`, on every row.
fn base_residual(c: &dprobe::ProbeCampaign, v: &[f64]) -> Vec<f64> {
    let fit = lsq::fit(&c.base_columns, v, &c.train);
    (0..v.len())
        .map(|i| v[i] - fit.predict(&c.base_columns, i))
        .collect()
}

/// Simulates case `index` (deterministic in `opts.seed` and `index`).
pub fn make_case(opts: &ProbeValidateOptions, index: usize) -> Result<ProbeCase, String> {
    let seed = opts
        .seed
        .wrapping_mul(1_000_003)
        .wrapping_add(index as u64)
        .wrapping_add(0x5eed_0012);
    let mut rng = StdRng::seed_from_u64(seed);
    let scheduled = harness::schedule(index, opts.null_every, WITHHELD.len(), &opts.snrs);
    let withheld = scheduled.map(|(k, _)| WITHHELD[k]);
    let snr = scheduled.map(|(_, s)| s);
    let plan = survey_plan();
    let mut probe = plain_probe(opts.noise_um);
    let mut told = Vec::new();
    if opts.hard {
        // Lobes and latch latency present and told, unless withheld.
        if withheld != Some(ProbeEffect::Lobing) {
            probe.lobe_um = 2.0;
            probe.lobe_phase_deg = rng.gen_range(0.0..120.0);
            told.push(ProbeEffect::Lobing);
        }
        if withheld != Some(ProbeEffect::LatchLatency) {
            probe.latency_ms = 0.3;
            told.push(ProbeEffect::LatchLatency);
        }
    }
    let model = ProbeModelSpec {
        pretravel: false,
        extra: told,
    };
    let dist0 = TouchDisturbances::default();
    let null_touches = simulate_disturbed_touches(&probe, &dist0, &plan, seed);
    let null_data = probe_data(&null_touches);
    let Some(kind) = withheld else {
        let n = null_data.touches.len();
        return Ok(ProbeCase {
            index,
            seed,
            withheld,
            snr,
            model,
            data: null_data,
            truth_um: vec![0.0; n],
            truth_params: serde_json::json!({}),
        });
    };
    let (p1, d1, truth_params) = with_unit_effect(kind, &probe, &mut rng, opts.hard);
    let unit_touches = simulate_disturbed_touches(&p1, &d1, &plan, seed);
    // The effect in position space (exactly what the unit effect adds to every latched point).
    let scaled = |f: f64| -> ProbeData {
        let mut d = null_data.clone();
        for (k, t) in d.touches.iter_mut().enumerate() {
            for a in 0..3 {
                t.position_mm[a] +=
                    f * (unit_touches[k].touch.latched_mm[a] - null_touches[k].touch.latched_mm[a]);
            }
        }
        d
    };
    let c0 = dprobe::build(&null_data, &model).map_err(|e| e.to_string())?;
    let c1 = dprobe::build(&scaled(1.0), &model).map_err(|e| e.to_string())?;
    let contrib: Vec<f64> = c1.y.iter().zip(&c0.y).map(|(a, b)| a - b).collect();
    let hold = &c0.holdout;
    let peak = |v: &[f64]| hold.iter().map(|&i| v[i].abs()).fold(0.0, f64::max);
    let raw_peak = peak(&contrib);
    let left_peak = peak(&base_residual(&c0, &contrib));
    let p = raw_peak.min(left_peak);
    if p.is_nan() || p <= 1e-9 {
        return Err(format!(
            "case {index}: withheld {kind} does not show on the held-out touches (peak {p:.3e} µm)"
        ));
    }
    let f = snr.expect("non-null") * opts.noise_um / p;
    let data = scaled(f);
    let c = dprobe::build(&data, &model).map_err(|e| e.to_string())?;
    let truth_um = c.y.iter().zip(&c0.y).map(|(a, b)| a - b).collect();
    Ok(ProbeCase {
        index,
        seed,
        withheld,
        snr,
        model,
        data,
        truth_um,
        truth_params,
    })
}

/// The diagnosis of one case.
#[derive(Debug, Clone, Serialize)]
pub struct ProbeCaseResult {
    pub index: usize,
    pub seed: u64,
    pub withheld: String,
    pub snr: Option<f64>,
    pub verdict: String,
    pub ties: Vec<String>,
    /// Verdict = withheld (or `none` on a null case).
    pub correct: bool,
    /// The withheld kind among the verdict and its ties.
    pub correct_or_tied: bool,
    pub gap_um: f64,
    pub shrink_pct: f64,
    pub oracle_shrink_pct: Option<f64>,
    pub truth: serde_json::Value,
    pub seconds: f64,
}

/// Held-out RMS of `y` after the base columns plus `extra` fitted on the training rows.
fn holdout_rms_after(c: &dprobe::ProbeCampaign, extra: Option<&[f64]>) -> f64 {
    let mut cols = c.base_columns.clone();
    if let Some(e) = extra {
        cols.push(e.to_vec());
    }
    harness::holdout_rms_after_fit(&cols, &c.y, &c.train, &c.holdout)
}

/// Simulates and diagnoses case `index`.
pub fn run_case(opts: &ProbeValidateOptions, index: usize) -> Result<ProbeCaseResult, String> {
    let t0 = std::time::Instant::now();
    let case = make_case(opts, index)?;
    let campaign = dprobe::build(&case.data, &case.model).map_err(|e| e.to_string())?;
    let pd = dprobe::diagnose(&campaign, &DiagnoseOptions::default()).map_err(|e| e.to_string())?;
    let d = &pd.diagnosis;
    let expect = case
        .withheld
        .map_or("none".to_string(), |k| k.name().to_string());
    let shrink = d.verdict_candidate().map_or(0.0, |c| c.shrink_pct);
    let oracle = case.withheld.map(|_| {
        let before = holdout_rms_after(&campaign, None);
        let after = holdout_rms_after(&campaign, Some(&case.truth_um));
        harness::shrink_pct(before, after)
    });
    Ok(ProbeCaseResult {
        index,
        seed: case.seed,
        withheld: expect.clone(),
        snr: case.snr,
        correct: d.verdict == expect,
        correct_or_tied: d.verdict == expect || d.ties.contains(&expect),
        verdict: d.verdict.clone(),
        ties: d.ties.clone(),
        gap_um: d.gap.holdout_rms_um,
        shrink_pct: shrink,
        oracle_shrink_pct: oracle,
        truth: case.truth_params,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// Top-1 accuracy at one SNR.
#[derive(Debug, Clone, Serialize)]
pub struct ProbeSnrRow {
    pub snr: f64,
    pub cases: usize,
    pub top1_pct: f64,
    pub top1_or_tied_pct: f64,
}

/// Per withheld kind.
#[derive(Debug, Clone, Serialize)]
pub struct ProbeKindRow {
    pub kind: String,
    pub cases: usize,
    pub top1_pct: f64,
    /// Verdicts given (kind → count).
    pub verdicts: std::collections::BTreeMap<String, usize>,
}

/// The figures.
#[derive(Debug, Clone, Serialize)]
pub struct ProbeSummary {
    /// `probe` or `probe-hard`.
    pub profile: String,
    pub cases: usize,
    pub seed: u64,
    pub noise_um: f64,
    pub holdout: String,
    /// Top-1 over the non-null cases at SNR ≥ 4 (target ≥ 90 %).
    pub top1_snr_ge4_pct: f64,
    pub top1_snr_ge4_cases: usize,
    /// Null cases with a verdict other than `none` (target ≤ 5 %).
    pub false_alarm_pct: f64,
    pub null_cases: usize,
    /// Median of the verdict's held-out shrink / the oracle's, correct non-null cases.
    pub median_shrink_over_oracle: Option<f64>,
    pub by_snr: Vec<ProbeSnrRow>,
    pub by_kind: Vec<ProbeKindRow>,
    pub results: Vec<ProbeCaseResult>,
}

harness::case_outcome!(ProbeCaseResult, withheld);

/// Summarises case results.
pub fn summarise(opts: &ProbeValidateOptions, results: Vec<ProbeCaseResult>) -> ProbeSummary {
    let non_null: Vec<&ProbeCaseResult> = results.iter().filter(|r| r.snr.is_some()).collect();
    let ge4 = harness::at_snr_ge(&results, 4.0);
    let nulls: Vec<&ProbeCaseResult> = results.iter().filter(|r| r.is_null()).collect();
    let by_snr = harness::snr_levels(opts.snrs.iter().copied())
        .into_iter()
        .map(|s| {
            let rows = harness::at_snr(&results, s);
            ProbeSnrRow {
                snr: s,
                cases: rows.len(),
                top1_pct: harness::pct(rows.iter().map(|r| r.correct)),
                top1_or_tied_pct: harness::pct(rows.iter().map(|r| r.correct_or_tied)),
            }
        })
        .collect();
    let by_kind = WITHHELD
        .iter()
        .map(|k| {
            let rows: Vec<&&ProbeCaseResult> =
                non_null.iter().filter(|r| r.withheld == k.name()).collect();
            let mut verdicts = std::collections::BTreeMap::new();
            for r in &rows {
                *verdicts.entry(r.verdict.clone()).or_insert(0) += 1;
            }
            ProbeKindRow {
                kind: k.name().into(),
                cases: rows.len(),
                top1_pct: harness::pct(rows.iter().map(|r| r.correct)),
                verdicts,
            }
        })
        .collect();
    let mut ratios: Vec<f64> = non_null
        .iter()
        .filter(|r| r.correct)
        .filter_map(|r| {
            r.oracle_shrink_pct
                .filter(|o| *o > 0.0)
                .map(|o| r.shrink_pct / o)
        })
        .collect();
    ProbeSummary {
        profile: if opts.hard { "probe-hard" } else { "probe" }.into(),
        cases: results.len(),
        seed: opts.seed,
        noise_um: opts.noise_um,
        holdout: format!("artefact={HOLDOUT_ARTEFACT}"),
        top1_snr_ge4_pct: harness::pct(ge4.iter().map(|r| r.correct)),
        top1_snr_ge4_cases: ge4.len(),
        false_alarm_pct: harness::pct(nulls.iter().map(|r| r.verdict != "none")),
        null_cases: nulls.len(),
        median_shrink_over_oracle: (!ratios.is_empty())
            .then(|| axcomp_numeric::stats::upper_median(&mut ratios)),
        by_snr,
        by_kind,
        results,
    }
}

/// Runs every case (`progress` after each).
pub fn validate(
    opts: &ProbeValidateOptions,
    mut progress: impl FnMut(&ProbeCaseResult),
) -> Result<ProbeSummary, String> {
    let results = harness::run_cases(opts.cases, |i| run_case(opts, i), &mut progress)?;
    Ok(summarise(opts, results))
}

impl ProbeSummary {
    /// Markdown tables.
    pub fn to_markdown(&self) -> String {
        let f = |x: f64| {
            if x.is_nan() {
                "–".to_string()
            } else {
                format!("{x:.1} %")
            }
        };
        let mut s = format!(
            "## Withheld-effect validation on probe touches ({}: {} cases, seed {}, noise σ {} µm, held out: {})\n\n\
             | figure | value | target |\n|---|---|---|\n\
             | top-1 at SNR ≥ 4 ({} cases) | {} | ≥ 90 % |\n\
             | false alarms on null cases ({} cases) | {} | ≤ 5 % |\n\
             | median verdict shrink / oracle shrink (correct cases) | {} | – |\n\n\
             | SNR | cases | top-1 | top-1 or tied |\n|---|---|---|---|\n",
            self.profile,
            self.cases,
            self.seed,
            self.noise_um,
            self.holdout,
            self.top1_snr_ge4_cases,
            f(self.top1_snr_ge4_pct),
            self.null_cases,
            f(self.false_alarm_pct),
            self.median_shrink_over_oracle
                .map_or("–".into(), |r| format!("{r:.3}")),
        );
        for r in &self.by_snr {
            s += &format!(
                "| {} | {} | {} | {} |\n",
                r.snr,
                r.cases,
                f(r.top1_pct),
                f(r.top1_or_tied_pct)
            );
        }
        s += "\n| withheld | cases | top-1 | verdicts |\n|---|---|---|---|\n";
        for r in &self.by_kind {
            let v: Vec<String> = r.verdicts.iter().map(|(k, n)| format!("{k} {n}")).collect();
            s += &format!(
                "| {} | {} | {} | {} |\n",
                r.kind,
                r.cases,
                f(r.top1_pct),
                v.join(", ")
            );
        }
        s
    }
}
