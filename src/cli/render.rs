//! `wildlight render`.

/// Options of `wildlight render`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `wildlight render`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wildlight render` is not yet available in this version")
}
