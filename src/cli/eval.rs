//! `wildlight eval`.

/// Options of `wildlight eval`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `wildlight eval`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wildlight eval` is not yet available in this version")
}
