//! Using a trained run: loading its model, rendering a capture's views with
//! every map, and writing them in the layout `wildlight eval` reads
//! (`OUT/<kind>/NNN.exr` + `OUT/views.json`).

use crate::config::TrainConfig;
use crate::model::Model;
use crate::pipeline::{Pipeline, eval_sdf};
use crate::render_view::render_view;
use crate::run::{CHECKPOINT_FILE, RunInfo, read_run};
use crate::trainer::{AVERAGE_COUNT, AVERAGE_PREFIX, load_model};
use anyhow::Context;
use std::path::Path;
use wildlight_data::exr_io::{write_exr_channels, write_exr_rgb};
use wildlight_data::writer::indexed_file_name;
use wildlight_data::{Camera, RgbImage, ViewMaps};
use wildlight_fields::{Checkpoint, FieldContext, NormalMethod};
use wildlight_render::{OccupancyGrid, RefreshMode, Sampler};

/// A trained model ready to render.
pub struct TrainedRun {
    /// The run's configuration.
    pub config: TrainConfig,
    /// The run's description (dataset path).
    pub info: RunInfo,
    /// The trained model.
    pub model: Model,
    /// Occupancy grid measured from the trained SDF.
    pub grid: OccupancyGrid,
    /// Render buffers.
    pub pipeline: Pipeline,
}

impl TrainedRun {
    /// Loads `RUN/config.toml`, `RUN/run.json` and `RUN/checkpoint.safetensors`.
    pub fn load(run: &Path) -> anyhow::Result<Self> {
        let (config, info) = read_run(run)?;
        let ckpt_path = run.join(CHECKPOINT_FILE);
        let ck = Checkpoint::load(&ckpt_path)
            .with_context(|| format!("cannot read the checkpoint {}", ckpt_path.display()))?;
        // A run without masks modelled the background (SPEC §6).
        let mut model = if info.masks.maskless() {
            Model::with_background(&config.model, config.seed)?
        } else {
            Model::new(&config.model, config.seed)?
        };
        // A run that averaged its parameters renders their mean (when the
        // average holds any yet: a snapshot from before its start has none).
        let averaged = config.optim.average_from < 1.0 && ck.metadata(AVERAGE_COUNT).is_some();
        load_model(&mut model, &ck, if averaged { AVERAGE_PREFIX } else { "" })?;
        let mut grid = OccupancyGrid::new(config.sampling.occupancy())?;
        let mut ctx = FieldContext::new();
        let s = model.s();
        grid.refresh(
            |p: &[[f32; 3]], o: &mut [f32]| eval_sdf(&model, p, o, &mut ctx),
            s,
            RefreshMode::Full,
        );
        let sampler = Sampler::new(config.sampling.sampler())?;
        let mut pipeline = Pipeline::new(sampler);
        pipeline.background_settings = config.sampling.background();
        Ok(Self {
            config,
            info,
            model,
            grid,
            pipeline,
        })
    }

    /// How the trained model's normals are computed.
    pub fn normal_method(&self) -> NormalMethod {
        self.model.normal_method()
    }

    /// Renders `camera` with flash energy `energy` at `scale` × its resolution.
    pub fn render(&mut self, camera: &Camera, energy: [f32; 3], scale: f64) -> ViewMaps {
        let fd = self.normal_method();
        render_view(
            &self.model,
            &self.grid,
            &mut self.pipeline,
            camera,
            energy,
            scale,
            fd,
        )
    }
}

fn to_image(w: u32, h: u32, px: impl Iterator<Item = [f32; 3]>) -> RgbImage {
    RgbImage {
        width: w,
        height: h,
        data: px.flat_map(|p| p.into_iter()).collect(),
    }
}

/// Writes every map of `maps` as `out/<kind>/NNN.exr` (kinds of the
/// conventions: image, flash, ambient (for a run without masks these three
/// show the background too), normal, depth (world units),
/// base_color, roughness, metallic, params (9 channels), acc).
pub fn write_view_maps(
    out: &Path,
    index: usize,
    maps: &ViewMaps,
    world_scale: f64,
) -> anyhow::Result<()> {
    let (w, h) = (maps.width, maps.height);
    let name = indexed_file_name(index, "exr");
    let write = |kind: &str, img: RgbImage| -> anyhow::Result<()> {
        let dir = out.join(kind);
        std::fs::create_dir_all(&dir)
            .with_context(|| format!("cannot create {}", dir.display()))?;
        write_exr_rgb(&dir.join(&name), &img)
            .with_context(|| format!("cannot write {}", dir.join(&name).display()))
    };
    write("image", to_image(w, h, maps.rgb.iter().copied()))?;
    write("flash", to_image(w, h, maps.flash.iter().copied()))?;
    write("ambient", to_image(w, h, maps.ambient.iter().copied()))?;
    write("normal", to_image(w, h, maps.normal.iter().copied()))?;
    let ws = world_scale as f32;
    write(
        "depth",
        to_image(w, h, maps.depth.iter().map(|d| [d * ws; 3])),
    )?;
    write(
        "base_color",
        to_image(w, h, maps.params.iter().map(|p| [p[0], p[1], p[2]])),
    )?;
    write(
        "roughness",
        to_image(w, h, maps.params.iter().map(|p| [p[3]; 3])),
    )?;
    write(
        "metallic",
        to_image(w, h, maps.params.iter().map(|p| [p[6]; 3])),
    )?;
    write("acc", to_image(w, h, maps.acc.iter().map(|a| [*a; 3])))?;
    let dir = out.join("params");
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    let chans: Vec<Vec<f32>> = (0..9)
        .map(|c| maps.params.iter().map(|p| p[c]).collect())
        .collect();
    let names: Vec<String> = (0..9).map(|c| format!("p{c}")).collect();
    let list: Vec<(&str, &[f32])> = names
        .iter()
        .map(String::as_str)
        .zip(chans.iter().map(Vec::as_slice))
        .collect();
    write_exr_channels(&dir.join(&name), w, h, &list)
        .with_context(|| format!("cannot write {}", dir.join(&name).display()))?;
    Ok(())
}

/// One entry of `views.json`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RenderedView {
    /// Image index.
    pub index: usize,
    /// `train` or `val`.
    pub split: &'static str,
    /// Whether the flash was on in the rendering.
    pub flash: bool,
}

/// Renders `cameras` (each with the flash energy `energy(camera)`) into
/// `out/<kind>/NNN.exr` and writes `out/views.json`; `progress` is called
/// after each view.
pub fn render_views_to_dir(
    trained: &mut TrainedRun,
    cameras: &[&Camera],
    energy: impl Fn(&Camera) -> [f32; 3],
    split: &'static str,
    scale: f64,
    out: &Path,
    mut progress: impl FnMut(),
) -> anyhow::Result<Vec<RenderedView>> {
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut records = Vec::new();
    for camera in cameras {
        let e = energy(camera);
        let maps = trained.render(camera, e, scale);
        write_view_maps(out, camera.index, &maps, camera.world_scale())?;
        records.push(RenderedView {
            index: camera.index,
            split,
            flash: e != [0.0; 3],
        });
        progress();
    }
    let path = out.join("views.json");
    wildlight_data::atomic::write_bytes_atomically(
        &path,
        serde_json::to_string_pretty(&records)?.as_bytes(),
    )
    .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(records)
}
