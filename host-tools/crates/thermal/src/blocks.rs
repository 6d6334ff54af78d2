//! Validation blocks: how the training rows are cut into operating conditions / regimes that a candidate
//! model is judged on when it has not seen them.
//!
//! Glossary:
//! - **block**: a set of training rows left out together; a candidate is fitted (with all its own choices:
//!   sensors, lags, penalty) without it and judged on it.
//! - **regime**: the thermal direction of a row: *heating* when the sensors' mean standardized temperature
//!   rises (smoothed over ±2 % of the training rows), *cooling* when it falls.
//! - **rule** (what [`transfer_blocks`] does, in this order):
//!   1. with `--cv COL` naming at least 3 conditions among the training rows, the blocks are those conditions;
//!   2. otherwise the training rows (in file order) are cut where the condition (if any) or the regime changes;
//!      runs shorter than `max(10, rows / 50)` rows are merged into the run before them;
//!   3. while there are fewer than B blocks (B = the `time_blocks` setting, 5), the longest block of at least twice that length is cut in two
//!      halves in time (forward-in-time blocks inside one regime);
//!   4. with fewer than 3 blocks after that (very short data), B equal contiguous blocks;
//!   5. with more than [`MAX_BLOCKS`] blocks, consecutive conditions, or consecutive runs of one regime, share
//!      a block (a block never mixes heating and cooling). The ±2 % smoothing itself resolves at most about
//!      25 regime runs.
//! - **time order** of blocks: by their first row; forward validation predicts each block from the blocks
//!   before it only.

/// Most validation blocks: beyond it, runs of one regime (or consecutive conditions) share a block, so the
/// cost of the validation stays bounded on long campaigns.
pub const MAX_BLOCKS: usize = 24;

/// The validation blocks of the training rows.
#[derive(Debug, Clone)]
pub struct Blocks {
    /// Block of each row (`None`: held out, not used).
    pub group_of_row: Vec<Option<usize>>,
    /// Display name of each block (condition, or time span and regime).
    pub names: Vec<String>,
    /// Blocks in time order (by first row).
    pub order: Vec<usize>,
    /// True when the blocks are the `--cv` conditions.
    pub by_condition: bool,
    /// The rule that made them, for the report.
    pub rule: String,
    /// Distinct regimes (conditions, or heating/cooling runs) the blocks come from.
    pub regimes: usize,
}

fn fmt_h(t: f64) -> String {
    format!("{:.2} h", t / 3600.0)
}

/// Cuts the training rows `train_idx` (file order) into validation blocks (see the module docs).
/// `sensors`: the usable sensor series (full length); `conditions`: the `--cv` labels, if any.
pub fn transfer_blocks(
    time_s: &[f64],
    sensors: &[&[f64]],
    conditions: Option<&[String]>,
    train_idx: &[usize],
    time_blocks: usize,
) -> Blocks {
    let n = time_s.len();
    let m = train_idx.len();
    // 1. conditions.
    if let Some(b) = conditions.and_then(|c| condition_blocks(c, train_idx, n)) {
        return b;
    }
    let mut group_of_row = vec![None; n];
    // 2. regimes.
    let (mut blocks, min_len) = regime_runs(sensors, conditions, train_idx);
    let regimes = blocks.len();
    // 3. and 4.
    let mut rule = split_in_time(
        &mut blocks,
        m,
        min_len,
        regimes,
        time_blocks,
        conditions.is_some(),
    );
    // 5.
    let (block_of_run, n_blocks) = group_runs(&blocks, &mut rule);
    let mut members: Vec<Vec<usize>> = vec![vec![]; n_blocks];
    for (r, &g) in block_of_run.iter().enumerate() {
        members[g].push(r);
    }
    let mut names = vec![];
    for (g, runs) in members.iter().enumerate() {
        for &r in runs {
            for &i in &train_idx[blocks[r].0..blocks[r].1] {
                group_of_row[i] = Some(g);
            }
        }
        let b = &blocks[runs[0]];
        let last = &blocks[*runs.last().expect("a block holds a run")];
        let b = &(b.0, last.1, b.2.clone());
        let runs_note = if runs.len() > 1 {
            format!(" ({} runs)", runs.len())
        } else {
            String::new()
        };
        let (t0, t1) = (time_s[train_idx[b.0]], time_s[train_idx[b.1 - 1]]);
        let regime = if rule.starts_with("equal") || rule.contains("equal contiguous") {
            String::new()
        } else if b.2.1 {
            ", heating".to_string()
        } else {
            ", cooling".to_string()
        };
        let cond = if b.2.0.is_empty() {
            String::new()
        } else {
            format!(", condition {}", b.2.0)
        };
        names.push(format!(
            "{}–{}{cond}{regime}{runs_note}",
            fmt_h(t0),
            fmt_h(t1)
        ));
    }
    if names.is_empty() {
        rule = "no training rows".into();
    }
    let k = names.len();
    Blocks {
        group_of_row,
        names,
        order: (0..k).collect(),
        by_condition: false,
        rule,
        regimes,
    }
}

/// Rule 1: the `--cv` conditions as blocks when the training rows hold at least 3 of them.
fn condition_blocks(c: &[String], train_idx: &[usize], n: usize) -> Option<Blocks> {
    let mut group_of_row = vec![None; n];
    let mut names: Vec<String> = vec![];
    for &i in train_idx {
        let g = match names.iter().position(|x| *x == c[i]) {
            Some(g) => g,
            None => {
                names.push(c[i].clone());
                names.len() - 1
            }
        };
        group_of_row[i] = Some(g);
    }
    if names.len() >= 3 {
        let k = names.len();
        // More than MAX_BLOCKS conditions: consecutive conditions (first-appearance order) share a block.
        let b = k.min(MAX_BLOCKS);
        let chunk = |c: usize| c * b / k;
        for g in group_of_row.iter_mut().flatten() {
            *g = chunk(*g);
        }
        let merged: Vec<String> = (0..b)
            .map(|j| {
                let members: Vec<&str> = (0..k)
                    .filter(|&c| chunk(c) == j)
                    .map(|c| names[c].as_str())
                    .collect();
                format!("condition {}", members.join("+"))
            })
            .collect();
        return Some(Blocks {
            group_of_row,
            names: merged,
            order: (0..b).collect(),
            by_condition: true,
            rule: if b < k {
                format!("{k} training conditions (--cv) in {b} blocks of consecutive conditions")
            } else {
                format!("{k} training conditions (--cv), each left out in turn")
            },
            regimes: k,
        });
    }
    None
}

/// Rule 2: contiguous runs of one regime (and condition), short runs merged into the run before them.
/// Returns the runs `[from, to)` in training positions with their label, and the shortest run length.
#[allow(clippy::type_complexity)]
fn regime_runs(
    sensors: &[&[f64]],
    conditions: Option<&[String]>,
    train_idx: &[usize],
) -> (Vec<(usize, usize, (String, bool))>, usize) {
    let m = train_idx.len();
    // Regimes from the sign of the smoothed rate of the mean standardized temperature.
    let mean_std: Vec<f64> = {
        let mut acc = vec![0.0; m];
        for s in sensors {
            let v: Vec<f64> = train_idx.iter().map(|&i| s[i]).collect();
            let mu = v.iter().sum::<f64>() / m as f64;
            let sd = (v.iter().map(|x| (x - mu).powi(2)).sum::<f64>() / m as f64).sqrt();
            let sd = if sd > 0.0 { sd } else { 1.0 };
            for (a, x) in acc.iter_mut().zip(&v) {
                *a += (x - mu) / sd;
            }
        }
        acc
    };
    let w = (m / 50).max(2);
    let label = |j: usize| -> (String, bool) {
        let (a, b) = (j.saturating_sub(w), (j + w).min(m - 1));
        let heating = mean_std[b] >= mean_std[a];
        let c = conditions.map_or(String::new(), |c| c[train_idx[j]].clone());
        (c, heating)
    };
    let mut runs: Vec<(usize, usize, (String, bool))> = vec![]; // [from, to) in train positions
    for j in 0..m {
        let l = label(j);
        match runs.last_mut() {
            Some(r) if r.2 == l => r.1 = j + 1,
            _ => runs.push((j, j + 1, l)),
        }
    }
    let min_len = (m / 50).max(10);
    let mut merged: Vec<(usize, usize, (String, bool))> = vec![];
    for r in runs {
        let short = r.1 - r.0 < min_len;
        match merged.last_mut() {
            Some(last) if short || last.1 - last.0 < min_len => {
                // A short run joins the one before it (a short first run takes the next one's label).
                if last.1 - last.0 < min_len && !short {
                    last.2 = r.2.clone();
                }
                last.1 = r.1;
            }
            _ => merged.push(r),
        }
    }
    // Neighbouring runs with the same label after merging become one.
    let mut blocks: Vec<(usize, usize, (String, bool))> = vec![];
    for r in merged {
        match blocks.last_mut() {
            Some(last) if last.2 == r.2 => last.1 = r.1,
            _ => blocks.push(r),
        }
    }
    (blocks, min_len)
}

/// Rules 3 and 4: the longest blocks cut in halves in time up to `time_blocks`; with fewer than 3, equal
/// contiguous blocks. Returns the rule as described in the report.
#[allow(clippy::type_complexity)]
fn split_in_time(
    blocks: &mut Vec<(usize, usize, (String, bool))>,
    m: usize,
    min_len: usize,
    regimes: usize,
    time_blocks: usize,
    by_condition_changes: bool,
) -> String {
    // 3. split the longest blocks in time.
    while blocks.len() < time_blocks {
        let Some((k, _)) = blocks
            .iter()
            .enumerate()
            .filter(|(_, b)| b.1 - b.0 >= 2 * min_len)
            .max_by_key(|(_, b)| b.1 - b.0)
        else {
            break;
        };
        let b = blocks[k].clone();
        let mid = (b.0 + b.1) / 2;
        blocks[k].1 = mid;
        blocks.insert(k + 1, (mid, b.1, b.2));
    }
    // 4. fallback.
    let rule;
    if blocks.len() < 3 {
        let b = time_blocks.min(m).max(1);
        *blocks = (0..b)
            .map(|k| (k * m / b, (k + 1) * m / b, (String::new(), true)))
            .filter(|r| r.1 > r.0)
            .collect();
        rule = format!(
            "{} equal contiguous time blocks of the training rows",
            blocks.len()
        );
    } else {
        rule = format!(
            "{} contiguous blocks of the training rows: {} regime run(s) (heating / cooling by the sign of the \
             sensors' smoothed mean rate{}; runs under {min_len} rows merged), longest cut in halves in time",
            blocks.len(),
            regimes,
            if by_condition_changes {
                ", and changes of the --cv condition"
            } else {
                ""
            }
        );
    }
    rule
}

/// Rule 5: with more than [`MAX_BLOCKS`] runs (long campaigns), the runs of each regime, in time order, are
/// grouped into consecutive chunks (a block may then hold several runs of the same regime, never two
/// regimes). Returns the block of each run and the number of blocks, and extends `rule`.
#[allow(clippy::type_complexity)]
fn group_runs(blocks: &[(usize, usize, (String, bool))], rule: &mut String) -> (Vec<usize>, usize) {
    let mut block_of_run: Vec<usize> = (0..blocks.len()).collect();
    let mut n_blocks = blocks.len();
    if blocks.len() > MAX_BLOCKS {
        let mut labels: Vec<(String, bool)> = vec![];
        for b in blocks {
            if !labels.contains(&b.2) {
                labels.push(b.2.clone());
            }
        }
        let total = blocks.len();
        n_blocks = 0;
        for l in &labels {
            let runs: Vec<usize> = (0..total).filter(|&r| blocks[r].2 == *l).collect();
            let g = ((MAX_BLOCKS * runs.len()) as f64 / total as f64)
                .round()
                .max(1.0) as usize;
            let g = g.min(runs.len());
            for (j, &r) in runs.iter().enumerate() {
                block_of_run[r] = n_blocks + j * g / runs.len();
            }
            n_blocks += g;
        }
        *rule += &format!(
            "; the {total} runs grouped into {n_blocks} blocks, each holding consecutive runs of one regime"
        );
    }
    (block_of_run, n_blocks)
}

/// Whether the training rows support fitting a lag for this sensor: its smoothed trace (moving mean over
/// ±2 % of the rows) shows at least two separate episodes of change — runs where its rate exceeds 10 % of
/// the largest rate, at least one smoothing window long, separated by a reversal of direction or a rest of
/// a window or more. A single step or a single monotone rise (e.g. a heater switched on once) does not: its
/// lagged copy is then only a function of the time since the start, which the data cannot tell from a lag.
/// `values`, `time_s`: the sensor and the time on the training rows, in file order.
pub fn lag_supported(time_s: &[f64], values: &[f64]) -> bool {
    lag_support(time_s, values).0 >= 2
}

/// (episodes of change, duration of the longest one in seconds) of a sensor's training trace (see
/// [`lag_supported`]).
pub fn lag_support(time_s: &[f64], values: &[f64]) -> (usize, f64) {
    let m = values.len();
    if m < 10 {
        return (0, 0.0);
    }
    let w = (m / 50).max(2);
    let smooth: Vec<f64> = (0..m)
        .map(|j| {
            let (a, b) = (j.saturating_sub(w), (j + w + 1).min(m));
            values[a..b].iter().sum::<f64>() / (b - a) as f64
        })
        .collect();
    let rate: Vec<f64> = (0..m)
        .map(|j| {
            let (a, b) = (j.saturating_sub(w), (j + w).min(m - 1));
            let dt = time_s[b] - time_s[a];
            if dt > 0.0 {
                (smooth[b] - smooth[a]) / dt
            } else {
                0.0
            }
        })
        .collect();
    let top = rate.iter().fold(0.0f64, |a, r| a.max(r.abs()));
    if top <= 0.0 {
        return (0, 0.0);
    }
    let state: Vec<i8> = rate
        .iter()
        .map(|&r| {
            if r > 0.1 * top {
                1
            } else if r < -0.1 * top {
                -1
            } else {
                0
            }
        })
        .collect();
    // Runs of equal state.
    let mut runs: Vec<(i8, usize)> = vec![];
    for &s in &state {
        match runs.last_mut() {
            Some(r) if r.0 == s => r.1 += 1,
            _ => runs.push((s, 1)),
        }
    }
    let mut episodes = 0;
    let mut last_sign = 0i8;
    let mut rest_since_last = true;
    let mut longest: f64 = 0.0;
    let mut start = 0usize;
    for &(s, len) in &runs {
        let from = start;
        start += len;
        if s != 0 && len >= w {
            longest = longest.max(time_s[(from + len).min(m - 1)] - time_s[from]);
        }
        if s == 0 {
            if len >= w {
                rest_since_last = true;
            }
            continue;
        }
        if len < w {
            continue;
        }
        if s != last_sign || rest_since_last {
            episodes += 1;
        }
        last_sign = s;
        rest_since_last = false;
    }
    (episodes, longest)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_step_does_not_support_a_lag_two_do() {
        // A heater switched on once (step, then flat) shows one episode; heating then cooling shows two.
        let t: Vec<f64> = (0..300).map(|k| k as f64 * 60.0).collect();
        let step: Vec<f64> = (0..300)
            .map(|k| 20.0 + 80.0 * (1.0 - (-(k as f64) / 3.0).exp()))
            .collect();
        assert!(!lag_supported(&t, &step));
        let up_down: Vec<f64> = (0..300)
            .map(|k| {
                if k < 150 {
                    20.0 + 0.1 * k as f64
                } else {
                    35.0 - 0.1 * (k - 150) as f64
                }
            })
            .collect();
        assert!(lag_supported(&t, &up_down));
    }

    #[test]
    fn many_conditions_share_at_most_max_blocks() {
        // 30 conditions of 50 rows: 30 > MAX_BLOCKS, so consecutive conditions share blocks; every row keeps
        // a block and every condition lies in exactly one block.
        let t: Vec<f64> = (0..1500).map(|k| k as f64 * 60.0).collect();
        let s: Vec<f64> = (0..1500).map(|k| (k as f64 * 0.01).sin()).collect();
        let cond: Vec<String> = (0..1500).map(|k| format!("c{}", k / 50)).collect();
        let train: Vec<usize> = (0..1500).collect();
        let b = transfer_blocks(&t, &[&s], Some(&cond), &train, 5);
        assert!(b.by_condition);
        assert_eq!(b.names.len(), MAX_BLOCKS, "{:?}", b.names);
        for c in 0..30 {
            let g = b.group_of_row[c * 50];
            assert!((c * 50..c * 50 + 50).all(|i| b.group_of_row[i] == g));
        }
    }

    #[test]
    fn heating_then_cooling_gives_a_cooling_block() {
        // 200 rows heating (exponential rise), 100 rows cooling: the cut between the regimes falls at row
        // 200 within the smoothing half-window (±6 rows), and the last block is labelled cooling.
        let t: Vec<f64> = (0..300).map(|k| k as f64 * 60.0).collect();
        let s: Vec<f64> = (0..300)
            .map(|k| {
                if k < 200 {
                    20.0 + 10.0 * (1.0 - (-(k as f64) / 60.0).exp())
                } else {
                    let top = 20.0 + 10.0 * (1.0 - (-200.0f64 / 60.0).exp());
                    20.0 + (top - 20.0) * (-((k - 200) as f64) / 40.0).exp()
                }
            })
            .collect();
        let train: Vec<usize> = (0..300).collect();
        let b = transfer_blocks(&t, &[&s], None, &train, 5);
        assert!(b.names.len() >= 3, "{:?}", b.names);
        assert!(
            b.names.last().unwrap().ends_with("cooling"),
            "{:?}",
            b.names
        );
        let first_cool = (0..300)
            .find(|&i| b.names[b.group_of_row[i].unwrap()].ends_with("cooling"))
            .unwrap();
        assert!((194..=206).contains(&first_cool), "cut at {first_cool}");
    }
}
