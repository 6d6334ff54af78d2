//! Plausibility of R-test rows: the data warnings `axcomp fit rtest` reports (and refuses under
//! `--strict`), built from `axcomp_data::sanity`'s checks.
//!
//! Terms:
//! - *sequence*: the rows of one path in one set-up, in file order: neighbours along it should agree.
//! - *unit mix*: readings of one column in two units (µm next to nm or mm), told by their magnitudes.

use axcomp_data::sanity::{self, DataWarning};
use axcomp_data::{DataError, Dataset};
use axcomp_kinematics::rotary::MachineKind;

use crate::RtestData;

/// Plausibility of R-test rows (see `axcomp_data::sanity`): a machine kind named in the file's `#`
/// comment lines other than `--machine`; per component, a reading far from its neighbours along its
/// path, a unit mix or an implausible median (nm taken for µm); positions beyond 10 m (µm taken for
/// mm); angle columns that look like radians.
pub fn rtest_warnings(
    path: &std::path::Path,
    ds: &Dataset,
    data: &RtestData,
) -> Result<Vec<DataWarning>, DataError> {
    let mut w: Vec<DataWarning> = header_machine(path, data.machine.kind)
        .into_iter()
        .collect();
    let mut sequences: Vec<(String, Vec<usize>)> = Vec::new();
    for i in 0..data.poses.len() {
        let key = format!("{}\u{1f}{}", data.path[i], data.setup[i]);
        match sequences.iter_mut().find(|(k, _)| *k == key) {
            Some((_, s)) => s.push(i),
            None => sequences.push((key, vec![i])),
        }
    }
    let sequences: Vec<Vec<usize>> = sequences.into_iter().map(|(_, s)| s).collect();
    for (k, col) in ["dx_um", "dy_um", "dz_um"].into_iter().enumerate() {
        let v: Vec<f64> = data.d_um.iter().map(|d| d[k]).collect();
        let mix = sanity::unit_mix(ds, col, &v, None);
        let outliers = || sanity::neighbour_outliers(ds, col, &v, &sequences);
        w.extend(mix.or_else(outliers));
        w.extend(sanity::implausible_magnitude(
            ds,
            col,
            &v,
            1000.0,
            "an R-test displacement of more than 1 mm is not plausible in µm: nm?",
        ));
    }
    for c in ["x_mm", "y_mm", "z_mm"] {
        w.extend(sanity::implausible_magnitude(
            ds,
            c,
            ds.numeric(c)?,
            1.0e4,
            "positions beyond 10 m are not plausible in mm: µm?",
        ));
    }
    for c in ["a_deg", "b_deg", "c_deg"]
        .into_iter()
        .filter(|c| ds.has(c))
    {
        w.extend(sanity::radians_for_degrees(ds, c, ds.numeric(c)?));
    }
    Ok(w)
}

/// A warning when the file's leading `#` comment lines name a machine kind and not `kind` (the twin
/// writes `# axcomp five-axis twin, machine bc-head`).
fn header_machine(path: &std::path::Path, kind: MachineKind) -> Option<DataWarning> {
    use std::io::BufRead;
    let file = std::fs::File::open(path).ok()?;
    let comments: Vec<(usize, String)> = std::io::BufReader::new(file)
        .lines()
        .map_while(Result::ok)
        .take_while(|l| l.trim_start().starts_with('#'))
        .enumerate()
        .collect();
    let kinds = [
        MachineKind::AcTrunnion,
        MachineKind::BcTrunnion,
        MachineKind::BcHead,
    ];
    let named = |k: MachineKind| comments.iter().find(|(_, l)| l.contains(k.name()));
    if named(kind).is_some() {
        return None;
    }
    let (other, (line, _)) = kinds.iter().find_map(|&k| named(k).map(|c| (k, c)))?;
    Some(DataWarning {
        kind: "machine_kind",
        column: String::new(),
        message: format!(
            "{}:{}: the file's header names machine {}, but it is fitted as --machine {}: the wrong \
             kinematics fit the wrong location errors",
            path.display(),
            line + 1,
            other.name(),
            kind.name()
        ),
        lines: vec![line + 1],
    })
}
