//! `wildlight bench`: benchmarks of the performance-critical parts.
//! Each benchmark is its own subcommand in its own module.

/// Options of `wildlight bench`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    which: Which,
}

#[derive(clap::Subcommand, Debug)]
enum Which {
    /// Hash-grid SDF field: forward and forward+backward throughput.
    Fields(bench_fields::Args),
    /// Asset export: wall time, peak memory and (--roundtrip) the round trip.
    Export(bench_export::Args),
    /// Training: rays per second and a step's time by phase.
    Train(bench_train::Args),
}

/// Runs the chosen benchmark.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.which {
        Which::Fields(a) => bench_fields::run(a),
        Which::Export(a) => bench_export::run(a),
        Which::Train(a) => bench_train::run(a),
    }
}

#[path = "bench_fields.rs"]
mod bench_fields;

#[path = "bench_export.rs"]
mod bench_export;

#[path = "bench_train.rs"]
mod bench_train;
