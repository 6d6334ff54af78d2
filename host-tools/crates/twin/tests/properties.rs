//! Properties over random axes, plans and seeds: the truth is the sum of the contributions, the
//! campaign is a function of (axis, plan, seed), and scaling an effect scales only its contribution.

use axcomp_twin::*;
use proptest::prelude::*;

fn kinds_from_mask(mask: u16) -> Vec<EffectKind> {
    EffectKind::ALL
        .into_iter()
        .filter(|k| mask & (1 << k.index()) != 0)
        .collect()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn truth_is_the_sum_of_contributions_and_runs_are_reproducible(
        mask in 1u16..(1 << EffectKind::COUNT),
        axis_seed in any::<u64>(),
        seed in any::<u64>(),
        plan_index in 0usize..Plan::NAMES.len(),
        factor in 0.1f64..10.0,
    ) {
        let kinds = kinds_from_mask(mask);
        let axis = Axis::random_seeded("p", 0.0, 200.0, &kinds, axis_seed);
        let plan = Plan::by_name(Plan::NAMES[plan_index], 0.0, 200.0, Some(200)).unwrap();
        let a = simulate(&axis, &plan, None, seed).unwrap();
        let b = simulate(&axis, &plan, None, seed).unwrap();
        prop_assert_eq!(&a, &b);
        for (row, t) in a.rows.iter().zip(&a.truth) {
            // Open loop: truth = count rounding of the target + Σ contributions (tolerance 1e-9 µm).
            let sum: f64 = t.contributions_um.iter().sum::<f64>() + (t.scale_mm - row.target_mm) * 1e3;
            prop_assert!((sum - t.deviation_um).abs() < 1e-9);
            // Kinds the axis does not have contribute nothing.
            for k in EffectKind::ALL {
                if !kinds.contains(&k) {
                    prop_assert_eq!(t.contributions_um[k.index()], 0.0);
                }
            }
        }
        // Scaling one kind scales its contribution and leaves the others and the noise alone.
        let kind = kinds[(seed % kinds.len() as u64) as usize];
        let mut scaled = axis.clone();
        prop_assert!(scaled.scale_effect(kind, factor));
        let c = simulate(&scaled, &plan, None, seed).unwrap();
        for i in 0..a.rows.len() {
            for k in EffectKind::ALL {
                let expected = if k == kind { factor * a.contribution_um(k, i) } else { a.contribution_um(k, i) };
                // Tolerance 1e-9 relative (f64 rounding of the scaled parameters).
                prop_assert!((c.contribution_um(k, i) - expected).abs() <= 1e-9 * expected.abs().max(1.0));
            }
            let noise_a = a.rows[i].deviation_um - a.truth[i].deviation_um;
            let noise_c = c.rows[i].deviation_um - c.truth[i].deviation_um;
            prop_assert!((noise_a - noise_c).abs() < 1e-9);
        }
    }
}
