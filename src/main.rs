//! The `wildlight` command line: a thin layer over the workspace crates.
//!
//! Each subcommand lives in its own module under `cli/` with an `Args`
//! struct (clap) and a `run` function; all the work happens in the crates.

use clap::{Parser, Subcommand};

mod cli;
mod plot;

/// Inverse rendering with a flashlight: shape and materials from
/// flash / no-flash photographs with known camera poses.
#[derive(Parser)]
#[command(
    name = "wildlight",
    version,
    about,
    long_about = None,
    propagate_version = true,
    after_help = "Start with `wildlight demo --quick` (about two minutes). README.md explains how to \
                  capture your own object; `wildlight <COMMAND> --help` lists every option with its default."
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Synthesize the default capture, reconstruct it, export it and print the metrics.
    Demo(cli::demo::Args),
    /// Describe a dataset: images, flash, cameras, masks, and warnings.
    Info(cli::info::Args),
    /// Evaluate the material model (SPEC section 3) on JSON lines, or plot a lobe.
    Brdf(cli::brdf::Args),
    /// Render a synthetic flash/no-flash capture with ground truth.
    Synth(cli::synth::Args),
    /// Reconstruct shape, materials and flash gain from a capture.
    Train(cli::train::Args),
    /// Render a trained run (or an exported asset) from a capture's cameras.
    Render(cli::render::Args),
    /// Export a trained run as glTF 2.0 (.glb) and OBJ+MTL+PNG.
    Export(cli::export::Args),
    /// Measure geometry, image and material accuracy.
    Eval(cli::eval::Args),
    /// Benchmarks of the performance-critical parts.
    Bench(cli::bench::Args),
}

/// Restores the default action of SIGPIPE, so that `wildlight … | head`
/// ends quietly when the reader goes away instead of panicking in `println!`
/// (Rust ignores SIGPIPE by default).
#[cfg(unix)]
fn default_sigpipe() {
    // SAFETY: called once at start-up, before any other thread exists;
    // SIG_DFL is a valid disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

fn main() -> std::process::ExitCode {
    #[cfg(unix)]
    default_sigpipe();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Demo(a) => cli::demo::run(a),
        Command::Info(a) => cli::info::run(a),
        Command::Brdf(a) => cli::brdf::run(a),
        Command::Synth(a) => cli::synth::run(a),
        Command::Train(a) => cli::train::run(a),
        Command::Render(a) => cli::render::run(a),
        Command::Export(a) => cli::export::run(a),
        Command::Eval(a) => cli::eval::run(a),
        Command::Bench(a) => cli::bench::run(a),
    };
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("error: {err:#}");
            std::process::ExitCode::FAILURE
        }
    }
}
