//! Repeated poses: the checks on repeats within one run, and the closure drift of poses revisited in later
//! runs (contract: "a pose measured again later in the same campaign (a closure check) is a further run of
//! its path; with absolute sphere centres such a run may hold a single pose").
//!
//! # Glossary
//! - **visit**: one row at a commanded pose (x, y, z, tilt, C equal bit for bit, −0 = 0) in one set-up.
//! - **revisit**: the same pose in the same set-up measured again in another `(path, run)` group, e.g. the
//!   probing of the sphere at B = C = 0 at the start and at the end of the campaign.
//! - **closure drift** ([`Revisit`]): last visit's reading minus the first visit's (by `time_s`, else file
//!   order), µm along machine X, Y, Z. The commanded pose and the set-up are the same, so every term of the
//!   location-error model cancels: what remains is the drift of the sphere or the tool point between the
//!   visits (what `setup_drift` / `thermal_drift` / `time_drift` model) plus the two readings' noise.
//!
//! # Why a single-pose run is accepted
//! The model has no per-path or per-run zero: every reading of a set-up is taken absolute, against the one
//! set of set-up offsets (the sphere's and the head's) of its set-up. A run of one pose therefore enters the
//! fit like any other pose, through the set-up offsets it shares with the rest of its set-up; it adds three
//! readings and no unknowns. (Were the readings relative, zeroed per run, a single pose would carry no
//! information: it would be its own zero.) A *path* of a single pose in total is still refused: a revisit
//! is a further run of a path measured elsewhere in the file, and a lone path id is more likely a typo.

use std::collections::HashMap;

use axcomp_data::Dataset;
use serde::Serialize;

use crate::{RtestData, RtestError};

/// A pose's identity: its commanded values bit for bit; with `signed_zero` false, `-0` and `0` alike
/// (`v + 0.0` maps −0 to +0). The repeat check keeps them apart (as it always has: a file whose K4 starts
/// at A = −0 and whose circle starts at A = 0 is accepted without a `run` column); the closure takes them
/// as the one pose they are.
fn pose_key(data: &RtestData, i: usize, signed_zero: bool) -> [u64; 5] {
    let p = &data.poses[i];
    [p.p_mm[0], p.p_mm[1], p.p_mm[2], p.tilt_deg, p.c_deg]
        .map(|v| if signed_zero { v } else { v + 0.0 }.to_bits())
}

/// Repeats within one (path, run, set-up) are errors naming both lines (a genuine repeat is another run);
/// a path with a single pose over all its runs is an error naming its line.
pub(crate) fn check_repeats(data: &RtestData, run: &[String]) -> Result<(), RtestError> {
    let n = data.poses.len();
    let mut seen: HashMap<(String, String, usize, [u64; 5]), usize> = HashMap::new();
    let mut path_count: HashMap<String, (usize, usize)> = HashMap::new();
    for i in 0..n {
        let k = (
            data.path[i].clone(),
            run[i].clone(),
            data.setup[i],
            pose_key(data, i, true),
        );
        if let Some(&j) = seen.get(&k) {
            let same = data.d_um[j] == data.d_um[i];
            return Err(RtestError::RepeatedPose {
                file: data.source.clone(),
                first: data.lines[j],
                second: data.lines[i],
                what: if same {
                    "identical readings: a duplicated row?"
                } else {
                    "conflicting readings"
                },
                group: format!(
                    "path `{}`, run `{}`, set-up `{}`",
                    data.path[i], run[i], data.setup_names[data.setup[i]]
                ),
            });
        }
        seen.insert(k, i);
        path_count.entry(data.path[i].clone()).or_insert((0, i)).0 += 1;
    }
    let mut singles: Vec<_> = path_count.into_iter().filter(|(_, v)| v.0 == 1).collect();
    singles.sort_by_key(|(_, v)| v.1);
    if let Some((path, (_, i))) = singles.into_iter().next() {
        return Err(RtestError::SinglePosePath {
            file: data.source.clone(),
            path: if path.is_empty() {
                "(the whole file)".into()
            } else {
                path
            },
            line: data.lines[i],
        });
    }
    Ok(())
}

/// One visit of a revisited pose.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Visit {
    /// File line.
    pub line: usize,
    pub path: String,
    pub run: String,
    /// `time_s` of the row, when the file has it.
    pub time_s: Option<f64>,
    pub d_um: [f64; 3],
}

/// A pose measured in more than one (path, run) group of one set-up, and its closure drift.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Revisit {
    /// Commanded pose: x, y, z (mm), tilt, C (degrees).
    pub pose: [f64; 5],
    pub setup: String,
    pub visits: usize,
    pub first: Visit,
    pub last: Visit,
    /// Last minus first reading, µm along machine X, Y, Z.
    pub drift_um: [f64; 3],
    /// Its magnitude, µm.
    pub magnitude_um: f64,
    /// Seconds between the visits (`None` without `time_s`).
    pub elapsed_s: Option<f64>,
}

/// The revisited poses of `data` (readings needed), ordered by the first visit's line. Visits are ordered
/// by `time_s` when the file has it, else by file order.
pub fn closure(ds: &Dataset, data: &RtestData) -> Vec<Revisit> {
    let n = data.poses.len();
    if data.d_um.len() != n {
        return Vec::new();
    }
    let run = ds.run().unwrap_or_else(|| vec![String::new(); n]);
    let time = ds.time_s().filter(|t| t.len() == n);
    let mut groups: Vec<((usize, [u64; 5]), Vec<usize>)> = Vec::new();
    let mut index: HashMap<(usize, [u64; 5]), usize> = HashMap::new();
    for i in 0..n {
        let k = (data.setup[i], pose_key(data, i, false));
        let g = *index.entry(k).or_insert_with(|| {
            groups.push((k, Vec::new()));
            groups.len() - 1
        });
        groups[g].1.push(i);
    }
    let visit = |i: usize| Visit {
        line: data.lines[i],
        path: data.path[i].clone(),
        run: run[i].clone(),
        time_s: time.map(|t| t[i]),
        d_um: data.d_um[i],
    };
    let mut out = Vec::new();
    for (_, mut rows) in groups {
        if rows.len() < 2 {
            continue;
        }
        if let Some(t) = time {
            rows.sort_by(|&a, &b| t[a].total_cmp(&t[b]).then(a.cmp(&b)));
        }
        let (f, l) = (rows[0], rows[rows.len() - 1]);
        let drift_um: [f64; 3] = std::array::from_fn(|c| data.d_um[l][c] - data.d_um[f][c]);
        let p = &data.poses[f];
        out.push(Revisit {
            pose: [p.p_mm[0], p.p_mm[1], p.p_mm[2], p.tilt_deg, p.c_deg],
            setup: data.setup_names[data.setup[f]].clone(),
            visits: rows.len(),
            first: visit(f),
            last: visit(l),
            drift_um,
            magnitude_um: drift_um.iter().map(|v| v * v).sum::<f64>().sqrt(),
            elapsed_s: time.map(|t| t[l] - t[f]),
        });
    }
    out.sort_by_key(|r| r.first.line);
    out
}

/// The JSON `closure` object: the revisited poses and what to compare their drift with.
pub fn closure_json(revisits: &[Revisit], sigma_xyz_um: [f64; 3], tilt: char) -> serde_json::Value {
    use serde_json::json;
    let poses: Vec<serde_json::Value> = revisits
        .iter()
        .map(|r| {
            json!({
                "pose": { "x_mm": r.pose[0], "y_mm": r.pose[1], "z_mm": r.pose[2],
                          format!("{tilt}_deg"): r.pose[3], "c_deg": r.pose[4] },
                "setup": r.setup,
                "visits": r.visits,
                "first": r.first,
                "last": r.last,
                "dx_um": r.drift_um[0], "dy_um": r.drift_um[1], "dz_um": r.drift_um[2],
                "magnitude_um": r.magnitude_um,
                "elapsed_s": r.elapsed_s,
            })
        })
        .collect();
    let max = revisits
        .iter()
        .map(|r| r.magnitude_um)
        .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))));
    json!({
        "definition": "per pose measured in more than one (path, run) of one set-up: last visit's reading minus the first's (by time_s, else file order), µm; the location-error model cancels at one pose, so this is the drift of the sphere or tool point between the visits (what setup_drift / thermal_drift / time_drift model) plus noise",
        "noise_std_um": sigma_xyz_um.map(|s| s * std::f64::consts::SQRT_2),
        "noise_std_definition": "√2 × the fit's residual standard deviation per component: the spread of a difference of two readings without drift",
        "max_magnitude_um": max,
        "poses": poses,
    })
}
