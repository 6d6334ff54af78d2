//! First-order lag of a temperature series, as the firmware runs it.
//!
//! Glossary:
//! - **lag** with time constant τ: `y_k = y_{k−1} + α_k (u_k − y_{k−1})`, `α_k = 1 − exp(−Δt_k/τ)` where
//!   `Δt_k = t_k − t_{k−1}` is the actual sample interval (exact discretisation of `τ ẏ = u − y` for an input
//!   held between samples). The firmware computes the same α once from its fixed sensor period.
//! - **initial state**: `y_0 = u_0` (the structure starts in equilibrium with the first reading); the filter is
//!   also restarted at a row whose time does not increase (a new recording segment).
//! - τ = 0: no lag, `y = u`.

/// The filter coefficient α for one step of `dt_s` seconds with time constant `tau_s` (τ = 0 → 1).
pub fn alpha(dt_s: f64, tau_s: f64) -> f64 {
    if tau_s <= 0.0 {
        1.0
    } else {
        1.0 - (-dt_s / tau_s).exp()
    }
}

/// Lagged copy of `u` sampled at times `time_s` (seconds, same length), written into `out`.
pub fn lag_into(time_s: &[f64], u: &[f64], tau_s: f64, out: &mut Vec<f64>) {
    out.clear();
    out.reserve(u.len());
    if u.is_empty() {
        return;
    }
    let mut y = u[0];
    out.push(y);
    // α is recomputed only when the sample interval changes (regular sampling: once).
    let (mut last_dt, mut a) = (f64::NAN, 1.0);
    for k in 1..u.len() {
        let dt = time_s[k] - time_s[k - 1];
        if dt.is_nan() || dt <= 0.0 || tau_s <= 0.0 {
            y = u[k];
        } else {
            if dt != last_dt {
                last_dt = dt;
                a = alpha(dt, tau_s);
            }
            y += a * (u[k] - y);
        }
        out.push(y);
    }
}

/// Lagged copy of `u` (see [`lag_into`]).
pub fn lag(time_s: &[f64], u: &[f64], tau_s: f64) -> Vec<f64> {
    let mut out = Vec::new();
    lag_into(time_s, u, tau_s, &mut out);
    out
}

/// First-order lag of `u` with time constant `tau_s`, rows visited in `order` (time order), the
/// diagnosis's regressor.
///
/// This is deliberately a second behaviour, not a copy of [`lag`]: the rows of a diagnosis campaign
/// are not in time order (they are visited through `order`), and a row whose time does not increase
/// (two samples at one instant, or an unsorted merge) *holds* the state (`Δt` clamped to 0 → α = 0)
/// instead of restarting the filter at that row's input as [`lag`] does for a new recording segment.
/// Restarting would make a duplicate timestamp reset a campaign's thermal regressor; holding would
/// make a recording that restarts its clock carry a stale state into the new segment. Each caller keeps
/// the behaviour its data needs. `tau_s` must be > 0.
pub fn lag_ordered(u: &[f64], t: &[f64], order: &[usize], tau_s: f64) -> Vec<f64> {
    let mut out = vec![0.0; u.len()];
    let mut state = u[order[0]];
    let mut t_prev = t[order[0]];
    for &i in order {
        let dt = (t[i] - t_prev).max(0.0);
        let a = 1.0 - (-dt / tau_s).exp();
        state += a * (u[i] - state);
        out[i] = state;
        t_prev = t[i];
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_response_matches_exponential() {
        // Step from 0 to 1 at t=0+, sampled irregularly: y(t) = 1 − exp(−t/τ) exactly for the exact
        // discretisation (reference: analytic step response; tolerance 1e-12).
        let t = [0.0, 0.5, 1.7, 2.0, 5.0, 11.0, 30.0];
        let u = [0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0];
        let y = lag(&t, &u, 4.0);
        // Input is held at u_k over (t_{k-1}, t_k] in this discretisation.
        for k in 1..t.len() {
            let want = 1.0 - (-(t[k]) / 4.0).exp();
            assert!((y[k] - want).abs() < 1e-12, "k={k}: {} vs {want}", y[k]);
        }
        assert_eq!(lag(&t, &u, 0.0), u.to_vec());
    }
}
