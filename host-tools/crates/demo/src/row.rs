//! What a chain of [`crate::all`] gives back: the system's row of the table, and the files, console
//! lines and data warnings it adds on the way.

use crate::OutputFile;

/// One system's row of the table.
pub(crate) struct Row {
    pub system: &'static str,
    pub figure: &'static str,
    pub before: f64,
    pub after: f64,
    pub firmware: String,
}

/// What the chains add on the way: files, console lines and data warnings.
#[derive(Default)]
pub(crate) struct ChainOutputs {
    pub files: Vec<OutputFile>,
    pub log: String,
    pub warnings: Vec<String>,
}
