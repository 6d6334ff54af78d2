//! A group image assembled from single-axis images and the group's stages: the axis images checked,
//! each axis's sensor names, the double-correction rule, the core's writer and its group check.

use axcomp_core::Compensator;
use axcomp_core::geometric::COMPONENT_NAMES;
use axcomp_core::group::AxisName;
use axcomp_core::group_image::{self, AxisSectionSpec};
use axcomp_core::inspect_image;
use axcomp_core::probe::ProbeSettings;
use axcomp_core::provenance::{self, ProvenanceRecord};
use axcomp_core::rotary::RotaryLocationSpec;

use crate::geometric::{GeometricSection, geometric_component_nonzero};
use crate::{Error, Result};

pub use crate::axis::GroupAxis;

/// An axis file must be one single-axis image of `image build`: a group image, another file or an
/// image with bytes after its end is refused naming the option (`given_as`) and the file (`shown`).
pub fn check_axis_image(given_as: &str, shown: &str, bytes: &[u8]) -> Result<()> {
    let arg = given_as;
    if bytes.starts_with(b"AXCI") && bytes.get(4..6) == Some(&2u16.to_le_bytes()[..]) {
        bail!(
            "--axis {arg}: {shown} is a group image (`image group`); an axis takes a single-axis image \
             of `image build`"
        );
    }
    if !bytes.starts_with(b"AXCI") {
        let what = match axcomp_files::model_text(bytes) {
            Err(why) => why,
            Ok(_) => "is not a firmware image (a text file; build one with `image build`)".into(),
        };
        bail!("--axis {arg}: {shown} {what}");
    }
    let info = inspect_image(bytes)
        .map_err(|e| Error::core(format!("--axis {arg}: {shown} is not a valid image"), e))?;
    ensure!(
        bytes.len() == info.len,
        "--axis {arg}: {shown} has {} bytes, its image header says {} (bytes after the image)",
        bytes.len(),
        info.len
    );
    Ok(())
}

/// The sensor names in a schema-1 image's header extension (empty without them).
pub fn carried_sensor_names(image: &[u8]) -> Vec<String> {
    let Ok(view) = group_image::parse(image) else {
        return vec![];
    };
    let Some(a) = view.axes().next() else {
        return vec![];
    };
    let n = inspect_image(a.axis.image).map_or(0, |i| i.n_sensors);
    (0..n)
        .map_while(|j| a.sensor_name(j).map(str::to_string))
        .collect()
}

/// Each axis's sensor names: those `given` (`--sensor-names NAME=N1,N2,..`) or else the names its
/// image carries (from `image build`). One name per sensor and no name twice on an axis: the firmware
/// wires each sensor to the board input of its name.
pub fn group_sensor_names(
    axes: &[GroupAxis],
    given: &[(AxisName, Vec<String>)],
) -> Result<Vec<Vec<String>>> {
    let lists: Vec<Vec<String>> = axes
        .iter()
        .map(|a| {
            given
                .iter()
                .find(|(n, _)| *n == a.name)
                .map(|(_, l)| l.clone())
                .unwrap_or_else(|| carried_sensor_names(&a.image))
        })
        .collect();
    for (n, _) in given {
        ensure!(
            axes.iter().any(|a| a.name == *n),
            "--sensor-names: axis {} is not one of the --axis",
            n.letter()
        );
    }
    for (a, list) in axes.iter().zip(&lists) {
        let (name, arg) = (a.name, &a.given_as);
        let sensors = usize::from(inspect_image(&a.image)?.n_sensors);
        let is_given = given.iter().any(|(n, _)| *n == name);
        if is_given {
            ensure!(
                list.len() == sensors,
                "--sensor-names {}={}: {} names, but axis {} (--axis {arg}) has {sensors} sensors",
                name.letter(),
                list.join(","),
                list.len(),
                name.letter()
            );
        }
        for (j, n) in list.iter().enumerate() {
            ensure!(
                !list[..j].contains(n),
                "axis {} (--axis {arg}{}): two sensors are named `{n}`; the firmware wires sensors by \
                 name, so both would read one input",
                name.letter(),
                if is_given { ", --sensor-names" } else { "" }
            );
        }
    }
    Ok(lists)
}

/// Every axis image's provenance records (re-labelled with the group axis), then `extra` (e.g. the
/// rotary model file's); at most [`provenance::MAX_RECORDS`].
pub fn group_provenance_records(
    axes: &[GroupAxis],
    extra: &[ProvenanceRecord],
) -> Result<Vec<ProvenanceRecord>> {
    let mut records = Vec::new();
    for a in axes {
        if let Ok(view) = group_image::parse(&a.image) {
            for p in view.provenance.iter() {
                for mut r in p.records() {
                    r.axis = a.name.code();
                    records.push(r);
                }
            }
        }
    }
    records.extend_from_slice(extra);
    ensure!(
        records.len() <= provenance::MAX_RECORDS,
        "{} model files: an image records at most {}",
        records.len(),
        provenance::MAX_RECORDS
    );
    Ok(records)
}

/// A group's stages besides the axes, each with how the user named its source (for messages).
#[derive(Debug, Clone, Copy, Default)]
pub struct GroupStages<'a> {
    /// The rotary section and its source (e.g. `r.json`).
    pub rotary: Option<(&'a RotaryLocationSpec, &'a str)>,
    /// The geometric section and its source (e.g. `g.json`).
    pub geometric: Option<(&'a GeometricSection, &'a str)>,
    /// The probe settings (section kind 4).
    pub probe: Option<&'a ProbeSettings>,
}

/// Refuses a group in which one error would be corrected twice (see the module glossary): an axis's
/// positioning table and the geometric model's positioning component of that axis, or the rotary
/// model's squareness and the geometric model's, both non-zero. The error names both sources of
/// each and the way out (`--exclude-geometric`).
pub fn refuse_double_correction(axes: &[GroupAxis], stages: &GroupStages<'_>) -> Result<()> {
    let Some((geo, geo_path)) = stages.geometric else {
        return Ok(());
    };
    let spec = geo.spec();
    let mut twice: Vec<(&str, String)> = Vec::new();
    for (k, name) in [AxisName::X, AxisName::Y, AxisName::Z]
        .into_iter()
        .enumerate()
    {
        let i = 7 * k; // EXX, EYY, EZZ
        let Some(axis) = axes.iter().find(|a| a.name == name) else {
            continue;
        };
        let mut comp = Box::new(Compensator::IDENTITY);
        if comp.load(&axis.image).is_err() || !comp.has_table() {
            continue;
        }
        let table_corrects = comp
            .forward_segments()
            .iter()
            .chain(comp.backward_segments())
            .any(|c| *c != [0.0; 4]);
        if table_corrects && geometric_component_nonzero(&spec, i) {
            twice.push((
                COMPONENT_NAMES[i],
                format!(
                    "axis {l}'s positioning table (--axis {}) and the geometry model's {} \
                     (--geometry {geo_path}) both correct {l}'s positioning error",
                    axis.given_as,
                    COMPONENT_NAMES[i],
                    l = name.letter()
                ),
            ));
        }
    }
    if let Some((r, rotary_path)) = stages.rotary {
        for q in 0..3 {
            // The rotary section holds EA0Z, EB0Z, EC0Y; the geometric one EC0Y, EB0Z, EA0Z.
            let i = 18 + q;
            if r.squareness_urad[2 - q] != 0.0 && geometric_component_nonzero(&spec, i) {
                twice.push((
                    COMPONENT_NAMES[i],
                    format!(
                        "the rotary model's squareness {n} (--rotary {rotary_path}) and the \
                         geometry model's {n} (--geometry {geo_path}) both correct it",
                        n = COMPONENT_NAMES[i]
                    ),
                ));
            }
        }
    }
    if twice.is_empty() {
        return Ok(());
    }
    let names: Vec<&str> = twice.iter().map(|(n, _)| *n).collect();
    Err(Error::DoubleCorrection(format!(
        "the group would correct the same error twice (nothing written):\n{}\nkeep one source of \
         each: `--exclude-geometric {}` leaves the geometry model's out (the axis table or the \
         rotary model corrects it; `image inspect` lists it as excluded), or build the group from \
         an axis image without a positioning table / a rotary model without that squareness to \
         keep the geometry model's",
        twice
            .iter()
            .map(|(_, why)| format!("  - {why}"))
            .collect::<Vec<_>>()
            .join("\n"),
        names.join(",")
    )))
}

/// The group image bytes of `axes` with their sensor names (`names`, one list per axis) and
/// `stages`, checked as a board checks any group (one axis id on two axes, a pivot far outside
/// the strokes).
pub fn write_group(
    axes: &[GroupAxis],
    names: &[Vec<String>],
    stages: &GroupStages<'_>,
) -> Result<Vec<u8>> {
    let name_refs: Vec<Vec<&str>> = names
        .iter()
        .map(|l| l.iter().map(String::as_str).collect())
        .collect();
    let geometric = stages.geometric.map(|(g, _)| g);
    let specs: Vec<AxisSectionSpec> = axes
        .iter()
        .zip(&name_refs)
        .map(|(a, names)| AxisSectionSpec {
            name: a.name,
            counts_per_rev: a.counts_per_rev,
            stroke_counts: geometric
                .filter(|_| !a.name.is_rotary())
                .map(|g| g.strokes()[a.name.code() as usize]),
            image: &a.image,
            sensor_names: names,
        })
        .collect();
    let geo_spec = geometric.map(GeometricSection::spec);
    let rotary = stages.rotary.map(|(r, _)| r);
    let mut buf = vec![
        0u8;
        group_image::group_image_len_with_stages(
            &specs,
            rotary,
            geo_spec.as_ref(),
            stages.probe
        )
    ];
    let n = group_image::write_group_image_with_stages(
        &specs,
        rotary,
        geo_spec.as_ref(),
        stages.probe,
        &mut buf,
    )
    .map_err(|e| Error::core("the group is not valid", e))?;
    buf.truncate(n);
    group_image::parse(&buf)
        .and_then(|v| v.check_group())
        .map_err(|e| Error::core("the group is not valid", e))?;
    Ok(buf)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::describe::describe_geometric;
    use crate::geometric::GeometricSection;
    use crate::geometric::exclude_geometric_components;
    use axcomp_core::geometric::GeometricGrid;

    /// The stages of a group with rotary model `r.json` and geometry model `g.json`.
    fn stages<'a>(geo: &'a GeometricSection, rot: &'a RotaryLocationSpec) -> GroupStages<'a> {
        GroupStages {
            rotary: Some((rot, "r.json")),
            geometric: Some((geo, "g.json")),
            probe: None,
        }
    }

    /// A rotary model and a geometric model that both carry a non-zero squareness term would correct
    /// it twice: refused, naming both sources and `--exclude-geometric`; a term only one of them
    /// carries is not a conflict. With the geometric EC0Y excluded the group passes and `inspect` lists
    /// EC0Y as excluded.
    #[test]
    fn double_squareness_correction_is_refused_unless_excluded() {
        let grid = GeometricGrid {
            start_counts: 0,
            segment_counts: 1000,
            n_segments: 1,
        };
        let mut geo = GeometricSection {
            chain: [0, 1, 2],
            work_axes: 0,
            identified: (1 << 21) - 1,
            tool_offset_um: [0.0; 3],
            // EC0Y, EB0Z, EA0Z.
            squareness_urad: [5.0, 0.0, -3.0],
            grids: [grid; 3],
            coefficients: vec![[1.0, 0.0, 0.0, 0.0]; 18],
        };
        // EA0Z, EB0Z, EC0Y: only EC0Y is in both.
        let rot = RotaryLocationSpec {
            squareness_urad: [0.0, 2.0, 7.0],
            ..RotaryLocationSpec::ZERO_AC
        };
        let e = format!(
            "{:#}",
            refuse_double_correction(&[], &stages(&geo, &rot)).unwrap_err()
        );
        assert!(
            e.contains(
                "the rotary model's squareness EC0Y (--rotary r.json) and the geometry model's \
                 EC0Y (--geometry g.json) both correct it"
            ),
            "{e}"
        );
        assert!(e.contains("`--exclude-geometric EC0Y`"), "{e}");
        assert!(!e.contains("EA0Z") && !e.contains("EB0Z"), "{e}");
        exclude_geometric_components(&mut geo, &["ec0y".into()]).unwrap();
        assert_eq!(geo.squareness_urad, [0.0, 0.0, -3.0]);
        refuse_double_correction(&[], &stages(&geo, &rot)).unwrap();
        let text = describe_geometric(&geo.spec());
        assert!(
            text.contains("  EC0Y 0 µrad, identified by the fit, EXCLUDED from this image"),
            "{text}"
        );
        assert!(text.contains("  EA0Z -3 µrad, identified\n"), "{text}");
    }
}
