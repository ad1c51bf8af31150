//! `wildlight export`.

/// Options of `wildlight export`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `wildlight export`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wildlight export` is not yet available in this version")
}
