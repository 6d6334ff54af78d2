//! The measurements behind the default selection's rule (`axcomp_rtest::select`): for every machine kind,
//! location errors ×0 / ×0.1 / ×1 (all effects beyond the model on), seeds FIRST..=LAST, and six ways of
//! judging (held-out circle at 0° / −60°, held-out K4, held-out run 2, `--cv path`, `--cv run`), per outer
//! fold: for the eight models by parameter group (bit 0 C axis, bit 1 tilt axis, bit 2 squareness; 0 = the
//! set-up offsets only, 7 = the full model) the squared errors of the inner leave-one-path-out (`inner_grp`)
//! and leave-one-quarter-of-a-path-out (`inner_blk`) predictions summed per chunk of 8 poses, the in-sample
//! SSE, and the outer held-out SSE of the model fitted on the fold's training rows. JSON lines on stdout, to
//! judge candidate rules offline on the same folds (docs/figures.md):
//! `cargo run --release -p axcomp-rtest --example rtest_select_dump -- 1 20 > design.jsonl`.
use axcomp_data::Split;
use axcomp_kinematics::rotary::N_LOCATION;
use axcomp_rtest::select::{in_sample_sse, leave_group_out_sq, linearise};
use axcomp_rtest::{fit_fixed, fit_shared, model_displacement};
use axcomp_twin::five_axis::{FiveAxisEffects, FiveAxisTwin};
use serde_json::json;

#[path = "common/mod.rs"]
mod common;

const GROUPS: [std::ops::Range<usize>; 3] = [0..4, 4..8, 8..11];

fn main() {
    let first: u64 = common::arg(1, 1);
    let last: u64 = common::arg(2, 20);
    let modes = [
        "h:path=C-circle@0",
        "h:path=C-circle@-60",
        "h:path=K4",
        "h:run=2",
        "cv:path",
        "cv:run",
    ];
    for kind in common::KINDS {
        let (m, paths) = common::machine_and_paths(kind);
        for scale in [0.0, 0.1, 1.0] {
            for seed in first..=last {
                let mut twin = FiveAxisTwin::random(m, seed);
                for v in twin.location.iter_mut() {
                    *v *= scale;
                }
                twin.effects = FiveAxisEffects::all_but_time_drift();
                let (ds, data) = common::measure(&twin, &paths, seed);
                let n = data.poses.len();
                let (pid, _) = axcomp_data::groups(&ds, "path").unwrap();
                let (rid, _) = axcomp_data::groups(&ds, "run").unwrap();
                for mode in modes {
                    let folds: Vec<(Vec<usize>, Vec<usize>)> = if let Some(col) =
                        mode.strip_prefix("cv:")
                    {
                        let (ids, labels) = axcomp_data::groups(&ds, col).unwrap();
                        (0..labels.len())
                            .map(|g| {
                                (
                                    (0..n).filter(|&r| ids[r] != g).collect(),
                                    (0..n).filter(|&r| ids[r] == g).collect(),
                                )
                            })
                            .collect()
                    } else {
                        let split = Split::from_args(Some(mode.strip_prefix("h:").unwrap()), None)
                            .unwrap()
                            .unwrap();
                        let Split::Holdout(h) = split else { panic!() };
                        let mask = h.mask(&ds).unwrap();
                        vec![(
                            (0..n).filter(|&r| !mask[r]).collect(),
                            (0..n).filter(|&r| mask[r]).collect(),
                        )]
                    };
                    for (fi, (train, test)) in folds.iter().enumerate() {
                        let full = fit_shared(&data, train, &Default::default(), None).unwrap();
                        let lin = linearise(&data, train, &full);
                        // inner groups: path, else run
                        let lab = |ids: &Vec<usize>| {
                            let mut v: Vec<usize> = train.iter().map(|&r| ids[r]).collect();
                            v.sort();
                            v.dedup();
                            v.len()
                        };
                        let grp: Vec<usize> = if lab(&pid) >= 2 {
                            train.iter().map(|&r| pid[r]).collect()
                        } else if lab(&rid) >= 2 {
                            train.iter().map(|&r| rid[r]).collect()
                        } else {
                            vec![0; train.len()]
                        };
                        // segments: (path, run); blocks: 4 contiguous per segment
                        let seg: Vec<usize> =
                            train.iter().map(|&r| pid[r] * 100 + rid[r]).collect();
                        let mut blk = vec![0usize; train.len()];
                        {
                            let mut segs = seg.clone();
                            segs.sort();
                            segs.dedup();
                            for (si, s) in segs.iter().enumerate() {
                                let idx: Vec<usize> =
                                    (0..train.len()).filter(|&i| seg[i] == *s).collect();
                                for (p, &i) in idx.iter().enumerate() {
                                    blk[i] = si * 4 + 4 * p / idx.len();
                                }
                            }
                        }
                        // chunks of 8 consecutive rows within a segment
                        let mut chunk = vec![0usize; train.len()];
                        {
                            let (mut cur, mut cnt, mut last) = (0usize, 0usize, usize::MAX);
                            for i in 0..train.len() {
                                if seg[i] != last || cnt == 8 {
                                    if i > 0 {
                                        cur += 1;
                                    }
                                    cnt = 0;
                                    last = seg[i];
                                }
                                chunk[i] = cur;
                                cnt += 1;
                            }
                        }
                        let nchunk = chunk.iter().max().unwrap() + 1;
                        let setup_cols: Vec<usize> = (0..lin.free.len())
                            .filter(|&c| lin.free[c] >= N_LOCATION)
                            .collect();
                        let mut models = Vec::new();
                        for mask in 0..8usize {
                            let mut cols = setup_cols.clone();
                            let mut fix: Vec<Option<String>> = vec![None; N_LOCATION];
                            for (g, range) in GROUPS.iter().enumerate() {
                                if mask & (1 << g) != 0 {
                                    cols.extend(
                                        (0..lin.free.len())
                                            .filter(|&c| range.contains(&lin.free[c])),
                                    );
                                } else {
                                    for k in range.clone() {
                                        fix[k] = Some("x".into());
                                    }
                                }
                            }
                            cols.sort();
                            let agg = |g: &Vec<usize>| -> Option<Vec<f64>> {
                                let sq = leave_group_out_sq(&lin, &cols, g)?;
                                let mut c = vec![0.0; nchunk];
                                for i in 0..train.len() {
                                    c[chunk[i]] += sq[i];
                                }
                                Some(c)
                            };
                            let inner_grp = if grp.iter().any(|&g| g != grp[0]) {
                                agg(&grp)
                            } else {
                                None
                            };
                            let inner_blk = agg(&blk);
                            let ins = in_sample_sse(&lin, &cols);
                            let f =
                                fit_fixed(&data, train, &Default::default(), None, &fix).unwrap();
                            let mut sse = 0.0;
                            for &r in test {
                                let p = model_displacement(
                                    &data.machine,
                                    &data.poses[r],
                                    data.setup[r],
                                    &f.theta,
                                );
                                sse += (0..3)
                                    .map(|c| (data.d_um[r][c] - p[c]).powi(2))
                                    .sum::<f64>();
                            }
                            models.push(json!({
                                "mask": mask, "ncols": cols.len(),
                                "inner_grp": inner_grp, "inner_blk": inner_blk,
                                "in_sse": ins, "out_sse": sse,
                                "theta": f.theta[..N_LOCATION].to_vec(),
                            }));
                        }
                        let chunk_grp: Vec<usize> = (0..nchunk)
                            .map(|c| grp[(0..train.len()).find(|&i| chunk[i] == c).unwrap()])
                            .collect();
                        let chunk_blk: Vec<usize> = (0..nchunk)
                            .map(|c| blk[(0..train.len()).find(|&i| chunk[i] == c).unwrap()])
                            .collect();
                        let raw: f64 = test
                            .iter()
                            .map(|&r| data.d_um[r].iter().map(|v| v * v).sum::<f64>())
                            .sum();
                        println!(
                            "{}",
                            json!({
                                "kind": kind.name(), "scale": scale, "seed": seed, "mode": mode, "fold": fi,
                                "ntrain": train.len(), "ntest": test.len(), "full_fit_rms": full.fit_rms_um,
                                "chunk_grp": chunk_grp, "chunk_blk": chunk_blk, "raw_sse": raw,
                                "truth": twin.location.to_vec(), "models": models,
                            })
                        );
                    }
                }
            }
        }
    }
}
