//! Effect terms in the model file of `fit rtest --effects` (read by name by `predict` and `image group
//! --rotary`): kind, parametrisation, each parameter's value, standard uncertainty and whether the poses
//! identify it, and the RMS of the correction the effect adds over the fitted poses (what an image that
//! cannot carry the effect leaves out).

use axcomp_effects::RotaryEffect;
use axcomp_kinematics::rotary::MachineKind;
use serde::{Deserialize, Serialize};

use crate::effects::{EffectBasis, EffectSet, EffectTerm, MODELLED};
use crate::{Fit, MODEL_ABSURD, ParamValue, RtestData};

/// One effect of a model file.
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct EffectModel {
    /// Contract name (`rotary_positioning`, `rotary_wobble`, `linear_geometry`).
    pub kind: String,
    pub basis: EffectBasis,
    /// By name, in signature order.
    pub parameters: Vec<(String, ParamValue)>,
    /// RMS over dx, dy, dz of the displacement this effect adds, over the fitted poses, µm.
    pub rms_over_fit_um: f64,
}

/// The effects of a fit, for the model file.
pub fn from_fit(data: &RtestData, f: &Fit, fit_rows: &[usize]) -> Vec<EffectModel> {
    let kind = data.machine.kind;
    let mut k0 = data.n_params();
    let mut out = Vec::new();
    for t in &f.effects.terms {
        let names = t.param_names(kind);
        let n = names.len();
        let values = &f.theta[k0..k0 + n];
        let parameters = names
            .into_iter()
            .enumerate()
            .map(|(i, (name, unit))| {
                let k = k0 + i;
                (
                    name,
                    ParamValue {
                        value: values[i],
                        unit: unit.into(),
                        std: f.std[k],
                        identified: f.ident.identified[k],
                        reason: f.ident.reasons[k].clone(),
                    },
                )
            })
            .collect();
        let only = EffectSet {
            terms: vec![t.clone()],
        };
        let d: Vec<[f64; 3]> = fit_rows
            .iter()
            .map(|&r| {
                let (le, so) = crate::split_params(&f.theta, data.setup[r]);
                only.displacement(&data.machine, &data.poses[r], &le, so, values)
            })
            .collect();
        out.push(EffectModel {
            kind: t.kind.name().to_string(),
            basis: t.basis.clone(),
            parameters,
            rms_over_fit_um: crate::rms3(&d),
        });
        k0 += n;
    }
    out
}

/// Checks a model file's effects (each kind one `fit rtest` models, its parameters by name exactly those
/// of its parametrisation, values finite) and returns them as an [`EffectSet`] and the values in
/// signature order. The error names the entry.
pub fn read(kind: MachineKind, effects: &[EffectModel]) -> Result<(EffectSet, Vec<f64>), String> {
    let mut set = EffectSet::default();
    let mut values = Vec::new();
    for (i, e) in effects.iter().enumerate() {
        let entry = format!("effects[{i}] ({})", e.kind);
        let modelled: Vec<&str> = MODELLED.iter().map(|k| k.name()).collect();
        let k: RotaryEffect = e
            .kind
            .parse()
            .ok()
            .filter(|k| MODELLED.contains(k))
            .ok_or_else(|| {
                format!(
                    "{entry}: unknown effect `{}` (a model may hold {})",
                    e.kind,
                    modelled.join(", ")
                )
            })?;
        let basis_ok = matches!(
            (k, &e.basis),
            (
                RotaryEffect::RotaryPositioning,
                EffectBasis::Positioning { .. }
            ) | (RotaryEffect::RotaryWobble, EffectBasis::Wobble { .. })
                | (RotaryEffect::LinearGeometry, EffectBasis::Linear { .. })
        );
        if !basis_ok {
            return Err(format!(
                "{entry}: basis {:?} is not one of this kind",
                e.basis
            ));
        }
        match &e.basis {
            EffectBasis::Positioning {
                c_harmonics,
                tilt_degree,
            } if *c_harmonics > 8 || *tilt_degree > 3 => {
                return Err(format!(
                    "{entry}: c_harmonics ≤ 8 and tilt_degree ≤ 3 expected"
                ));
            }
            EffectBasis::Wobble {
                per_revolution,
                tilt_degree,
            } if per_revolution.iter().any(|&h| h == 0 || h > 8) || *tilt_degree > 3 => {
                return Err(format!(
                    "{entry}: per_revolution 1…8 and tilt_degree ≤ 3 expected"
                ));
            }
            EffectBasis::Linear {
                axes,
                degree,
                range_mm,
            } => {
                let ranges_ok = range_mm.iter().all(|r| {
                    r.iter().all(|v| v.is_finite() && v.abs() < MODEL_ABSURD) && r[1] > r[0]
                });
                if axes.len() != range_mm.len()
                    || axes.iter().any(|&a| a > 2)
                    || *degree == 0
                    || *degree > 3
                    || !ranges_ok
                {
                    return Err(format!(
                        "{entry}: axes 0…2 each with a range [low, high] mm (low < high), degree 1…3 expected"
                    ));
                }
            }
            _ => {}
        }
        let term = EffectTerm {
            kind: k,
            basis: e.basis.clone(),
        };
        let want = term.param_names(kind);
        let mut slots: Vec<Option<f64>> = vec![None; want.len()];
        for (j, (name, p)) in e.parameters.iter().enumerate() {
            let at = format!("{entry}.parameters[{j}] ({name})");
            let Some(s) = want.iter().position(|(n, _)| n == name) else {
                return Err(format!("{at}: not a parameter of this effect"));
            };
            if p.unit != want[s].1 {
                return Err(format!("{at}: unit `{}`, expected `{}`", p.unit, want[s].1));
            }
            if !(p.value.is_finite() && p.value.abs() < MODEL_ABSURD) {
                return Err(format!(
                    "{at}: {:e} is not a finite number of plausible size",
                    p.value
                ));
            }
            if slots[s].replace(p.value).is_some() {
                return Err(format!("{at}: appears twice"));
            }
        }
        let missing: Vec<&str> = want
            .iter()
            .zip(&slots)
            .filter(|(_, v)| v.is_none())
            .map(|((n, _), _)| n.as_str())
            .collect();
        if !missing.is_empty() {
            return Err(format!(
                "{entry}: missing parameters {}",
                missing.join(", ")
            ));
        }
        values.extend(slots.into_iter().flatten());
        set.terms.push(term);
    }
    Ok((set, values))
}
