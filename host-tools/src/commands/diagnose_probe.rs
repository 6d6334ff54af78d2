//! `axcomp diagnose` on probe touches (`approach_x`, `approach_y`, `approach_z`): the base model fitted on the
//! training rows, the held-out gap, and which unmodelled effect of the contract's vocabulary explains it.

use super::diagnose::Args;

pub fn run(_args: &Args, ds: axcomp_data::Dataset) -> anyhow::Result<()> {
    anyhow::bail!(
        "{}: diagnosis of probe touches (`approach_x`, `approach_y`, `approach_z`) is not available in this build (issue 12)",
        ds.source()
    )
}
