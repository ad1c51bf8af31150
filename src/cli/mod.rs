//! One module per subcommand. Each has `Args` (clap) and `run(Args)`.

pub mod bench;
pub mod brdf;
pub mod demo;
pub mod eval;
pub mod export;
pub mod import;
pub mod info;
pub mod reconstruct;
pub mod render;
pub mod synth;
pub mod train;
