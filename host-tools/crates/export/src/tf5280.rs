//! Beckhoff TwinCAT TF5280 (ISG kernel) volumetric compensation: ISG CSV parameter files and the
//! compensation list (`.lis`) that names them.
//!
//! # Glossary (what the vendor documents, and what was chosen where it is silent)
//! - **ISG CSV** ([ISG CSV format]): whitespace-separated columns; the first line that is not a comment is
//!   the header of argument names (`X`, `Y`, `Z` in mm; `A`, `B`, `C` in degrees) and error-parameter
//!   names; the rows below are records; `//` starts a comment line; `#` starts a new block (new header).
//! - **units** ([units]): parameter values in mm (offsets) and rad (angles); arguments in mm.
//! - **names** ([parameters]): component errors `EXX` … `ECZ` (ISO 230-1), position errors `X0Y` … `C0C`;
//!   the model's squareness `EC0Y`, `EB0Z`, `EA0Z` are ISG's `C0Y`, `B0Z`, `A0Z`.
//! - **compensation list** ([configuration], [update example]): `key value` lines, `#` comments: the
//!   logical axis number of `X`, `Y`, `Z`, `chain` (the axis order of the kinematic chain, walked from the
//!   workpiece to the tool, as in the documented `CBYXZ` for a machine with B and C in the workpiece),
//!   `workpiece_axes` (how many axes of the chain lie on the workpiece side, [P-VOLC-00008]), and
//!   `file[j]` / `file_format[j] ISG_CSV`.
//! - **chosen, the vendor pages being silent or unreachable here**: logical axis numbers 1, 2, 3 for X, Y, Z
//!   (edit them to the machine's); the file paths written as bare names (the controller reads the path as
//!   given: prefix the folder the files are copied to); the sign of a workpiece-side axis's values (below).
//! - **sign**: ISO 230-1 states each component as the error motion of the axis's own carriage, and the list
//!   says which carriages carry the workpiece, so the files give each axis's own error motion: for a
//!   tool-side axis the model's value (tool point relative to the workpiece), for a workpiece-side axis its
//!   negative (the table moving by +δ moves the tool relative to the workpiece by −δ). Squareness (`C0Y`,
//!   `B0Z`, `A0Z`) is the orientation of an axis's line of motion, which is the same line whichever side
//!   moves along it: the model's value, unchanged. Rule of the ISG manual ([workpiece axes]): an axis the
//!   measurement treats as tool-side must be configured tool-side; these files follow the stacking the model
//!   was fitted with.
//!
//! [ISG CSV format]: https://infosys.beckhoff.com/content/1033/tf5280_volumetric_comp/296429067.html
//! [units]: https://infosys.beckhoff.com/content/1033/tf5280_volumetric_comp/296426379.html
//! [parameters]: https://infosys.beckhoff.com/content/1033/tf5280_volumetric_comp/296423819.html
//! [configuration]: https://infosys.beckhoff.com/content/1033/tf5280_volumetric_comp/296390283.html
//! [update example]: https://infosys.beckhoff.com/content/1033/tf5280_volumetric_comp/1218769547.html
//! [P-VOLC-00008]: https://www.isg-stuttgart.de/fileadmin/kernel/kernel-html/en-GB/106014347.html
//! [workpiece axes]: https://isg-stuttgart.de/fileadmin/kernel/kernel-html/de-DE/296411019.html

use axcomp_geometry::GeometryModel;
use axcomp_kinematics::{Axis, Component, ComponentKind};

use crate::{ExportError, ExportFile, positions};

/// The vendor pages this writer follows (also written into each file).
pub const SOURCES: [&str; 4] = [
    "https://infosys.beckhoff.com/content/1033/tf5280_volumetric_comp/296429067.html (ISG CSV format)",
    "https://infosys.beckhoff.com/content/1033/tf5280_volumetric_comp/296426379.html (units)",
    "https://infosys.beckhoff.com/content/1033/tf5280_volumetric_comp/296423819.html (parameter names)",
    "https://infosys.beckhoff.com/content/1033/tf5280_volumetric_comp/296390283.html (compensation list)",
];

/// Most records per component file.
pub const MAX_RECORDS: usize = 100_000;

/// The compensation list's file name.
pub const LIST_FILE: &str = "volcomp.lis";
/// The position-error (squareness) file's name.
pub const POSITION_FILE: &str = "position_errors.csv";

/// The component file of axis `a`.
pub fn component_file(a: Axis) -> String {
    format!("components_{}.csv", a.letter())
}

/// ISG's name of a model component: `EXX` … `ECZ` as they are, squareness `EC0Y` → `C0Y`.
pub fn isg_name(c: Component) -> &'static str {
    match c {
        Component::EC0Y => "C0Y",
        Component::EB0Z => "B0Z",
        Component::EA0Z => "A0Z",
        _ => c.name(),
    }
}

/// Factor from the model's value (µm or µrad) to the file's value (mm or rad) of component `c`: 1e-3 or
/// 1e-6, negated for a component of a workpiece-side axis (see the module glossary).
pub fn file_factor(model: &GeometryModel, c: Component) -> f64 {
    let unit = match c.kind() {
        ComponentKind::Linear { .. } => 1e-3,
        _ => 1e-6,
    };
    match c.axis() {
        Some(a) if model.topology.work.contains(&a) => -unit,
        _ => unit,
    }
}

fn comment_head(model: &GeometryModel, what: &str) -> String {
    let mut s = format!("// axcomp: {what}\n// Format (Beckhoff TwinCAT TF5280, ISG CSV):\n");
    for src in &SOURCES[..3] {
        s.push_str(&format!("//   {src}\n"));
    }
    s.push_str(&format!(
        "// Model: axis stacking {} (workpiece axes from the bed outward / tool axes), chain {} from the \
         workpiece to the tool; fitted by {}\n",
        model.topology.label(),
        chain(model),
        model.method
    ));
    let missing: Vec<&str> = model
        .components
        .iter()
        .filter(|m| !m.identified)
        .map(|m| m.name.as_str())
        .collect();
    if !missing.is_empty() {
        s.push_str(&format!(
            "// Not identified by the measurement (held at the prior 0): {}\n",
            missing.join(" ")
        ));
    }
    s
}

/// The chain letters, workpiece to tool.
pub fn chain(model: &GeometryModel) -> String {
    model.topology.chain().iter().map(|a| a.letter()).collect()
}

fn axis_file(model: &GeometryModel, a: Axis, step_mm: f64) -> Result<ExportFile, ExportError> {
    let g = model.grids[a.index()];
    let qs = positions(g.lo, g.hi, step_mm, MAX_RECORDS)?;
    let comps = &Component::ALL[6 * a.index()..6 * a.index() + 6];
    let side = if model.topology.work.contains(&a) {
        "carries the workpiece: each value is the axis's own error motion, the negative of the model's \
         (tool relative to workpiece)"
    } else {
        "carries the tool: each value is the axis's own error motion, equal to the model's (tool relative \
         to workpiece)"
    };
    let mut s = comment_head(model, &format!("component errors of axis {}", a.letter()));
    s.push_str(&format!(
        "// Units: argument {l} in mm; E{l}{l} E{o1}{l} E{o2}{l} in mm (ISO 230-1 positioning, straightness); \
         EA{l} EB{l} EC{l} in rad (roll/pitch/yaw, right-handed)\n// Sign: {l} {side}; errors are reached − \
         commanded\n",
        l = a.letter(),
        o1 = ['Y', 'X', 'X'][a.index()],
        o2 = ['Z', 'Z', 'Y'][a.index()],
    ));
    s.push(a.letter());
    for c in comps {
        s.push(' ');
        s.push_str(isg_name(*c));
    }
    s.push('\n');
    for q in qs {
        s.push_str(&format!("{q:.4}"));
        for c in comps {
            let v = model.component_value(*c, q) * file_factor(model, *c);
            match c.kind() {
                ComponentKind::Linear { .. } => s.push_str(&format!(" {v:.7}")),
                _ => s.push_str(&format!(" {v:.10}")),
            }
        }
        s.push('\n');
    }
    Ok(ExportFile::new(component_file(a), s))
}

fn position_file(model: &GeometryModel) -> ExportFile {
    let sq = [Component::EC0Y, Component::EB0Z, Component::EA0Z];
    let mut s = comment_head(model, "position errors (squareness of the linear axes)");
    s.push_str(
        "// Units: rad. C0Y: Y's line about Z (Y runs along (-C0Y, 1, 0)); B0Z: Z's line about Y; A0Z: Z's \
         line about X (Z runs along (B0Z, -A0Z, 1)); X's line is the reference\n// Sign: ISO 230-1, \
         right-handed; the orientation of a line of motion, the same whichever side moves along it\n",
    );
    let names: Vec<&str> = sq.iter().map(|c| isg_name(*c)).collect();
    s.push_str(&names.join(" "));
    s.push('\n');
    let vals: Vec<String> = sq
        .iter()
        .map(|c| {
            format!(
                "{:.10}",
                model.component_value(*c, 0.0) * file_factor(model, *c)
            )
        })
        .collect();
    s.push_str(&vals.join(" "));
    s.push('\n');
    ExportFile::new(POSITION_FILE, s)
}

fn list_file(model: &GeometryModel, files: &[String]) -> ExportFile {
    let mut s = String::from(
        "# axcomp: Beckhoff TwinCAT TF5280 volumetric compensation list (ISG), written from a geometry model\n",
    );
    s.push_str(&format!("# Format: {}\n", SOURCES[3]));
    s.push_str(
        "# Units of the parameter files: arguments mm; offsets mm; angles rad (see each file's header)\n\
         # Logical axis numbers: 1, 2, 3 were chosen for X, Y, Z; set them to the machine's\n",
    );
    for (k, a) in Axis::ALL.iter().enumerate() {
        s.push_str(&format!("{:<24} {}\n", a.letter(), k + 1));
    }
    let work: String = model
        .topology
        .work
        .iter()
        .rev()
        .map(|a| a.letter())
        .collect();
    s.push_str(&format!(
        "# Axis stacking: chain from the workpiece to the tool; its first {} axes ({}) carry the workpiece. \
         Sign: each parameter file gives every axis's own error motion (a workpiece axis's values are the \
         negative of the tool-relative-to-workpiece error the model was fitted as)\n",
        model.topology.work.len(),
        if work.is_empty() { "none".into() } else { work }
    ));
    s.push_str(&format!("{:<24} {}\n", "chain", chain(model)));
    s.push_str(&format!(
        "{:<24} {}\n",
        "workpiece_axes",
        model.topology.work.len()
    ));
    s.push_str(
        "# Parameter files: bare names; the controller reads each path as given, so prefix the folder they \
         are copied to (e.g. C:\\volcomp\\)\n",
    );
    for (j, f) in files.iter().enumerate() {
        s.push_str(&format!("{:<24} {f}\n", format!("file[{j}]")));
        s.push_str(&format!("{:<24} ISG_CSV\n", format!("file_format[{j}]")));
    }
    ExportFile::new(LIST_FILE, s)
}

/// The TF5280 export of `model`: one component file per axis (`step_mm` apart, ≤ 0: 40 steps), the
/// position-error file, and the compensation list naming them.
pub fn export(model: &GeometryModel, step_mm: f64) -> Result<Vec<ExportFile>, ExportError> {
    let mut out = Vec::new();
    for a in Axis::ALL {
        out.push(axis_file(model, a, step_mm)?);
    }
    out.push(position_file(model));
    let names: Vec<String> = out.iter().map(|f| f.name.clone()).collect();
    out.insert(0, list_file(model, &names));
    Ok(out)
}

/// One block of an ISG CSV file: the header names and the records.
#[derive(Debug, Clone, PartialEq)]
pub struct IsgBlock {
    pub header: Vec<String>,
    pub rows: Vec<Vec<f64>>,
}

/// Whether `name` is an ISG argument (`X` … `C`) or an error parameter of the vendor's list
/// (`E[XYZABC][XYZABC]`, `[XYZABC]0[XYZABC]`).
pub fn is_isg_name(name: &str) -> bool {
    let l = |c: u8| b"XYZABC".contains(&c);
    match name.as_bytes() {
        [a] => l(*a),
        [b'E', d, a] => l(*d) && l(*a),
        [d, b'0', a] => l(*d) && l(*a),
        _ => false,
    }
}

/// Reads an ISG CSV file by the documented grammar: `//` comment lines, a header of known names, records
/// of as many numbers, `#` starting a new block. The error names the line.
pub fn parse_isg_csv(text: &str) -> Result<Vec<IsgBlock>, String> {
    let mut blocks: Vec<IsgBlock> = Vec::new();
    let mut open = false;
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.is_empty() || t.starts_with("//") {
            continue;
        }
        if t.starts_with('#') {
            open = false;
            continue;
        }
        let words: Vec<&str> = t.split_whitespace().collect();
        if !open {
            if let Some(w) = words.iter().find(|w| !is_isg_name(w)) {
                return Err(format!(
                    "line {}: header name `{w}` is not an ISG name",
                    i + 1
                ));
            }
            blocks.push(IsgBlock {
                header: words.iter().map(|w| w.to_string()).collect(),
                rows: Vec::new(),
            });
            open = true;
            continue;
        }
        let block = blocks.last_mut().expect("open block");
        let row: Result<Vec<f64>, _> = words.iter().map(|w| w.parse::<f64>()).collect();
        let row = row.map_err(|e| format!("line {}: {e}", i + 1))?;
        if row.len() != block.header.len() {
            return Err(format!(
                "line {}: {} values under a header of {}",
                i + 1,
                row.len(),
                block.header.len()
            ));
        }
        block.rows.push(row);
    }
    Ok(blocks)
}

/// Reads a compensation list: `key value` lines, `#` comments. The error names the line.
pub fn parse_list(text: &str) -> Result<Vec<(String, String)>, String> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let mut w = t.split_whitespace();
        match (w.next(), w.next(), w.next()) {
            (Some(k), Some(v), None) => out.push((k.to_string(), v.to_string())),
            _ => return Err(format!("line {}: not `key value`: {t}", i + 1)),
        }
    }
    Ok(out)
}
