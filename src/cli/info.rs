//! `wildlight info`.

/// Options of `wildlight info`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `wildlight info`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wildlight info` is not yet available in this version")
}
