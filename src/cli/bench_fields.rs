//! `wildlight bench fields`.

/// Options of `wildlight bench fields`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs the fields benchmark.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wildlight bench fields` is not yet available in this version")
}
