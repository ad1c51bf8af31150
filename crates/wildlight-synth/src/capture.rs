//! A whole synthetic capture: the object, the rig, the rendering of every
//! view and the dataset folder with its ground truth (SPEC §5 and the
//! shared conventions):
//!
//! ```text
//! OUT/cameras_sphere.npz   OUT/image/NNN.exr   OUT/mask/NNN.png
//! OUT/gt/<kind>/NNN.exr    kinds: base_color roughness metallic normal depth flash ambient params
//! OUT/gt/mesh_world.ply    OUT/gt/mesh_normalized.ply    OUT/gt/material.json
//! OUT/gt/background.json   the background, unless it is the room (crate::background)
//! OUT/val/...              the held-out views, same layout (no meshes)
//! ```

use std::path::{Path, PathBuf};

use glam::{DMat4, Vec3};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use wildlight_data::{Camera, DatasetWriter};
use wildlight_material::{BrdfSettings, PARAM_COUNT};
use wildlight_mesh::TriMesh;
use wildlight_pathtrace::EnvMap;

use crate::background::{Background, BackgroundInfo, BackgroundKind};
use crate::error::SynthError;
use crate::ground_truth::{GroundTruthMaterial, MaterialDefinition};
use crate::mesher::mesh_sdf;
use crate::render::{RenderScene, ShadingSettings, ViewImages, render_view};
use crate::rig::{RigOptions, Split};
use crate::scenes::BuiltinScene;

/// Radius of the sphere a `--mesh` object is scaled into (normalized frame).
pub const MESH_RADIUS: f64 = 0.8;

/// The object of a capture.
#[derive(Clone, Debug, PartialEq)]
pub enum SceneSource {
    /// A built-in procedural scene.
    Builtin(BuiltinScene),
    /// A PLY or OBJ file, rescaled into the sphere of radius [`MESH_RADIUS`].
    MeshFile(PathBuf),
}

/// Everything `wildlight synth` needs.
#[derive(Clone, Debug)]
pub struct SynthOptions {
    /// The object.
    pub source: SceneSource,
    /// The material (None: the scene's own; `patches` for a mesh file).
    pub material: Option<MaterialDefinition>,
    /// Cameras, flash and exposure.
    pub rig: RigOptions,
    /// Ambient samples per pixel of the training views. The default 256
    /// keeps the renderer's own noise far below a camera's: at 64 samples
    /// the kettle's photos sat 34.2 dB from a 1024-sample rendering, and
    /// that noise, with its long bright tail, pulled the L1 fit of SPEC §4
    /// towards the darker median (the glaze came out 4–6 % dark); at 256
    /// they sit 43.8 dB from it. Sensor noise is `noise`'s job.
    pub spp: usize,
    /// Ambient samples per pixel of the held-out views. They are the
    /// references of the image metrics, so they are rendered closer to the
    /// converged image than the training photos (and without sensor noise):
    /// a metric against a noisy reference would be capped by that noise
    /// (at 64 samples the kettle's no-flash references sit 31.9 dB from a
    /// 1024-sample rendering).
    pub val_spp: usize,
    /// Environment map file (None: the procedural sky).
    pub env: Option<PathBuf>,
    /// Multiplier of the environment radiance.
    pub env_strength: f64,
    /// What the photos show where their rays miss the object
    /// ([`crate::background`]). A table raises the rig's lowest elevation
    /// to [`crate::background::TABLE_MIN_ELEVATION_DEG`].
    pub background: BackgroundKind,
    /// Grid points per axis when meshing a built-in scene.
    pub mesh_resolution: usize,
    /// Sensor noise level (0 = off), see [`ShadingSettings::noise`].
    pub noise: f64,
    /// Saturation cap, written as `max_intensity` (None = none, full HDR).
    /// The default, [`DEFAULT_SATURATION`], clips like a well-exposed photo.
    pub saturation: Option<f64>,
    /// Material model settings.
    pub brdf: BrdfSettings,
    /// Output folder.
    pub out: PathBuf,
    /// Replace an existing capture in `out`.
    pub overwrite: bool,
    /// Show a progress bar on stderr (only drawn on a terminal).
    pub progress: bool,
}

/// The default saturation cap: a camera's white point at the default
/// exposure. Under it lie the ambient image and the diffuse part of the flash
/// reflection; only specular highlights (under 1 % of the object's pixels in
/// the default scene) clip, as they do in a well-exposed 8-bit photo. This is
/// also the peak of the image metrics.
pub const DEFAULT_SATURATION: f64 = 1.0;

impl Default for SynthOptions {
    fn default() -> Self {
        SynthOptions {
            source: SceneSource::Builtin(BuiltinScene::ALL[0]),
            material: None,
            rig: RigOptions::default(),
            spp: 256,
            val_spp: 1024,
            env: None,
            env_strength: 1.0,
            background: BackgroundKind::Room,
            mesh_resolution: 160,
            noise: 0.0,
            saturation: Some(DEFAULT_SATURATION),
            brdf: BrdfSettings::default(),
            out: PathBuf::from("capture"),
            overwrite: false,
            progress: true,
        }
    }
}

/// What was written.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureSummary {
    /// Output folder.
    pub out: PathBuf,
    /// Scene name (or mesh file).
    pub scene: String,
    /// Training views written.
    pub train_views: usize,
    /// Held-out views written.
    pub val_views: usize,
    /// Training views with the flash on.
    pub train_flash_views: usize,
    /// Triangles of the ground-truth mesh.
    pub triangles: usize,
}

/// The object's mesh in the normalized frame, its name and default material.
pub fn scene_mesh(
    source: &SceneSource,
    mesh_resolution: usize,
) -> Result<(TriMesh, String, MaterialDefinition), SynthError> {
    match source {
        SceneSource::Builtin(scene) => {
            if !(16..=1024).contains(&mesh_resolution) {
                return Err(SynthError::InvalidOption {
                    what: "--mesh-resolution".into(),
                    problem: format!("{mesh_resolution} (must be in 16..=1024)"),
                });
            }
            let s = *scene;
            let mesh = mesh_sdf(&|p| s.distance(p), 0.9, mesh_resolution);
            Ok((
                mesh,
                s.name().to_string(),
                MaterialDefinition::Procedural {
                    name: s.name().into(),
                },
            ))
        }
        SceneSource::MeshFile(path) => {
            let mut mesh = TriMesh::read(path)?;
            let bad = |problem: &str| SynthError::BadMesh {
                path: path.clone(),
                problem: problem.into(),
            };
            if mesh.triangles.is_empty() {
                return Err(bad("the mesh has no triangles"));
            }
            if mesh.positions.iter().any(|p| !p.is_finite()) {
                return Err(bad("the mesh has NaN or infinite vertex coordinates"));
            }
            let bb = mesh
                .bounding_box()
                .ok_or_else(|| bad("the mesh has no vertices"))?;
            let c = bb.center();
            let radius = mesh
                .positions
                .iter()
                .map(|p| (*p - c).length())
                .fold(0.0f32, f32::max);
            if !(radius > 0.0) {
                return Err(bad("all vertices coincide"));
            }
            let s = (MESH_RADIUS / radius as f64) as f32;
            for p in &mut mesh.positions {
                *p = (*p - c) * s;
            }
            mesh.colors = None;
            mesh.uvs = None;
            let name = path
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            Ok((
                mesh,
                name,
                MaterialDefinition::Procedural {
                    name: "patches".into(),
                },
            ))
        }
    }
}

fn remove_previous(out: &Path) -> Result<(), SynthError> {
    for name in ["image", "mask", "gt", "val"] {
        let p = out.join(name);
        if p.is_dir() {
            std::fs::remove_dir_all(&p).map_err(|e| SynthError::Io {
                path: p.clone(),
                action: "removing",
                source: e,
            })?;
        }
    }
    let p = out.join("cameras_sphere.npz");
    if p.exists() {
        std::fs::remove_file(&p).map_err(|e| SynthError::Io {
            path: p.clone(),
            action: "removing",
            source: e,
        })?;
    }
    Ok(())
}

fn write_view_maps(
    writer: &DatasetWriter,
    index: usize,
    maps: &ViewImages,
) -> Result<(), SynthError> {
    writer.write_image(index, &maps.image)?;
    writer.write_mask(index, &maps.mask)?;
    for (kind, img) in [
        ("base_color", &maps.base_color),
        ("roughness", &maps.roughness),
        ("metallic", &maps.metallic),
        ("normal", &maps.normal),
        ("depth", &maps.depth),
        ("flash", &maps.flash),
        ("ambient", &maps.ambient),
    ] {
        writer.write_map(kind, index, img)?;
    }
    let planes: Vec<Vec<f32>> = (0..PARAM_COUNT)
        .map(|c| maps.params.iter().map(|p| p[c]).collect())
        .collect();
    let names: Vec<String> = (0..PARAM_COUNT).map(|c| format!("p{c}")).collect();
    let channels: Vec<(&str, &[f32])> = names
        .iter()
        .map(|n| n.as_str())
        .zip(planes.iter().map(|p| p.as_slice()))
        .collect();
    writer.write_map_channels(
        "params",
        index,
        maps.image.width,
        maps.image.height,
        &channels,
    )?;
    Ok(())
}

/// Renders and writes a whole capture.
pub fn synthesize(opts: &SynthOptions) -> Result<CaptureSummary, SynthError> {
    let bad = |what: &str, problem: String| SynthError::InvalidOption {
        what: what.into(),
        problem,
    };
    for (flag, spp) in [("--spp", opts.spp), ("--val-spp", opts.val_spp)] {
        if spp == 0 || spp > 65536 {
            return Err(bad(flag, format!("{spp} (must be in 1..=65536)")));
        }
    }
    if !(opts.env_strength > 0.0 && opts.env_strength.is_finite()) {
        return Err(bad(
            "--env-strength",
            format!("{} (must be > 0)", opts.env_strength),
        ));
    }
    if !(opts.noise >= 0.0 && opts.noise.is_finite()) {
        return Err(bad("--noise", format!("{} (must be ≥ 0)", opts.noise)));
    }
    if let Some(cap) = opts.saturation
        && !(cap > 0.0 && cap.is_finite())
    {
        return Err(bad("--saturation", format!("{cap} (must be > 0)")));
    }
    if let Some(m) = &opts.material {
        m.validate().map_err(|p| bad("--material", p))?;
    }
    let rig = opts.background.rig(&opts.rig)?;
    let views = rig.build()?;
    let (mesh, scene_name, default_material) = scene_mesh(&opts.source, opts.mesh_resolution)?;
    let background = Background::new(opts.background, &mesh)?;
    background.check_cameras(&views)?;
    if opts.out.exists() {
        let non_empty = std::fs::read_dir(&opts.out)
            .map(|mut d| d.next().is_some())
            .unwrap_or(true);
        if non_empty {
            if !opts.overwrite {
                return Err(bad(
                    "--out",
                    format!(
                        "{} exists and is not empty (pass --overwrite to replace the capture)",
                        opts.out.display()
                    ),
                ));
            }
            remove_previous(&opts.out)?;
        }
    }
    let env = match &opts.env {
        Some(path) => EnvMap::load(path)?,
        None => EnvMap::procedural_sky(),
    }
    .scaled(opts.env_strength * rig.exposure);

    let material = opts.material.clone().unwrap_or(default_material);
    let scene = RenderScene::new(&mesh, material.clone()).with_background(background);
    let settings = ShadingSettings {
        spp: opts.spp,
        brdf: opts.brdf,
        noise: opts.noise,
        saturation: opts.saturation,
        seed: rig.seed,
    };
    let val_settings = ShadingSettings {
        spp: opts.val_spp,
        noise: 0.0,
        ..settings
    };

    let train = DatasetWriter::create(&opts.out)?;
    let val = if rig.val_views > 0 {
        Some(train.val()?)
    } else {
        None
    };

    let total_rows = views.len() as u64 * rig.height as u64;
    let bar = if opts.progress {
        let bar = ProgressBar::with_draw_target(Some(total_rows), ProgressDrawTarget::stderr());
        bar.set_style(
            ProgressStyle::with_template(
                "{msg} [{elapsed_precise}] {wide_bar} {pos}/{len} rows (eta {eta})",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        bar
    } else {
        ProgressBar::hidden()
    };
    let mut train_cams: Vec<Camera> = Vec::new();
    let mut val_cams: Vec<Camera> = Vec::new();
    for view in &views {
        bar.set_message(format!(
            "{} {} {:03}",
            scene_name,
            if view.split == Split::Train {
                "train"
            } else {
                "val"
            },
            view.camera.index
        ));
        let on_row = || bar.inc(1);
        let maps = render_view(
            &scene,
            &env,
            &view.camera,
            view.global_index,
            match view.split {
                Split::Train => &settings,
                Split::Val => &val_settings,
            },
            rig.world_scale,
            &on_row,
        )?;
        match view.split {
            Split::Train => {
                write_view_maps(&train, view.camera.index, &maps)?;
                train_cams.push(view.camera.clone());
            }
            Split::Val => {
                if let Some(v) = &val {
                    write_view_maps(v, view.camera.index, &maps)?;
                }
                val_cams.push(view.camera.clone());
            }
        }
    }
    bar.finish_and_clear();
    train.write_cameras(&train_cams, opts.saturation)?;
    if let Some(v) = &val {
        v.write_cameras(&val_cams, opts.saturation)?;
    }

    // Ground truth: meshes and material.
    let gt_dir = opts.out.join("gt");
    std::fs::create_dir_all(&gt_dir).map_err(|e| SynthError::Io {
        path: gt_dir.clone(),
        action: "creating folder",
        source: e,
    })?;
    mesh.write(gt_dir.join("mesh_normalized.ply"))?;
    let scale_mat: DMat4 = rig.scale_mat();
    let mut world = mesh.clone();
    world.positions = mesh
        .positions
        .iter()
        .map(|p| scale_mat.transform_point3(p.as_dvec3()).as_vec3())
        .collect::<Vec<Vec3>>();
    world.write(gt_dir.join("mesh_world.ply"))?;
    GroundTruthMaterial::new(
        &scene_name,
        material,
        rig.world_scale,
        rig.world_offset,
        opts.brdf,
    )
    .save(&gt_dir.join("material.json"))?;
    if background.kind() != BackgroundKind::Room {
        // a capture without the record shows the room, as every capture
        // written before the option does
        BackgroundInfo::new(&background, rig.world_scale, rig.world_offset).save(&opts.out)?;
    }

    Ok(CaptureSummary {
        out: opts.out.clone(),
        scene: scene_name,
        train_views: train_cams.len(),
        val_views: val_cams.len(),
        train_flash_views: train_cams.iter().filter(|c| c.flash()).count(),
        triangles: mesh.triangles.len(),
    })
}
