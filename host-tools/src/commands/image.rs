//! `axcomp image build|inspect` (not yet built).

#[derive(Debug, clap::Args)]
pub struct BuildArgs {}
#[derive(Debug, clap::Args)]
pub struct InspectArgs {}

pub fn build(_args: BuildArgs) -> anyhow::Result<()> {
    anyhow::bail!("`image build` is not implemented yet")
}
pub fn inspect(_args: InspectArgs) -> anyhow::Result<()> {
    anyhow::bail!("`image inspect` is not implemented yet")
}
