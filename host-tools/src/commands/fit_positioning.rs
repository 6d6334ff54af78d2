//! `axcomp fit_positioning` (not yet built).

#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`fit_positioning` is not implemented yet")
}
