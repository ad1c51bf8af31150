//! `wildlight demo`.

/// Options of `wildlight demo`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `wildlight demo`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wildlight demo` is not yet available in this version")
}
