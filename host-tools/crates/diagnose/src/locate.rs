//! Where the held-out gap lies.
//!
//! Glossary: **gap energy** = squared held-out residual of the model; **excess** = gap energy minus the
//! noise level estimated on the training rows; **region** = a contiguous range of one variable; its
//! **share** = the fraction of the held-out gap energy inside it (of the positive part of a gain, so always in 0..1); **lift** = share / fraction of held-out
//! rows inside it (1 = not concentrated).
//!
//! Method: per variable the held-out rows are binned (equal count — quantiles of the values — or one bin per
//! distinct value when there are few), and the contiguous run of bins with the largest total excess is found (maximum-subarray,
//! Kadane); a second, disjoint run is reported when it still holds ≥ 10 % of the gap.

use serde::Serialize;

use crate::obs::Observations;

/// A region of one variable holding a part of the held-out gap.
#[derive(Debug, Clone, Serialize)]
pub struct Region {
    pub variable: String,
    pub from: f64,
    pub to: f64,
    pub share: f64,
    pub rows_fraction: f64,
    pub lift: f64,
}

fn kadane(x: &[f64], allowed: &[bool]) -> Option<(usize, usize, f64)> {
    let mut best: Option<(usize, usize, f64)> = None;
    let (mut start, mut acc) = (0usize, 0.0f64);
    let mut open = false;
    for i in 0..x.len() {
        if !allowed[i] {
            open = false;
            continue;
        }
        if !open || acc <= 0.0 {
            start = i;
            acc = 0.0;
            open = true;
        }
        acc += x[i];
        if acc > 0.0 && best.is_none_or(|b| acc > b.2) {
            best = Some((start, i, acc));
        }
    }
    best
}

fn regions_of(name: &str, v: &[f64], g: &[f64], noise2: f64, out: &mut Vec<Region>) {
    let n = v.len();
    // Shares are of the positive part of `g` (a refit's gain can be negative on some rows: a share of the
    // signed total could exceed 100 %), so every share lies in 0..1.
    let total: f64 = g.iter().map(|x| x.max(0.0)).sum();
    if n < 4 || total <= 0.0 {
        return;
    }
    let lo = v.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = v.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    if hi.partial_cmp(&lo) != Some(core::cmp::Ordering::Greater) {
        return;
    }
    let mut uniq: Vec<f64> = v.to_vec();
    uniq.sort_by(|a, b| a.total_cmp(b));
    uniq.dedup_by(|a, b| (*a - *b).abs() <= 1e-9 * (hi - lo));
    let nb_target = (n / 10).clamp(4, 24);
    // Bin edges: per distinct value (few values), else equal-count bins (quantiles of the values), so
    // that a densely measured range — e.g. the stroke ends of a survey — is resolved finely.
    let few = uniq.len() <= nb_target;
    let cuts: Vec<f64> = if few {
        Vec::new()
    } else {
        let mut sorted = v.to_vec();
        sorted.sort_by(|a, b| a.total_cmp(b));
        let mut c: Vec<f64> = (1..nb_target).map(|k| sorted[k * n / nb_target]).collect();
        c.dedup();
        c.retain(|&x| x > lo);
        c
    };
    let edges: Vec<(f64, f64)> = if few {
        uniq.iter().map(|&u| (u, u)).collect()
    } else {
        let mut bounds = vec![lo];
        bounds.extend(&cuts);
        bounds.push(hi);
        bounds.windows(2).map(|w| (w[0], w[1])).collect()
    };
    let nb = edges.len();
    let bin_of = |x: f64| -> usize {
        if few {
            uniq.iter()
                .position(|&u| (u - x).abs() <= 1e-9 * (hi - lo))
                .unwrap_or(0)
        } else {
            cuts.partition_point(|&c| c <= x)
        }
    };
    let mut energy = vec![0.0; nb];
    let mut positive = vec![0.0; nb];
    let mut count = vec![0usize; nb];
    for i in 0..n {
        let b = bin_of(v[i]);
        energy[b] += g[i];
        positive[b] += g[i].max(0.0);
        count[b] += 1;
    }
    let excess: Vec<f64> = (0..nb)
        .map(|b| energy[b] - noise2 * count[b] as f64)
        .collect();
    let mut allowed = vec![true; nb];
    for k in 0..2 {
        let Some((s, e, _)) = kadane(&excess, &allowed) else {
            break;
        };
        let share = (positive[s..=e].iter().sum::<f64>() / total).clamp(0.0, 1.0);
        let rows = count[s..=e].iter().sum::<usize>() as f64 / n as f64;
        if k == 1 && share < 0.1 {
            break;
        }
        out.push(Region {
            variable: name.to_string(),
            from: edges[s].0,
            to: edges[e].1,
            share,
            rows_fraction: rows,
            lift: if rows > 0.0 { share / rows } else { 0.0 },
        });
        // Exclude the region and its neighbours so a second region is disjoint.
        for a in allowed
            .iter_mut()
            .take((e + 2).min(nb))
            .skip(s.saturating_sub(1))
        {
            *a = false;
        }
    }
}

/// The variables [`locate`] and [`locate_gain`] search, in their order.
fn axis_variables(obs: &Observations) -> Vec<(&'static str, &[f64])> {
    [
        ("target_mm", &obs.position_mm),
        ("time_s", &obs.time_s),
        ("velocity_mm_s", &obs.velocity_mm_s),
        ("direction", &obs.direction),
    ]
    .into_iter()
    .filter_map(|(name, col)| col.as_deref().map(|c| (name, c)))
    .collect()
}

/// Regions of `target_mm`, `time_s`, `velocity_mm_s` and `direction` holding most of the held-out gap,
/// largest share first. `residual` covers all rows; `noise2` is the noise variance (training residual).
pub fn locate(obs: &Observations, residual: &[f64], noise2: f64) -> Vec<Region> {
    locate_variables(&axis_variables(obs), &obs.holdout_rows(), residual, noise2)
}

/// [`locate`] over named variables (values over all rows) and the held-out rows `ho`.
pub fn locate_variables(
    vars: &[(&str, &[f64])],
    ho: &[usize],
    residual: &[f64],
    noise2: f64,
) -> Vec<Region> {
    let g: Vec<f64> = ho.iter().map(|&i| residual[i] * residual[i]).collect();
    let mut out = Vec::new();
    for (name, c) in vars {
        let v: Vec<f64> = ho.iter().map(|&i| c[i]).collect();
        regions_of(name, &v, &g, noise2, &mut out);
    }
    out.sort_by(|a, b| b.share.total_cmp(&a.share).then(b.lift.total_cmp(&a.lift)));
    out
}

/// Regions where a refit removes most held-out gap energy: per held-out row the *gain* is
/// `before² − after²` (base residual vs. residual after the refit), binned and searched like
/// [`locate`], with the average gain per row in place of the noise level (so a region is where the
/// refit acts more than on average, lift > 1). Shares are fractions of the total gain.
pub fn locate_gain(obs: &Observations, before: &[f64], after: &[f64]) -> Vec<Region> {
    locate_gain_variables(&axis_variables(obs), &obs.holdout_rows(), before, after)
}

/// [`locate_gain`] over named variables (values over all rows) and the held-out rows `ho`.
pub fn locate_gain_variables(
    vars: &[(&str, &[f64])],
    ho: &[usize],
    before: &[f64],
    after: &[f64],
) -> Vec<Region> {
    let g: Vec<f64> = ho
        .iter()
        .map(|&i| before[i] * before[i] - after[i] * after[i])
        .collect();
    // Excess over the average gain per row: the region where the refit acts more than on average.
    let mean_gain = g.iter().sum::<f64>() / g.len().max(1) as f64;
    let mut out = Vec::new();
    for (name, c) in vars {
        let v: Vec<f64> = ho.iter().map(|&i| c[i]).collect();
        regions_of(name, &v, &g, mean_gain, &mut out);
    }
    out.sort_by(|a, b| b.share.total_cmp(&a.share).then(b.lift.total_cmp(&a.lift)));
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_a_localised_bump() {
        // Gap energy 25 only for x in [80, 100], noise 1 elsewhere: the region must be [80, 100] and hold
        // 25·21/(25·21 + 80) ≈ 0.868 of the gap (reference: direct count; tol 1e-9).
        let v: Vec<f64> = (0..=100).map(|i| i as f64).collect();
        let g: Vec<f64> = v
            .iter()
            .map(|&x| if x >= 80.0 { 25.0 } else { 1.0 })
            .collect();
        let mut out = Vec::new();
        regions_of("target_mm", &v, &g, 1.0, &mut out);
        let r = &out[0];
        assert!(r.from >= 75.0 && r.from <= 80.0 && r.to == 100.0, "{r:?}");
        let inside: f64 = v
            .iter()
            .zip(&g)
            .filter(|(x, _)| **x >= r.from)
            .map(|(_, g)| g)
            .sum();
        assert!((r.share - inside / g.iter().sum::<f64>()).abs() < 1e-9);
    }

    #[test]
    fn shares_stay_within_0_and_1_when_gains_are_negative() {
        // A refit that gains 4 on x ≥ 90 and loses 0.35 elsewhere has a signed total of 4·11 − 0.35·90 =
        // 12.5, so a signed share of the gaining region would be 44/12.5 = 352 %. Shares are of the positive
        // part: the gaining region holds exactly 100 % (reference: direct sum, tol 1e-12).
        let v: Vec<f64> = (0..=100).map(|i| i as f64).collect();
        let g: Vec<f64> = v
            .iter()
            .map(|&x| if x >= 90.0 { 4.0 } else { -0.35 })
            .collect();
        let mut out = Vec::new();
        regions_of("target_mm", &v, &g, 0.0, &mut out);
        assert!(!out.is_empty());
        for r in &out {
            assert!((0.0..=1.0).contains(&r.share), "{r:?}");
        }
        assert!((out[0].share - 1.0).abs() < 1e-12, "{:?}", out[0]);
    }

    #[test]
    fn gain_is_located_where_the_refit_acts() {
        // Residual before: noise ±0.5 everywhere plus 2 on x ≥ 190; after: the noise only. The gain
        // (before² − after²) is 4 + 2·2·(±0.5) = 2 or 6 on x ≥ 190 and 0 elsewhere, so the top `target_mm`
        // region must start at or after 180 (one bin of ~10 mm may be merged), hold the whole gain
        // (share 1 within 1e-9: direct sum) and have a lift ≥ 5 (it covers ≤ 1/10 of the rows + 1 bin).
        let n = 2001;
        let x: Vec<f64> = (0..n).map(|i| i as f64 * 0.1).collect();
        let noise: Vec<f64> = (0..n)
            .map(|i| if i % 2 == 0 { 0.5 } else { -0.5 })
            .collect();
        let before: Vec<f64> = x
            .iter()
            .zip(&noise)
            .map(|(&x, &e)| e + if x >= 190.0 { 2.0 } else { 0.0 })
            .collect();
        let obs = Observations {
            target: before.clone(),
            held_out: vec![true; n],
            position_mm: Some(x),
            ..Default::default()
        };
        let regions = locate_gain(&obs, &before, &noise);
        let r = regions
            .iter()
            .find(|r| r.variable == "target_mm")
            .expect("a target_mm region");
        assert!(r.from >= 180.0 && r.to == 200.0, "{r:?}");
        assert!((r.share - 1.0).abs() < 1e-9, "{r:?}");
        assert!(r.lift >= 5.0, "{r:?}");
    }
}
