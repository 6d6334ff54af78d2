//! Deterministic test noise: Gaussian draws from a seeded generator.
//!
//! Every simulator and test that adds measurement noise draws it here, so the same seed gives the same
//! figures everywhere (`StdRng` seeded by the caller, standard normal by `rand_distr`).

use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};

/// A generator seeded with `seed` (the one every simulator and test uses).
pub fn rng(seed: u64) -> StdRng {
    StdRng::seed_from_u64(seed)
}

/// One Gaussian draw with standard deviation `sigma` (no draw and 0 for `sigma <= 0`, so a noiseless
/// run does not advance the generator).
pub fn gauss(rng: &mut StdRng, sigma: f64) -> f64 {
    if sigma > 0.0 {
        let z: f64 = StandardNormal.sample(rng);
        sigma * z
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_seed_same_noise_and_zero_sigma_draws_nothing() {
        let (mut a, mut b) = (rng(7), rng(7));
        let x: Vec<f64> = (0..5).map(|_| gauss(&mut a, 2.0)).collect();
        assert_eq!(gauss(&mut b, 0.0), 0.0);
        let y: Vec<f64> = (0..5).map(|_| gauss(&mut b, 2.0)).collect();
        assert_eq!(x, y);
        assert!(x.iter().all(|v| v.is_finite() && *v != 0.0));
    }
}
