//! `wildlight brdf`.

/// Options of `wildlight brdf`.
#[derive(clap::Args, Debug)]
pub struct Args {}

/// Runs `wildlight brdf`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`wildlight brdf` is not yet available in this version")
}
