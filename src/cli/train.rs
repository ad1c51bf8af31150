//! `wildlight train`: reconstruct shape, materials and flash gain from a capture.

use anyhow::Context;
use std::path::PathBuf;
use wildlight_train::TrainConfig;
use wildlight_train::config::parse_duration;
use wildlight_train::run::{MaskChoice, RunOptions, planned_iters, resumed_config, train};

/// Options of `wildlight train`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Capture folder (SPEC §5 layout; without masks, the background is modelled, SPEC §6)
    /// [default with --resume: the capture recorded in RUN/run.json].
    #[arg(long, value_name = "DIR", required_unless_present_any = ["resume", "print_config"])]
    pub data: Option<PathBuf>,
    /// Run folder: configuration, checkpoints, metrics and previews go here.
    #[arg(long, value_name = "RUN", required_unless_present = "print_config")]
    pub out: Option<PathBuf>,
    /// TOML configuration; keys left out take their defaults (see --print-config)
    /// [default: none: the built-in defaults]. Ignored with --resume (the run's own
    /// config.toml is used).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Print the resolved configuration (defaults + --config + overrides; with --resume,
    /// the run's own) and exit.
    #[arg(long)]
    pub print_config: bool,
    /// Optimisation steps [default: the configuration's `iters`, 4000; with --time-budget,
    /// as many as the budget allows; with --resume, the run's own].
    #[arg(long, value_name = "N")]
    pub iters: Option<u64>,
    /// Train for this much wall time, e.g. 90s, 30m, 1h30m (a checkpoint is written).
    /// Without --iters the budget plans the run: it trains until the time is up, its
    /// learning-rate decay fitted to the steps the budget allows; with --iters it stops at
    /// whichever comes first [default: none: stop after --iters steps].
    #[arg(long, value_name = "DURATION", value_parser = parse_duration)]
    pub time_budget: Option<std::time::Duration>,
    /// Keep a snapshot of the model each time this much more wall time has passed,
    /// e.g. 10m: RUN/snapshots/step_NNNNNN/ (a run folder that render, export and eval
    /// read) [default: none].
    #[arg(long, value_name = "DURATION", value_parser = parse_duration)]
    pub snapshot_every: Option<std::time::Duration>,
    /// Seed of every random choice [default: the configuration's `seed`, 0].
    #[arg(long, value_name = "S")]
    pub seed: Option<u64>,
    /// Continue the run in --out from its last checkpoint, with its own configuration and
    /// step count (--iters may raise it, not lower it).
    #[arg(long)]
    pub resume: bool,
    /// Whether to train with the capture's masks: `use` (an error when it has none) or
    /// `ignore` (train as if it had none: the background is modelled, SPEC §6)
    /// [default: the masks when the capture has them; with --resume, the run's own].
    #[arg(long, value_name = "use|ignore")]
    pub masks: Option<MasksArg>,
    /// No progress bar (there is none either when stderr is not a terminal).
    #[arg(long)]
    pub quiet: bool,
}

/// The values of `--masks`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum MasksArg {
    /// Train with the capture's masks.
    Use,
    /// Train as if the capture had no masks.
    Ignore,
}

impl MasksArg {
    /// The trainer's mask choice for `--masks` (absent: the capture's own).
    pub fn choice(arg: Option<MasksArg>) -> MaskChoice {
        match arg {
            None => MaskChoice::Auto,
            Some(MasksArg::Use) => MaskChoice::Use,
            Some(MasksArg::Ignore) => MaskChoice::Ignore,
        }
    }
}

/// The comment that heads `--print-config`'s output.
const CONFIG_HEADER: &str = "\
# wildlight train: the resolved configuration (defaults, then --config, then
# --iters and --seed; with --resume, the run's own, --iters raising its step
# count). A file given to --config may keep only the keys it changes, in any
# table; every key is documented on `TrainConfig` and the types it holds
# (crates/wildlight-train/src/config.rs).
";

/// Runs `wildlight train`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut config = match &args.config {
        Some(p) => TrainConfig::load(p)?,
        None => TrainConfig::default(),
    };
    config.iters = planned_iters(args.iters, args.time_budget, config.iters);
    if let Some(s) = args.seed {
        config.seed = s;
    }
    config.validate().map_err(anyhow::Error::msg)?;
    if args.print_config {
        let shown = match (&args.out, args.resume) {
            (Some(out), true) => resumed_config(out, args.iters)?.0,
            (None, true) => anyhow::bail!("--resume needs --out: the run folder to continue"),
            _ => config,
        };
        print!("{CONFIG_HEADER}{}", shown.to_toml());
        return Ok(());
    }
    let out = args.out.context("--out is required")?;
    let summary = train(&RunOptions {
        data: args.data,
        out,
        config,
        time_budget: args.time_budget,
        snapshot_every: args.snapshot_every,
        resume: args.resume,
        resume_iters: args.iters,
        progress: !args.quiet && std::io::IsTerminal::is_terminal(&std::io::stderr()),
        masks: MasksArg::choice(args.masks),
    })?;
    let last = summary.last.as_ref();
    eprintln!(
        "trained {} steps in {:.1} s{}; run folder {}",
        summary.steps,
        summary.seconds,
        last.map(|l| format!(
            " (last batch: loss {:.4}, PSNR {:.2} dB, s {:.0}, gain {:.3})",
            l.loss, l.psnr, l.s, l.gamma
        ))
        .unwrap_or_default(),
        summary.run.display()
    );
    if summary.skipped_steps > 0 {
        eprintln!(
            "warning: {} steps were skipped because of non-finite values",
            summary.skipped_steps
        );
    }
    Ok(())
}
