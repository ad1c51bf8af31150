//! The `wildlight` command line: a thin layer over the workspace crates.
//!
//! Each subcommand lives in its own module under `cli/` with an `Args`
//! struct (clap) and a `run` function; all the work happens in the crates.

use clap::{Parser, Subcommand};

mod cli;
mod display;
mod field_source;
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
    /// Photos in, asset out: import, train without masks, export the object, preview.
    Reconstruct(cli::reconstruct::Args),
    /// Turn a folder of photos into a capture: COLMAP poses, linear images, flash labels.
    Import(cli::import::Args),
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
        Command::Reconstruct(a) => cli::reconstruct::run(a),
        Command::Import(a) => cli::import::run(a),
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
            eprintln!("error: {}", error_message(&err));
            std::process::ExitCode::FAILURE
        }
    }
}

/// An error and its causes on one line, outermost first ("context: cause:
/// its cause"), as anyhow's `{:#}` writes them, except that a cause whose
/// text the line already holds is left out: errors that name their file
/// and reason in their own message also keep the reason as their source
/// (`{path}: {source}`), which `{:#}` would print twice.
fn error_message(err: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in err.chain() {
        let text = cause.to_string();
        if line.is_empty() {
            line = text;
        } else if !line.contains(&text) {
            line.push_str(": ");
            line.push_str(&text);
        }
    }
    line
}

#[cfg(test)]
mod tests {
    use super::error_message;

    /// An error that names its file and reason and keeps the reason as its
    /// source, as the crates' I/O errors do.
    #[derive(Debug)]
    struct Named {
        source: std::io::Error,
    }

    impl std::fmt::Display for Named {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            write!(f, "mesh.ply: {}", self.source)
        }
    }

    impl std::error::Error for Named {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            Some(&self.source)
        }
    }

    #[test]
    fn a_cause_already_in_the_message_is_printed_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let err = anyhow::Error::new(Named { source: io }).context("cannot load the capture");
        assert_eq!(
            error_message(&err),
            "cannot load the capture: mesh.ply: no such file"
        );
        // causes that add something are all kept, outermost first
        let err = anyhow::anyhow!("bad value")
            .context("reading x.toml")
            .context("train");
        assert_eq!(error_message(&err), "train: reading x.toml: bad value");
    }
}
