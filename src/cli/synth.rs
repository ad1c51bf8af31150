//! `wildlight synth`: render a synthetic flash/no-flash capture with ground truth.

use std::path::PathBuf;

use anyhow::Context;
use wildlight_material::BrdfSettings;
use wildlight_synth::{
    BackgroundKind, BuiltinScene, MaterialDefinition, RigOptions, SceneSource, SynthOptions,
    synthesize,
};

/// Options of `wildlight synth`.
#[derive(clap::Args, Debug)]
#[command(group(clap::ArgGroup::new("object").args(["scene", "mesh", "list"]).required(true)))]
pub struct Args {
    /// Built-in scene to render (see --list; the first one, kettle, is the default
    /// benchmark scene). Exactly one of --scene, --mesh, --list is required.
    #[arg(long, value_name = "NAME")]
    pub scene: Option<String>,
    /// Render this PLY or OBJ mesh instead, rescaled into the sphere of radius 0.8.
    #[arg(long, value_name = "FILE")]
    pub mesh: Option<PathBuf>,
    /// List the built-in scenes (default first) and exit.
    #[arg(long)]
    pub list: bool,
    /// Output dataset folder (required unless --list).
    #[arg(long, value_name = "DIR", required_unless_present = "list")]
    pub out: Option<PathBuf>,
    /// Replace an existing capture in --out.
    #[arg(long)]
    pub overwrite: bool,
    /// Material: a procedural material name (kettle, sampler, patches) or a JSON object of
    /// material parameters, e.g. '{"base_color":[0.8,0.2,0.1],"roughness":0.3,"metallic":0}'.
    /// [default: the scene's own material; `patches` for --mesh]
    #[arg(long, value_name = "NAME|JSON")]
    pub material: Option<String>,
    /// Number of training views.
    #[arg(long, default_value_t = 64)]
    pub views: usize,
    /// Number of held-out (novel) views written to val/.
    #[arg(long, default_value_t = 8)]
    pub val_views: usize,
    /// Image width in pixels.
    #[arg(long, default_value_t = 256)]
    pub width: u32,
    /// Image height in pixels.
    #[arg(long, default_value_t = 256)]
    pub height: u32,
    /// Horizontal field of view in degrees.
    #[arg(long, default_value_t = 40.0)]
    pub fov: f64,
    /// Camera distance from the object centre, in normalized units (object radius ≲ 0.8).
    #[arg(long, default_value_t = 2.6)]
    pub distance: f64,
    /// Lowest camera elevation in degrees (raised to 5 with --background table).
    #[arg(long, default_value_t = -10.0, allow_negative_numbers = true)]
    pub elevation_min: f64,
    /// Highest camera elevation in degrees.
    #[arg(long, default_value_t = 60.0, allow_negative_numbers = true)]
    pub elevation_max: f64,
    /// Random pose perturbation in [0, 1] (azimuth, elevation, distance, look-at point).
    #[arg(long, default_value_t = 0.5)]
    pub jitter: f64,
    /// World units per normalized unit (scale_mat's scale).
    #[arg(long, default_value_t = 2.5)]
    pub world_scale: f64,
    /// World position of the object centre (scale_mat's translation), as x,y,z.
    #[arg(long, value_delimiter = ',', num_args = 3, default_values_t = [0.4, -0.3, 1.2], allow_negative_numbers = true)]
    pub world_offset: Vec<f64>,
    /// Fraction of views with the flash on (flash and no-flash views are not paired).
    #[arg(long, default_value_t = 0.5)]
    pub flash_fraction: f64,
    /// Flash energy (RGB, equal channels) in normalized units, before exposure.
    #[arg(long, default_value_t = 10.0)]
    pub flash_power: f64,
    /// Exposure multiplier on all light; the written light_energy includes it.
    #[arg(long, default_value_t = 1.0)]
    pub exposure: f64,
    /// Ambient Monte Carlo samples per pixel of the training views.
    #[arg(long, default_value_t = 256)]
    pub spp: usize,
    /// Ambient Monte Carlo samples per pixel of the held-out views in val/,
    /// the references of `wildlight eval images` (rendered without sensor
    /// noise, so the metric measures the reconstruction, not the noise).
    #[arg(long, default_value_t = 1024)]
    pub val_spp: usize,
    /// Environment map (equirectangular .exr or .hdr, +y up)
    /// [default: a procedural sky with a sun].
    #[arg(long, value_name = "FILE")]
    pub env: Option<PathBuf>,
    /// Multiplier of the environment radiance.
    #[arg(long, default_value_t = 1.0)]
    pub env_strength: f64,
    /// What the photos show where their rays miss the object: `room`, the environment map
    /// that lights the object; `table`, the room and a large checkered wooden table top the
    /// object stands on (lit by the room and the flash, shadowed by the object; the lowest
    /// camera elevation is raised to 5° so that every camera looks from above the table);
    /// `none`, black (0). Masks and ground truth stay the object's; gt/background.json
    /// records a table (its plane in both frames) or none.
    #[arg(long, value_enum, default_value_t = Background::Room)]
    pub background: Background,
    /// Sensor noise: Gaussian, standard deviation NOISE·sqrt(value + 0.01) per channel (0 = off).
    #[arg(long, default_value_t = 0.0)]
    pub noise: f64,
    /// Clip images at this saturation cap and write it as max_intensity, like a camera's white
    /// point (only specular highlights clip at the default exposure); `none` keeps the full HDR
    /// range.
    #[arg(long, value_name = "CAP|none", default_value = "1", value_parser = parse_cap)]
    pub saturation: Cap,
    /// Clearcoat Fresnel F_c of the material model (SPEC §8: 0.2 appendix, 0.04 reference code).
    #[arg(long, default_value_t = 0.2)]
    pub clearcoat_fresnel: f64,
    /// Grid points per axis when meshing a built-in scene (ground-truth mesh resolution).
    #[arg(long, default_value_t = 160)]
    pub mesh_resolution: usize,
    /// Random seed (poses, flash choice, Monte Carlo, noise).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Do not show the progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Runs `wildlight synth`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.list {
        for scene in BuiltinScene::ALL {
            println!("{:<10} {}", scene.name(), scene.description());
        }
        return Ok(());
    }
    let source = match (&args.scene, &args.mesh) {
        (Some(_), Some(_)) => anyhow::bail!("give either --scene or --mesh, not both"),
        (Some(name), None) => {
            SceneSource::Builtin(BuiltinScene::from_name(name).with_context(|| {
                let known: Vec<_> = BuiltinScene::ALL.iter().map(|s| s.name()).collect();
                format!(
                    "unknown scene '{name}' (built-in scenes: {})",
                    known.join(", ")
                )
            })?)
        }
        (None, Some(path)) => SceneSource::MeshFile(path.clone()),
        (None, None) => anyhow::bail!("give --scene NAME or --mesh FILE (or --list)"),
    };
    let out = args.out.context("--out DIR is required")?;
    let material = args
        .material
        .as_deref()
        .map(MaterialDefinition::parse)
        .transpose()?;
    let offset: [f64; 3] = args
        .world_offset
        .as_slice()
        .try_into()
        .context("--world-offset needs three numbers x,y,z")?;
    let rig = RigOptions {
        views: args.views,
        val_views: args.val_views,
        width: args.width,
        height: args.height,
        fov_deg: args.fov,
        distance: args.distance,
        elevation_min_deg: args.elevation_min,
        elevation_max_deg: args.elevation_max,
        jitter: args.jitter,
        world_scale: args.world_scale,
        world_offset: offset,
        flash_fraction: args.flash_fraction,
        flash_energy: [args.flash_power; 3],
        exposure: args.exposure,
        seed: args.seed,
    };
    if !(args.clearcoat_fresnel > 0.0 && args.clearcoat_fresnel <= 1.0) {
        anyhow::bail!(
            "--clearcoat-fresnel {} must be in (0, 1]",
            args.clearcoat_fresnel
        );
    }
    let opts = SynthOptions {
        source,
        material,
        rig,
        spp: args.spp,
        val_spp: args.val_spp,
        env: args.env,
        env_strength: args.env_strength,
        background: args.background.kind(),
        mesh_resolution: args.mesh_resolution,
        noise: args.noise,
        saturation: args.saturation.0,
        brdf: BrdfSettings {
            clearcoat_fresnel: args.clearcoat_fresnel,
        },
        out,
        overwrite: args.overwrite,
        progress: !args.quiet,
    };
    let start = std::time::Instant::now();
    let summary = synthesize(&opts)?;
    eprintln!(
        "wrote {}: scene {}, {} training views ({} with flash), {} val views, {} triangles, {:.1} s",
        summary.out.display(),
        summary.scene,
        summary.train_views,
        summary.train_flash_views,
        summary.val_views,
        summary.triangles,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}

/// The values of `--background`.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Background {
    /// The environment map, seen where a ray misses the object.
    Room,
    /// The room and a textured table top the object stands on.
    Table,
    /// Black.
    None,
}

impl Background {
    /// The synthesizer's kind.
    fn kind(self) -> BackgroundKind {
        match self {
            Background::Room => BackgroundKind::Room,
            Background::Table => BackgroundKind::Table,
            Background::None => BackgroundKind::None,
        }
    }
}

/// A saturation cap, or none.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cap(pub Option<f64>);

/// Parses `--saturation`: a positive number or `none`.
fn parse_cap(text: &str) -> Result<Cap, String> {
    if text.trim().eq_ignore_ascii_case("none") {
        return Ok(Cap(None));
    }
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(Cap(Some(v))),
        _ => Err(format!("'{text}' is not a positive number or 'none'")),
    }
}
