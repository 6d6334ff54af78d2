//! Least squares (QR) reaches the optimum that a stochastic search approaches: the reference patent fitted
//! the thermal-error coefficients by particle swarm optimisation (PSO); here a small PSO written for this
//! test minimises the same mean squared error and must never beat the QR solution (tolerance 1e-9 relative),
//! while getting close to it (within 5 %).

use axcomp_numeric::lsq::lstsq;
use axcomp_twin::synth::{SynthConfig, generate};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng, rngs::StdRng};

fn mse(x: &DMatrix<f64>, y: &[f64], b: &[f64]) -> f64 {
    let n = x.nrows();
    (0..n)
        .map(|i| {
            let p: f64 = (0..x.ncols()).map(|j| x[(i, j)] * b[j]).sum();
            (y[i] - p).powi(2)
        })
        .sum::<f64>()
        / n as f64
}

#[test]
fn least_squares_is_the_optimum_pso_approaches() {
    let d = generate(&SynthConfig::default());
    // Static model on three (collinear) sensors, every 10th row, temperatures as rises from the first row.
    let rows: Vec<usize> = (0..d.time_s.len()).step_by(10).collect();
    let sens = [1usize, 6, 11];
    let x = DMatrix::from_fn(rows.len(), 4, |r, c| {
        if c == 0 {
            1.0
        } else {
            d.sensors_degc[sens[c - 1]][rows[r]] - d.sensors_degc[sens[c - 1]][0]
        }
    });
    let y: Vec<f64> = rows.iter().map(|&i| d.error_um[i]).collect();
    let ls = lstsq(&x, &y, 0.0, Some(0)).unwrap();
    let ls_obj = mse(&x, &y, &ls.coef);

    // PSO: 40 particles, 400 iterations, inertia 0.72, c1 = c2 = 1.49 (Clerc–Kennedy constriction values),
    // search box ±50 per coefficient, fixed seed.
    let mut rng = StdRng::seed_from_u64(7);
    let (np, dim) = (40, 4);
    let mut pos: Vec<Vec<f64>> = (0..np)
        .map(|_| (0..dim).map(|_| rng.gen_range(-50.0..50.0)).collect())
        .collect();
    let mut vel: Vec<Vec<f64>> = vec![vec![0.0; dim]; np];
    let mut pbest = pos.clone();
    let mut pbest_f: Vec<f64> = pos.iter().map(|p| mse(&x, &y, p)).collect();
    let mut g = 0;
    for i in 0..np {
        if pbest_f[i] < pbest_f[g] {
            g = i;
        }
    }
    let (mut gbest, mut gbest_f) = (pbest[g].clone(), pbest_f[g]);
    for _ in 0..400 {
        for i in 0..np {
            for j in 0..dim {
                let (r1, r2): (f64, f64) = (rng.r#gen(), rng.r#gen());
                vel[i][j] = 0.72 * vel[i][j]
                    + 1.49 * r1 * (pbest[i][j] - pos[i][j])
                    + 1.49 * r2 * (gbest[j] - pos[i][j]);
                pos[i][j] += vel[i][j];
            }
            let f = mse(&x, &y, &pos[i]);
            if f < pbest_f[i] {
                pbest_f[i] = f;
                pbest[i] = pos[i].clone();
                if f < gbest_f {
                    gbest_f = f;
                    gbest = pos[i].clone();
                }
            }
        }
    }
    println!(
        "LS objective {ls_obj:.6} µm², PSO {gbest_f:.6} µm²; LS coef {:?}, PSO {:?}",
        ls.coef, gbest
    );
    assert!(
        gbest_f >= ls_obj * (1.0 - 1e-9),
        "PSO {gbest_f} beat least squares {ls_obj}: LS is not the optimum"
    );
    assert!(
        gbest_f <= ls_obj * 1.05,
        "PSO {gbest_f} did not approach LS {ls_obj} within 5 %"
    );
}
