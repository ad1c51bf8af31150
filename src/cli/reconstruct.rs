//! `wildlight reconstruct`: photos in, asset out. The import (COLMAP poses,
//! linear light, flash labels, the region of interest), training (without
//! masks the background is modelled, SPEC §6), the export of the object
//! alone, and a preview of the asset relit under the flash and under a
//! neutral light, one after the other:
//!
//! ```text
//! DIR/reconstruct.json   the photo folder and what each stage did
//! DIR/capture/           the import (SPEC §5 layout, import.json, roi.png)
//! DIR/run/               the training run
//! DIR/export/            model.glb, model.obj + .mtl + PNG maps, mesh_raw.ply
//!                        (world units: the capture's frame)
//! DIR/preview.png        photos against the asset under the flash and a
//!                        neutral light
//! ```
//!
//! Each stage leaves a finished folder or nothing, so a second call with
//! the same `--out` continues where the first stopped: a finished import
//! is kept, a run with a checkpoint is resumed to the steps it planned, a
//! finished export is kept.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use crate::field_source::ExportSource;
use anyhow::{Context, bail};
use wildlight_data::Dataset;
use wildlight_export::{AssetTracer, ExportOptions, FlashSettings, LightingSettings, read_glb};
use wildlight_pathtrace::EnvMap;
use wildlight_train::TrainConfig;
use wildlight_train::config::parse_duration;
use wildlight_train::inference::TrainedRun;
use wildlight_train::run::{CHECKPOINT_FILE, MaskChoice, RunOptions, planned_iters, train};

use crate::cli::export::{AssetArgs, run_cameras, run_scale_mat, with_object_only};
use crate::cli::import::ImportArgs;
use crate::display::{exposure_for, rgb, tile, tone_map};

/// Options of `wildlight reconstruct`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Folder of photos (JPEG, PNG 8/16-bit, or linear EXR), all one size,
    /// about half taken with the flash.
    #[arg(value_name = "PHOTOS_DIR")]
    pub photos: PathBuf,
    /// Folder of the reconstruction: capture/, run/, export/, preview.png.
    /// Call again with the same folder to continue an interrupted one.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Wall time of the whole reconstruction, e.g. 30m, 1h: training gets
    /// what the import leaves, less a reserve for the export and the
    /// preview. A resumed reconstruction finishes the steps its training
    /// planned instead.
    #[arg(long, value_name = "DURATION", value_parser = parse_duration, default_value = "30m")]
    pub time_budget: Duration,
    /// Stop training after this many steps, if the budget allows them
    /// [default: as many as the budget allows].
    #[arg(long, value_name = "N")]
    pub iters: Option<u64>,
    /// Training configuration (TOML; keys left out take their defaults,
    /// see `wildlight train --print-config`).
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Seed of every random choice of training [default: the configuration's].
    #[arg(long, value_name = "S")]
    pub seed: Option<u64>,
    #[command(flatten)]
    pub import: ImportArgs,
    #[command(flatten)]
    pub asset: AssetArgs,
    /// Keep the surface the object stands on in the export (by default the
    /// object alone is kept when the capture has no masks).
    #[arg(long)]
    pub keep_support: bool,
    /// Print a JSON summary on stdout instead of the table.
    #[arg(long)]
    pub json: bool,
    /// No progress bars or stage lines.
    #[arg(long)]
    pub quiet: bool,
}

/// `DIR/reconstruct.json`.
const STATE_FILE: &str = "reconstruct.json";
/// Time kept back from training for the export and the preview, per
/// million marching-cubes cells (at least [`MIN_RESERVE`]).
const RESERVE_PER_MCELL: f64 = 0.6;
/// The least time kept back from training for the export and the preview.
const MIN_RESERVE: Duration = Duration::from_secs(60);
/// The least training time a budget leaves.
const MIN_TRAINING: Duration = Duration::from_secs(60);
/// Views in the preview.
const PREVIEW_VIEWS: usize = 3;
/// Longer side of a preview tile, in pixels.
const PREVIEW_TILE: f64 = 360.0;
/// Environment samples per pixel of the neutral-light row.
const PREVIEW_SPP: usize = 32;

/// What `reconstruct.json` records: the photo folder (a second call must
/// name the same one) and what each stage did, in order.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
struct State {
    photos: PathBuf,
    version: String,
    #[serde(default)]
    stages: Vec<Stage>,
}

/// One stage of one call.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
struct Stage {
    name: String,
    /// "done", "reused" (finished by an earlier call) or "resumed".
    outcome: String,
    seconds: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    detail: Option<serde_json::Value>,
}

/// The folders and files of a reconstruction.
struct Layout {
    root: PathBuf,
    capture: PathBuf,
    run: PathBuf,
    export: PathBuf,
    preview: PathBuf,
}

impl Layout {
    fn new(root: &Path) -> Layout {
        Layout {
            root: root.to_path_buf(),
            capture: root.join("capture"),
            run: root.join("run"),
            export: root.join("export"),
            preview: root.join("preview.png"),
        }
    }

    /// Whether the import finished (an import writes its folder whole).
    fn imported(&self) -> bool {
        self.capture.join("import.json").is_file()
            && self.capture.join("cameras_sphere.npz").is_file()
    }

    /// Whether the export finished after the run's last checkpoint.
    fn exported(&self) -> bool {
        let (glb, ckpt) = (
            self.export.join("model.glb"),
            self.run.join(CHECKPOINT_FILE),
        );
        glb.is_file()
            && self.export.join("mesh_raw.ply").is_file()
            && modified(&glb) >= modified(&ckpt)
    }
}

fn modified(path: &Path) -> Option<std::time::SystemTime> {
    std::fs::metadata(path).and_then(|m| m.modified()).ok()
}

/// Reads `DIR/reconstruct.json`, or starts a new one after checking that
/// `DIR` holds nothing else; refuses a `DIR` made from other photos.
fn open_state(layout: &Layout, photos: &Path) -> anyhow::Result<State> {
    let photos = std::fs::canonicalize(photos)
        .with_context(|| format!("{}: no such folder of photos", photos.display()))?;
    if !photos.is_dir() {
        bail!("{}: not a folder of photos", photos.display());
    }
    let path = layout.root.join(STATE_FILE);
    if path.is_file() {
        let state: State = serde_json::from_str(
            &std::fs::read_to_string(&path)
                .with_context(|| format!("cannot read {}", path.display()))?,
        )
        .with_context(|| format!("{}: not a reconstruction record", path.display()))?;
        if state.photos != photos {
            bail!(
                "{} holds the reconstruction of {}, not of {}: choose another --out",
                layout.root.display(),
                state.photos.display(),
                photos.display()
            );
        }
        return Ok(state);
    }
    if layout.root.exists() {
        let entries = std::fs::read_dir(&layout.root)
            .with_context(|| format!("cannot read {}", layout.root.display()))?
            .count();
        if entries > 0 {
            bail!(
                "{} is not empty and holds no reconstruction ({STATE_FILE}): choose an empty or new --out",
                layout.root.display()
            );
        }
    }
    std::fs::create_dir_all(&layout.root)
        .with_context(|| format!("cannot create {}", layout.root.display()))?;
    Ok(State {
        photos,
        version: env!("CARGO_PKG_VERSION").to_string(),
        stages: Vec::new(),
    })
}

impl State {
    fn record(
        &mut self,
        layout: &Layout,
        name: &str,
        outcome: &str,
        started: Instant,
        detail: Option<serde_json::Value>,
    ) -> anyhow::Result<()> {
        self.stages.push(Stage {
            name: name.into(),
            outcome: outcome.into(),
            seconds: started.elapsed().as_secs_f64(),
            detail,
        });
        let path = layout.root.join(STATE_FILE);
        wildlight_data::atomic::write_bytes_atomically(
            &path,
            serde_json::to_string_pretty(self)?.as_bytes(),
        )
        .with_context(|| format!("cannot write {}", path.display()))
    }
}

/// The time kept back from training for exporting at `resolution` and the
/// preview.
fn export_reserve(resolution: u32) -> Duration {
    let cells = (resolution as f64).powi(3) / 1e6;
    MIN_RESERVE.max(Duration::from_secs_f64(RESERVE_PER_MCELL * cells))
}

/// Runs `wildlight reconstruct`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let started = Instant::now();
    // Check the options before anything slow.
    args.asset.check()?;
    let mut config = match &args.config {
        Some(p) => TrainConfig::load(p)?,
        None => TrainConfig::default(),
    };
    if let Some(s) = args.seed {
        config.seed = s;
    }
    config.validate().map_err(anyhow::Error::msg)?;
    let layout = Layout::new(&args.out);
    let mut state = open_state(&layout, &args.photos)?;
    let quiet = args.quiet || args.json;
    let say = |line: &str| {
        if !quiet {
            eprintln!("{line}");
        }
    };
    let bars = !quiet && std::io::IsTerminal::is_terminal(&std::io::stderr());

    // 1. Import.
    let t = Instant::now();
    if layout.imported() {
        say(&format!(
            "1/4 import: kept the finished import in {}",
            layout.capture.display()
        ));
        state.record(&layout, "import", "reused", t, None)?;
    } else {
        say(&format!("1/4 import of {}", args.photos.display()));
        let opts = args.import.options(&args.photos, &layout.capture)?;
        let report = wildlight_import::import(&opts, &|line: &str| {
            if !quiet {
                eprintln!("    {line}");
            }
        })
        .with_context(|| format!("cannot import {}", args.photos.display()))?;
        if !quiet {
            eprint!("{}", indent(&report.to_table()));
        }
        let detail = serde_json::json!({
            "registered": report.registered,
            "photos": report.photo_count,
            "flash": report.flash_count,
            "no_flash": report.no_flash_count,
        });
        state.record(&layout, "import", "done", t, Some(detail))?;
    }

    // 2. Training.
    let t = Instant::now();
    let resumed = layout.run.join(CHECKPOINT_FILE).is_file();
    let options = if resumed {
        say(&format!(
            "2/4 training: continuing the run in {} to the steps it planned",
            layout.run.display()
        ));
        RunOptions {
            data: Some(layout.capture.clone()),
            out: layout.run.clone(),
            config: config.clone(),
            time_budget: None,
            snapshot_every: None,
            resume: true,
            resume_iters: args.iters,
            progress: bars,
            masks: MaskChoice::Auto,
        }
    } else {
        let reserve = export_reserve(args.asset.resolution);
        let left = args
            .time_budget
            .saturating_sub(started.elapsed())
            .saturating_sub(reserve);
        if left < MIN_TRAINING {
            eprintln!(
                "warning: --time-budget {} leaves {:.0} s for training after the import and a \
                 reserve of {:.0} s for the export; training for {:.0} s",
                humantime(args.time_budget),
                left.as_secs_f64(),
                reserve.as_secs_f64(),
                MIN_TRAINING.as_secs_f64()
            );
        }
        let budget = left.max(MIN_TRAINING);
        say(&format!(
            "2/4 training for {} (without masks: the background is modelled)",
            humantime(budget)
        ));
        let mut config = config.clone();
        config.iters = planned_iters(args.iters, Some(budget), config.iters);
        RunOptions {
            data: Some(layout.capture.clone()),
            out: layout.run.clone(),
            config,
            time_budget: Some(budget),
            snapshot_every: None,
            resume: false,
            resume_iters: None,
            progress: bars,
            masks: MaskChoice::Auto,
        }
    };
    let summary = train(&options)?;
    say(&format!(
        "    {} steps in all, {:.0} s in this call",
        summary.steps, summary.seconds
    ));
    state.record(
        &layout,
        "train",
        if resumed { "resumed" } else { "done" },
        t,
        Some(serde_json::json!({"steps": summary.steps})),
    )?;

    // 3. Export.
    let t = Instant::now();
    let mut trained = TrainedRun::load(&layout.run)?;
    let gain = trained.model.gamma();
    if layout.exported() {
        say(&format!(
            "3/4 export: kept the finished export in {}",
            layout.export.display()
        ));
        state.record(&layout, "export", "reused", t, None)?;
    } else {
        say(&format!("3/4 export into {}", layout.export.display()));
        let cameras = run_cameras(&trained)?;
        let options = args.asset.options(run_scale_mat(&cameras)?, true, bars)?;
        let options = with_object_only(&mut trained, &cameras, options, false, args.keep_support)?;
        let report = export_whole(&trained, &options, &layout)?;
        state.record(
            &layout,
            "export",
            "done",
            t,
            Some(serde_json::to_value(&report)?),
        )?;
    }
    drop(trained);

    // 4. Preview.
    let t = Instant::now();
    say(&format!("4/4 preview {}", layout.preview.display()));
    write_relit_preview(&layout, gain)?;
    state.record(&layout, "preview", "done", t, None)?;

    let total = started.elapsed().as_secs_f64();
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "out": layout.root,
                "capture": layout.capture,
                "run": layout.run,
                "export": layout.export,
                "model_glb": layout.export.join("model.glb"),
                "mesh_raw_ply": layout.export.join("mesh_raw.ply"),
                "preview": layout.preview,
                "steps": summary.steps,
                "flash_gain": gain,
                "seconds": total,
                "stages": state.stages,
            }))?
        );
    } else {
        println!(
            "reconstructed {} in {:.0} s ({} training steps in all)",
            state.photos.display(),
            total,
            summary.steps
        );
        for (what, path) in [
            ("capture", layout.capture.clone()),
            ("run", layout.run.clone()),
            ("asset", layout.export.join("model.glb")),
            ("OBJ", layout.export.join("model.obj")),
            ("raw mesh", layout.export.join("mesh_raw.ply")),
            ("preview", layout.preview.clone()),
        ] {
            println!("  {what:<9} {}", path.display());
        }
    }
    Ok(())
}

/// Exports into a hidden sibling folder and renames it onto `export/`, so
/// that `export/` is always a finished export.
fn export_whole(
    trained: &TrainedRun,
    options: &ExportOptions,
    layout: &Layout,
) -> anyhow::Result<wildlight_export::ExportReport> {
    let partial = layout.root.join(".export.partial");
    if partial.exists() {
        std::fs::remove_dir_all(&partial)
            .with_context(|| format!("cannot remove {}", partial.display()))?;
    }
    std::fs::create_dir_all(&partial)
        .with_context(|| format!("cannot create {}", partial.display()))?;
    let source = ExportSource::new(trained);
    let (_, report) = wildlight_export::export_to_dir(&source, options, &partial)
        .context("the export of the trained run failed")?;
    if layout.export.exists() {
        std::fs::remove_dir_all(&layout.export)
            .with_context(|| format!("cannot replace {}", layout.export.display()))?;
    }
    std::fs::rename(&partial, &layout.export).with_context(|| {
        format!(
            "cannot move {} to {}",
            partial.display(),
            layout.export.display()
        )
    })?;
    Ok(report)
}

/// Up to `n` of `items`, evenly spread (first and last included).
fn spread<T: Copy>(items: &[T], n: usize) -> Vec<T> {
    match items.len() {
        0 => Vec::new(),
        len if len <= n => items.to_vec(),
        len => (0..n)
            .map(|k| items[(k * (len - 1) + (n - 1) / 2) / (n - 1).max(1)])
            .collect(),
    }
}

/// Box-filters a linear image down to `width × height`.
fn shrink(img: &wildlight_data::RgbImage, width: u32, height: u32) -> Vec<[f32; 3]> {
    let (sx, sy) = (
        img.width as f64 / width as f64,
        img.height as f64 / height as f64,
    );
    let mut out = Vec::with_capacity((width * height) as usize);
    for y in 0..height {
        for x in 0..width {
            let (x0, x1) = ((x as f64 * sx) as u32, ((x + 1) as f64 * sx).ceil() as u32);
            let (y0, y1) = ((y as f64 * sy) as u32, ((y + 1) as f64 * sy).ceil() as u32);
            let (mut sum, mut n) = ([0.0f32; 3], 0.0f32);
            for yy in y0..y1.min(img.height) {
                for xx in x0..x1.min(img.width) {
                    let p = rgb(img, (yy * img.width + xx) as usize);
                    for c in 0..3 {
                        sum[c] += p[c];
                    }
                    n += 1.0;
                }
            }
            out.push(sum.map(|s| s / n.max(1.0)));
        }
    }
    out
}

/// Writes `preview.png`: for a few flash photos of the capture (evenly
/// spread; any photos when none has the flash), the photo, the asset under
/// that photo's flash alone (gain `gain` as trained, the photo's exposure),
/// and the asset under a uniform white light from every direction (its own
/// exposure). Read back from `model.glb`, so the preview shows the file a
/// user loads.
fn write_relit_preview(layout: &Layout, gain: f32) -> anyhow::Result<()> {
    let dataset = Dataset::load(&layout.capture, &wildlight_data::LoadOptions::default())
        .with_context(|| format!("cannot load the capture {}", layout.capture.display()))?;
    let flash: Vec<usize> = (0..dataset.views.len())
        .filter(|&v| dataset.views[v].camera.flash())
        .collect();
    let all: Vec<usize> = (0..dataset.views.len()).collect();
    let chosen = spread(if flash.is_empty() { &all } else { &flash }, PREVIEW_VIEWS);
    let glb = layout.export.join("model.glb");
    let asset = read_glb(&glb)?;
    let first = &dataset.views[chosen[0]].camera;
    let to_normalized = first.scale_mat.as_mat4().inverse();
    let tracer = AssetTracer::new(&asset, to_normalized)
        .with_context(|| format!("cannot prepare {} for ray tracing", glb.display()))?;
    let white = EnvMap::from_texels(2, 2, vec![[1.0; 3]; 4]).map_err(anyhow::Error::msg)?;
    let flash_light = LightingSettings {
        flash: FlashSettings {
            gain,
            ..FlashSettings::default()
        },
        env: None,
        spp: 1,
        seed: 0,
    };
    let neutral_light = LightingSettings {
        env: Some(white),
        spp: PREVIEW_SPP,
        ..flash_light.clone()
    };
    let scale = (PREVIEW_TILE / first.width.max(first.height) as f64).min(1.0);
    let (w, h) = (
        ((first.width as f64 * scale).round() as u32).max(1),
        ((first.height as f64 * scale).round() as u32).max(1),
    );
    struct Column {
        photo: Vec<[f32; 3]>,
        flash: Option<wildlight_data::ViewMaps>,
        neutral: wildlight_data::ViewMaps,
    }
    let mut columns = Vec::new();
    for &v in &chosen {
        let view = &dataset.views[v];
        let camera = &view.camera;
        if (camera.width, camera.height) != (first.width, first.height) {
            continue;
        }
        let energy = camera.light_energy;
        columns.push(Column {
            photo: shrink(&view.image, w, h),
            flash: camera
                .flash()
                .then(|| tracer.render_view(camera, energy, scale, camera.index, &flash_light)),
            neutral: tracer.render_view(camera, [0.0; 3], scale, camera.index, &neutral_light),
        });
    }
    let photo_exposure = exposure_for(
        columns
            .iter()
            .flat_map(|c| c.photo.iter().flatten().copied())
            .collect(),
    );
    let covered = |maps: &wildlight_data::ViewMaps| -> Vec<f32> {
        maps.rgb
            .iter()
            .zip(&maps.acc)
            .filter(|(_, a)| **a > 0.0)
            .flat_map(|(c, _)| *c)
            .collect()
    };
    let neutral_exposure = exposure_for(columns.iter().flat_map(|c| covered(&c.neutral)).collect());
    let maps_tile = |maps: &wildlight_data::ViewMaps, exposure: f32| {
        tile(
            w,
            h,
            |i| maps.rgb[i].map(|c| tone_map(c, exposure)),
            |i| maps.acc[i],
        )
    };
    let mut rows: Vec<Vec<Option<image::RgbImage>>> = vec![Vec::new(); 3];
    let mut column_labels = Vec::new();
    for c in &columns {
        column_labels.push(String::new());
        rows[0].push(Some(tile(
            w,
            h,
            |i| c.photo[i].map(|v| tone_map(v, photo_exposure)),
            |_| 1.0,
        )));
        rows[1].push(c.flash.as_ref().map(|m| maps_tile(m, photo_exposure)));
        rows[2].push(Some(maps_tile(&c.neutral, neutral_exposure)));
    }
    crate::plot::ImageGrid {
        tile_width: w,
        tile_height: h,
        column_labels,
        row_labels: ["PHOTO", "FLASH", "NEUTRAL"]
            .iter()
            .map(|s| s.to_string())
            .collect(),
        tiles: rows,
    }
    .write_png(&layout.preview)
}

/// A duration as `30m`, `1h05m` or `45s`.
fn humantime(d: Duration) -> String {
    let s = d.as_secs();
    match (s / 3600, s % 3600 / 60, s % 60) {
        (0, 0, s) => format!("{s}s"),
        (0, m, 0) => format!("{m}m"),
        (0, m, s) => format!("{m}m{s:02}s"),
        (h, m, _) => format!("{h}h{m:02}m"),
    }
}

/// Indents every line by four spaces.
fn indent(text: &str) -> String {
    text.lines().map(|l| format!("    {l}\n")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spread_keeps_the_ends_and_spaces_the_rest() {
        let items: Vec<usize> = (0..10).collect();
        assert_eq!(spread(&items, 3), vec![0, 5, 9]);
        assert_eq!(spread(&items[..2], 3), vec![0, 1]);
        assert_eq!(spread(&items, 1), vec![0]);
        assert!(spread::<usize>(&[], 3).is_empty());
    }

    #[test]
    fn shrinking_averages_each_footprint() {
        // 4×2 → 2×1: each output pixel averages a 2×2 block.
        let img = wildlight_data::RgbImage {
            width: 4,
            height: 2,
            data: (0..8).flat_map(|i| [i as f32, 0.0, 1.0]).collect(),
        };
        let out = shrink(&img, 2, 1);
        assert_eq!(out, vec![[2.5, 0.0, 1.0], [4.5, 0.0, 1.0]]);
    }

    #[test]
    fn the_reserve_grows_with_the_grid() {
        assert_eq!(export_reserve(64), MIN_RESERVE);
        // 512³ = 134 M cells: 80.5 s
        assert!((export_reserve(512).as_secs_f64() - 0.6 * 134.217728).abs() < 1e-6);
    }

    #[test]
    fn durations_read_as_written() {
        assert_eq!(humantime(Duration::from_secs(45)), "45s");
        assert_eq!(humantime(Duration::from_secs(1800)), "30m");
        assert_eq!(humantime(Duration::from_secs(1805)), "30m05s");
        assert_eq!(humantime(Duration::from_secs(3900)), "1h05m");
    }
}
