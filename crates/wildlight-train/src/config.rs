//! The training configuration: every setting with its documented default,
//! read from TOML (`--config FILE`), printed by `--print-config`, and saved
//! into each run folder so that a run can be resumed and re-rendered.
//!
//! A schedule is given in fractions of the planned run (the steps `iters`
//! or a time budget plans): a key ending in `_from` is where a thing starts,
//! `_until` where it stops, and `_final` is a value reached at the last
//! planned step. The measurements behind the defaults are in
//! `docs/benchmark-log.md` ("Settings: the measurements behind the
//! defaults"); settings of experiments that were measured and not kept are
//! listed in [`crate::retired`], and a file that still names them loads
//! with a warning.

use serde::{Deserialize, Serialize};
use wildlight_fields::{Activation, HashGridConfig, Interpolation, SdfFieldConfig};
use wildlight_material::BrdfSettings;

/// Everything that defines a training run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Seed of every random choice (initialisation, rays, jitter).
    pub seed: u64,
    /// Optimisation steps; the learning-rate decay spans them (a time
    /// budget may end the run sooner and fits the decay to it).
    pub iters: u64,
    /// Rays per step.
    pub batch_rays: usize,
    /// Share of each batch drawn from mask-foreground pixels, in [0, 1].
    pub foreground_fraction: f64,
    /// Share of each batch drawn from the silhouette band, in [0, 1]; with
    /// `foreground_fraction` at most 1, the rest is drawn from all pixels.
    pub silhouette_fraction: f64,
    /// Half-width in pixels of the silhouette band around each mask edge.
    pub silhouette_band: u32,
    /// How often a flash photo's pixel is drawn against a no-flash photo's
    /// (> 0; 1: alike, 2: twice as often).
    pub flash_view_weight: f64,
    /// Extra points per step, uniform in the ball of radius 1.2, for the
    /// eikonal term.
    pub eikonal_points: usize,
    /// Loss weights.
    pub loss: LossConfig,
    /// Optimiser settings.
    pub optim: OptimConfig,
    /// The fields.
    pub model: ModelConfig,
    /// Sampling along rays.
    pub sampling: SamplingConfig,
    /// Logging, previews and checkpoints.
    pub output: OutputConfig,
}

impl Default for TrainConfig {
    fn default() -> Self {
        Self {
            seed: 0,
            iters: 4000,
            batch_rays: 1024,
            foreground_fraction: 0.7,
            silhouette_fraction: 0.2,
            silhouette_band: 2,
            flash_view_weight: 1.0,
            eikonal_points: 512,
            loss: LossConfig::default(),
            optim: OptimConfig::default(),
            model: ModelConfig::default(),
            sampling: SamplingConfig::default(),
            output: OutputConfig::default(),
        }
    }
}

/// Weights of the terms of SPEC §4 and of the project's four priors.
/// `material_smoothness`, `normal_smoothness`, `binary_metallic` and
/// `visual_hull` at 0 train with SPEC §4's objective alone.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LossConfig {
    /// Weight of the L1 colour loss (SPEC §4: 1).
    pub color: f64,
    /// Weight of the eikonal term (SPEC §4: 0.1).
    pub eikonal: f64,
    /// Weight of the mask cross-entropy (SPEC §4: 1).
    pub mask: f64,
    /// Weight λ of the material smoothness prior (`crate::smoothness`), ≥ 0; 0: off.
    pub material_smoothness: f64,
    /// Largest offset per axis of the smoothness pairs (normalized units),
    /// for the material and the normal prior alike.
    pub smoothness_radius: f64,
    /// The material prior's weight at the last planned step, as a factor of
    /// λ: it falls along the learning rate's cosine (1: constant).
    pub material_smoothness_final: f64,
    /// Weight of the normal smoothness prior (`crate::normal_smoothness`), ≥ 0; 0: off.
    pub normal_smoothness: f64,
    /// Factor on both smoothness priors' weights (material and normal) in
    /// runs without masks, ≥ 0 (0: off there, as in SPEC §4).
    pub smoothness_without_masks: f64,
    /// The normal prior's weight at the last planned step, as a factor of
    /// `normal_smoothness` (1: constant).
    pub normal_smoothness_final: f64,
    /// Weight of the binary-metallic prior (`crate::metallic_prior`), ≥ 0; 0: off.
    pub binary_metallic: f64,
    /// Fraction of the planned run at which the binary-metallic prior starts, in [0, 1].
    #[serde(alias = "binary_metallic_start")]
    pub binary_metallic_from: f64,
    /// Fraction of the planned run at which it stops, in [0, 1] (1: at the end).
    #[serde(alias = "binary_metallic_end")]
    pub binary_metallic_until: f64,
    /// Weight of the visual-hull prior (`crate::visual_hull`; needs masks), ≥ 0; 0: off.
    pub visual_hull: f64,
    /// Pixels by which each mask is dilated before it carves the visual hull.
    pub visual_hull_dilation: u32,
    /// Points drawn per step for the visual-hull prior.
    pub visual_hull_points: usize,
}

impl Default for LossConfig {
    fn default() -> Self {
        Self {
            color: 1.0,
            eikonal: 0.1,
            mask: 1.0,
            material_smoothness: 0.1,
            smoothness_radius: 0.02,
            material_smoothness_final: 0.3,
            normal_smoothness: 2.0,
            normal_smoothness_final: 0.3,
            smoothness_without_masks: 0.0,
            binary_metallic: 0.3,
            binary_metallic_from: 0.5,
            binary_metallic_until: 0.7,
            visual_hull: 1.0,
            visual_hull_dilation: 3,
            visual_hull_points: 2048,
        }
    }
}

/// Adam settings per parameter group and the schedule.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OptimConfig {
    /// Adam learning rate of the hash tables.
    pub lr_grid: f64,
    /// Adam learning rate of the MLPs.
    pub lr_mlp: f64,
    /// Per-field factors on `lr_grid` (`[optim.grid_lr_factors]`).
    pub grid_lr_factors: FieldLrFactors,
    /// Per-field factors on `lr_mlp` (`[optim.mlp_lr_factors]`).
    pub mlp_lr_factors: FieldLrFactors,
    /// Learning rate of the NeuS sharpness parameter v (s = exp(10 v)).
    pub lr_sharpness: f64,
    /// Learning rate of the log flash gain.
    pub lr_gain: f64,
    /// Steps of the linear learning-rate warm-up (from 0.01 of the rate).
    pub warmup_steps: u64,
    /// Learning-rate factor reached at the last planned step (cosine decay).
    #[serde(alias = "final_lr_factor")]
    pub lr_factor_final: f64,
    /// Steps over which the NeuS cos-annealing ratio rises from 0 to 1.
    pub cos_anneal_steps: u64,
    /// Hash levels active at the first step (coarse to fine; 0: all).
    pub c2f_start_levels: usize,
    /// Steps between activating one more hash level.
    pub c2f_steps_per_level: u64,
    /// Fraction of the planned run from which the parameters are averaged
    /// (`crate::averaging`) for rendering and export, in [0, 1] (1: never).
    pub average_from: f64,
    /// Steps between two parameter sets added to the average.
    pub average_every: u64,
}

impl Default for OptimConfig {
    fn default() -> Self {
        Self {
            lr_grid: 1e-2,
            lr_mlp: 1e-3,
            grid_lr_factors: FieldLrFactors::default(),
            mlp_lr_factors: FieldLrFactors::default(),
            lr_sharpness: 1e-2,
            lr_gain: 1e-2,
            warmup_steps: 100,
            lr_factor_final: 0.05,
            cos_anneal_steps: 500,
            c2f_start_levels: 4,
            c2f_steps_per_level: 100,
            average_from: 0.9,
            average_every: 5,
        }
    }
}

/// A factor (≥ 0; 1 by default, 0 freezes) on a learning rate for each of
/// the model's fields.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FieldLrFactors {
    /// The signed distance field.
    pub sdf: f64,
    /// The material field.
    pub material: f64,
    /// The ambient radiance field and its room.
    pub ambient: f64,
}

impl Default for FieldLrFactors {
    fn default() -> Self {
        Self {
            sdf: 1.0,
            material: 1.0,
            ambient: 1.0,
        }
    }
}

impl FieldLrFactors {
    /// (name, value) of each factor, for validation.
    fn named(&self, table: &str) -> [(String, f64); 3] {
        [
            (format!("optim.{table}.sdf"), self.sdf),
            (format!("optim.{table}.material"), self.material),
            (format!("optim.{table}.ambient"), self.ambient),
        ]
    }
}

/// A hash-grid + MLP field's size. In a TOML file a field's table may give
/// any of its keys: the others keep that field's defaults.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldSize {
    /// Hash levels.
    pub levels: usize,
    /// Features per level.
    pub features_per_level: usize,
    /// log2 of the table size per level.
    pub log2_table_size: u32,
    /// Coarsest resolution (cells per axis over [−1, 1]).
    pub base_resolution: u32,
    /// Finest resolution.
    pub finest_resolution: u32,
    /// Hidden layer widths.
    pub hidden: Vec<usize>,
    /// How the hash levels blend cell corners (`linear` or `smoothstep`).
    #[serde(default)]
    pub interpolation: Interpolation,
}

/// A [`FieldSize`] table in which any key may be left out.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct PartialFieldSize {
    levels: Option<usize>,
    features_per_level: Option<usize>,
    log2_table_size: Option<u32>,
    base_resolution: Option<u32>,
    finest_resolution: Option<u32>,
    hidden: Option<Vec<usize>>,
    interpolation: Option<Interpolation>,
}

impl PartialFieldSize {
    /// The keys given, the others from `defaults`.
    fn over(self, defaults: FieldSize) -> FieldSize {
        FieldSize {
            levels: self.levels.unwrap_or(defaults.levels),
            features_per_level: self
                .features_per_level
                .unwrap_or(defaults.features_per_level),
            log2_table_size: self.log2_table_size.unwrap_or(defaults.log2_table_size),
            base_resolution: self.base_resolution.unwrap_or(defaults.base_resolution),
            finest_resolution: self.finest_resolution.unwrap_or(defaults.finest_resolution),
            hidden: self.hidden.unwrap_or(defaults.hidden),
            interpolation: self.interpolation.unwrap_or(defaults.interpolation),
        }
    }
}

/// Deserializers of [`ModelConfig`]'s field tables that fill the keys a
/// file leaves out from the default of that field.
macro_rules! field_table_with_defaults {
    ($($name:ident => $slot:ident),* $(,)?) => {$(
        fn $name<'de, D: serde::Deserializer<'de>>(d: D) -> Result<FieldSize, D::Error> {
            Ok(PartialFieldSize::deserialize(d)?.over(ModelConfig::default().$slot))
        }
    )*};
}
field_table_with_defaults!(
    sdf_table => sdf,
    material_table => material,
    ambient_table => ambient,
    ambient_room_table => ambient_room,
    background_table => background,
);

impl FieldSize {
    /// The hash-grid settings.
    pub fn grid(&self) -> HashGridConfig {
        HashGridConfig {
            n_levels: self.levels,
            n_features: self.features_per_level,
            log2_table_size: self.log2_table_size,
            base_resolution: self.base_resolution,
            finest_resolution: self.finest_resolution,
            init_range: 1e-4,
            interpolation: self.interpolation,
        }
    }
}

/// The fields of the model (SPEC §2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModelConfig {
    /// The SDF field's size.
    #[serde(deserialize_with = "sdf_table")]
    pub sdf: FieldSize,
    /// Geometry features the SDF field outputs beside φ (ambient inputs).
    pub geometry_features: usize,
    /// Radius of the sphere the SDF starts as (normalized units).
    pub init_radius: f32,
    /// The material field's size (the 9 parameters of Θ through a sigmoid).
    #[serde(deserialize_with = "material_table")]
    pub material: FieldSize,
    /// The ambient radiance field's size.
    #[serde(deserialize_with = "ambient_table")]
    pub ambient: FieldSize,
    /// Initial NeuS sharpness parameter v (s = exp(10 v)).
    pub init_sharpness: f32,
    /// Initial log flash gain.
    pub init_log_gain: f32,
    /// Material model settings (clearcoat Fresnel).
    pub brdf: BrdfSettings,
    /// Θ the material field starts at, in SPEC §3 order, each in (0, 1)
    /// (the material network's output bias is set to their logits).
    pub init_material: [f32; 9],
    /// Whether the ambient term's gradient reaches the material field
    /// through its Θ input (off: Θ learns from the flash term alone).
    pub ambient_trains_material: bool,
    /// Factor in [0, 1] on the gradient that the flash photos send to the
    /// ambient term from `ambient_flash_gradient_late_from` on (1 before;
    /// 0: the room is learnt from the no-flash photos alone).
    pub ambient_flash_gradient_late: f64,
    /// Fraction of the planned run from which `ambient_flash_gradient_late`
    /// applies, in [0, 1] (1: never).
    pub ambient_flash_gradient_late_from: f64,
    /// The form of the ambient term ([`AmbientModel`]).
    pub ambient_model: AmbientModel,
    /// The room's size: the reflected-direction field of
    /// [`AmbientModel::NeuralRoom`], whose grid encodes ω on the unit sphere.
    #[serde(deserialize_with = "ambient_room_table")]
    pub ambient_room: FieldSize,
    /// The background field's size (runs without masks, SPEC §6): its grid
    /// encodes the contracted point u = (x/|x|)(2 − 1/|x|) over [−2, 2]³.
    #[serde(deserialize_with = "background_table")]
    pub background: FieldSize,
    /// How the SDF's gradient ∇φ (the normals, the eikonal term) is computed.
    pub sdf_normals: SdfNormals,
}

/// How the SDF's gradient ∇φ is computed in training and rendering.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SdfNormals {
    /// Tetrahedral finite differences whose step is the cell of the finest
    /// active SDF level (it shrinks as levels activate): five evaluations
    /// of the field per point.
    FiniteDifferences,
    /// The analytic gradient through the network and the hash encoding (one
    /// evaluation and a reverse sweep per point) once every SDF level is
    /// active; until then (coarse to fine) the finite differences, whose
    /// step, as wide as the finest active cell, smooths the early shape: the
    /// analytic gradient from the first step left the Mitsuba torus's mesh
    /// at 300 steps twice as far from the truth (0.0107 against 0.0056).
    Analytic,
}

/// The form of the ambient term a_k (SPEC §2 names its inputs: geometry
/// features, normal, view direction, Θ; it leaves the form open). The
/// direction is the view direction mirrored about the normal,
/// ω = d − 2(d·n)n.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AmbientModel {
    /// One network of the named inputs gives the RGB radiance.
    Neural,
    /// [`AmbientModel::Neural`] with [`ROOM_FEATURES`] more inputs: the
    /// room, a field of ω alone (the `ambient_room` hash grid over the unit
    /// sphere) that every point of the object shares, so that a sharp
    /// reflection seen at one point is where a new view expects it at
    /// another.
    NeuralRoom,
}

/// Outputs of the room of [`AmbientModel::NeuralRoom`].
pub const ROOM_FEATURES: usize = 8;

impl Default for ModelConfig {
    fn default() -> Self {
        Self {
            sdf: FieldSize {
                levels: 14,
                features_per_level: 2,
                log2_table_size: 19,
                base_resolution: 16,
                finest_resolution: 1024,
                hidden: vec![64],
                // C¹ across cells: with trilinear weights the zero level set
                // kinks at every face of the finest cells, a crinkle that
                // marching cubes at 512³ cannot follow (issue 8: 1.2 % apart
                // in eq. 16 after 30 minutes; 0.07 % with smoothstep).
                interpolation: Interpolation::Smoothstep,
            },
            geometry_features: 15,
            init_radius: 0.5,
            material: FieldSize {
                levels: 12,
                features_per_level: 2,
                log2_table_size: 18,
                base_resolution: 16,
                finest_resolution: 1024,
                hidden: vec![64],
                interpolation: Default::default(),
            },
            ambient: FieldSize {
                levels: 8,
                features_per_level: 2,
                log2_table_size: 17,
                base_resolution: 8,
                finest_resolution: 256,
                hidden: vec![64, 64],
                interpolation: Default::default(),
            },
            init_sharpness: 0.3,
            init_log_gain: 0.0,
            brdf: BrdfSettings::default(),
            init_material: [0.5, 0.5, 0.5, 0.5, 0.5, 0.05, 0.05, 0.5, 0.05],
            ambient_trains_material: true,
            ambient_flash_gradient_late: 0.0,
            ambient_flash_gradient_late_from: 0.8,
            ambient_model: AmbientModel::NeuralRoom,
            ambient_room: FieldSize {
                levels: 6,
                features_per_level: 2,
                log2_table_size: 16,
                base_resolution: 4,
                finest_resolution: 128,
                hidden: vec![],
                interpolation: Default::default(),
            },
            background: FieldSize {
                levels: 12,
                features_per_level: 2,
                log2_table_size: 15,
                base_resolution: 4,
                finest_resolution: 512,
                hidden: vec![32],
                interpolation: Default::default(),
            },
            // Quality per step as the finite differences' within the seeds'
            // noise, steps about 1.17× as fast (docs/benchmark-log.md, session 41).
            sdf_normals: SdfNormals::Analytic,
        }
    }
}

impl ModelConfig {
    /// The SDF field's settings.
    pub fn sdf_field(&self) -> SdfFieldConfig {
        SdfFieldConfig {
            grid: self.sdf.grid(),
            bound: 1.0,
            hidden: self.sdf.hidden.clone(),
            activation: Activation::Softplus { beta: 100.0 },
            n_features: self.geometry_features,
            sphere_init_radius: Some(self.init_radius),
        }
    }
}

/// Sampling along rays (SPEC §2 and the occupancy grid).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SamplingConfig {
    /// Occupancy grid cells per axis.
    pub grid_resolution: usize,
    /// Steps between two full refreshes of the occupancy grid (≥ 1).
    pub grid_refresh_every: u64,
    /// Coarse sections per occupancy-grid cell along a ray.
    pub coarse_steps_per_cell: f32,
    /// Most coarse sections per ray.
    pub max_coarse: usize,
    /// Importance (fine) samples per ray.
    pub fine_samples: usize,
    /// Background samples per ray beyond the unit sphere (runs without masks; ≥ 2).
    pub background_samples: usize,
    /// Radius of the farthest background sample, in radii of the unit sphere (> 1).
    pub background_far_radius: f64,
}

impl Default for SamplingConfig {
    fn default() -> Self {
        Self {
            grid_resolution: 64,
            grid_refresh_every: 16,
            coarse_steps_per_cell: 2.0,
            max_coarse: 48,
            fine_samples: 8,
            background_samples: 32,
            background_far_radius: 1000.0,
        }
    }
}

/// What a run writes, and how often.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OutputConfig {
    /// Steps between metrics lines (≥ 1).
    pub log_every: u64,
    /// Steps between preview images (0: none).
    pub preview_every: u64,
    /// Steps between checkpoints (≥ 1; one is also written at the end).
    pub checkpoint_every: u64,
    /// Preview images' size as a fraction of the capture's, in (0, 1].
    pub preview_scale: f64,
}

impl Default for OutputConfig {
    fn default() -> Self {
        Self {
            log_every: 10,
            preview_every: 500,
            checkpoint_every: 500,
            preview_scale: 0.5,
        }
    }
}

impl SamplingConfig {
    /// The occupancy grid settings.
    pub fn occupancy(&self) -> wildlight_render::OccupancySettings {
        wildlight_render::OccupancySettings {
            resolution: self.grid_resolution,
            ..wildlight_render::OccupancySettings::default()
        }
    }

    /// The background's sampling (runs without masks).
    pub fn background(&self) -> wildlight_render::BackgroundSettings {
        wildlight_render::BackgroundSettings {
            samples: self.background_samples,
            far_radius: self.background_far_radius,
        }
    }

    /// The fast sampler's settings.
    pub fn sampler(&self) -> wildlight_render::SamplerSettings {
        wildlight_render::SamplerSettings {
            coarse_steps_per_cell: self.coarse_steps_per_cell,
            max_coarse: self.max_coarse,
            n_fine: self.fine_samples,
            ..wildlight_render::SamplerSettings::default()
        }
    }
}

impl TrainConfig {
    /// Parses a TOML configuration (missing keys take their defaults);
    /// retired settings are left out ([`Self::from_toml_with_retired`]).
    pub fn from_toml(text: &str) -> Result<Self, toml::de::Error> {
        Ok(Self::from_toml_with_retired(text)?.0)
    }

    /// Parses a TOML configuration, leaving out the settings of retired
    /// experiments ([`crate::retired`]), which it returns; any other key
    /// that is not a setting is an error that names it and its line.
    pub fn from_toml_with_retired(
        text: &str,
    ) -> Result<(Self, Vec<crate::retired::RetiredSetting>), toml::de::Error> {
        let mut root = toml::de::DeTable::parse(text)?;
        let retired = crate::retired::strip(root.get_mut());
        let config = Self::deserialize(toml::de::Deserializer::from(root)).map_err(|mut e| {
            e.set_input(Some(text));
            e
        })?;
        Ok((config, retired))
    }

    /// Reads a configuration file ([`Self::from_toml`]); an error names the
    /// file and, for a file that is not a valid configuration, the key and
    /// its line. Retired settings are ignored with a warning on stderr.
    pub fn load(path: &std::path::Path) -> anyhow::Result<Self> {
        use anyhow::Context;
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read the configuration {}", path.display()))?;
        let (config, retired) = Self::from_toml_with_retired(&text)
            .with_context(|| format!("{}: not a valid training configuration", path.display()))?;
        for line in crate::retired::warnings(&retired) {
            eprintln!("warning: {}: {line}", path.display());
        }
        Ok(config)
    }

    /// The configuration as TOML.
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("the configuration serialises")
    }

    /// Checks values a user could get wrong; returns a message naming the setting.
    pub fn validate(&self) -> Result<(), String> {
        let bad = |what: &str, why: &str| Err(format!("{what}: {why}"));
        if self.iters == 0 {
            return bad("iters", "must be at least 1");
        }
        if self.batch_rays == 0 {
            return bad("batch_rays", "must be at least 1");
        }
        if !(0.0..=1.0).contains(&self.foreground_fraction) {
            return bad("foreground_fraction", "must be in [0, 1]");
        }
        if !(0.0..=1.0).contains(&self.silhouette_fraction) {
            return bad("silhouette_fraction", "must be in [0, 1]");
        }
        if !(self.flash_view_weight.is_finite() && self.flash_view_weight > 0.0) {
            return bad("flash_view_weight", "must be a positive number");
        }
        if self.foreground_fraction + self.silhouette_fraction > 1.0 {
            return bad(
                "silhouette_fraction",
                "foreground_fraction + silhouette_fraction must be at most 1",
            );
        }
        if self.silhouette_fraction > 0.0 && self.silhouette_band == 0 {
            return bad(
                "silhouette_band",
                "must be at least 1 when silhouette_fraction > 0",
            );
        }
        let (loss, optim, model) = (&self.loss, &self.optim, &self.model);
        for (name, v) in [
            ("loss.binary_metallic_from", loss.binary_metallic_from),
            ("loss.binary_metallic_until", loss.binary_metallic_until),
            ("optim.average_from", optim.average_from),
            (
                "model.ambient_flash_gradient_late",
                model.ambient_flash_gradient_late,
            ),
            (
                "model.ambient_flash_gradient_late_from",
                model.ambient_flash_gradient_late_from,
            ),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return bad(name, "must be in [0, 1] (a fraction of the run)");
            }
        }
        let weights = [
            ("loss.color", loss.color),
            ("loss.eikonal", loss.eikonal),
            ("loss.mask", loss.mask),
            ("loss.material_smoothness", loss.material_smoothness),
            ("loss.smoothness_radius", loss.smoothness_radius),
            (
                "loss.material_smoothness_final",
                loss.material_smoothness_final,
            ),
            ("loss.normal_smoothness", loss.normal_smoothness),
            ("loss.normal_smoothness_final", loss.normal_smoothness_final),
            (
                "loss.smoothness_without_masks",
                loss.smoothness_without_masks,
            ),
            ("loss.binary_metallic", loss.binary_metallic),
            ("loss.visual_hull", loss.visual_hull),
            ("optim.lr_grid", optim.lr_grid),
            ("optim.lr_mlp", optim.lr_mlp),
            ("optim.lr_sharpness", optim.lr_sharpness),
            ("optim.lr_gain", optim.lr_gain),
        ]
        .map(|(name, v)| (name.to_string(), v));
        let factors = optim
            .grid_lr_factors
            .named("grid_lr_factors")
            .into_iter()
            .chain(optim.mlp_lr_factors.named("mlp_lr_factors"));
        for (name, v) in weights.into_iter().chain(factors) {
            if !(v.is_finite() && v >= 0.0) {
                return bad(&name, "must be finite and ≥ 0");
            }
        }
        if optim.average_every == 0 {
            return bad("optim.average_every", "must be at least 1");
        }
        if model.init_material.iter().any(|v| !(*v > 0.0 && *v < 1.0)) {
            return bad("model.init_material", "every value must be in (0, 1)");
        }
        if self.sampling.background_samples < 2 {
            return bad("sampling.background_samples", "must be at least 2");
        }
        if !(self.sampling.background_far_radius.is_finite()
            && self.sampling.background_far_radius > 1.0)
        {
            return bad(
                "sampling.background_far_radius",
                "must be finite and > 1 (radii of the unit sphere)",
            );
        }
        if self.sampling.grid_refresh_every == 0 {
            return bad("sampling.grid_refresh_every", "must be at least 1");
        }
        if self.output.log_every == 0 || self.output.checkpoint_every == 0 {
            return bad(
                "output",
                "log_every and checkpoint_every must be at least 1",
            );
        }
        if !(self.output.preview_scale > 0.0 && self.output.preview_scale <= 1.0) {
            return bad("output.preview_scale", "must be in (0, 1]");
        }
        Ok(())
    }
}

/// Parses a duration such as `90s`, `30m`, `1h`, `1h30m` or a plain number of seconds.
pub fn parse_duration(text: &str) -> Result<std::time::Duration, String> {
    let t = text.trim();
    if let Ok(secs) = t.parse::<f64>()
        && secs.is_finite()
        && secs >= 0.0
    {
        return Ok(std::time::Duration::from_secs_f64(secs));
    }
    let mut total = 0.0;
    let mut number = String::new();
    let mut seen_unit = false;
    for ch in t.chars() {
        if ch.is_ascii_digit() || ch == '.' {
            number.push(ch);
            continue;
        }
        let unit = match ch {
            'h' => 3600.0,
            'm' => 60.0,
            's' => 1.0,
            _ => return Err(format!("'{text}': unknown unit '{ch}' (use h, m or s)")),
        };
        let v: f64 = number
            .parse()
            .map_err(|_| format!("'{text}': expected a number before '{ch}'"))?;
        total += v * unit;
        number.clear();
        seen_unit = true;
    }
    if !number.is_empty() || !seen_unit {
        return Err(format!(
            "'{text}': expected a duration such as 90s, 30m or 1h30m"
        ));
    }
    Ok(std::time::Duration::from_secs_f64(total))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn toml_round_trip_and_partial_files() {
        let c = TrainConfig::default();
        assert_eq!(TrainConfig::from_toml(&c.to_toml()).unwrap(), c);
        let partial = TrainConfig::from_toml("iters = 7\n[loss]\neikonal = 0.3\n").unwrap();
        assert_eq!(partial.iters, 7);
        assert_eq!(partial.loss.eikonal, 0.3);
        assert_eq!(partial.loss.mask, 1.0);
        let err = TrainConfig::from_toml("iterz = 7\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("iterz"), "{err}");
    }

    #[test]
    fn load_reads_a_file_and_names_it_in_errors() {
        let dir = tempfile::tempdir().unwrap();
        let good = dir.path().join("good.toml");
        std::fs::write(&good, "iters = 12\n[loss]\neikonal = 0.25\n").unwrap();
        let c = TrainConfig::load(&good).unwrap();
        assert_eq!((c.iters, c.loss.eikonal), (12, 0.25));
        assert_eq!(c.loss.mask, TrainConfig::default().loss.mask);

        let missing = dir.path().join("missing.toml");
        let err = format!("{:#}", TrainConfig::load(&missing).unwrap_err());
        assert!(err.contains("cannot read the configuration"), "{err}");
        assert!(err.contains("missing.toml"), "{err}");

        let bad = dir.path().join("bad.toml");
        std::fs::write(&bad, "iters = 12\n[loss]\neikonall = 0.25\n").unwrap();
        let err = format!("{:#}", TrainConfig::load(&bad).unwrap_err());
        assert!(err.contains("bad.toml"), "{err}");
        assert!(err.contains("eikonall"), "{err}");
        assert!(err.contains("line 3"), "{err}");
    }

    #[test]
    fn a_field_table_may_give_some_keys() {
        let c = TrainConfig::from_toml(
            "[model.ambient]\nhidden = [32]\n[model.sdf]\nfinest_resolution = 512\n",
        )
        .unwrap();
        let d = ModelConfig::default();
        assert_eq!(c.model.ambient.hidden, vec![32]);
        assert_eq!(
            c.model.ambient,
            FieldSize {
                hidden: vec![32],
                ..d.ambient.clone()
            }
        );
        // The SDF's own defaults fill its table (smoothstep, 14 levels),
        // not those of another field or of the type.
        assert_eq!(c.model.sdf.finest_resolution, 512);
        assert_eq!(c.model.sdf.levels, d.sdf.levels);
        assert_eq!(c.model.sdf.interpolation, Interpolation::Smoothstep);
        assert_eq!(c.model.material, d.material);
        // A misspelt key is still an error that names it and its line.
        let err =
            TrainConfig::from_toml("[model]\ninit_radius = 0.4\n[model.ambient]\nlevelz = 4\n")
                .unwrap_err()
                .to_string();
        assert!(err.contains("levelz") && err.contains("line 4"), "{err}");
    }

    /// Keys renamed to the naming rule of schedules still read under their
    /// old names, and are written under the new ones.
    #[test]
    fn renamed_keys_read_under_their_old_names() {
        let old = "[loss]\nbinary_metallic_start = 0.25\nbinary_metallic_end = 0.5\n\
                   [optim]\nfinal_lr_factor = 0.1\n";
        let c = TrainConfig::from_toml(old).unwrap();
        assert_eq!(c.loss.binary_metallic_from, 0.25);
        assert_eq!(c.loss.binary_metallic_until, 0.5);
        assert_eq!(c.optim.lr_factor_final, 0.1);
        let written = c.to_toml();
        assert!(written.contains("binary_metallic_from = 0.25"), "{written}");
        assert!(written.contains("lr_factor_final = 0.1"), "{written}");
        assert!(!written.contains("binary_metallic_start"), "{written}");
        assert_eq!(TrainConfig::from_toml(&written).unwrap(), c);
    }

    #[test]
    fn validation_names_the_setting() {
        let c = TrainConfig {
            foreground_fraction: 1.5,
            ..TrainConfig::default()
        };
        assert!(c.validate().unwrap_err().contains("foreground_fraction"));
        assert!(TrainConfig::default().validate().is_ok());
        // The two shares of a batch cannot add up to more than all of it.
        let c = TrainConfig {
            foreground_fraction: 0.8,
            silhouette_fraction: 0.3,
            ..TrainConfig::default()
        };
        let err = c.validate().unwrap_err();
        assert!(
            err.contains("silhouette_fraction") && err.contains("at most 1"),
            "{err}"
        );
        let c = TrainConfig {
            silhouette_fraction: 0.1,
            silhouette_band: 0,
            ..TrainConfig::default()
        };
        assert!(c.validate().unwrap_err().contains("silhouette_band"));
        // Every schedule's fraction is in [0, 1], and the late ambient
        // gradient's factor too.
        let rejected = |c: &TrainConfig, name: &str| {
            let err = c.validate().unwrap_err();
            err.starts_with(name) && err.contains("[0, 1]")
        };
        type Field = fn(&mut TrainConfig) -> &mut f64;
        let fields: [(&str, Field); 5] = [
            ("loss.binary_metallic_from", |c| {
                &mut c.loss.binary_metallic_from
            }),
            ("loss.binary_metallic_until", |c| {
                &mut c.loss.binary_metallic_until
            }),
            ("optim.average_from", |c| &mut c.optim.average_from),
            ("model.ambient_flash_gradient_late:", |c| {
                &mut c.model.ambient_flash_gradient_late
            }),
            ("model.ambient_flash_gradient_late_from", |c| {
                &mut c.model.ambient_flash_gradient_late_from
            }),
        ];
        for bad in [1.5, -0.1, f64::NAN] {
            for (name, field) in fields {
                let mut c = TrainConfig::default();
                *field(&mut c) = bad;
                assert!(rejected(&c, name), "{name} = {bad}");
            }
        }
        // Weights and learning rates are finite and ≥ 0.
        let mut c = TrainConfig::default();
        c.loss.normal_smoothness = -1.0;
        assert!(c.validate().unwrap_err().contains("loss.normal_smoothness"));
        let mut c = TrainConfig::default();
        c.optim.lr_gain = f64::INFINITY;
        assert!(c.validate().unwrap_err().contains("optim.lr_gain"));
    }

    /// The per-field learning-rate factors read from their own tables,
    /// default to 1, and a negative one is refused by name.
    #[test]
    fn field_learning_rate_factors() {
        let c = TrainConfig::from_toml("[optim.mlp_lr_factors]\nambient = 3\n").unwrap();
        assert_eq!(c.optim.mlp_lr_factors.ambient, 3.0);
        assert_eq!(c.optim.mlp_lr_factors.sdf, 1.0);
        assert_eq!(c.optim.grid_lr_factors, FieldLrFactors::default());
        assert!(c.validate().is_ok());
        let mut bad = TrainConfig::default();
        bad.optim.grid_lr_factors.material = -0.5;
        let err = bad.validate().unwrap_err();
        assert!(err.contains("optim.grid_lr_factors.material"), "{err}");
    }

    #[test]
    fn durations() {
        assert_eq!(parse_duration("90s").unwrap().as_secs(), 90);
        assert_eq!(parse_duration("30m").unwrap().as_secs(), 1800);
        assert_eq!(parse_duration("1h30m").unwrap().as_secs(), 5400);
        assert_eq!(parse_duration("12").unwrap().as_secs(), 12);
        assert!(parse_duration("5x").is_err());
        assert!(parse_duration("m").is_err());
    }
}
