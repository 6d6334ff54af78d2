//! `axcomp diagnose` on R-test / sphere-centre data (`dx_um`, `dy_um`, `dz_um` at rotary poses): the base model fitted on the
//! training rows, the held-out gap, and which unmodelled effect of the contract's vocabulary explains it.

use super::diagnose::Args;

pub fn run(_args: &Args, ds: axcomp_data::Dataset) -> anyhow::Result<()> {
    anyhow::bail!(
        "{}: diagnosis of R-test / sphere-centre data (`dx_um`, `dy_um`, `dz_um` at rotary poses) is not available in this build (issue 11)",
        ds.source()
    )
}
