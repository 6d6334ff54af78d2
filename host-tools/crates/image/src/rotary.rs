//! A rotary-axis model as the group image's rotary section: the 11 ISO 230-7 location errors of a
//! `fit rtest` model, or the hand-written AC-trunnion form.

use axcomp_core::rotary::{RotaryLocationSpec, RotaryMachine};
use axcomp_kinematics::rotary::MachineKind;
use axcomp_rtest::RtestModel;

use crate::angle_table::{EffectsInImage, effects_in_image};
use crate::{Context, Error, Result};

/// The core's rotary section from a `fit rtest` model: every location error and squareness term goes
/// in with the model's value (f32), the value `predict` uses. A parameter marked `identified: false`
/// is either fixed at its prior 0 (flagged in `not_identified`) or estimated but not told apart alone
/// (weakly determined, or determined only in combination with an effect term the fit fixed to 0, e.g.
/// `EA0C` with `rotary_positioning`'s tilt offset: its value then carries both); the latter goes in
/// as estimated, or the image would leave out what the fit put into it. Refused: a model whose parameter list is not the 11 names
/// of its machine kind, in order (the stage could not represent the rest), a non-finite value, a
/// value beyond the stage's first-order range, a tool length out of range.
pub fn rotary_from_rtest_model(
    model: &RtestModel,
    pivot_counts: [i64; 3],
    tool_length_mm: Option<f64>,
) -> Result<RotaryLocationSpec> {
    let machine = match model.machine {
        MachineKind::AcTrunnion => RotaryMachine::AcTrunnion,
        MachineKind::BcTrunnion => RotaryMachine::BcTrunnion,
        MachineKind::BcHead => RotaryMachine::BcHead,
    };
    let names = machine.constant_names();
    let got: Vec<&str> = model
        .location_errors
        .iter()
        .map(|(n, _)| n.as_str())
        .collect();
    ensure!(
        got == names,
        "the model's location errors {got:?} are not the {} parameters the firmware's rotary stage represents ({names:?}); refusing rather than dropping any",
        model.machine.name()
    );
    let mut values = [0.0f32; 11];
    let mut not_identified = 0u16;
    for (k, (name, p)) in model.location_errors.iter().enumerate() {
        let unit = if matches!(k, 0 | 1 | 4 | 5) {
            "um"
        } else {
            "urad"
        };
        ensure!(
            p.unit == unit,
            "{name}: unit `{}`, expected `{unit}`",
            p.unit
        );
        if !p.identified && p.value == 0.0 {
            not_identified |= 1 << k;
            continue;
        }
        ensure!(
            p.value.is_finite(),
            "{name}: value {} is not a number",
            p.value
        );
        ensure!(
            p.value.abs() <= 1.0e4,
            "{name}: {} {unit} is beyond the rotary stage's first-order range (10 mm / 10 mrad)",
            p.value
        );
        values[k] = p.value as f32;
    }
    let tool_mm = match (machine, tool_length_mm) {
        (RotaryMachine::BcHead, None) => model.pivot_mm,
        (_, Some(l)) => l,
        (_, None) => bail!(
            "a {} model needs --tool-length-mm L (spindle gauge line to tool tip)",
            model.machine.name()
        ),
    };
    ensure!(
        tool_mm.is_finite() && (0.0..=1.0e4).contains(&tool_mm),
        "tool length {tool_mm} mm: need 0..=10000 mm"
    );
    let spec = RotaryLocationSpec {
        machine,
        ex0c_um: values[0],
        ey0c_um: values[1],
        ea0c_urad: values[2],
        eb0c_urad: values[3],
        ey0a_um: values[4],
        ez0a_um: values[5],
        eb0a_urad: values[6],
        ec0a_urad: values[7],
        squareness_urad: [values[8], values[9], values[10]],
        pivot_counts,
        tool_length_um: (tool_mm * 1000.0) as f32,
        not_identified,
        wobble: axcomp_core::rotary::RotaryWobble::NONE,
    };
    spec.validate()
        .map_err(|e| Error::core("the rotary section is not valid", e))?;
    Ok(spec)
}

/// The hand-written AC-trunnion form (`ex0c_um`, `ey0c_um`, `ea0c_urad`, `eb0c_urad`, `ey0a_um`,
/// `ez0a_um`, `eb0a_urad`, `ec0a_urad`, `pivot_counts` [x, y, z], `tool_length_um`); `label` names
/// the file in messages (e.g. `--rotary r.json`).
pub fn rotary_from_hand_written(label: &str, v: &serde_json::Value) -> Result<RotaryLocationSpec> {
    let f = |k: &str| -> Result<f32> {
        v.get(k)
            .and_then(|x| x.as_f64())
            .map(|x| x as f32)
            .ok_or_else(|| Error::Invalid(format!("{label}: missing number `{k}`")))
    };
    let pivot = v
        .get("pivot_counts")
        .and_then(|p| p.as_array())
        .filter(|a| a.len() == 3)
        .and_then(|a| {
            let mut out = [0i64; 3];
            for (o, x) in out.iter_mut().zip(a) {
                *o = x.as_i64()?;
            }
            Some(out)
        })
        .ok_or_else(|| Error::Invalid(format!("{label}: `pivot_counts` must be three integers")))?;
    Ok(RotaryLocationSpec {
        ex0c_um: f("ex0c_um")?,
        ey0c_um: f("ey0c_um")?,
        ea0c_urad: f("ea0c_urad")?,
        eb0c_urad: f("eb0c_urad")?,
        ey0a_um: f("ey0a_um")?,
        ez0a_um: f("ez0a_um")?,
        eb0a_urad: f("eb0a_urad")?,
        ec0a_urad: f("ec0a_urad")?,
        pivot_counts: pivot,
        tool_length_um: f("tool_length_um")?,
        ..RotaryLocationSpec::ZERO_AC
    })
}

/// What `image group --rotary` makes of a rotary model file: the rotary section, and what of the
/// model's effects the image carries (the rotary axes' angle tables) and leaves out.
#[derive(Debug, Clone)]
pub struct RotarySection {
    pub spec: RotaryLocationSpec,
    pub effects: EffectsInImage,
}

/// The rotary section from a rotary model file's `text` (`label` names it in messages, e.g.
/// `--rotary r.json`): a `fit rtest --out` model placed by `pivot_counts` (`X,Y,Z`, required for it)
/// and `tool_length_mm`, or the hand-written AC-trunnion form (which carries its own placement).
pub fn rotary_section(
    label: &str,
    text: &str,
    pivot_counts: Option<&str>,
    tool_length_mm: Option<f64>,
) -> Result<RotarySection> {
    let v: serde_json::Value =
        serde_json::from_str(text).with_context(|| format!("{label}: not JSON"))?;
    if let Some(kind) = v
        .get("format")
        .and_then(|f| f.as_str())
        .and_then(axcomp_files::model_kind)
    {
        bail!(
            "{label}: {kind}, not a rotary-axis model (give the model of `fit rtest --out`, or the \
             hand-written AC-trunnion form)"
        );
    }
    if v.get("kind").and_then(|k| k.as_str()) == Some("rtest") {
        let model =
            RtestModel::from_json(text, label).map_err(|e| Error::Invalid(format!("{e:#}")))?;
        let pivot = pivot_counts.with_context(|| {
            format!(
                "{label}: a `fit rtest` model needs --pivot-counts X,Y,Z (the counts of the R-test frame's origin)"
            )
        })?;
        let pivot = crate::args::parse_pivot_counts(pivot)?;
        let mut spec = rotary_from_rtest_model(&model, pivot, tool_length_mm)
            .map_err(|e| Error::Invalid(format!("{label}: {e}")))?;
        // The rotary stage carries the 11 location errors and the wobble; of the other effects,
        // what the axis tables can apply goes there and the rest is said, with the correction it
        // leaves out.
        let effects =
            effects_in_image(&model).map_err(|e| Error::Invalid(format!("{label}: {e}")))?;
        if let Some(w) = effects.wobble {
            spec.wobble = w;
        }
        return Ok(RotarySection { spec, effects });
    }
    ensure!(
        pivot_counts.is_none() && tool_length_mm.is_none(),
        "{label}: the hand-written form carries pivot_counts and tool_length_um itself; \
         --pivot-counts and --tool-length-mm are for a `fit rtest` model"
    );
    let spec = rotary_from_hand_written(label, &v)?;
    Ok(RotarySection {
        spec,
        effects: EffectsInImage::default(),
    })
}
