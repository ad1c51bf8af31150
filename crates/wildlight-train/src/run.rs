//! A run folder and the training loop behind `wildlight train`:
//!
//! ```text
//! RUN/config.toml              the resolved configuration
//! RUN/run.json                 the dataset path and the wildlight version
//! RUN/checkpoint.safetensors   the latest checkpoint (written atomically)
//! RUN/metrics.jsonl            one JSON line per logged step
//! RUN/previews/step_NNNNNN.png preview strips
//! RUN/snapshots/step_NNNNNN/   with a snapshot interval: the model as it
//!                              was at each mark of wall time (a run folder
//!                              of its own: config.toml, run.json, the
//!                              checkpoint, and snapshot.json with the step
//!                              and the seconds since this invocation began)
//! ```

use crate::config::TrainConfig;
use crate::rays::TrainingRays;
use crate::render_view::render_view;
use crate::trainer::{StepStats, Trainer};
use anyhow::{Context, bail};
use indicatif::{ProgressBar, ProgressStyle};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use wildlight_data::{Dataset, LoadOptions};

/// File names inside a run folder.
pub const CONFIG_FILE: &str = "config.toml";
/// See [`CONFIG_FILE`].
pub const RUN_FILE: &str = "run.json";
/// See [`CONFIG_FILE`].
pub const CHECKPOINT_FILE: &str = "checkpoint.safetensors";
/// See [`CONFIG_FILE`].
pub const METRICS_FILE: &str = "metrics.jsonl";
/// See [`CONFIG_FILE`].
pub const SNAPSHOTS_DIR: &str = "snapshots";
/// See [`CONFIG_FILE`].
pub const SNAPSHOT_FILE: &str = "snapshot.json";

/// What `run.json` records.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct RunInfo {
    /// The dataset folder (absolute).
    pub data: PathBuf,
    /// The wildlight version that created the run.
    pub version: String,
    /// Whether the run trained with the capture's masks (absent in runs of
    /// older versions, which all did).
    #[serde(default)]
    pub masks: MaskMode,
}

/// How a run used masks (`run.json`'s `masks`). A run without them models
/// the background (SPEC §6): its model has a background field.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum MaskMode {
    /// Trained with the capture's masks.
    #[default]
    Used,
    /// The capture has masks, and the run trained as if it had none.
    Ignored,
    /// The capture has no masks.
    Absent,
}

impl MaskMode {
    /// Whether the run trained without masks (and has a background).
    pub fn maskless(self) -> bool {
        self != MaskMode::Used
    }
}

/// What `wildlight train --masks` asks for.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MaskChoice {
    /// The capture's masks when it has them, else train without.
    #[default]
    Auto,
    /// The capture's masks (an error when it has none).
    Use,
    /// Train as if the capture had no masks.
    Ignore,
}

/// The mask mode of a new run on `dataset`.
pub fn mask_mode(dataset: &Dataset, choice: MaskChoice) -> anyhow::Result<MaskMode> {
    let with = dataset.views.iter().filter(|v| v.mask.is_some()).count();
    let all = with == dataset.views.len();
    Ok(match choice {
        MaskChoice::Ignore if with > 0 => MaskMode::Ignored,
        MaskChoice::Ignore => MaskMode::Absent,
        MaskChoice::Use | MaskChoice::Auto if all => MaskMode::Used,
        MaskChoice::Auto if with == 0 => MaskMode::Absent,
        MaskChoice::Use if with == 0 => bail!(
            "the capture has no masks (mask/NNN.png for every image), and --masks use asks for \
             them; leave --masks out to train without masks (the background is then modelled, \
             SPEC §6)"
        ),
        _ => bail!(
            "{with} of the capture's {} images have a mask: --masks ignore trains without them \
             (the background is then modelled, SPEC §6); with masks, every image needs one",
            dataset.views.len()
        ),
    })
}

/// The training rays of `dataset` in the mask mode `mode`.
pub fn training_rays(dataset: &Dataset, mode: MaskMode) -> TrainingRays {
    let mut rays = TrainingRays::new(dataset);
    if mode.maskless() {
        rays.ignore_masks();
    }
    rays
}

/// The share of the image at which the unit sphere is said to fill a view
/// (the synthetic rig's cameras, at 2.6 radii with a 40° field of view, see
/// it cover 93 %).
const SPHERE_FILLS_VIEW: f64 = 0.95;

/// The share of camera `c`'s image (on a grid of 32 × 32 pixel positions)
/// whose rays meet the unit sphere.
fn sphere_coverage(c: &wildlight_data::Camera) -> f64 {
    let n = 32;
    let mut hits = 0;
    for j in 0..n {
        for i in 0..n {
            let x = (i as f64 + 0.5) / n as f64 * c.width as f64 - 0.5;
            let y = (j as f64 + 0.5) / n as f64 * c.height as f64 - 0.5;
            let ray = c.ray(x, y);
            let od = ray.origin.dot(ray.dir);
            let b2 = ray.origin.length_squared() - od * od;
            if od < 0.0 && b2 < 1.0 {
                hits += 1;
            }
        }
    }
    hits as f64 / (n * n) as f64
}

/// How far the ray through the middle of camera `c`'s image passes from the
/// sphere's centre (unit sphere radii; infinite when it points away).
fn centre_ray_miss(c: &wildlight_data::Camera) -> f64 {
    let ray = c.ray(0.5 * c.width as f64 - 0.5, 0.5 * c.height as f64 - 0.5);
    let od = ray.origin.dot(ray.dir) / ray.dir.length_squared();
    if od >= 0.0 {
        return f64::INFINITY;
    }
    (ray.origin - od * ray.dir).length()
}

/// Checks a capture for training without masks: the background lives
/// beyond the unit sphere, so every camera must be outside it (an error
/// naming those that are not). Returns the warnings: the sphere filling
/// most of the views (little background seen, and the object's samples
/// may then model it inside the sphere), and the sphere off the middle of
/// most of the views (photos that do not aim at the object, or a region of
/// interest beside it: the object may not be inside the sphere).
pub fn check_maskless_capture(dataset: &Dataset) -> anyhow::Result<Vec<String>> {
    let inside: Vec<String> = dataset
        .views
        .iter()
        .filter(|v| v.camera.center.length() <= 1.0)
        .map(|v| format!("{} (at {:.2})", v.camera.index, v.camera.center.length()))
        .collect();
    if !inside.is_empty() {
        bail!(
            "training without masks needs every camera outside the unit sphere (the background \
             is modelled beyond it, SPEC §6), but {} of {} cameras are inside it, at these \
             distances from its centre: {}; normalize the capture so that the sphere holds the \
             object alone (scale_mat)",
            inside.len(),
            dataset.views.len(),
            inside.join(", ")
        );
    }
    let coverage: Vec<f64> = dataset
        .views
        .iter()
        .map(|v| sphere_coverage(&v.camera))
        .collect();
    let filled = coverage.iter().filter(|c| **c > SPHERE_FILLS_VIEW).count();
    let mut warnings = Vec::new();
    if 2 * filled > coverage.len() {
        let mean = coverage.iter().sum::<f64>() / coverage.len() as f64;
        let dist: Vec<f64> = dataset
            .views
            .iter()
            .map(|v| v.camera.center.length())
            .collect();
        let (near, far) = dist
            .iter()
            .fold((f64::MAX, 0.0f64), |(a, b), d| (a.min(*d), b.max(*d)));
        warnings.push(format!(
            "without masks: the unit sphere fills more than {:.0} % of the image in {filled} of {} \
             views ({:.0} % on average; cameras at {near:.2} to {far:.2} sphere radii): the \
             background is seen only around its edge, and what the sphere holds besides the \
             object (a table, a wall) becomes surface; a smaller sphere (scale_mat) helps",
            SPHERE_FILLS_VIEW * 100.0,
            coverage.len(),
            mean * 100.0
        ));
    }
    let mut misses: Vec<f64> = dataset
        .views
        .iter()
        .map(|v| centre_ray_miss(&v.camera))
        .collect();
    let off = misses.iter().filter(|d| **d > 1.0).count();
    if 2 * off > misses.len() {
        misses.sort_by(f64::total_cmp);
        warnings.push(format!(
            "without masks: the unit sphere is off the middle of the image in {off} of {} views \
             (the ray through the middle passes {:.2} sphere radii from its centre at the \
             median): the object should be near the middle of the photos and inside the sphere \
             (scale_mat), or the background model will hold it",
            misses.len(),
            misses[misses.len() / 2]
        ));
    }
    Ok(warnings)
}

/// Options of a training run.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Dataset folder (may be left out with `resume`).
    pub data: Option<PathBuf>,
    /// Run folder.
    pub out: PathBuf,
    /// The configuration (ignored with `resume`: the run's own is used).
    pub config: TrainConfig,
    /// Stop after this much wall time (or at `config.iters` steps, whichever
    /// comes first); the learning-rate decay is fitted to the steps it
    /// allows at the pace measured. [`planned_iters`] gives the step count
    /// of a run that the budget alone should end.
    pub time_budget: Option<Duration>,
    /// Keep a snapshot of the model each time this much more wall time has
    /// passed (`RUN/snapshots/`), e.g. for a training curve against time.
    /// Unlike frequent checkpoints (about 0.8 s each for the default
    /// model), only the marks pay.
    pub snapshot_every: Option<Duration>,
    /// Continue the run in `out` from its checkpoint.
    pub resume: bool,
    /// With `resume`: train on to this many steps in all, if more than the
    /// run's own (`None`: the run's own step count, or with a time budget
    /// alone, as many as the budget allows; [`planned_iters`]).
    pub resume_iters: Option<u64>,
    /// Show a progress bar.
    pub progress: bool,
    /// Whether to train with the capture's masks (with `resume`: `Auto`,
    /// or the run's own mode).
    pub masks: MaskChoice,
}

/// What a finished run reports.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RunSummary {
    /// Steps taken in total.
    pub steps: u64,
    /// Wall time of this invocation in seconds.
    pub seconds: f64,
    /// The last step's statistics.
    pub last: Option<StepStats>,
    /// Steps skipped because of non-finite values.
    pub skipped_steps: u64,
    /// The run folder.
    pub run: PathBuf,
}

fn write_atomic(path: &Path, bytes: &[u8]) -> anyhow::Result<()> {
    wildlight_data::atomic::write_bytes_atomically(path, bytes)
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Creates the run folder `out` (with its `previews` folder) and writes its
/// resolved configuration, the dataset it trains on (made absolute) and
/// its mask mode.
pub fn write_run_files(
    out: &Path,
    config: &TrainConfig,
    data: &Path,
    masks: MaskMode,
) -> anyhow::Result<()> {
    std::fs::create_dir_all(out.join("previews"))
        .with_context(|| format!("cannot create {}", out.display()))?;
    let data_abs = std::fs::canonicalize(data).unwrap_or(data.to_path_buf());
    write_atomic(&out.join(CONFIG_FILE), config.to_toml().as_bytes())?;
    write_atomic(
        &out.join(RUN_FILE),
        serde_json::to_string_pretty(&RunInfo {
            data: data_abs,
            version: env!("CARGO_PKG_VERSION").to_string(),
            masks,
        })?
        .as_bytes(),
    )
}

/// Reads a run folder's configuration and dataset path.
pub fn read_run(run: &Path) -> anyhow::Result<(TrainConfig, RunInfo)> {
    let cfg_path = run.join(CONFIG_FILE);
    anyhow::ensure!(
        cfg_path.is_file(),
        "{} is not a wildlight run folder: it has no {CONFIG_FILE}",
        run.display()
    );
    let config = TrainConfig::load(&cfg_path)?;
    let info_path = run.join(RUN_FILE);
    let info: RunInfo = serde_json::from_str(
        &std::fs::read_to_string(&info_path)
            .with_context(|| format!("cannot read {}", info_path.display()))?,
    )
    .with_context(|| format!("{}: not a valid run description", info_path.display()))?;
    Ok((config, info))
}

/// The step count (`iters`) of a run that its time budget alone plans: it
/// trains until the time is up, and this only bounds it. A run folder whose
/// `iters` is this was planned by its budget, and its own step count is
/// the one the budget planned.
pub const BUDGET_MAX_STEPS: u64 = 1_000_000;

/// The step count a run trains to, from the steps asked for (`--iters`)
/// and the time budget: the steps asked for when given (a time budget may
/// still stop the run sooner); with a budget alone [`BUDGET_MAX_STEPS`],
/// so that the budget ends the run and the learning-rate decay is fitted
/// to the steps it allows; with neither, `otherwise` (the configuration's,
/// or a resumed run's own).
pub fn planned_iters(iters: Option<u64>, time_budget: Option<Duration>, otherwise: u64) -> u64 {
    match (iters, time_budget) {
        (Some(n), _) => n,
        (None, Some(_)) => BUDGET_MAX_STEPS,
        (None, None) => otherwise,
    }
}

/// The configuration a resumed run trains with, and its description: the
/// run's own, its step count raised to `iters` when that is more.
pub fn resumed_config(run: &Path, iters: Option<u64>) -> anyhow::Result<(TrainConfig, RunInfo)> {
    let (mut config, info) = read_run(run)?;
    if let Some(n) = iters {
        config.iters = config.iters.max(n);
    }
    Ok((config, info))
}

/// Loads a capture for training and checks that it can be trained on.
/// Returns the dataset and the warnings a user should see.
pub fn load_capture(data: &Path) -> anyhow::Result<(Dataset, Vec<String>)> {
    let dataset = Dataset::load(data, &LoadOptions::default())
        .with_context(|| format!("cannot load the capture {}", data.display()))?;
    let mut warnings = Vec::new();
    if dataset.flash_count() == 0 {
        warnings.push(format!(
            "{}: no image has the flash on (every light_energy is zero): geometry and ambient \
             light will be learned, but reflectance is then unconstrained",
            data.display()
        ));
    }
    Ok((dataset, warnings))
}

/// Trains (or resumes) a run.
pub fn train(opts: &RunOptions) -> anyhow::Result<RunSummary> {
    let ckpt = opts.out.join(CHECKPOINT_FILE);
    let (config, data, recorded) = if opts.resume {
        let (config, info) = read_run(&opts.out)?;
        if !ckpt.exists() {
            bail!(
                "{}: nothing to resume (no {CHECKPOINT_FILE})",
                opts.out.display()
            );
        }
        let asked = match opts.masks {
            MaskChoice::Auto => None,
            MaskChoice::Use => Some(false),
            MaskChoice::Ignore => Some(true),
        };
        if asked.is_some_and(|maskless| maskless != info.masks.maskless()) {
            bail!(
                "{}: the run trained {} masks, and a resumed run continues as it began",
                opts.out.display(),
                if info.masks.maskless() {
                    "without"
                } else {
                    "with"
                }
            );
        }
        (
            config,
            opts.data.clone().unwrap_or(info.data),
            Some(info.masks),
        )
    } else {
        if ckpt.exists() {
            bail!(
                "{} already holds a trained run; pass --resume to continue it, or choose another --out",
                opts.out.display()
            );
        }
        let data = opts
            .data
            .clone()
            .context("--data is required for a new run")?;
        (opts.config.clone(), data, None)
    };
    config.validate().map_err(anyhow::Error::msg)?;
    let (dataset, mut warnings) = load_capture(&data)?;
    let masks = match recorded {
        Some(MaskMode::Used) => mask_mode(&dataset, MaskChoice::Use)?,
        Some(mode) => mode,
        None => mask_mode(&dataset, opts.masks)?,
    };
    if masks.maskless() {
        warnings.extend(
            check_maskless_capture(&dataset)
                .with_context(|| format!("the capture {}", data.display()))?,
        );
    }
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    let rays = training_rays(&dataset, masks);
    let mut trainer = Trainer::new(config, rays)?;
    if opts.resume {
        trainer.load_checkpoint(&ckpt)?;
        // The run's own step count: the one its budget planned, for a run
        // that its budget alone planned.
        let own = if trainer.config.iters == BUDGET_MAX_STEPS {
            trainer.planned_total_steps()
        } else {
            trainer.config.iters
        };
        let asked = opts.resume_iters.map(|n| n.max(own));
        trainer.set_iters(planned_iters(asked, opts.time_budget, own));
    }
    let config = trainer.config.clone();
    write_run_files(&opts.out, &config, &data, masks)?;
    let preview_view = dataset
        .val
        .as_ref()
        .and_then(|v| v.views.first())
        .unwrap_or(&dataset.views[0])
        .clone();
    let metrics_path = opts.out.join(METRICS_FILE);
    let mut metrics = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&metrics_path)
        .with_context(|| format!("cannot open {}", metrics_path.display()))?;

    let start = Instant::now();
    let first_step = trainer.step;
    let first_plan = trainer.planned_total_steps();
    /// Steps timed before a time budget's step count is estimated.
    const PLAN_AFTER_STEPS: u64 = 20;
    let bar = if opts.progress {
        let b = ProgressBar::new(config.iters);
        b.set_style(
            ProgressStyle::with_template(
                "{elapsed_precise} [{bar:30}] {pos}/{len} ETA {eta} {msg}",
            )
            .expect("valid template")
            .progress_chars("=> "),
        );
        b.set_position(trainer.step);
        b
    } else {
        ProgressBar::hidden()
    };
    let mut last = None;
    let mut snapshots = 0u32;
    while trainer.step < config.iters {
        if opts.time_budget.is_some_and(|b| start.elapsed() >= b) {
            if config.iters == BUDGET_MAX_STEPS {
                // The budget alone planned the run, and it ends here (even
                // before its pace was measured): so `--resume` with no more
                // steps or time has nothing left to do.
                let planned = trainer.planned_total_steps().min(trainer.step);
                trainer.plan_total_steps(planned);
            }
            break;
        }
        let stats = trainer.step();
        let done = trainer.step;
        if let Some(budget) = opts.time_budget {
            // Fit the learning-rate decay to the steps the budget allows at
            // the speed measured so far, so it ends decayed when time is up.
            let elapsed = start.elapsed().as_secs_f64();
            if done - first_step >= PLAN_AFTER_STEPS && elapsed > 0.0 {
                let rate = (done - first_step) as f64 / elapsed;
                let planned = first_step as f64 + rate * budget.as_secs_f64();
                trainer.plan_total_steps(planned as u64);
                bar.set_length(trainer.planned_total_steps());
            }
        }
        if done.is_multiple_of(config.output.log_every) || done == config.iters {
            let elapsed = start.elapsed().as_secs_f64();
            let rays_per_s = (done - first_step) as f64 * config.batch_rays as f64 / elapsed;
            let mut line = serde_json::to_value(&stats)?;
            line["time"] = serde_json::json!(elapsed);
            line["rays_per_s"] = serde_json::json!(rays_per_s);
            writeln!(metrics, "{line}")?;
            bar.set_message(format!(
                "loss {:.4} psnr {:.1} s {:.0} γ {:.3} {:.0} rays/s",
                stats.loss, stats.psnr, stats.s, stats.gamma, rays_per_s
            ));
        }
        bar.set_position(done);
        if config.output.preview_every > 0 && done.is_multiple_of(config.output.preview_every) {
            write_step_preview(&mut trainer, &preview_view, &opts.out, done)?;
        }
        if done.is_multiple_of(config.output.checkpoint_every) {
            trainer.save_checkpoint(&ckpt)?;
        }
        if let Some(every) = opts.snapshot_every.filter(|e| !e.is_zero()) {
            let elapsed = start.elapsed();
            if elapsed >= every * (snapshots + 1) {
                write_snapshot(&trainer, &opts.out, elapsed)?;
                // one snapshot however many marks a slow step passed
                snapshots = (elapsed.as_secs_f64() / every.as_secs_f64()) as u32;
            }
        }
        last = Some(stats);
    }
    bar.finish_and_clear();
    // A resumed run with nothing left to do leaves its checkpoint (and so
    // whatever was made from it, e.g. an export) as it was.
    if trainer.step > first_step || trainer.planned_total_steps() != first_plan || !opts.resume {
        trainer.save_checkpoint(&ckpt)?;
        if config.output.preview_every > 0 {
            let step = trainer.step;
            write_step_preview(&mut trainer, &preview_view, &opts.out, step)?;
        }
    }
    Ok(RunSummary {
        steps: trainer.step,
        seconds: start.elapsed().as_secs_f64(),
        last,
        skipped_steps: trainer.skipped_steps,
        run: opts.out.clone(),
    })
}

/// What `snapshot.json` records.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct SnapshotInfo {
    /// Steps taken when the snapshot was written.
    pub step: u64,
    /// Seconds since this invocation of the training loop began.
    pub seconds: f64,
}

/// Writes `RUN/snapshots/step_NNNNNN/`: the run's configuration and
/// `run.json`, the trainer's checkpoint and `snapshot.json`, each file
/// atomically. Named by the step, so a resumed run adds to the snapshots
/// of earlier invocations and never replaces them.
fn write_snapshot(trainer: &Trainer, out: &Path, elapsed: Duration) -> anyhow::Result<()> {
    let dir = out
        .join(SNAPSHOTS_DIR)
        .join(format!("step_{:06}", trainer.step));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    for name in [CONFIG_FILE, RUN_FILE] {
        let from = out.join(name);
        let bytes =
            std::fs::read(&from).with_context(|| format!("cannot read {}", from.display()))?;
        write_atomic(&dir.join(name), &bytes)?;
    }
    trainer.save_checkpoint(&dir.join(CHECKPOINT_FILE))?;
    let info = SnapshotInfo {
        step: trainer.step,
        seconds: elapsed.as_secs_f64(),
    };
    write_atomic(
        &dir.join(SNAPSHOT_FILE),
        serde_json::to_string_pretty(&info)?.as_bytes(),
    )
}

fn write_step_preview(
    trainer: &mut Trainer,
    view: &wildlight_data::View,
    out: &Path,
    step: u64,
) -> anyhow::Result<()> {
    let fd = trainer.normal_method();
    let energy = view.camera.light_energy.map(|e| e as f32);
    let scale = trainer.config.output.preview_scale;
    let maps = render_view(
        &trainer.model,
        &trainer.grid,
        &mut trainer.pipeline,
        &view.camera,
        energy,
        scale,
        fd,
    );
    let path = out.join("previews").join(format!("step_{step:06}.png"));
    crate::preview::write_preview(&path, view, &maps)
}
