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

/// The tests' self-contained noise: uniform numbers from a 64-bit LCG (Knuth's MMIX constants, top 53
/// bits, never 0 or 1) and normal numbers by Box–Muller. Independent of `rand`'s versions, so figures a
/// test asserts never move with a dependency update.
#[derive(Debug, Clone)]
pub struct TestNoise(pub u64);

impl TestNoise {
    /// A uniform number in (0, 1).
    pub fn uniform(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// A standard normal number (Box–Muller, cosine branch).
    pub fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (core::f64::consts::TAU * v).cos()
    }
}

#[cfg(test)]
mod test_noise_tests {
    use super::TestNoise;

    #[test]
    fn lcg_is_deterministic_and_roughly_standard_normal() {
        // Reference: a standard normal has mean 0 and variance 1; with 20,000 draws the sample mean is
        // within 0.05 and the variance within 0.05 of them (≈ 7 and 5 standard errors).
        let mut a = TestNoise(11);
        let x: Vec<f64> = (0..20_000).map(|_| a.normal()).collect();
        let mut b = TestNoise(11);
        assert_eq!(b.normal(), x[0]);
        let m = x.iter().sum::<f64>() / x.len() as f64;
        let v = x.iter().map(|e| (e - m) * (e - m)).sum::<f64>() / x.len() as f64;
        assert!(
            m.abs() < 0.05 && (v - 1.0).abs() < 0.05,
            "mean {m}, var {v}"
        );
    }
}
