//! `axcomp validate_diagnosis` (not yet built).

#[derive(Debug, clap::Args)]
pub struct Args {}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`validate_diagnosis` is not implemented yet")
}
