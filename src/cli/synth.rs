//! `wildlight synth`.

/// Options of `wildlight synth`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `wildlight synth`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wildlight synth` is not yet available in this version")
}
