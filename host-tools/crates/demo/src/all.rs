//! `axcomp demo --all`: every system's chain on the twin, one row per system.
//!
//! Glossary:
//! - *system*: positioning (one linear axis, ISO 230-2), thermo-force (drift with temperature on
//!   one axis), three-axis geometry (21 ISO 230-1 components), five-axis rotary (ISO 230-7 location
//!   errors, R-test), touch probe (stylus radius and pretravel).
//! - *chain*: measure on the twin → fit (the library the `fit` command calls) → image (the core's
//!   image writers, as `image build` / `image group`) → the firmware library applies the image
//!   (`axcomp_core::Compensator` / `group::Group`, loaded from the image bytes) → before / after on
//!   data the fit never saw.
//! - *before / after*: the figure named in the row, uncompensated and through the firmware library.
//!   The probe has no firmware stage for its calibration (the core's probe section only latches
//!   touches: filter, latency, lockout): its "after" is the host's correction (`axcomp predict`),
//!   and the row says so.

use std::fmt::Write as _;
use std::time::Instant;

use serde_json::json;

use crate::row::{ChainOutputs, Row};
use crate::{OutputFile, Result, StepContext};

/// A chain: noise seed and outputs in, the system's row out.
type Chain = fn(u64, &mut ChainOutputs) -> Result<Row>;

/// The chains in the table's order, with the names errors give them.
const CHAINS: [(&str, Chain); 5] = [
    ("positioning", crate::chains::positioning),
    ("thermo-force", crate::chains::thermo_force),
    ("geometry", crate::chains::geometry),
    ("rotary", crate::rotary::rotary),
    ("probe", crate::probe::probe),
];

/// What every chain gives the command.
pub struct AllDemo {
    /// Each chain's data and image, then `demo_all.json` and `report.md`.
    pub files: Vec<OutputFile>,
    /// What the chains report on the way (the probe calibration's summary), then the table.
    pub console: String,
    /// Data warnings of the chains, one message each.
    pub warnings: Vec<String>,
    /// Number of systems (rows of the table).
    pub systems: usize,
    /// Time taken, s.
    pub seconds: f64,
}

/// The table: one row per system, before / after and the firmware stage that applied the image.
fn table(rows: &[Row]) -> Result<String> {
    let mut table = String::new();
    writeln!(
        table,
        "{:<20} {:>10} {:>10} {:>7}  {:<62} firmware stage",
        "system", "before", "after", "less", "figure (data the fit never saw)"
    )?;
    for r in rows {
        writeln!(
            table,
            "{:<20} {:>10.3} {:>10.3} {:>6.1}%  {:<62} {}",
            r.system,
            r.before,
            r.after,
            100.0 * (1.0 - r.after / r.before),
            r.figure,
            r.firmware
        )?;
    }
    Ok(table)
}

/// Runs every chain with noise seed `seed`: the table, `demo_all.json`, `report.md` and each chain's
/// data and image.
pub fn run(seed: u64) -> Result<AllDemo> {
    let t0 = Instant::now();
    let mut out = ChainOutputs::default();
    let mut rows = Vec::new();
    let mut times = Vec::new();
    for (name, chain) in CHAINS {
        let t = Instant::now();
        let row = chain(seed, &mut out).step(|| format!("demo --all: the {name} chain"))?;
        rows.push(row);
        times.push(t.elapsed().as_secs_f64());
    }
    let table = table(&rows)?;
    let seconds = t0.elapsed().as_secs_f64();
    let summary = json!({
        "seed": seed,
        "seconds": seconds,
        "systems": rows.iter().zip(&times).map(|(r, s)| json!({
            "system": r.system, "figure": r.figure, "before": r.before, "after": r.after,
            "firmware": r.firmware, "seconds": s,
        })).collect::<Vec<_>>(),
    });
    let report = format!(
        "# axcomp demo --all\n\nEvery system's chain on the twin: measure → fit → image → the firmware \
         library applies the image → before/after on data the fit never saw (seed {seed}).\n\n```\n{table}```\n"
    );
    let ChainOutputs {
        mut files,
        log,
        warnings,
    } = out;
    files.push((
        "demo_all.json".into(),
        (serde_json::to_string_pretty(&summary)? + "\n").into_bytes(),
    ));
    files.push(("report.md".into(), report.into_bytes()));
    Ok(AllDemo {
        files,
        console: log + &table,
        warnings,
        systems: rows.len(),
        seconds,
    })
}
