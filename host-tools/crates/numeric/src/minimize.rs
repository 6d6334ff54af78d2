//! One-dimensional minimisation.
//!
//! Glossary:
//! - **golden-section search**: shrinks a bracket `[a, b]` of a unimodal function by the golden ratio each
//!   step, keeping the lower of two interior points; after `k` steps the bracket is `0.618^k` of its width.

/// Golden-section minimisation of `f` on `[a, b]`, `iters` steps; returns the abscissa of the minimum.
pub fn golden_min(f: &mut dyn FnMut(f64) -> f64, mut a: f64, mut b: f64, iters: usize) -> f64 {
    let r = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = b - r * (b - a);
    let mut d = a + r * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    if fc < fd { c } else { d }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn golden_finds_the_minimum_of_a_parabola() {
        // Reference: (x − 0.3)² has its minimum at 0.3; 60 steps shrink [−1, 2] to 3·0.618^60 ≈ 9e-13, so
        // the abscissa is within 1e-9 of 0.3.
        let x = golden_min(&mut |x| (x - 0.3) * (x - 0.3), -1.0, 2.0, 60);
        assert!((x - 0.3).abs() < 1e-9, "{x}");
    }
}
