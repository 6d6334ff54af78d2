//! `axcomp fit_thermal` (not yet built).

#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`fit_thermal` is not implemented yet")
}
