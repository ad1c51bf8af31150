//! `wildlight export`: turns a trained run into a PBR asset (SPEC §9):
//! `model.glb`, `model.obj` + `model.mtl` + PNG maps, and `mesh_raw.ply`.

use crate::field_source::ExportSource;
use anyhow::{Context, bail};
use std::path::PathBuf;
use wildlight_export::{AtlasOptions, ExportOptions, MarchingOptions, export_to_dir};
use wildlight_train::inference::TrainedRun;
use wildlight_train::support::BackgroundSupportSearch;

/// Options of `wildlight export`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The run folder written by `wildlight train`.
    #[arg(long, value_name = "RUN")]
    pub run: PathBuf,
    /// Output folder.
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    #[command(flatten)]
    pub asset: AssetArgs,
    /// Keep vertices in the normalized frame instead of world units.
    #[arg(long)]
    pub normalized: bool,
    /// Keep the object alone: cut away the surface it stands on (a table
    /// top crossing the region of interest) and everything below it, what
    /// lies outside the unit sphere, and every piece but the largest
    /// [default: on for runs trained without masks].
    #[arg(long, conflicts_with = "keep_support")]
    pub object_only: bool,
    /// Keep everything the field holds inside the unit sphere, support
    /// included (the default for runs trained with masks).
    #[arg(long)]
    pub keep_support: bool,
    /// No progress bars.
    #[arg(long)]
    pub quiet: bool,
}

/// The size of an exported asset: the options `export` and `reconstruct` share.
#[derive(clap::Args, Debug, Clone)]
pub struct AssetArgs {
    /// Marching-cubes cells per axis over the unit sphere's bounding cube.
    #[arg(long, default_value_t = 512)]
    pub resolution: u32,
    /// Largest face count of the simplified mesh.
    #[arg(long, default_value_t = 131_072)]
    pub faces: usize,
    /// Texture width and height in texels.
    #[arg(long, default_value_t = 2048)]
    pub texture: u32,
}

impl AssetArgs {
    /// Checks the ranges (before anything slow runs).
    pub fn check(&self) -> anyhow::Result<()> {
        self.options(glam::Mat4::IDENTITY, true, false).map(|_| ())
    }

    /// The export settings for a capture whose normalized frame maps to the
    /// world by `scale_mat`.
    pub fn options(
        &self,
        scale_mat: glam::Mat4,
        world_units: bool,
        progress: bool,
    ) -> anyhow::Result<ExportOptions> {
        export_options(
            self.resolution,
            self.faces,
            self.texture,
            scale_mat,
            world_units,
            progress,
        )
    }
}

/// The export settings of `args` for a capture whose normalized frame maps
/// to the world by `scale_mat`, after checking the ranges.
pub fn export_options(
    resolution: u32,
    faces: usize,
    texture: u32,
    scale_mat: glam::Mat4,
    world_units: bool,
    progress: bool,
) -> anyhow::Result<ExportOptions> {
    if !(16..=2048).contains(&resolution) {
        bail!("--resolution {resolution} is outside 16..=2048");
    }
    if !(64..=16384).contains(&texture) {
        bail!("--texture {texture} is outside 64..=16384");
    }
    if faces < 4 {
        bail!("--faces {faces} is too small");
    }
    Ok(ExportOptions {
        marching: MarchingOptions {
            resolution,
            ..MarchingOptions::default()
        },
        max_faces: faces,
        atlas: AtlasOptions {
            texture_size: texture,
            ..AtlasOptions::default()
        },
        scale_mat,
        world_units,
        progress,
        ..ExportOptions::default()
    })
}

/// The cameras of a trained run's capture (read once: the scale_mat and the
/// background's support plane both need them).
pub fn run_cameras(trained: &TrainedRun) -> anyhow::Result<Vec<wildlight_data::Camera>> {
    wildlight_data::Dataset::load_cameras(&trained.info.data).with_context(|| {
        format!(
            "cannot read the cameras of the run's capture {}",
            trained.info.data.display()
        )
    })
}

/// The normalized → world map of a run's capture (its first camera's scale_mat).
pub fn run_scale_mat(cameras: &[wildlight_data::Camera]) -> anyhow::Result<glam::Mat4> {
    cameras
        .first()
        .map(|c| c.scale_mat.as_mat4())
        .context("the run's capture has no cameras")
}

/// `options` set to keep the object alone when `object_only` is asked for,
/// or by default for a run trained without masks (its surface then holds
/// what the object stands on, unless `keep_support`). The support plane is
/// then also looked for in the run's background (the table beyond the
/// sphere), for the surface may hold too little of it.
pub fn with_object_only(
    trained: &mut TrainedRun,
    cameras: &[wildlight_data::Camera],
    options: ExportOptions,
    object_only: bool,
    keep_support: bool,
) -> anyhow::Result<ExportOptions> {
    let object_only = object_only || (!keep_support && trained.info.masks.maskless());
    let known_support = if object_only && trained.model.background.is_some() {
        trained
            .support_from_background(cameras, &BackgroundSupportSearch::default())
            .map(|s| s.plane)
    } else {
        None
    };
    Ok(ExportOptions {
        object_only,
        known_support,
        ..options
    })
}

/// Runs `wildlight export`.
pub fn run(args: Args) -> anyhow::Result<()> {
    // Check the options before the (slow) loading of the run.
    args.asset.check()?;
    let mut trained = TrainedRun::load(&args.run)?;
    let cameras = run_cameras(&trained)?;
    let options = args.asset.options(
        run_scale_mat(&cameras)?,
        !args.normalized,
        !args.quiet && std::io::IsTerminal::is_terminal(&std::io::stderr()),
    )?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("cannot create {}", args.out.display()))?;
    let options = with_object_only(
        &mut trained,
        &cameras,
        options,
        args.object_only,
        args.keep_support,
    )?;
    let source = ExportSource::new(&trained);
    let (files, report) = export_to_dir(&source, &options, &args.out)
        .with_context(|| format!("export of {} failed", args.run.display()))?;
    eprintln!(
        "wrote {}, {} and {}",
        files.glb.display(),
        files.obj.display(),
        files.raw_ply.display()
    );
    eprintln!("{}", serde_json::to_string(&report)?);
    Ok(())
}
