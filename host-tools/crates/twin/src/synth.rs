//! Synthetic thermo-force campaigns with known truth (the twin reuses this generator).
//!
//! Glossary:
//! - **condition**: one operating condition, a spindle speed level with its process parameters (depth of
//!   cut `ap`, feed per tooth `fz`); the campaign runs each condition as a **heating phase** (spindle on,
//!   cutting) followed by a **cooling phase** (spindle off), one after another, continuously in time.
//! - **latent source**: an unobserved heat state (spindle bearings, drive, ambient); each follows its heat
//!   input through a first-order lag.
//! - **sensor**: a measured temperature, a mixture of the latent sources (each through its own short lag)
//!   plus white noise; sensors are therefore strongly collinear.
//! - **truth**: the error is `b0 + Σ b_k (lag(T_k, τ_k) − T_k(0)) + χ·F + noise` over a few *true* sensors
//!   `k` (their noise-free temperatures), with `F = K·ap^x·fz^y·n^z` while cutting.
//! - **oracle**: the true model (true sensors, coefficients, lags, χ) applied to the *measured* sensor and
//!   force columns: the best any fitted model can hope for.

use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal, Uniform};

use axcomp_effects::thermal_model::{ForceTerm, SensorTerm, Series, ThermalModel};
use axcomp_numeric::lag::lag;

/// Generator settings.
#[derive(Debug, Clone)]
pub struct SynthConfig {
    pub seed: u64,
    /// Sample interval (s).
    pub dt_s: f64,
    /// Spindle speed per condition (rpm); one condition per entry.
    pub speeds_rpm: Vec<f64>,
    /// Depth of cut and feed per tooth per condition (same length as `speeds_rpm`).
    pub ap_mm: Vec<f64>,
    pub fz_mm: Vec<f64>,
    pub heat_s: f64,
    pub cool_s: f64,
    pub n_sensors: usize,
    pub sensor_noise_degc: f64,
    pub error_noise_um: f64,
    /// Relative noise of the measured force.
    pub force_noise_rel: f64,
    /// True sensors (indices), coefficients (µm/K) and lags (s).
    pub true_sensors: Vec<usize>,
    pub true_coef_um_per_k: Vec<f64>,
    pub true_tau_s: Vec<f64>,
    pub b0_um: f64,
    pub chi_um_per_n: f64,
    /// Force law `F = k·ap^x·fz^y·n^z` (N).
    pub law: [f64; 4],
}

impl Default for SynthConfig {
    fn default() -> Self {
        SynthConfig {
            seed: 1,
            dt_s: 10.0,
            speeds_rpm: vec![4000.0, 6000.0, 8000.0, 10000.0, 12000.0],
            ap_mm: vec![1.0, 2.0, 1.5, 2.5, 1.2],
            fz_mm: vec![0.08, 0.05, 0.1, 0.06, 0.12],
            heat_s: 7200.0,
            cool_s: 3600.0,
            n_sensors: 16,
            sensor_noise_degc: 0.03,
            error_noise_um: 0.3,
            force_noise_rel: 0.02,
            true_sensors: vec![1, 6, 11],
            true_coef_um_per_k: vec![3.0, -2.0, 1.5],
            true_tau_s: vec![600.0, 1800.0, 0.0],
            b0_um: 1.0,
            chi_um_per_n: 0.01,
            law: [1800.0, 0.9, 0.75, -0.1],
        }
    }
}

/// A generated campaign.
#[derive(Debug, Clone)]
pub struct SynthData {
    pub time_s: Vec<f64>,
    pub condition: Vec<usize>,
    pub spindle_rpm: Vec<f64>,
    pub ap_mm: Vec<f64>,
    pub fz_mm: Vec<f64>,
    /// Measured force (N), 0 while not cutting.
    pub force_n: Vec<f64>,
    /// Sensor names (`s01`, `s02`, …), measured and noise-free temperatures.
    pub sensor_names: Vec<String>,
    pub sensors_degc: Vec<Vec<f64>>,
    pub sensors_true_degc: Vec<Vec<f64>>,
    /// Measured error (µm) and the noise-free error.
    pub error_um: Vec<f64>,
    pub error_true_um: Vec<f64>,
    pub truth: ThermalModel,
}

/// Generates a campaign from `cfg` (deterministic for a given seed).
pub fn generate(cfg: &SynthConfig) -> SynthData {
    let mut rng = StdRng::seed_from_u64(cfg.seed);
    let nc = cfg.speeds_rpm.len();
    let per = cfg.heat_s + cfg.cool_s;
    let n = ((nc as f64 * per) / cfg.dt_s).round() as usize;
    let time_s: Vec<f64> = (0..n).map(|k| k as f64 * cfg.dt_s).collect();
    let condition: Vec<usize> = time_s
        .iter()
        .map(|t| ((t / per) as usize).min(nc - 1))
        .collect();
    let running: Vec<bool> = time_s.iter().map(|t| t % per < cfg.heat_s).collect();
    let spindle_rpm: Vec<f64> = (0..n)
        .map(|k| {
            if running[k] {
                cfg.speeds_rpm[condition[k]]
            } else {
                0.0
            }
        })
        .collect();
    let ap_mm: Vec<f64> = (0..n)
        .map(|k| {
            if running[k] {
                cfg.ap_mm[condition[k]]
            } else {
                0.0
            }
        })
        .collect();
    let fz_mm: Vec<f64> = (0..n)
        .map(|k| {
            if running[k] {
                cfg.fz_mm[condition[k]]
            } else {
                0.0
            }
        })
        .collect();
    simulate(cfg, &mut rng, time_s, condition, spindle_rpm, ap_mm, fz_mm)
}

/// Sensors, force and error for a given schedule (speed, depth of cut, feed per row); the rest of
/// [`generate`], shared with [`spindle_campaign`].
fn simulate(
    cfg: &SynthConfig,
    rng: &mut StdRng,
    time_s: Vec<f64>,
    condition: Vec<usize>,
    spindle_rpm: Vec<f64>,
    ap_mm: Vec<f64>,
    fz_mm: Vec<f64>,
) -> SynthData {
    let n = time_s.len();
    let running: Vec<bool> = spindle_rpm.iter().map(|s| *s > 0.0).collect();
    let [k_law, x, y, z] = cfg.law;
    let force_true: Vec<f64> = (0..n)
        .map(|k| {
            if running[k] {
                k_law * ap_mm[k].powf(x) * fz_mm[k].powf(y) * spindle_rpm[k].powf(z)
            } else {
                0.0
            }
        })
        .collect();
    // Latent heat sources (K above ambient).
    let heat1: Vec<f64> = spindle_rpm
        .iter()
        .map(|s| 8.0 * (s / 12000.0).powf(1.5))
        .collect();
    let heat2: Vec<f64> = spindle_rpm.iter().map(|s| 5.0 * s / 12000.0).collect();
    let s1 = lag(&time_s, &prepend_zero(&heat1), 900.0);
    let s2 = lag(&time_s, &prepend_zero(&heat2), 2400.0);
    let phase = Uniform::new(0.0, std::f64::consts::TAU).sample(rng);
    let s3: Vec<f64> = time_s
        .iter()
        .map(|t| 1.2 * (std::f64::consts::TAU * t / 86400.0 + phase).sin())
        .collect();
    let sources = [s1, s2, s3];
    // Sensors: mixtures of the sources through short individual lags.
    let uw = Uniform::new(0.0, 0.3);
    let ut = Uniform::new(0.0, 400.0);
    let noise_t = Normal::new(0.0, cfg.sensor_noise_degc.max(1e-12)).unwrap();
    let mut sensor_names = vec![];
    let mut sensors_true = vec![];
    let mut sensors = vec![];
    for i in 0..cfg.n_sensors {
        let main = i % 3;
        let mut t = vec![20.0; n];
        for (j, s) in sources.iter().enumerate() {
            let w = if j == main {
                0.6 + uw.sample(rng)
            } else {
                uw.sample(rng)
            };
            let l = lag(&time_s, s, ut.sample(rng));
            for (tv, lv) in t.iter_mut().zip(l) {
                *tv += w * lv;
            }
        }
        let meas: Vec<f64> = t.iter().map(|v| v + noise_t.sample(rng)).collect();
        sensor_names.push(format!("s{:02}", i + 1));
        sensors_true.push(t);
        sensors.push(meas);
    }
    let noise_f = Normal::new(0.0, 1.0).unwrap();
    let force_n: Vec<f64> = force_true
        .iter()
        .map(|f| f * (1.0 + cfg.force_noise_rel * noise_f.sample(rng)))
        .collect();
    let truth = ThermalModel {
        b0_um: cfg.b0_um,
        terms: cfg
            .true_sensors
            .iter()
            .zip(&cfg.true_coef_um_per_k)
            .zip(&cfg.true_tau_s)
            .map(|((&s, &b), &tau)| SensorTerm {
                sensor: sensor_names[s].clone(),
                reference_degc: sensors_true[s][0],
                tau_s: tau,
                coef_um_per_k: b,
            })
            .collect(),
        forces: vec![ForceTerm {
            column: "force_N".into(),
            chi_um_per_n: cfg.chi_um_per_n,
        }],
    };
    let true_series: Vec<Series> = sensor_names
        .iter()
        .zip(&sensors_true)
        .map(|(name, v)| Series {
            name: name.clone(),
            values: v.clone(),
        })
        .collect();
    let error_true_um = truth
        .predict(
            &time_s,
            &true_series,
            &[Series {
                name: "force_N".into(),
                values: force_true.clone(),
            }],
        )
        .expect("truth uses generated columns");
    let noise_e = Normal::new(0.0, cfg.error_noise_um.max(1e-12)).unwrap();
    let error_um = error_true_um
        .iter()
        .map(|e| e + noise_e.sample(rng))
        .collect();
    SynthData {
        time_s,
        condition,
        spindle_rpm,
        ap_mm,
        fz_mm,
        force_n,
        sensor_names,
        sensors_degc: sensors,
        sensors_true_degc: sensors_true,
        error_um,
        error_true_um,
        truth,
    }
}

/// A campaign resembling a machine-tool spindle study: nine constant speeds (each heating 3 h under cut, then
/// 1.5 h stopped), then a 5.5 h block whose speed changes every 20 min among the nine levels and stops —
/// 46 h, 16 collinear sensors, one force column and five displacement channels, each with its own true
/// sensors, coefficients, lags and force compliance (truths in [`SpindleCampaign::channels`]).
#[derive(Debug, Clone)]
pub struct SpindleCampaign {
    /// The sensors, force and schedule; `condition` 0–8 are the constant speeds, 9 the variable block;
    /// `error_um` is channel 1.
    pub data: SynthData,
    /// Channel name, measured error (µm), truth model.
    pub channels: Vec<(String, Vec<f64>, ThermalModel)>,
}

/// Generates the spindle campaign (see [`SpindleCampaign`]), deterministic for a seed; sample interval
/// `dt_s`, error noise σ 0.3 µm.
pub fn spindle_campaign(seed: u64, dt_s: f64) -> SpindleCampaign {
    let speeds = [
        2000.0, 4000.0, 6000.0, 8000.0, 10000.0, 12000.0, 9000.0, 5000.0, 3000.0,
    ];
    let ap = [1.0, 2.0, 1.5, 2.5, 1.2, 1.0, 1.8, 2.2, 1.4];
    let fz = [0.08, 0.05, 0.1, 0.06, 0.12, 0.07, 0.09, 0.05, 0.1];
    let (heat_s, cool_s, var_s, step_s) = (3.0 * 3600.0, 1.5 * 3600.0, 5.5 * 3600.0, 1200.0);
    let per = heat_s + cool_s;
    let total = 9.0 * per + var_s;
    let n = (total / dt_s).round() as usize;
    let time_s: Vec<f64> = (0..n).map(|k| k as f64 * dt_s).collect();
    let mut rng = StdRng::seed_from_u64(seed);
    let levels = Uniform::new(0usize, 10);
    let var_steps = (var_s / step_s).ceil() as usize;
    // Level 9 = stopped.
    let var_level: Vec<usize> = (0..var_steps).map(|_| levels.sample(&mut rng)).collect();
    let mut condition = vec![0usize; n];
    let mut spindle_rpm = vec![0.0; n];
    let mut ap_mm = vec![0.0; n];
    let mut fz_mm = vec![0.0; n];
    for k in 0..n {
        let t = time_s[k];
        let level = if t < 9.0 * per {
            let c = (t / per) as usize;
            condition[k] = c;
            (t % per < heat_s).then_some(c)
        } else {
            condition[k] = 9;
            let l = var_level[(((t - 9.0 * per) / step_s) as usize).min(var_steps - 1)];
            (l < 9).then_some(l)
        };
        if let Some(l) = level {
            spindle_rpm[k] = speeds[l];
            ap_mm[k] = ap[l];
            fz_mm[k] = fz[l];
        }
    }
    let cfg = SynthConfig {
        seed,
        dt_s,
        speeds_rpm: speeds.to_vec(),
        ap_mm: ap.to_vec(),
        fz_mm: fz.to_vec(),
        ..SynthConfig::default()
    };
    let data = simulate(&cfg, &mut rng, time_s, condition, spindle_rpm, ap_mm, fz_mm);
    // Channel truths: (true sensors, µm/K, τ / s, b0 / µm, χ / µm/N).
    type ChannelTruth = ([usize; 3], [f64; 3], [f64; 3], f64, f64);
    let truths: [ChannelTruth; 5] = [
        (
            [1, 6, 11],
            [3.0, -2.0, 1.5],
            [600.0, 1800.0, 0.0],
            1.0,
            0.01,
        ),
        (
            [0, 4, 8],
            [2.0, 1.0, -1.0],
            [300.0, 0.0, 1200.0],
            -0.5,
            -0.005,
        ),
        (
            [2, 7, 13],
            [-1.5, 2.5, 1.0],
            [0.0, 900.0, 2400.0],
            0.0,
            0.02,
        ),
        ([3, 9, 14], [1.0, 1.0, 1.0], [1200.0, 600.0, 0.0], 2.0, 0.0),
        (
            [5, 10, 15],
            [4.0, -3.0, 0.5],
            [0.0, 3000.0, 300.0],
            0.5,
            0.008,
        ),
    ];
    let true_series: Vec<Series> = data
        .sensor_names
        .iter()
        .zip(&data.sensors_true_degc)
        .map(|(name, v)| Series {
            name: name.clone(),
            values: v.clone(),
        })
        .collect();
    let [k_law, x, y, z] = cfg.law;
    let force_true: Vec<f64> = (0..n)
        .map(|k| {
            if data.spindle_rpm[k] > 0.0 {
                k_law * data.ap_mm[k].powf(x) * data.fz_mm[k].powf(y) * data.spindle_rpm[k].powf(z)
            } else {
                0.0
            }
        })
        .collect();
    let noise_e = Normal::new(0.0, cfg.error_noise_um).unwrap();
    let channels = truths
        .iter()
        .enumerate()
        .map(|(c, (sens, coef, tau, b0, chi))| {
            let truth = ThermalModel {
                b0_um: *b0,
                terms: (0..3)
                    .map(|j| SensorTerm {
                        sensor: data.sensor_names[sens[j]].clone(),
                        reference_degc: data.sensors_true_degc[sens[j]][0],
                        tau_s: tau[j],
                        coef_um_per_k: coef[j],
                    })
                    .collect(),
                forces: vec![ForceTerm {
                    column: "force_N".into(),
                    chi_um_per_n: *chi,
                }],
            };
            let clean = truth
                .predict(
                    &data.time_s,
                    &true_series,
                    &[Series {
                        name: "force_N".into(),
                        values: force_true.clone(),
                    }],
                )
                .expect("truth uses generated columns");
            let err: Vec<f64> = clean.iter().map(|e| e + noise_e.sample(&mut rng)).collect();
            (format!("ch{}_um", c + 1), err, truth)
        })
        .collect();
    SpindleCampaign { data, channels }
}

impl SpindleCampaign {
    /// The campaign as CSV: time, condition (`0`–`8`, `variable`), schedule, force, sensors, the five
    /// channels.
    pub fn to_csv(&self) -> String {
        let d = &self.data;
        let mut s = String::from("time_s,condition,spindle_rpm,ap_mm,fz_mm,force_N");
        for n in &d.sensor_names {
            s += &format!(",{n}_degC");
        }
        for (name, _, _) in &self.channels {
            s += &format!(",{name}");
        }
        s.push('\n');
        for k in 0..d.time_s.len() {
            let cond = if d.condition[k] == 9 {
                "variable".to_string()
            } else {
                d.condition[k].to_string()
            };
            s += &format!(
                "{},{cond},{},{},{},{:.3}",
                d.time_s[k], d.spindle_rpm[k], d.ap_mm[k], d.fz_mm[k], d.force_n[k]
            );
            for t in &d.sensors_degc {
                s += &format!(",{:.4}", t[k]);
            }
            for (_, e, _) in &self.channels {
                s += &format!(",{:.4}", e[k]);
            }
            s.push('\n');
        }
        s
    }

    /// The oracle of channel `c`: its truth on the measured sensor and force columns.
    pub fn oracle(&self, c: usize) -> Vec<f64> {
        self.channels[c]
            .2
            .predict(
                &self.data.time_s,
                &self.data.sensor_series(),
                &self.data.force_series(),
            )
            .expect("oracle uses generated columns")
    }
}

/// The latent sources start cold: the heat input enters from the second sample on.
fn prepend_zero(v: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(v.len());
    out.push(0.0);
    out.extend_from_slice(&v[..v.len().saturating_sub(1)]);
    out
}

impl SynthData {
    /// Measured sensors as [`Series`] (names without `_degC`).
    pub fn sensor_series(&self) -> Vec<Series> {
        self.sensor_names
            .iter()
            .zip(&self.sensors_degc)
            .map(|(n, v)| Series {
                name: n.clone(),
                values: v.clone(),
            })
            .collect()
    }

    /// Measured force as [`Series`] (`force_N`).
    pub fn force_series(&self) -> Vec<Series> {
        vec![Series {
            name: "force_N".into(),
            values: self.force_n.clone(),
        }]
    }

    /// The oracle prediction: the true model (true sensors, coefficients, lags, χ, reference readings) on the
    /// measured sensor and force columns.
    pub fn oracle_prediction(&self) -> Vec<f64> {
        self.truth
            .predict(&self.time_s, &self.sensor_series(), &self.force_series())
            .expect("oracle uses generated columns")
    }

    /// Header of the contract CSV.
    pub fn csv_header(&self) -> String {
        let mut h = String::from("time_s,condition,spindle_rpm,ap_mm,fz_mm,force_N");
        for n in &self.sensor_names {
            h += &format!(",{n}_degC");
        }
        h += ",error_um";
        h
    }

    /// The campaign as contract CSV text (one `#` comment line with the truth, then the header).
    pub fn to_csv(&self) -> String {
        let mut s = format!("# axcomp-thermal synth: truth {}\n", self.truth.formula());
        s += &self.csv_header();
        s.push('\n');
        for k in 0..self.time_s.len() {
            s += &format!(
                "{},{},{},{},{},{:.3}",
                self.time_s[k],
                self.condition[k],
                self.spindle_rpm[k],
                self.ap_mm[k],
                self.fz_mm[k],
                self.force_n[k]
            );
            for t in &self.sensors_degc {
                s += &format!(",{:.4}", t[k]);
            }
            s += &format!(",{:.4}\n", self.error_um[k]);
        }
        s
    }

    /// Writes the contract CSV atomically ([`axcomp_files::write_atomic`]).
    pub fn write_csv(&self, path: &std::path::Path) -> std::io::Result<()> {
        axcomp_files::write_atomic(path, self.to_csv().as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn truth_and_shapes() {
        let d = generate(&SynthConfig::default());
        assert_eq!(d.sensors_degc.len(), 16);
        assert_eq!(d.time_s.len(), 5 * 1080);
        // The noise-free error is exactly the truth on the noise-free columns; the measured one differs by the
        // error noise only: its RMS difference is the configured 0.3 µm within 5 % (5400 samples).
        let diff: Vec<f64> = d
            .error_um
            .iter()
            .zip(&d.error_true_um)
            .map(|(a, b)| a - b)
            .collect();
        let r = axcomp_numeric::stats::rms(&diff);
        assert!((r - 0.3).abs() < 0.015, "noise rms {r}");
        // Sensors are collinear: the first two sensors sharing a main source correlate > 0.9.
        let a = &d.sensors_degc[0];
        let b = &d.sensors_degc[3];
        let (ma, mb) = (
            axcomp_numeric::stats::mean(a),
            axcomp_numeric::stats::mean(b),
        );
        let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
        let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
        let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
        assert!(
            cov / (va * vb).sqrt() > 0.9,
            "corr {}",
            cov / (va * vb).sqrt()
        );
    }
}
