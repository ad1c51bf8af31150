//! `wildlight render`: renders a trained run (`--run`) or an exported asset
//! (`--asset FILE.glb`) from a capture's cameras, with every map (image,
//! flash-only, ambient-only, normal, depth, base colour, roughness,
//! metallic, all 9 parameters, accumulated weight). The output folder is
//! what `wildlight eval images` and `eval materials` read.
//!
//! An asset is ray traced: its textures are sampled at each hit, the flash
//! term is SPEC §2's, and the ambient term is an environment map (`--env`)
//! integrated the way the synthetic captures are (no `--env`: no ambient
//! light).

use anyhow::{Context, bail};
use glam::Mat4;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::{Path, PathBuf};
use wildlight_data::{Camera, Dataset};
use wildlight_export::{AssetTracer, FlashSettings, LightingSettings, read_glb};
use wildlight_pathtrace::EnvMap;
use wildlight_train::inference::{RenderedView, TrainedRun, render_views_to_dir, write_view_maps};

/// Which cameras to render.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Split {
    /// The training views.
    Train,
    /// The held-out views in the capture's `val/` folder.
    Val,
}

/// Whether the flash is on in the rendering.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Flash {
    /// Every view with the flash (the capture's flash energy).
    On,
    /// Every view without the flash (ambient light only).
    Off,
    /// As each photo was taken.
    AsCaptured,
}

/// The frame an asset's vertices are in.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum AssetFrame {
    /// World units (the export's default): x_world = scale_mat · x_normalized.
    World,
    /// The normalized frame (`wildlight export --normalized`).
    Normalized,
}

/// Options of `wildlight render`.
#[derive(clap::Args, Debug)]
#[command(group(clap::ArgGroup::new("what").required(true).args(["run", "asset"])))]
pub struct Args {
    /// The run folder written by `wildlight train`.
    #[arg(long, value_name = "RUN")]
    pub run: Option<PathBuf>,
    /// An asset written by `wildlight export` (model.glb) to ray trace
    /// instead of a run; needs --data.
    #[arg(long, value_name = "FILE.glb")]
    pub asset: Option<PathBuf>,
    /// Capture whose cameras are rendered [default with --run: the run's
    /// own capture].
    #[arg(long, value_name = "DIR")]
    pub data: Option<PathBuf>,
    /// Which split's cameras.
    #[arg(long, value_enum, default_value_t = Split::Val)]
    pub split: Split,
    /// Views to render by image index, e.g. `0,3,5-7` [default: all].
    #[arg(long, value_name = "LIST")]
    pub views: Option<String>,
    /// Flash on, off, or as captured.
    #[arg(long, value_enum, default_value_t = Flash::AsCaptured)]
    pub flash: Flash,
    /// Output folder [default: RUN/render-<split>, or render-<split> next
    /// to the asset].
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
    /// Resolution as a fraction of the capture's.
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Asset only: environment light, an equirectangular .exr or .hdr
    /// file, or `sky` for the synthetic captures' default sky [default: no
    /// ambient light].
    #[arg(long, value_name = "FILE|sky")]
    pub env: Option<String>,
    /// Asset only: multiplier of the environment's radiance.
    #[arg(long, default_value_t = 1.0)]
    pub env_strength: f64,
    /// Asset only: environment samples per pixel.
    #[arg(long, default_value_t = 64)]
    pub spp: usize,
    /// Asset only: seed of the environment samples.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Asset only: the flash gain γ (SPEC §2) multiplying the capture's
    /// flash energy.
    #[arg(long, default_value_t = 1.0)]
    pub flash_gain: f32,
    /// Asset only: the frame of the asset's vertices [default: as recorded
    /// in the file by `wildlight export`, else world].
    #[arg(long, value_enum)]
    pub asset_frame: Option<AssetFrame>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Parses `0,3,5-7` into indices.
fn parse_views(text: &str) -> anyhow::Result<Vec<usize>> {
    let mut out = Vec::new();
    for part in text.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        if let Some((a, b)) = part.split_once('-') {
            let (a, b): (usize, usize) = (
                a.trim()
                    .parse()
                    .with_context(|| format!("--views: '{part}' is not a range"))?,
                b.trim()
                    .parse()
                    .with_context(|| format!("--views: '{part}' is not a range"))?,
            );
            if a > b {
                bail!("--views: range '{part}' is empty");
            }
            out.extend(a..=b);
        } else {
            out.push(
                part.parse()
                    .with_context(|| format!("--views: '{part}' is not an index"))?,
            );
        }
    }
    Ok(out)
}

/// The cameras of one split of a capture, the ones chosen by `--views`,
/// and the flash energy `--flash on` uses.
struct ChosenViews {
    split_dir: PathBuf,
    split_name: &'static str,
    cameras: Vec<Camera>,
    wanted: Vec<usize>,
    capture_energy: Option<[f32; 3]>,
}

impl ChosenViews {
    fn load(data: &Path, args: &Args) -> anyhow::Result<Self> {
        let split_dir = match args.split {
            Split::Train => data.to_path_buf(),
            Split::Val => data.join("val"),
        };
        let cameras = Dataset::load_cameras(&split_dir)
            .with_context(|| format!("cannot read the cameras of {}", split_dir.display()))?;
        // The flash energy used for --flash on: the capture's own.
        let train_cameras = if args.split == Split::Train {
            cameras.clone()
        } else {
            Dataset::load_cameras(data).unwrap_or_default()
        };
        let capture_energy = train_cameras
            .iter()
            .chain(&cameras)
            .find(|c| c.flash())
            .map(|c| c.light_energy.map(|e| e as f32));
        if args.flash == Flash::On && capture_energy.is_none() {
            bail!("--flash on: no view of {} has the flash on", data.display());
        }
        let wanted = match &args.views {
            Some(list) => {
                let idx = parse_views(list)?;
                for i in &idx {
                    if !cameras.iter().any(|c| c.index == *i) {
                        bail!("--views: {} has no view {i}", split_dir.display());
                    }
                }
                idx
            }
            None => cameras.iter().map(|c| c.index).collect(),
        };
        Ok(ChosenViews {
            split_dir,
            split_name: match args.split {
                Split::Train => "train",
                Split::Val => "val",
            },
            cameras,
            wanted,
            capture_energy,
        })
    }

    fn chosen(&self) -> Vec<&Camera> {
        self.wanted
            .iter()
            .filter_map(|i| self.cameras.iter().find(|c| c.index == *i))
            .collect()
    }

    /// The flash energy of `camera` under `--flash`.
    fn energy(&self, flash: Flash, camera: &Camera) -> [f32; 3] {
        match flash {
            Flash::Off => [0.0; 3],
            Flash::AsCaptured => camera.light_energy.map(|e| e as f32),
            Flash::On => self.capture_energy.unwrap_or([0.0; 3]),
        }
    }
}

fn progress_bar(args: &Args, views: usize) -> ProgressBar {
    if args.quiet || !std::io::IsTerminal::is_terminal(&std::io::stderr()) {
        ProgressBar::hidden()
    } else {
        ProgressBar::new(views as u64).with_style(
            ProgressStyle::with_template("rendering [{bar:30}] {pos}/{len} views ETA {eta}")
                .expect("valid template")
                .progress_chars("=> "),
        )
    }
}

/// Runs `wildlight render`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !(args.scale > 0.0 && args.scale <= 4.0) {
        bail!("--scale {} is outside (0, 4]", args.scale);
    }
    match (&args.run, &args.asset) {
        (Some(run), None) => render_run(run.clone(), &args),
        (None, Some(asset)) => render_asset(asset.clone(), &args),
        _ => bail!("give exactly one of --run and --asset"),
    }
}

fn render_run(run: PathBuf, args: &Args) -> anyhow::Result<()> {
    if args.env.is_some() {
        bail!("--env lights an exported asset: use it with --asset, not --run");
    }
    let mut trained = TrainedRun::load(&run)?;
    let data = args
        .data
        .clone()
        .unwrap_or_else(|| trained.info.data.clone());
    let views = ChosenViews::load(&data, args)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| run.join(format!("render-{}", views.split_name)));
    let chosen = views.chosen();
    let bar = progress_bar(args, chosen.len());
    let records = render_views_to_dir(
        &mut trained,
        &chosen,
        |camera| views.energy(args.flash, camera),
        views.split_name,
        args.scale,
        &out,
        || bar.inc(1),
    )?;
    bar.finish_and_clear();
    eprintln!("rendered {} views into {}", records.len(), out.display());
    Ok(())
}

/// The environment light of `--env` (radiance × `--env-strength`).
fn environment(args: &Args) -> anyhow::Result<Option<EnvMap>> {
    let Some(env) = &args.env else {
        return Ok(None);
    };
    if !(args.env_strength > 0.0 && args.env_strength.is_finite()) {
        bail!("--env-strength {} must be > 0", args.env_strength);
    }
    if args.spp == 0 {
        bail!("--spp must be at least 1");
    }
    let map = if env == "sky" {
        EnvMap::procedural_sky()
    } else {
        let path = Path::new(env);
        if !path.is_file() {
            bail!(
                "--env: {} is not a file (give an .exr or .hdr map, or `sky`)",
                path.display()
            );
        }
        EnvMap::load(path)?
    };
    Ok(Some(map.scaled(args.env_strength)))
}

fn render_asset(asset_path: PathBuf, args: &Args) -> anyhow::Result<()> {
    if !asset_path.is_file() {
        bail!(
            "--asset: {} does not exist or is not a file",
            asset_path.display()
        );
    }
    if !asset_path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"))
    {
        bail!(
            "--asset: {} is not a .glb file (render the model.glb that `wildlight export` writes)",
            asset_path.display()
        );
    }
    let Some(data) = args.data.clone() else {
        bail!("--asset needs --data DATASET: the capture whose cameras and flash to use");
    };
    let env = environment(args)?;
    let asset = read_glb(&asset_path)?;
    let views = ChosenViews::load(&data, args)?;
    let chosen = views.chosen();
    let scale_mat = views
        .cameras
        .first()
        .map(|c| c.scale_mat.as_mat4())
        .with_context(|| format!("{} has no cameras", views.split_dir.display()))?;
    let recorded = asset.frame.map(|f| match f {
        wildlight_export::AssetFrame::World => AssetFrame::World,
        wildlight_export::AssetFrame::Normalized => AssetFrame::Normalized,
    });
    let to_normalized = match args.asset_frame.or(recorded).unwrap_or(AssetFrame::World) {
        AssetFrame::World => scale_mat.inverse(),
        AssetFrame::Normalized => Mat4::IDENTITY,
    };
    if !(args.flash_gain > 0.0 && args.flash_gain.is_finite()) {
        bail!("--flash-gain {} must be > 0", args.flash_gain);
    }
    let tracer = AssetTracer::new(&asset, to_normalized)
        .with_context(|| format!("cannot prepare {} for ray tracing", asset_path.display()))?;
    let lighting = LightingSettings {
        flash: FlashSettings {
            gain: args.flash_gain,
            ..FlashSettings::default()
        },
        env,
        spp: args.spp,
        seed: args.seed,
    };
    let out = args.out.clone().unwrap_or_else(|| {
        asset_path
            .parent()
            .unwrap_or(Path::new("."))
            .join(format!("render-{}", views.split_name))
    });
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;
    let bar = progress_bar(args, chosen.len());
    let mut records = Vec::with_capacity(chosen.len());
    let mut surface_pixels = 0usize;
    for camera in &chosen {
        let energy = views.energy(args.flash, camera);
        let view = tracer.render_view(
            camera,
            energy.map(f64::from),
            args.scale,
            camera.index,
            &lighting,
        );
        surface_pixels += view.hits().iter().filter(|h| **h).count();
        write_view_maps(&out, camera.index, &view, camera.world_scale())?;
        records.push(RenderedView {
            index: camera.index,
            split: views.split_name,
            flash: energy != [0.0; 3],
        });
        bar.inc(1);
    }
    let path = out.join("views.json");
    wildlight_data::atomic::write_bytes_atomically(
        &path,
        serde_json::to_string_pretty(&records)?.as_bytes(),
    )
    .with_context(|| format!("cannot write {}", path.display()))?;
    bar.finish_and_clear();
    if surface_pixels == 0 {
        eprintln!(
            "warning: no view sees the asset; is --asset-frame right (world for a default export, normalized for --normalized)?"
        );
    }
    eprintln!("rendered {} views into {}", records.len(), out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::parse_views;

    #[test]
    fn view_lists() {
        assert_eq!(parse_views("0,3,5-7").unwrap(), vec![0, 3, 5, 6, 7]);
        assert!(parse_views("4-2").is_err());
        assert!(parse_views("x").is_err());
    }
}
