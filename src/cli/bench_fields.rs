//! `wildlight bench fields`: throughput of the hash-grid SDF field
//! (forward, forward + backward, and forward + backward with FD normals).
//! Thread count: the rayon pool (`RAYON_NUM_THREADS`).

use wildlight_fields::bench::{BenchConfig, run as run_bench};

/// Options of `wildlight bench fields`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
    /// Points per batch.
    #[arg(long, default_value_t = 1 << 18)]
    batch: usize,
    /// Timed repetitions (medians are reported).
    #[arg(long, default_value_t = 7)]
    reps: usize,
    /// log2 of the hash-table size per level.
    #[arg(long, default_value_t = 19)]
    log2_table_size: u32,
    /// Hidden activation: "softplus" (beta 100, used with the sphere init) or "relu".
    #[arg(long, default_value = "softplus")]
    activation: String,
}

/// Runs the fields benchmark.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut cfg = BenchConfig::default();
    anyhow::ensure!(
        args.batch > 0 && args.reps > 0,
        "--batch and --reps must be positive"
    );
    cfg.batch = args.batch;
    cfg.reps = args.reps;
    cfg.field.grid.log2_table_size = args.log2_table_size;
    cfg.field.activation = match args.activation.as_str() {
        "softplus" => wildlight_fields::Activation::Softplus { beta: 100.0 },
        "relu" => wildlight_fields::Activation::Relu,
        other => anyhow::bail!("unknown --activation '{other}' (softplus or relu)"),
    };
    let r = run_bench(&cfg)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        let g = &cfg.field.grid;
        println!(
            "SDF field: {} levels x {} features, 2^{} entries, resolution {}..{}, hidden {:?} ({:?}), {} outputs",
            g.n_levels,
            g.n_features,
            g.log2_table_size,
            g.base_resolution,
            g.finest_resolution,
            cfg.field.hidden,
            cfg.field.activation,
            1 + cfg.field.n_features
        );
        println!(
            "batch {} points, {} threads, medians of {} runs",
            cfg.batch, r.threads, cfg.reps
        );
        println!(
            "forward:                      {:>12.0} points/s",
            r.fwd_points_per_s
        );
        println!(
            "forward + backward:           {:>12.0} points/s",
            r.fwd_bwd_points_per_s
        );
        println!(
            "forward + backward + normals: {:>12.0} points/s",
            r.fwd_bwd_normals_points_per_s
        );
        println!(
            "forward + backward + analytic gradient: {:>6.0} points/s",
            r.fwd_bwd_analytic_points_per_s
        );
        println!(
            "per CPU second (all threads): forward {:.0}, forward + backward {:.0} points",
            r.fwd_points_per_cpu_s, r.fwd_bwd_points_per_cpu_s
        );
        println!(
            "time share: encoding {:.0}%, MLP {:.0}% (enc fwd {:.1} ms, bwd {:.1} ms; MLP fwd {:.1} ms, bwd {:.1} ms)",
            100.0 * r.encoding_share,
            100.0 * r.mlp_share,
            1e3 * r.encoding_fwd_s,
            1e3 * r.encoding_bwd_s,
            1e3 * r.mlp_fwd_s,
            1e3 * r.mlp_bwd_s
        );
    }
    Ok(())
}
