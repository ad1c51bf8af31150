//! `wildlight train`.

/// Options of `wildlight train`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `wildlight train`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wildlight train` is not yet available in this version")
}
