//! `wildlight bench train`: training throughput on a capture (rays per
//! second and a step's time by phase; medians of fresh repetitions).
//! Thread count: the rayon pool (`RAYON_NUM_THREADS`).

use crate::cli::train::MasksArg;
use std::path::PathBuf;
use wildlight_train::TrainConfig;
use wildlight_train::bench::{TrainBench, bench_train};
use wildlight_train::run::{check_maskless_capture, load_capture, mask_mode, training_rays};

/// Options of `wildlight bench train`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Capture folder (SPEC §5 layout).
    #[arg(long, value_name = "DIR")]
    data: PathBuf,
    /// TOML configuration, as `train --config` [default: the built-in defaults].
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// `use` or `ignore` the capture's masks, as `train --masks`
    /// [default: the masks when the capture has them].
    #[arg(long, value_name = "use|ignore")]
    masks: Option<MasksArg>,
    /// Steps trained before timing.
    #[arg(long, default_value_t = 100)]
    warmup: u64,
    /// Steps timed.
    #[arg(long, default_value_t = 500)]
    steps: u64,
    /// Repetitions, each from a fresh model (medians are reported).
    #[arg(long, default_value_t = 3)]
    reps: usize,
    /// Seed of the model and the ray draws.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Print the report as JSON.
    #[arg(long)]
    json: bool,
}

/// Runs the training benchmark.
pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.steps > 0 && args.reps > 0,
        "--steps and --reps must be positive"
    );
    let mut config = match &args.config {
        Some(p) => TrainConfig::load(p)?,
        None => TrainConfig::default(),
    };
    config.seed = args.seed;
    config.iters = args.warmup + args.steps;
    config.validate().map_err(anyhow::Error::msg)?;
    let (dataset, mut warnings) = load_capture(&args.data)?;
    let mode = mask_mode(&dataset, MasksArg::choice(args.masks))?;
    if mode.maskless() {
        warnings.extend(check_maskless_capture(&dataset)?);
    }
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    let bench = TrainBench {
        warmup: args.warmup,
        steps: args.steps,
        reps: args.reps,
    };
    let report = bench_train(&config, || training_rays(&dataset, mode), &bench)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    let p = &report.phase_ms;
    println!(
        "training on {} ({}), {} rays a step, {} threads: {} warm-up steps, then {} timed, medians of {} runs",
        args.data.display(),
        if report.maskless {
            "no masks: background modelled"
        } else {
            "with masks"
        },
        report.batch_rays,
        report.threads,
        report.warmup,
        report.steps,
        report.reps.len()
    );
    println!(
        "rays per second:  {:>10.0}   ({:.1} samples a ray)",
        report.rays_per_s, report.samples_per_ray
    );
    println!(
        "a step (ms):      setup {:.1}, forward {:.1}, backward {:.1}, priors {:.1}, visual hull {:.1}, update {:.1}",
        p.setup, p.forward, p.backward, p.priors, p.hull, p.update
    );
    if report.maskless {
        let step = p.setup + p.forward + p.backward + p.priors + p.hull + p.update;
        println!(
            "the background:   {:.1} ms of forward + backward ({:.0} % of a step)",
            p.background,
            100.0 * p.background / step.max(1e-9)
        );
    }
    let each: Vec<String> = report
        .reps
        .iter()
        .map(|r| format!("{:.0}", r.rays_per_s))
        .collect();
    println!("each run (rays/s): {}", each.join(", "));
    Ok(())
}
