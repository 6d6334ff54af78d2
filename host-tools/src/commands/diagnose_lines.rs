//! `axcomp diagnose` on laser-line data (`x_mm`, `y_mm`, `z_mm`, `line`, `deviation_um`): the base model fitted on the
//! training rows, the held-out gap, and which unmodelled effect of the contract's vocabulary explains it.

use super::diagnose::Args;

pub fn run(_args: &Args, ds: axcomp_data::Dataset) -> anyhow::Result<()> {
    anyhow::bail!(
        "{}: diagnosis of laser-line data (`x_mm`, `y_mm`, `z_mm`, `line`, `deviation_um`) is not available in this build (issue 10)",
        ds.source()
    )
}
