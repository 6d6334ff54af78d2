//! `axcomp diagnose` (not yet built).

#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`diagnose` is not implemented yet")
}
