//! Heidenhain TNC nonlinear axis error compensation: compensation value tables (`.COM`) and their assignment
//! table (`.CMA`).
//!
//! # Glossary (what the vendor documents, and what was chosen where it is silent)
//! - **table file** (TNC table format): a first line `BEGIN <name> <unit>` (`MM`), a line of column names,
//!   one line per entry, a last line `[END]`; columns separated by blanks.
//! - **`.COM`** ([entering values]): column `NR` (entry number), `AXISPOS` (the compensation point, mm from
//!   the machine datum), and one column per compensated axis named by its axis key, holding that axis's
//!   compensation value at the point (mm). One table per argument axis; at most 256 entries
//!   ([TNC 407 module 9095]: "more than 256 entries" is an error).
//! - **`.CMA`** ([assignment]): one column per axis; the `.COM` entered in column `A` gives
//!   `[axis of the .COM's value column] = F(A)`; `ACTIVE` holds `*` on the active line.
//! - **value and sign** (chosen: the documents plot the *error curve* that is entered, "Error in Z [mm]"
//!   over Y, [TNC 407 example]): each value is the model's error, reached − commanded, of the tool point
//!   relative to the workpiece along that axis, mm. An axis is compensated in its programmed direction, so
//!   no per-axis sign flip applies whichever side the axis carries.
//! - **what a 1-D table takes**: every positioning and straightness component, and the squareness terms
//!   (`X = −EC0Y·y` in `Y.COM`; `X = +EB0Z·z`, `Y = −EA0Z·z` in `Z.COM`), which depend on one axis only.
//!   Not taken: the angular components `EAX` … `ECZ`, whose effect (angle × lever arm to the tool point)
//!   depends on two or more axes and on the tool length (KinematicsComp's domain). The export states the
//!   error that remains without them over the model's volume ([`Remaining`]).
//!
//! [entering values]: https://www.easymanua.ls/heidenhain/manualplus-620/manual/506189?p=716
//! [assignment]: https://www.easymanua.ls/heidenhain/manualplus-620/manual/506189?p=718
//! [TNC 407 module 9095]: https://azmanual.top/manuals/797826/heidenhain-tnc-407-243-020-technical-manual.html?page=622
//! [TNC 407 example]: https://azmanual.top/manuals/797826/heidenhain-tnc-407-243-020-technical-manual.html?page=153

use axcomp_geometry::GeometryModel;
use axcomp_kinematics::{Axis, Component};

use crate::{ExportError, ExportFile, positions};

/// The vendor pages this writer follows.
pub const SOURCES: [&str; 3] = [
    "https://www.easymanua.ls/heidenhain/manualplus-620/manual/506189?p=716 (.COM columns NR, AXISPOS, axis keys)",
    "https://www.easymanua.ls/heidenhain/manualplus-620/manual/506189?p=718 (.CMA assignment, ACTIVE)",
    "https://azmanual.top/manuals/797826/heidenhain-tnc-407-243-020-technical-manual.html?page=622 (at most 256 entries per .COM)",
];

/// Most entries of one `.COM` table.
pub const MAX_ENTRIES: usize = 256;
/// The assignment table's name.
pub const CMA_FILE: &str = "AXCOMP.CMA";
/// The notes file (units, signs, what the tables cannot take and the error that remains).
pub const NOTES_FILE: &str = "README.txt";

/// The `.COM` of argument axis `a`.
pub fn com_file(a: Axis) -> String {
    format!("{}.COM", a.letter())
}

/// The error (µm) along axis `k` that the table of argument axis `a` gives at position `q` (mm): the
/// positioning/straightness component of `a` in direction `k`, plus the squareness term that depends on `a`.
pub fn table_value_um(model: &GeometryModel, a: Axis, k: Axis, q: f64) -> f64 {
    let comp = Component::ALL[6 * a.index() + k.index()];
    let mut v = model.component_value(comp, q);
    let sq = |c: Component| model.component_value(c, 0.0) * q * 1e-3;
    match (a, k) {
        (Axis::Y, Axis::X) => v -= sq(Component::EC0Y),
        (Axis::Z, Axis::X) => v += sq(Component::EB0Z),
        (Axis::Z, Axis::Y) => v -= sq(Component::EA0Z),
        _ => {}
    }
    v
}

/// The error that remains with the tables applied, over an 11×11×11 grid of the model's measured volume at
/// tool offset 0 (µm): RMS and largest |e| before (the model's error) and after (model − tables).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Remaining {
    pub before_rms_um: f64,
    pub before_max_um: f64,
    pub after_rms_um: f64,
    pub after_max_um: f64,
}

/// [`Remaining`] of `model`'s tables (evaluated with the model's own kinematics, `GeometryModel::error_at`).
pub fn remaining(model: &GeometryModel) -> Remaining {
    let (lo, hi) = (model.volume_min_mm, model.volume_max_mm);
    let n = 11;
    let (mut sb, mut sa, mut mb, mut ma, mut count) = (0.0, 0.0, 0.0f64, 0.0f64, 0.0);
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let f = |d: usize, s: usize| lo[d] + (hi[d] - lo[d]) * s as f64 / (n - 1) as f64;
                let q = [f(0, i), f(1, j), f(2, k)];
                let Some(e) = model.error_at(q, [0.0; 3]) else {
                    continue;
                };
                let mut r = e;
                for a in Axis::ALL {
                    for kk in Axis::ALL {
                        r[kk.index()] -= table_value_um(model, a, kk, q[a.index()]);
                    }
                }
                let (nb, na) = (norm(e), norm(r));
                sb += nb * nb;
                sa += na * na;
                mb = mb.max(nb);
                ma = ma.max(na);
                count += 1.0;
            }
        }
    }
    Remaining {
        before_rms_um: (sb / count).sqrt(),
        before_max_um: mb,
        after_rms_um: (sa / count).sqrt(),
        after_max_um: ma,
    }
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn com(model: &GeometryModel, a: Axis, step_mm: f64) -> Result<ExportFile, ExportError> {
    let g = model.grids[a.index()];
    let qs = positions(g.lo, g.hi, step_mm, MAX_ENTRIES)?;
    let name = com_file(a);
    let mut s = format!("BEGIN {name} MM\n");
    s.push_str(&format!(
        "{:<6}{:>14}{:>14}{:>14}{:>14}\n",
        "NR", "AXISPOS", "X", "Y", "Z"
    ));
    for (nr, q) in qs.iter().enumerate() {
        s.push_str(&format!("{nr:<6}{q:>+14.4}"));
        for k in Axis::ALL {
            s.push_str(&format!(
                "{:>+14.6}",
                table_value_um(model, a, k, *q) * 1e-3
            ));
        }
        s.push('\n');
    }
    s.push_str("[END]\n");
    Ok(ExportFile::new(name, s))
}

fn cma() -> ExportFile {
    let mut s = format!("BEGIN {CMA_FILE}\n{:<6}", "NR");
    for a in Axis::ALL {
        s.push_str(&format!("{:<12}", a.letter()));
    }
    s.push_str("ACTIVE\n0     ");
    for a in Axis::ALL {
        s.push_str(&format!("{:<12}", com_file(a)));
    }
    s.push_str("*\n[END]\n");
    ExportFile::new(CMA_FILE, s)
}

fn notes(model: &GeometryModel, r: &Remaining) -> ExportFile {
    let mut s = String::from(
        "axcomp: Heidenhain TNC nonlinear axis error compensation from a geometry model (fit geometry)\n\n",
    );
    s.push_str(
        "Format (the .COM and .CMA tables have no comment syntax, so this file states it):\n",
    );
    for src in SOURCES {
        s.push_str(&format!("  {src}\n"));
    }
    s.push_str(&format!(
        "\nFiles: {CMA_FILE} assigns X.COM, Y.COM, Z.COM (line 0, ACTIVE *); in column A of the .CMA, the \
         .COM gives X, Y and Z compensation as functions of axis A.\nUnits: AXISPOS mm from the machine datum \
         (the model's axis positions); values mm.\nSign: each value is the error, reached − commanded, of the \
         tool point relative to the workpiece along the column's axis (the error curve the control \
         compensates); axis stacking of the model {} (no per-axis sign flip: axes are compensated in their \
         programmed direction).\nSquareness is folded in: Y.COM column X holds EXY − EC0Y·y, Z.COM columns X \
         and Y hold EXZ + EB0Z·z and EYZ − EA0Z·z.\n",
        model.topology.label()
    ));
    s.push_str(
        "\nNot taken: the angular components EAX EBX ECX EAY EBY ECY EAZ EBZ ECZ (their effect, angle × lever \
         arm to the tool point, depends on several axes and on the tool length: KinematicsComp).\n",
    );
    s.push_str(&format!(
        "Error that remains without them, over an 11×11×11 grid of the measured volume at tool offset 0 \
         (the project's kinematics, GeometryModel::error_at): |e| RMS {:.3} µm, max {:.3} µm (model error \
         before any table: RMS {:.3} µm, max {:.3} µm).\n",
        r.after_rms_um, r.after_max_um, r.before_rms_um, r.before_max_um
    ));
    let missing: Vec<&str> = model
        .components
        .iter()
        .filter(|m| !m.identified)
        .map(|m| m.name.as_str())
        .collect();
    if !missing.is_empty() {
        s.push_str(&format!(
            "Not identified by the measurement (held at the prior 0): {}\n",
            missing.join(" ")
        ));
    }
    ExportFile::new(NOTES_FILE, s)
}

/// The Heidenhain export of `model`: `X.COM`, `Y.COM`, `Z.COM` (`step_mm` apart, ≤ 0: 40 steps; at most
/// [`MAX_ENTRIES`]), the `.CMA`, and the notes; with the [`Remaining`] error.
pub fn export(
    model: &GeometryModel,
    step_mm: f64,
) -> Result<(Vec<ExportFile>, Remaining), ExportError> {
    let mut out = Vec::new();
    for a in Axis::ALL {
        out.push(com(model, a, step_mm)?);
    }
    out.push(cma());
    let r = remaining(model);
    out.push(notes(model, &r));
    Ok((out, r))
}

/// A TNC table read back: the name and unit of its `BEGIN` line, the column names, the entries.
#[derive(Debug, Clone, PartialEq)]
pub struct TncTable {
    pub name: String,
    pub unit: Option<String>,
    pub columns: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

/// Reads a TNC table by its grammar: `BEGIN name [unit]`, the column names, entries of as many fields,
/// `[END]` last. The error names the line.
pub fn parse_table(text: &str) -> Result<TncTable, String> {
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    let first: Vec<&str> = lines
        .first()
        .ok_or("empty table")?
        .split_whitespace()
        .collect();
    if first.first() != Some(&"BEGIN") || first.len() < 2 || first.len() > 3 {
        return Err(format!("line 1: `{}` is not `BEGIN name [unit]`", lines[0]));
    }
    if lines.last().map(|l| l.trim()) != Some("[END]") || lines.len() < 3 {
        return Err("the last line is not `[END]`".into());
    }
    let columns: Vec<String> = lines[1].split_whitespace().map(String::from).collect();
    let mut rows = Vec::new();
    for (i, l) in lines[2..lines.len() - 1].iter().enumerate() {
        let f: Vec<String> = l.split_whitespace().map(String::from).collect();
        if f.len() != columns.len() {
            return Err(format!(
                "line {}: {} fields under {} columns",
                i + 3,
                f.len(),
                columns.len()
            ));
        }
        rows.push(f);
    }
    Ok(TncTable {
        name: first[1].to_string(),
        unit: first.get(2).map(|u| u.to_string()),
        columns,
        rows,
    })
}
