//! The candidate families of a probe campaign (see the glossary of [`super`]): one function per effect
//! kind, each adding its family, or saying why it is not applicable, and what touches cannot tell apart.

use axcomp_effects::ProbeEffect;
use axcomp_probe::DirSpeed;
use serde_json::json;

use super::{ProbeData, ProbeFamily, ProbeVariant, params};

/// The per-touch variables the families are built from (over all rows).
pub(super) struct Inputs<'a> {
    pub(super) d: &'a ProbeData,
    pub(super) train: &'a [usize],
    pub(super) ds: &'a [DirSpeed],
    /// The artefact's outward normal at each touch.
    pub(super) normal: &'a [[f64; 3]],
    /// The radial residual before any projection, µm.
    pub(super) y_raw: &'a [f64],
    pub(super) n: usize,
    /// cos²φ and sin²φ of the approach's elevation φ, and the probing speed.
    pub(super) c2: Vec<f64>,
    pub(super) t2: Vec<f64>,
    pub(super) v: Vec<f64>,
    /// The training touches have more than one probing speed.
    pub(super) has_speed: bool,
}

impl<'a> Inputs<'a> {
    pub(super) fn new(
        d: &'a ProbeData,
        train: &'a [usize],
        ds: &'a [DirSpeed],
        normal: &'a [[f64; 3]],
        y_raw: &'a [f64],
    ) -> Inputs<'a> {
        let c2: Vec<f64> = ds.iter().map(|x| (1.0 - x.t * x.t).max(0.0)).collect();
        let t2: Vec<f64> = ds.iter().map(|x| x.t * x.t).collect();
        let v: Vec<f64> = ds.iter().map(|x| x.v).collect();
        let has_speed = {
            let (lo, hi) = train
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |a, &i| {
                    (a.0.min(v[i]), a.1.max(v[i]))
                });
            hi - lo > 1e-9 * hi.abs().max(1e-9)
        };
        Inputs {
            d,
            train,
            ds,
            normal,
            y_raw,
            n: ds.len(),
            c2,
            t2,
            v,
            has_speed,
        }
    }

    /// Azimuthal harmonic `k` of the approach × cos²φ: (cos kθ, sin kθ) columns.
    fn harmonic(&self, k: usize) -> (Vec<f64>, Vec<f64>) {
        let (c2, ds) = (&self.c2, self.ds);
        let cs = (0..self.n)
            .map(|i| c2[i] * (k as f64 * ds[i].theta).cos())
            .collect();
        let sn = (0..self.n)
            .map(|i| c2[i] * (k as f64 * ds[i].theta).sin())
            .collect();
        (cs, sn)
    }
}

/// The candidate families, the kinds not applicable (with why) and what touches cannot tell apart.
#[derive(Default)]
pub(super) struct Families {
    pub(super) families: Vec<ProbeFamily>,
    pub(super) not_applicable: Vec<(ProbeEffect, String)>,
    pub(super) notes: Vec<String>,
}

/// Every family the touches allow.
pub(super) fn build(x: &Inputs) -> Families {
    let mut out = Families::default();
    lobing(x, &mut out);
    speed(x, &mut out);
    stylus_bending(x, &mut out);
    machine_geometry(x, &mut out);
    thermal_drift(x, &mut out);
    out
}

/// `lobing`: azimuthal harmonics of the approach × cos²φ (needs lateral training touches).
fn lobing(x: &Inputs, out: &mut Families) {
    let Families {
        families,
        not_applicable,
        ..
    } = out;
    let c2 = &x.c2;
    let has_azimuth = x.train.iter().any(|&i| c2[i] > 0.05);
    let mut vars = Vec::new();
    // Order 2 is left out: on a sphere it is a linear machine error's pattern (n_x² − n_y², n_x·n_y).
    let orders: [(&[usize], bool); 5] = [
        (&[3], false),
        (&[3, 6], false),
        (&[3, 6], true),
        (&[3, 6, 9], true),
        (&[4, 8], true),
    ];
    for (ks, zonal) in orders {
        let mut cols = Vec::new();
        for &k in ks {
            let (a, b) = x.harmonic(k);
            cols.push(a);
            cols.push(b);
        }
        if zonal {
            cols.push(c2.clone());
        }
        let m = cols.len();
        vars.push(ProbeVariant {
            columns: cols,
            params: params(&[
                ("azimuth_orders", json!(ks)),
                ("zonal_cos2_elevation", json!(zonal)),
            ]),
            n_params: m,
        });
    }
    if has_azimuth {
        families.push(ProbeFamily {
            kind: ProbeEffect::Lobing,
            variants: vars,
        });
    } else {
        not_applicable.push((
            ProbeEffect::Lobing,
            "no lateral touch among the training touches".into(),
        ));
    }
}

/// `speed_pretravel` and `latch_latency` (need more than one probing speed).
fn speed(x: &Inputs, out: &mut Families) {
    let Families {
        families,
        not_applicable,
        notes,
    } = out;
    let (n, c2, t2, v, has_speed) = (x.n, &x.c2, &x.t2, &x.v, x.has_speed);
    if has_speed {
        let lat: Vec<f64> = (0..n).map(|i| v[i] * c2[i]).collect();
        let ax: Vec<f64> = (0..n).map(|i| v[i] * t2[i]).collect();
        let (h3c, h3s) = x.harmonic(3);
        let vh3c: Vec<f64> = (0..n).map(|i| v[i] * h3c[i]).collect();
        let vh3s: Vec<f64> = (0..n).map(|i| v[i] * h3s[i]).collect();
        families.push(ProbeFamily {
            kind: ProbeEffect::SpeedPretravel,
            variants: vec![
                ProbeVariant {
                    columns: vec![lat.clone(), ax.clone()],
                    params: params(&[("terms", json!(["v·cos²φ", "v·sin²φ"]))]),
                    n_params: 2,
                },
                ProbeVariant {
                    columns: vec![lat, ax, vh3c, vh3s],
                    params: params(&[(
                        "terms",
                        json!(["v·cos²φ", "v·sin²φ", "v·cos²φ·cos3θ", "v·cos²φ·sin3θ"]),
                    )]),
                    n_params: 4,
                },
            ],
        });
        families.push(ProbeFamily {
            kind: ProbeEffect::LatchLatency,
            variants: vec![ProbeVariant {
                columns: vec![v.clone()],
                params: params(&[(
                    "terms",
                    json!(["v (along the approach, every direction alike)"]),
                )]),
                n_params: 1,
            }],
        });
        notes.push(
            "latch latency and a speed-linear pretravel both move the latched point along the approach by an \
             amount ∝ speed: touches tell them apart only when the speed term differs between lateral and \
             axial touches (speed_pretravel); an isotropic speed term is latch_latency, with speed_pretravel \
             tied"
                .into(),
        );
    } else {
        for k in [ProbeEffect::SpeedPretravel, ProbeEffect::LatchLatency] {
            not_applicable.push((
                k,
                "one probing speed in the training touches (or no feed_mm_min)".into(),
            ));
        }
    }
}

/// `stylus_bending`: cos φ or cos²φ (needs training touches at more than one elevation).
fn stylus_bending(x: &Inputs, out: &mut Families) {
    let Families {
        families,
        not_applicable,
        ..
    } = out;
    let (train, c2) = (x.train, &x.c2);
    let el_spread = {
        let (lo, hi) = train
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |a, &i| {
                (a.0.min(c2[i]), a.1.max(c2[i]))
            });
        hi - lo
    };
    if el_spread > 0.05 {
        families.push(ProbeFamily {
            kind: ProbeEffect::StylusBending,
            variants: vec![
                ProbeVariant {
                    columns: vec![c2.iter().map(|x| x.sqrt()).collect()],
                    params: params(&[("term", json!("cos φ (horizontal approach component)"))]),
                    n_params: 1,
                },
                ProbeVariant {
                    columns: vec![c2.clone()],
                    params: params(&[("term", json!("cos²φ"))]),
                    n_params: 1,
                },
            ],
        });
    } else {
        not_applicable.push((
            ProbeEffect::StylusBending,
            "the training touches have one elevation: bending is a constant there".into(),
        ));
    }
}

/// `machine_geometry`: the normal times low-order polynomials of the (nominal) touch position.
fn machine_geometry(x: &Inputs, out: &mut Families) {
    let Families {
        families, notes, ..
    } = out;
    let (d, n, normal, y_raw) = (x.d, x.n, x.normal, x.y_raw);
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for t in &d.touches {
        for k in 0..3 {
            lo[k] = lo[k].min(t.position_mm[k]);
            hi[k] = hi[k].max(t.position_mm[k]);
        }
    }
    let mid = [0, 1, 2].map(|k| 0.5 * (lo[k] + hi[k]));
    let half = (0..3)
        .map(|k| 0.5 * (hi[k] - lo[k]))
        .fold(0.0, f64::max)
        .max(1.0);
    // Positions without the measured radial residual (the nominal surface-side point): a column built
    // from the latched position itself would hold the target (`n·p = |p − C| + n·C` on a sphere).
    let q: Vec<[f64; 3]> = (0..n)
        .map(|i| {
            let p = d.touches[i].position_mm;
            [0, 1, 2].map(|k| (p[k] - y_raw[i] * 1e-3 * normal[i][k] - mid[k]) / half)
        })
        .collect();
    let col = |k: usize, f: &dyn Fn(&[f64; 3]) -> f64| -> Vec<f64> {
        (0..n).map(|i| normal[i][k] * f(&q[i])).collect()
    };
    let mut lin = Vec::new();
    for k in 0..3 {
        for j in 0..3 {
            lin.push(col(k, &|p| p[j]));
        }
    }
    let mut quad = lin.clone();
    for k in 0..3 {
        for j in 0..3 {
            quad.push(col(k, &|p| p[j] * p[j]));
        }
        for (a, b) in [(0, 1), (0, 2), (1, 2)] {
            quad.push(col(k, &|p| p[a] * p[b]));
        }
    }
    let scale = params(&[("centre_mm", json!(mid)), ("scale_mm", json!(half))]);
    let mut p1 = scale.clone();
    p1.insert("degree".into(), json!(1));
    let mut p2 = scale;
    p2.insert("degree".into(), json!(2));
    families.push(ProbeFamily {
        kind: ProbeEffect::MachineGeometry,
        variants: vec![
            ProbeVariant {
                columns: lin,
                params: p1,
                n_params: 9,
            },
            ProbeVariant {
                columns: quad,
                params: p2,
                n_params: 27,
            },
        ],
    });
    notes.push(
        "a linear machine error seen on one sphere is a degree-2 pattern of the normal, like a direction \
         dependence of the probe: only artefacts at other places (a plane grid, a second sphere) tell them \
         apart"
            .into(),
    );
}

/// `thermal_drift`: the normal times ΔT (a drift), and ΔT (a size change), per `*_degC` sensor.
fn thermal_drift(x: &Inputs, out: &mut Families) {
    let Families {
        families,
        not_applicable,
        ..
    } = out;
    let (d, train, n, normal) = (x.d, x.train, x.n, x.normal);
    let mut vars = Vec::new();
    for (name, t) in &d.temperatures {
        let m = train.iter().map(|&i| t[i]).sum::<f64>() / train.len() as f64;
        let dt: Vec<f64> = t.iter().map(|x| x - m).collect();
        let spread = train
            .iter()
            .map(|&i| dt[i])
            .fold(0.0f64, |a, x| a.max(x.abs()));
        if spread.is_nan() || spread <= 1e-6 {
            continue;
        }
        let drift: Vec<Vec<f64>> = (0..3)
            .map(|k| (0..n).map(|i| normal[i][k] * dt[i]).collect())
            .collect();
        vars.push(ProbeVariant {
            columns: drift.clone(),
            params: params(&[("sensor", json!(name)), ("terms", json!("n·ΔT (drift)"))]),
            n_params: 3,
        });
        let mut with_size = drift;
        with_size.push(dt.clone());
        vars.push(ProbeVariant {
            columns: with_size,
            params: params(&[
                ("sensor", json!(name)),
                ("terms", json!("n·ΔT + ΔT (drift and size)")),
            ]),
            n_params: 4,
        });
    }
    if vars.is_empty() {
        not_applicable.push((
            ProbeEffect::ThermalDrift,
            "no *_degC column that varies over the training touches".into(),
        ));
    } else {
        families.push(ProbeFamily {
            kind: ProbeEffect::ThermalDrift,
            variants: vars,
        });
    }
}
