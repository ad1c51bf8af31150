//! The training configuration: every setting with its documented default,
//! read from TOML (`--config FILE`), printed by `--print-config`, and saved
//! into each run folder so that a run can be resumed and re-rendered.

use serde::{Deserialize, Serialize};

pub use crate::smoothness::RelativeDifference;
use wildlight_fields::{Activation, HashGridConfig, Interpolation, SdfFieldConfig};
use wildlight_material::{
    BASE_COLOR, BrdfSettings, CLEARCOAT, CLEARCOAT_GLOSS, DIELECTRIC, METALLIC, PARAM_COUNT,
    ROUGHNESS, SUBSURFACE,
};

/// Everything that defines a training run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrainConfig {
    /// Seed of every random choice (initialisation, rays, jitter).
    pub seed: u64,
    /// Optimisation steps (the learning-rate schedule spans them).
    pub iters: u64,
    /// Rays per step. 2,048 rays pay the per-step costs (Adam over the hash
    /// tables, the priors' fixed point counts) half as often, 15–20 %
    /// more rays per second, and still lost to 1,024 at 30 minutes on the
    /// default scene (docs/benchmark-log.md, session 16).
    pub batch_rays: usize,
    /// Share of the rays drawn from mask foreground pixels (the rest from
    /// the silhouette band and from all pixels).
    pub foreground_fraction: f64,
    /// Share of the rays drawn from the silhouette band: pixels within
    /// `silhouette_band` pixels of a mask edge, on either side, where the
    /// mask loss sees the outline (0 = none).
    pub silhouette_fraction: f64,
    /// Half-width of the silhouette band in pixels.
    pub silhouette_band: u32,
    /// Share of the rays drawn in proportion to a running estimate of the
    /// colour error over tiles of the images (`crate::error_map`), where
    /// the model is most wrong (0 = none). Off by default: at 3,000 steps
    /// on the default capture (seed 0; defaults: mesh 0.00183, base colour
    /// 19.98 dB, novel views 26.75 / 28.92 dB), 0.1 of the batch taken
    /// from the foreground share gave mesh 0.00154, base colour 19.57 dB,
    /// novel views 26.86 / 29.24 dB, and 0.2 gave 0.00162, 19.36 dB,
    /// 26.91 / 29.13 dB: the views and the shape gain a little, base colour
    /// loses more.
    pub error_fraction: f64,
    /// Share of the planned steps after which the error-guided draws start
    /// (0, the default: from the first step). Before it their share of the
    /// batch goes to the foreground draws, while the error map is measured
    /// from the first step, so the draws start from a settled estimate.
    /// At 3,000 steps (seed 0; defaults 25.33 dB, views 27.44 / 29.45 dB)
    /// 0.1 of the batch from 0.8 of the run gave 25.20 dB and 27.53 /
    /// 29.50 dB: a third of the flash views' gain of draws from the start
    /// (session 24) for a seventh of their cost in base colour.
    pub error_from: f64,
    /// Side of the error map's tiles in pixels.
    pub error_tile: u32,
    /// How often a flash image's pixel is drawn against a no-flash image's,
    /// in the foreground, band and uniform draws (1 = alike, the default;
    /// 2 = twice as often), for captures with many more photos of one
    /// kind than of the other. On the default capture (half with the
    /// flash; 3,000 steps, seed 0; 1: base colour 25.08 dB, novel views
    /// 27.38 / 29.36 dB) 2 gave 23.08 dB, 27.50 / 29.16 dB (the steel
    /// darkens along its F0 / roughness ridge) and 0.5 gave 23.73 dB,
    /// 27.05 / 29.23 dB: the even mix stays.
    pub flash_view_weight: f64,
    /// Extra points drawn uniformly in the ball of radius 1.2 for the eikonal term.
    pub eikonal_points: usize,
    /// Loss weights and learning rates.
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
            error_fraction: 0.0,
            error_from: 0.0,
            error_tile: 4,
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

/// Weights of the terms of SPEC §4.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LossConfig {
    /// L1 colour loss weight.
    pub color: f64,
    /// Weight of a squared colour error over the same channels as the L1
    /// term (`crate::loss::add_colour_l2`; the project's addition to SPEC
    /// §4). 0 (the default) turns it off. At 3,000 steps (seed 0) it
    /// lifts the novel views and costs the metals: λ = 10 gave flash /
    /// no-flash views 27.26 / 29.07 dB against 26.71 / 28.77, base colour
    /// 19.56 against 22.50 dB (steel F0 0.29 for 0.75); λ = 3: 27.09 /
    /// 29.14 dB, 19.65 dB; λ = 10 from half way (`color_l2_start` 0.5):
    /// 27.22 / 29.00 dB, 20.21 dB.
    pub color_l2: f64,
    /// When the squared colour term starts, as a fraction of the planned
    /// steps (0, the default: from the first step; 0.5: the second half).
    pub color_l2_start: f64,
    /// Eikonal weight (SPEC §4: 0.1).
    pub eikonal: f64,
    /// Mask binary cross-entropy weight (SPEC §4: 1.0).
    pub mask: f64,
    /// Weight λ of the material smoothness prior (`crate::smoothness`; the
    /// project's addition to SPEC §4): the mean difference of Θ between
    /// surface points and points up to `smoothness_radius` away. 0 turns it
    /// off. 0 → 0.05 was measured on the 30-minute benchmark (an early
    /// model): base colour 15.3 → 17.8 dB, roughness error 0.23 → 0.04,
    /// novel views +0.6 dB. At the current defaults, 3,000 steps, seed 0:
    /// 0.02 / 0.05 / 0.1 / 0.15 gave base colour 19.72 / 21.02 / 22.50 /
    /// 22.40 dB, flash views 26.92 / 26.95 / 26.71 / 26.38 dB (seed 1, 0.05
    /// against 0.1: 20.69 against 21.69 dB, 26.91 against 26.82 dB); the
    /// default is 0.1. Stronger smoothing brightens the metals (steel F0
    /// 0.44 → 0.54 for 0.75) but bleeds the bright glaze into the darker
    /// parts next to it (`smoothness_relative`).
    pub material_smoothness: f64,
    /// Largest offset of the smoothness pairs, per axis (normalized units;
    /// offsets are uniform in ±this). 0.02 by default (0.01 until session
    /// 21): with `material_smoothness_final` 0.3, at 3,000 steps, base
    /// colour 24.99 against 22.91 dB on seed 0, 24.34 against 21.47 dB on
    /// seed 1, 20.79 against 20.90 dB on seed 2, the views
    /// within 0.1 dB: the wider pairs find the metals' roughness and F0,
    /// the weaker prior at the end lets the glaze's dots sharpen again.
    pub smoothness_radius: f64,
    /// The material smoothness prior's weight at the last step, as a
    /// factor of `material_smoothness` (0.3 by default, 1 until session
    /// 21; 1 keeps it constant). From the
    /// end of the warm-up the factor falls from 1 to this value along the
    /// learning rate's cosine, so the prior is at full strength while the
    /// metals separate from the dielectrics and lets the views be fitted
    /// more closely at the end. At 3,000 steps (seed 0) with
    /// `smoothness_radius` 0.01, 0.3 lost base colour (21.13 against
    /// 22.44 dB) for +0.07 / −0.12 dB of novel views; with 0.02 it is what
    /// lets the dots sharpen (see `smoothness_radius`).
    pub material_smoothness_final: f64,
    /// Per-parameter factors w_i of the material smoothness prior (all 1
    /// by default): λ · w_i is parameter i's weight. At 3,000 steps (seed
    /// 0) every unequal set tried lost the metals (metallic 0.03, base
    /// colour 14.3 dB): λ = 0.05 with roughness and metallic ×3, λ = 0.15
    /// with base colour ×1/3, λ = 0.3 with base colour ×1/6; λ = 0.15 with
    /// metallic ×1/3 made the dielectrics rough metals (16.2 dB).
    pub smoothness_factors: SmoothnessFactors,
    /// How the material smoothness prior makes the differences of base
    /// colour, dielectric specular and clearcoat relative: `"pair"` (the
    /// default; each pair by its own sum) or `"batch"` (by the mean over all
    /// pairs, so both sides of a boundary are pushed alike). `"batch"` at
    /// λ = 0.05 or 0.1 (3,000 steps, seed 0) lost the metals: base colour
    /// 14.0 / 14.1 dB.
    pub smoothness_relative: RelativeDifference,
    /// Saturation scale c of the material smoothness prior's differences
    /// (`crate::smoothness`): each enters as c · ln(1 + δ/c), whose push
    /// c / (c + δ) fades across a boundary between two materials, so that
    /// a thin part (the terracotta foot between the brass ring and the
    /// glaze) is not pulled towards its neighbours. 0 (the default) keeps
    /// the L1 difference δ. At 3,000 steps (seed 0, base colour 24.99 dB
    /// without it): 0.05 or 0.15 on every parameter from the first step got
    /// every dielectric right (terracotta metallic 0.02) and made the
    /// metals dark dielectrics (14.1 / 14.2 dB): the L1 pull of the bright
    /// parts' base colour is what makes them metals. 0.05 on roughness and
    /// metallic only (21.67 dB) or metallic only (23.73 dB) let the glazes
    /// drift towards metal; 0.05 on every parameter from half the run
    /// (`smoothness_saturation_start` 0.5) gave 25.18 dB, views +0.13 /
    /// +0.03 dB, terracotta metallic 0.34 against 0.39, and on seed 1
    /// 23.65 against 24.34 dB (the metals darker).
    pub smoothness_saturation: f64,
    /// The share of the planned steps before which the smoothness prior
    /// stays L1 (0, the default: saturated from the first step), so that
    /// the parts can separate under the plain prior first.
    pub smoothness_saturation_start: f64,
    /// The parameters whose differences `smoothness_saturation` saturates,
    /// by their names in `[loss.smoothness_factors]`; all seven by default.
    pub smoothness_saturated_parameters: Vec<String>,
    /// The pairs' offset at the first step (0, the default: always
    /// `smoothness_radius`). From the end of the warm-up the offset falls
    /// from this value to `smoothness_radius` along the learning rate's
    /// cosine, for the material and the normal prior alike, so that the
    /// parts settle under the wide prior and patterns within a part
    /// sharpen under the narrow one.
    pub smoothness_radius_start: f64,
    /// Offset of a second set of smoothness pairs, per axis (normalized
    /// units; 0, the default: none), for the parameters named in
    /// `wide_smoothness_parameters`, which are then compared at this offset
    /// instead of `smoothness_radius` (same λ and factors). Roughness and
    /// metallic change only between parts, base colour also within them
    /// (the glaze's dots): at 3,000 steps (seed 0) `smoothness_radius`
    /// 0.02 for all parameters recovered the metals' roughness and F0
    /// (brass 0.307 for 0.30) and blurred the dots into the glaze, 0.005
    /// kept the dots and darkened the metals. Roughness and metallic at
    /// 0.02 or 0.03 with the rest at 0.01 held every point's metallic at
    /// 0.04: the metals became dark dielectrics (14.5 dB against 22.91).
    pub wide_smoothness_radius: f64,
    /// The parameters compared at `wide_smoothness_radius`, by their names
    /// in `[loss.smoothness_factors]` (`"base_color"`, `"roughness"`,
    /// `"clearcoat_gloss"`, `"subsurface"`, `"metallic"`, `"dielectric"`,
    /// `"clearcoat"`); empty by default.
    pub wide_smoothness_parameters: Vec<String>,
    /// Weight λ of the normal smoothness prior (`crate::normal_smoothness`;
    /// the project's addition to SPEC §4): the mean pseudo-Huber size of a
    /// difference of the unit normals (`normal_difference`) around the same
    /// points as the material prior. 0 turns it off. With the first
    /// difference, measured at 3,000 steps on the default capture with
    /// 64-sample photos: 0 → 0.05 → 0.5 → 2 gave normals 5.5° → 4.7° →
    /// 4.4° → 8.5°, base colour 17.8 → 18.3 → 18.6 → 14.8 dB, novel views
    /// 25.2 / 26.5 → 25.6 / 27.1 → 26.0 / 27.1 → 23.8 / 25.6 dB (against
    /// 1024-sample references) and mesh 0.0022 → 0.0023 → 0.0024 → 0.0063:
    /// much more than 0.5 flattens real detail. The second difference
    /// costs nothing on constant curvature and takes more: at 3,000 steps
    /// on 256-sample photos (seed 0), the first difference at 0.5 against
    /// the second at 0.5 / 2 / 8 gave base colour 19.98 against 20.53 /
    /// 21.02 / 20.73 dB, novel views 26.75 / 28.92 against 26.91 / 29.00,
    /// 26.95 / 28.96 and 26.90 / 28.80 dB, mesh 0.00183 against 0.00172 /
    /// 0.00174 / 0.00173: the default is the second difference at 2.
    pub normal_smoothness: f64,
    /// Largest offset of the normal prior's pairs, per axis (normalized
    /// units; 0, the default: the material prior's `smoothness_radius`).
    /// The normal prior then compares the same random offsets scaled to
    /// this reach, so the material prior can reach across parts while the
    /// normals are compared at a shorter distance, where a crease is not
    /// averaged away. At 3,000 steps (seed 0, against the shared 0.02:
    /// base colour 24.99 dB, novel views 27.35 / 29.14 dB, normals 0.57°
    /// median): 0.01 gave 24.09 dB, 27.45 / 29.27 dB, 0.76°; 0.005 23.15
    /// dB, 27.37 / 29.28 dB, 1.05°: the views gain a little, the materials
    /// lose more.
    pub normal_smoothness_radius: f64,
    /// The normal prior's weight at the last step, as a factor of
    /// `normal_smoothness` (0.3 by default since session 23; 1 keeps it
    /// constant); it falls along the learning rate's cosine as
    /// `material_smoothness_final` does, so creases can sharpen as the run
    /// ends. At 3,000 steps, against 1: seed 0 base colour 24.86 against
    /// 24.99 dB, novel views 27.45 / 29.34 against 27.35 / 29.14 dB, mesh
    /// 0.00179 against 0.00174; seed 1 24.38 against 24.34 dB, 27.39 /
    /// 28.89 against 27.37 / 28.76 dB, 0.00160 against 0.00176. 0.1 (seed
    /// 0): 24.80 dB, 27.36 / 29.40 dB, mesh 0.00192.
    pub normal_smoothness_final: f64,
    /// Relaxes the normal prior where the photo disagrees with the model:
    /// each pair weighs 1 / (1 + (e / e₀)²), e the L1 colour error of the
    /// ray it came from (its three channels, under the colour loss's
    /// saturation rule: a channel where both the prediction and the photo
    /// reach the capture's clipping level counts 0) and e₀ this setting (0, the default: every pair weighs 1). A crease the
    /// smooth surface bridges keeps its rays' error high, and the prior then
    /// stops holding the surface flat there. At 3,000 steps (seeds 0 / 1;
    /// defaults 25.44 / 24.68 dB, views 27.53 / 29.51 and 27.53 / 29.09 dB)
    /// e₀ = 0.1 gave base colour 24.90 / 24.63 dB and novel views 27.80 /
    /// 29.51 and 27.73 / 29.27 dB; e₀ = 0.3 gave 25.24 / 24.92 dB, 27.66 /
    /// 29.43 and 27.60 / 29.16 dB (session 31).
    pub normal_smoothness_relax: f64,
    /// Which difference of the normals the normal prior penalises.
    pub normal_difference: NormalDifference,
    /// Weight λ of the binary-metallic prior (`crate::metallic_prior`; the
    /// project's addition to SPEC §4): the mean m (1 − m) of the metallic
    /// value at the surface points. 0 turns it off; the default, 0.3, is a
    /// push from 0.5 to 0.7 of the run on the metallic readout alone
    /// (`binary_metallic_readout_only`, session 30). At 0.1
    /// from the first step (3,000 steps, seed 0) it drove the metals to
    /// metallic 0 with the terracotta (base colour 14.3 against 21.0 dB):
    /// every point starts at metallic 0.05, nearer to 0. From step 1,500
    /// (`binary_metallic_start` 0.5) at 0.1 it gave 20.60 dB: right
    /// terracotta, but the glazes' small metallic went to 0 and the brass
    /// darkened. For 30 minutes (seed 0, from about half the run) it lifted
    /// the terracotta from 13.8 to 25.1 dB and dropped the brass from 21.9
    /// to 14.7 dB: base colour 24.09 against 24.94 dB.
    pub binary_metallic: f64,
    /// When the binary-metallic prior starts, as a fraction of the planned
    /// steps (0: from the first step; 0.5, the default: the second half).
    /// Later, the metals have had time to climb past one half before the
    /// prior pushes each point to its nearer end.
    pub binary_metallic_start: f64,
    /// When the binary-metallic prior stops, as a fraction of the planned
    /// steps (1: it stays on to the end; the default 0.7). Before 1 it is a
    /// push that is then released: a part that the push carried into the
    /// dielectric basin stays there only if the photos agree. At 3,000
    /// steps (seed 0, session 28's defaults 25.33 dB) λ 0.3 from 0.5 to 0.7 left the
    /// terracotta a dielectric to the end (metallic 0.00, base colour
    /// 0.52 0.30 0.21 for 0.50 0.28 0.18) but the metals darker (21.07 dB
    /// with the ceiling at 0.5, the brass at metallic 0.72; 23.85 dB
    /// two-sided, the brass at 0.97 with base colour 0.62 0.43 0.27 for
    /// 0.85 0.60 0.30), and they did not recover after the release
    /// (docs/benchmark-log.md, session 28).
    pub binary_metallic_end: f64,
    /// Hash-table levels of at least this many cells per axis are the only
    /// parameters of the material field that the binary-metallic prior
    /// moves (0, the default: every level and the network; read only when
    /// `binary_metallic_readout_only` is false). A local push:
    /// the network and the coarse levels, shared by a part and its
    /// neighbours, do not carry the metals along with the part pushed.
    /// At 3,000 steps (seed 0, λ 0.3 from 0.5 to 0.7 of the run) levels of
    /// 100 cells or more did not move the terracotta (metallic 0.37 for
    /// 0.38 without the prior), nor did λ 1 on levels of 50 or more; every
    /// level without the network moved it to 0.13 and darkened the metals
    /// (24.42 against 25.33 dB): the terracotta and the brass beside it
    /// share the coarse levels.
    pub binary_metallic_min_resolution: u32,
    /// The binary-metallic prior moves only the metallic row of the
    /// material network's last layer (true, the default since session 30;
    /// false: every parameter, or the levels of
    /// `binary_metallic_min_resolution`). The push can
    /// then not touch base colour or roughness anywhere. At 3,000 steps
    /// (λ 0.3 from 0.5 to 0.7 of the run) it takes the glazes' small
    /// metallic (0.03–0.08) to 0.00–0.04 but leaves the terracotta a
    /// partial metal (0.23–0.36): base colour +0.11 / +0.20 / +0.02 dB and
    /// flash views +0.09 / +0.12 / +0.16 dB on seeds 0 / 1 / 2. From 0.25
    /// of the run base colour swung from +0.29 to −0.76 dB; from 0.1 the
    /// metals never turned (docs/benchmark-log.md, session 29).
    pub binary_metallic_readout_only: bool,
    /// Weight μ of the metal anchor (`crate::metallic_prior::MetalAnchor`)
    /// while the binary-metallic prior pushes: the points that were metals
    /// when the push began keep their base colour and roughness of then
    /// (0, the default: not held). With the push from 0.75 to 0.9 of the
    /// run (λ 0.3, 3,000 steps, seed 0) μ 30 gave 25.56 against 25.33 dB
    /// (24.89 dB without the anchor): terracotta metallic 0.15, the metals
    /// nearly as bright as without the push, but the flash views 0.13 dB
    /// lower (the terracotta, now a dielectric, keeps the glazes'
    /// roughness 0.41 for its 0.85); on seed 1 24.50 against 24.48 dB,
    /// the flash views 0.17 dB lower. From half the run μ 3 or 30 held
    /// nothing (24.11 / 24.16 dB): the metals are darker then than at the
    /// end of a run without the push, and the anchor keeps them so.
    pub binary_metallic_anchor: f64,
    /// The binary-metallic prior leaves out the points whose metallic
    /// value is above this (1, the default: none left out; 0.5: it only
    /// pushes partial metals down to 0, not metals up to 1). At 0.5 (3,000
    /// steps, seed 0, λ 0.1 from half the run) the metals fell anyway, the
    /// brass from metallic 0.95 to 0.90 (0.60 at λ 0.3) and from 17.6 to
    /// 13.2 dB: the field that pushes the terracotta down carries its
    /// neighbours with it, so the ceiling does not spare them.
    pub binary_metallic_ceiling: f64,
    /// Weight λ of the visual-hull prior (`crate::visual_hull`; the
    /// project's addition to SPEC §4): the mean max(0, δ − φ) at points
    /// outside the masks' visual hull, in the occupied cells of the
    /// occupancy grid, so that no floater grows away from the object. 0
    /// turns it off; it needs masks. At 1 (the default) the 30-minute
    /// benchmark's seed-2 run kept one mesh component where it had grown a
    /// floater beside the knob (mesh 0.00163 against 0.00338, novel views
    /// 27.49 / 29.99 against 27.01 / 29.45 dB, base colour 23.32 against
    /// 23.15 dB); at 3,000 steps (seed 0) it changed nothing measurable
    /// (22.44 / 26.72 / 28.92 dB against 22.50 / 26.71 / 28.77).
    pub visual_hull: f64,
    /// Pixels by which each mask is dilated before it carves the hull
    /// (room for masks a pixel or two off at the outline).
    pub visual_hull_dilation: u32,
    /// Points drawn per step for the visual-hull prior.
    pub visual_hull_points: usize,
}

/// Per-parameter factors of the material smoothness prior
/// (`crate::smoothness`), `[loss.smoothness_factors]` in a config file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SmoothnessFactors {
    /// Factor of the three base colour channels.
    pub base_color: f64,
    /// Factor of the roughness.
    pub roughness: f64,
    /// Factor of the clearcoat gloss.
    pub clearcoat_gloss: f64,
    /// Factor of the subsurface weight.
    pub subsurface: f64,
    /// Factor of the metallic weight.
    pub metallic: f64,
    /// Factor of the dielectric specular weight.
    pub dielectric: f64,
    /// Factor of the clearcoat weight.
    pub clearcoat: f64,
}

impl Default for SmoothnessFactors {
    fn default() -> Self {
        Self {
            base_color: 1.0,
            roughness: 1.0,
            clearcoat_gloss: 1.0,
            subsurface: 1.0,
            metallic: 1.0,
            dielectric: 1.0,
            clearcoat: 1.0,
        }
    }
}

impl SmoothnessFactors {
    /// The names of the factors, as in `[loss.smoothness_factors]`.
    pub const NAMES: [&'static str; 7] = [
        "base_color",
        "roughness",
        "clearcoat_gloss",
        "subsurface",
        "metallic",
        "dielectric",
        "clearcoat",
    ];

    /// `value` at the Θ indices of the parameters called `names`, 0
    /// elsewhere (unknown names are left out; validation refuses them).
    pub fn scales_of(names: &[String], value: f64) -> [f64; PARAM_COUNT] {
        let mut out = [0.0; PARAM_COUNT];
        for range in names.iter().filter_map(|n| Self::indices(n)) {
            out[range].fill(value);
        }
        out
    }

    /// The factors in Θ's order (`wildlight_material::PARAM_NAMES`).
    pub fn per_parameter(&self) -> [f64; PARAM_COUNT] {
        let mut w = [0.0; PARAM_COUNT];
        w[BASE_COLOR..BASE_COLOR + 3].fill(self.base_color);
        w[ROUGHNESS] = self.roughness;
        w[CLEARCOAT_GLOSS] = self.clearcoat_gloss;
        w[SUBSURFACE] = self.subsurface;
        w[METALLIC] = self.metallic;
        w[DIELECTRIC] = self.dielectric;
        w[CLEARCOAT] = self.clearcoat;
        w
    }

    /// The Θ indices of the factor called `name` (a field of this struct),
    /// or `None` for an unknown name.
    pub fn indices(name: &str) -> Option<std::ops::Range<usize>> {
        let one = |i: usize| Some(i..i + 1);
        match name {
            "base_color" => Some(BASE_COLOR..BASE_COLOR + 3),
            "roughness" => one(ROUGHNESS),
            "clearcoat_gloss" => one(CLEARCOAT_GLOSS),
            "subsurface" => one(SUBSURFACE),
            "metallic" => one(METALLIC),
            "dielectric" => one(DIELECTRIC),
            "clearcoat" => one(CLEARCOAT),
            _ => None,
        }
    }

    /// The factors split between the two sets of smoothness pairs: (the
    /// pairs at `smoothness_radius`, the pairs at `wide_smoothness_radius`),
    /// each in Θ's order, the parameters named in `wide` moved to the
    /// second (unknown names are left out; validation refuses them).
    pub fn split(&self, wide: &[String]) -> ([f64; PARAM_COUNT], [f64; PARAM_COUNT]) {
        let all = self.per_parameter();
        let mut near = all;
        let mut far = [0.0; PARAM_COUNT];
        for range in wide.iter().filter_map(|n| Self::indices(n)) {
            for i in range {
                far[i] = all[i];
                near[i] = 0.0;
            }
        }
        (near, far)
    }

    /// (name, value) of every factor, for validation.
    fn named(&self) -> [(&'static str, f64); 7] {
        [
            ("loss.smoothness_factors.base_color", self.base_color),
            ("loss.smoothness_factors.roughness", self.roughness),
            (
                "loss.smoothness_factors.clearcoat_gloss",
                self.clearcoat_gloss,
            ),
            ("loss.smoothness_factors.subsurface", self.subsurface),
            ("loss.smoothness_factors.metallic", self.metallic),
            ("loss.smoothness_factors.dielectric", self.dielectric),
            ("loss.smoothness_factors.clearcoat", self.clearcoat),
        ]
    }
}

/// The difference of the unit normals that the normal smoothness prior
/// (`crate::normal_smoothness`) penalises.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NormalDifference {
    /// n(x + ε) − n(x): any turning of the normal costs, curvature too, so
    /// a small tightly curved part (a handle, a knob) is pulled flatter.
    First,
    /// The part of n(x + ε) + n(x − ε) − 2 n(x) tangent to the surface at
    /// x: zero where the surface bends at a constant rate along ±ε (a
    /// sphere, a cylinder), so only changes of curvature (speckle, bumps,
    /// creases) cost.
    Second,
}

impl Default for LossConfig {
    fn default() -> Self {
        Self {
            color: 1.0,
            color_l2: 0.0,
            color_l2_start: 0.0,
            eikonal: 0.1,
            mask: 1.0,
            material_smoothness: 0.1,
            smoothness_radius: 0.02,
            material_smoothness_final: 0.3,
            smoothness_factors: SmoothnessFactors::default(),
            smoothness_relative: RelativeDifference::Pair,
            smoothness_saturation: 0.0,
            smoothness_saturation_start: 0.0,
            smoothness_saturated_parameters: SmoothnessFactors::NAMES
                .iter()
                .map(|n| n.to_string())
                .collect(),
            smoothness_radius_start: 0.0,
            wide_smoothness_radius: 0.0,
            wide_smoothness_parameters: Vec::new(),
            normal_smoothness: 2.0,
            normal_smoothness_radius: 0.0,
            normal_smoothness_final: 0.3,
            normal_smoothness_relax: 0.0,
            normal_difference: NormalDifference::Second,
            binary_metallic: 0.3,
            binary_metallic_start: 0.5,
            binary_metallic_end: 0.7,
            binary_metallic_min_resolution: 0,
            binary_metallic_readout_only: true,
            binary_metallic_anchor: 0.0,
            binary_metallic_ceiling: 1.0,
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
    /// Learning rate of the hash tables.
    pub lr_grid: f64,
    /// Learning rate of the MLPs.
    pub lr_mlp: f64,
    /// Per-field factors on `lr_grid` (`[optim.grid_lr_factors]`).
    pub grid_lr_factors: FieldLrFactors,
    /// Per-field factors on `lr_mlp` (`[optim.mlp_lr_factors]`).
    pub mlp_lr_factors: FieldLrFactors,
    /// Learning rate of the NeuS sharpness parameter v (s = exp(10 v)).
    pub lr_sharpness: f64,
    /// Learning rate of the log flash gain.
    pub lr_gain: f64,
    /// Linear warm-up steps.
    pub warmup_steps: u64,
    /// Learning-rate factor reached at the last step (cosine decay).
    pub final_lr_factor: f64,
    /// Steps over which the NeuS cos-annealing ratio rises from 0 to 1.
    pub cos_anneal_steps: u64,
    /// Hash levels active at the start (coarse-to-fine; 0 = all from the start).
    pub c2f_start_levels: usize,
    /// Steps between activating one more level.
    pub c2f_steps_per_level: u64,
    /// Share of the planned steps during which every point's metallic
    /// value is held at its start (`model.init_material`'s), with no
    /// gradient, so that roughness and base colour settle on dielectric
    /// explanations first (0, the default: never held). At 3,000 steps
    /// (seed 0) 0.5 made the terracotta dielectric (metallic 0.32 → 0.04)
    /// and kept the metals dielectric too (metallic 0.07, base colour 0.07:
    /// 14.54 dB against 22.91); 0.1 let the metals turn (0.94–0.97) but
    /// darker, and held the terracotta only half way (0.21): 21.67 dB.
    pub metallic_hold: f64,
    /// Share of the planned steps after which the parameters are averaged
    /// (`crate::averaging`): a finished run renders and exports the mean of
    /// its parameters from this point on, taken every `average_every`
    /// steps (by default the last 10 %, every 5 steps); 1 never averages.
    /// Training itself is unchanged (the live
    /// parameters go on as before), so the two compare on one run: at
    /// 3,000 steps (seed 0) the mean of the last 10 % every 5 steps scored
    /// mesh 0.00163 against 0.00177, normals 0.51° against 0.65° (median),
    /// base colour 25.12 against 25.08 dB, novel views 27.51 / 29.40 against
    /// 27.38 / 29.36 dB; the last 30 % every 10 steps 0.00151, 0.52°,
    /// 24.91 dB, 27.48 / 29.31 dB (the material still drifts that early).
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
            final_lr_factor: 0.05,
            cos_anneal_steps: 500,
            c2f_start_levels: 4,
            c2f_steps_per_level: 100,
            metallic_hold: 0.0,
            average_from: 0.9,
            average_every: 5,
        }
    }
}

/// A factor on a learning rate for each of the model's fields, so one
/// field can learn faster or slower than the others. 1 everywhere by
/// default. Measured at 3,000 steps on the default capture (seed 0; base
/// colour, flash / no-flash views against the defaults' 22.91 dB, 27.36 /
/// 29.24 dB): the ambient MLP at ×3 gave 21.29 dB, 27.86 / 29.74 dB; the
/// SDF MLP at ×3 22.05 dB, 27.34 / 29.13 dB; the material MLP at ×3 21.90
/// dB, 27.34 / 29.11 dB; the material grid at ×2 22.20 dB, 27.26 / 29.17
/// dB.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FieldLrFactors {
    /// The signed distance field.
    pub sdf: f64,
    /// The material field.
    pub material: f64,
    /// The ambient radiance field (and its specular part, when present).
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

/// A hash-grid + MLP field's size. In a TOML file a field's table may give
/// any of its keys: the others keep that field's defaults (an optional
/// field such as `model.metallic_field` has none and is given whole).
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
    ambient_specular_table => ambient_specular,
    ambient_room_table => ambient_room,
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

/// The three fields of the model (SPEC §2).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ModelConfig {
    /// The SDF field.
    #[serde(deserialize_with = "sdf_table")]
    pub sdf: FieldSize,
    /// Geometry features the SDF field outputs next to φ.
    pub geometry_features: usize,
    /// Radius of the initial sphere.
    pub init_radius: f32,
    /// The material field (9 parameters through a sigmoid).
    #[serde(deserialize_with = "material_table")]
    pub material: FieldSize,
    /// Metallic from a field of its own, of this size (absent, the
    /// default: from the material field with the other eight). The
    /// material field's metallic output then goes unused, and the
    /// binary-metallic prior (`loss.binary_metallic`) moves only this
    /// field, never base colour or roughness (`crate::material_field`).
    /// Not better on the default scene (3,000 steps, seed 0, a field of 8
    /// levels of 2^16 entries, 16 to 512 cells, one hidden layer of 16):
    /// base colour 21.45 against 25.33 dB, the terracotta more metallic
    /// (0.52) and the metals darker; with the binary-metallic prior from
    /// half the run 20.28 dB (the terracotta pushed to metallic 0.97).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub metallic_field: Option<FieldSize>,
    /// The ambient radiance field.
    #[serde(deserialize_with = "ambient_table")]
    pub ambient: FieldSize,
    /// Initial NeuS sharpness parameter v (s = exp(10 v)).
    pub init_sharpness: f32,
    /// Initial log flash gain.
    pub init_log_gain: f32,
    /// Material model settings (clearcoat Fresnel).
    pub brdf: BrdfSettings,
    /// The material parameters Θ the field starts at, in SPEC §3 order
    /// (base colour RGB, roughness, clearcoat gloss, subsurface, metallic,
    /// dielectric, clearcoat), each in (0, 1): the output bias of the
    /// material network is set to their logits. Starting metallic,
    /// subsurface and clearcoat low encodes the prior that most surfaces are
    /// plain dielectrics; the flash photos must then earn the other lobes.
    /// Starting the clearcoat at 0.5 and its gloss at 0.8 (3,000 steps,
    /// seed 0) ended at 0.57 / 0.79 on every part, metals included, and
    /// raised the glazes' roughness to 0.55 (0.4): base colour 21.98 dB
    /// against 22.91, flash views 27.28 against 27.36 dB.
    pub init_material: [f32; 9],
    /// Whether the colour loss of the ambient term also trains the material
    /// field through the ambient network's Θ input. Off, Θ is explained by
    /// the flash term alone (SPEC §2 gives the ambient field Θ as an input;
    /// it says nothing about its gradient).
    pub ambient_trains_material: bool,
    /// The factor on the gradient that the flash photos send to the ambient
    /// term, in [0, 1]. At 0 the ambient term of a flash photo is taken as
    /// given: the ambient fields learn from the no-flash photos alone, so
    /// what the flash adds to a pixel must be explained by the flash term
    /// (the NeuS weights still learn from every photo). Measured at 3,000
    /// steps on the default capture (session 20): 0 raised the aligned base
    /// colour by 0.61 / 0.81 dB on seeds 0 / 1 (the glazes, the steel and
    /// the brass; not the terracotta) and lowered the novel views by 0.57 /
    /// 0.27 and 0.67 / 0.43 dB (flash / no flash); 0.3 gave neither. The
    /// default, 1, keeps the views; `ambient_flash_gradient_late` takes
    /// over for the end of the run.
    pub ambient_flash_gradient: f64,
    /// The factor on the flash photos' ambient gradient from
    /// `ambient_flash_gradient_late_from` × the planned steps on (rounded up),
    /// in [0, 1] (0 by default since session 26); `ambient_flash_gradient`
    /// before. Late in a run the ambient fields have learnt the room, and at 0
    /// what the flash adds to a photo must be explained by the flash term
    /// alone. Against 1 throughout, each pair the same run up to the switch at
    /// 0.8 of the run: at 3,000 steps base colour 25.33 against 25.12 dB on
    /// seed 0, 24.48 against 24.32 dB on seed 1 and 22.20 against 22.11 dB on
    /// seed 2, novel views 27.44 / 29.45 against 27.51 / 29.40 dB, 27.41 /
    /// 29.10 against 27.47 / 29.06 dB and 27.41 / 29.25 against 27.47 / 29.21
    /// dB (flash / no flash); over the last 4,894 of 14,026 steps (seed 0, both
    /// resumed from the 20-minute snapshot of a 30-minute run) 24.65 against
    /// 24.42 dB, 28.38 / 30.41 against 28.31 / 30.28 dB, mesh 0.00152 against
    /// 0.00150. From 0.6 of the run (3,000 steps, seed 0): 25.43 dB, 27.32 /
    /// 29.39 dB.
    pub ambient_flash_gradient_late: f64,
    /// The share of the planned steps after which
    /// `ambient_flash_gradient_late` applies (0.8 by default; 1: never).
    pub ambient_flash_gradient_late_from: f64,
    /// Which direction the ambient field sees in its spherical-harmonics
    /// input.
    pub ambient_direction: AmbientDirection,
    /// How the ambient term is formed from its fields and Θ. The default,
    /// [`AmbientModel::NeuralRoom`], measured against
    /// [`AmbientModel::Neural`] on the default capture: +0.25 / +0.36 dB
    /// of novel views (flash / no flash) at 3,000 steps, and after the
    /// 30-minute benchmark 27.77 / 30.29 dB against 27.54 / 29.93 dB, base
    /// colour 20.06 against 19.73 dB, for about 8 % more time per step.
    pub ambient_model: AmbientModel,
    /// Spherical-harmonics bands of the ambient direction input, 1–4 (band
    /// l has 2l + 1 functions; 4 bands are the 16 inputs of the encoding).
    /// The inputs of the bands above are held at zero. Fewer bands give
    /// the ambient field less view dependence to fit the noise of single
    /// photos with. Measured at 3,000 steps on the default capture (with
    /// the normal prior at 0.5): 2 bands lost 1.1 / 1.7 dB of novel views
    /// (flash / no flash) against 4, so 4 stays the default.
    pub ambient_sh_bands: usize,
    /// The room-reflection field E_s of [`AmbientModel::DiffuseSpecular`]
    /// (unused by the other forms). Its hash grid should stay
    /// coarse: one room is reflected by every part of the object, and a
    /// field that could vary from one part to the next would let a dark
    /// dielectric pass for a metal again.
    #[serde(deserialize_with = "ambient_specular_table")]
    pub ambient_specular: FieldSize,
    /// The reflected-direction field of [`AmbientModel::NeuralRoom`]: its
    /// hash grid encodes ω as a point of the unit sphere, so its finest
    /// resolution sets the sharpest reflection it can hold (2/128 of the
    /// cube ≈ 0.9°); `hidden = []` makes its output a linear map of the
    /// encoding. A finer room (7 levels up to 256, 2¹⁷ entries) gained base
    /// colour and lost both kinds of novel view after the 30-minute
    /// benchmark (seed 2): 23.78 against 23.35 dB, views 27.57 / 30.09
    /// against 27.97 / 30.24 dB (flash / no flash), so the default stays.
    #[serde(deserialize_with = "ambient_room_table")]
    pub ambient_room: FieldSize,
}

/// The form of the ambient term a_k (SPEC §2 names its inputs: geometry
/// features, normal, view direction, Θ; it leaves the form open).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AmbientModel {
    /// One network of all the inputs gives the RGB radiance.
    Neural,
    /// A diffuse part and a mirrored-room part, tinted by Θ:
    /// a = (1 − m)·base ⊙ E_d + F0 ⊙ E_s, where E_d ≥ 0 (the `ambient`
    /// field of the features and the normal) is the irradiance the diffuse
    /// lobe sees, E_s ≥ 0 (the `ambient_specular` field of the direction
    /// and the roughness, on a coarse grid) is the room seen in the mirror
    /// direction, and F0 = m·base + 0.08·(1 − m)·sp + 0.25·F_c·cc is the
    /// normal-incidence reflectance of SPEC §3's specular lobes. The same
    /// room is then reflected by every part of the object, so a part that
    /// mirrors it brightly must be a metal (or coated), not a dark
    /// dielectric: the ambient photos now constrain Θ, not just a free
    /// network.
    DiffuseSpecular,
    /// [`AmbientModel::Neural`] with [`ROOM_FEATURES`] more inputs: a field
    /// of the reflected direction ω alone (the `ambient_room` hash grid
    /// over the unit sphere, shared by every point of the object). The
    /// spherical harmonics of ω hold only a blurred room; a sharp
    /// reflection (a window, a lamp, the sun in a glaze) needs a finer
    /// encoding, and one the whole object shares, so that a reflection
    /// seen at one point is where a new view expects it at another.
    NeuralRoom,
}

/// Outputs of the reflected-direction field of [`AmbientModel::NeuralRoom`].
pub const ROOM_FEATURES: usize = 8;

/// The direction the ambient radiance field is given (SPEC §2 leaves the
/// choice open: "view direction").
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum AmbientDirection {
    /// The camera ray's direction.
    View,
    /// The view direction mirrored about the surface normal, ω_r = d − 2(d·n)n
    /// (Ref-NeRF's parameterisation): reflections of the room then vary
    /// smoothly with it, which low-order harmonics can follow.
    Reflected,
}

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
            metallic_field: None,
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
            ambient_flash_gradient: 1.0,
            ambient_flash_gradient_late: 0.0,
            ambient_flash_gradient_late_from: 0.8,
            ambient_direction: AmbientDirection::Reflected,
            ambient_model: AmbientModel::NeuralRoom,
            ambient_sh_bands: 4,
            ambient_room: FieldSize {
                levels: 6,
                features_per_level: 2,
                log2_table_size: 16,
                base_resolution: 4,
                finest_resolution: 128,
                hidden: vec![],
                interpolation: Default::default(),
            },
            ambient_specular: FieldSize {
                levels: 3,
                features_per_level: 2,
                log2_table_size: 12,
                base_resolution: 2,
                finest_resolution: 8,
                hidden: vec![64],
                interpolation: Default::default(),
            },
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
    /// Steps between occupancy grid refreshes.
    pub grid_refresh_every: u64,
    /// Coarse sections per grid cell.
    pub coarse_steps_per_cell: f32,
    /// Most coarse sections per ray.
    pub max_coarse: usize,
    /// Importance (fine) samples per ray. Fewer samples make a step
    /// cheaper at the same quality: at 3,000 steps on the default capture
    /// (seed 0, 2 threads) 16 / 8 / 4 gave base colour 22.44 / 22.38 /
    /// 22.09 dB, novel views 26.72 / 28.92, 26.80 / 28.97 and 26.75 /
    /// 28.87 dB (flash / no flash), mesh 0.00173 / 0.00177 / 0.00166, in
    /// 344 / 259 / 233 s of training (about 17,700 / 10,400 / 6,700
    /// samples per 1,024-ray batch at the end): the default is 8.
    pub fine_samples: usize,
}

impl Default for SamplingConfig {
    fn default() -> Self {
        Self {
            grid_resolution: 64,
            grid_refresh_every: 16,
            coarse_steps_per_cell: 2.0,
            max_coarse: 48,
            fine_samples: 8,
        }
    }
}

/// What a run writes, and how often.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OutputConfig {
    /// Steps between metrics lines.
    pub log_every: u64,
    /// Steps between preview images (0 = none).
    pub preview_every: u64,
    /// Steps between checkpoints (a checkpoint is also written at the end).
    pub checkpoint_every: u64,
    /// Preview images are rendered at this fraction of the capture's resolution.
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
    /// Parses a TOML configuration (missing keys take their defaults).
    pub fn from_toml(text: &str) -> Result<Self, toml::de::Error> {
        toml::from_str(text)
    }

    /// Reads a configuration file ([`Self::from_toml`]); an error names the
    /// file and, for a file that is not a valid configuration, the key and
    /// its line.
    pub fn load(path: &std::path::Path) -> anyhow::Result<Self> {
        use anyhow::Context;
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read the configuration {}", path.display()))?;
        Self::from_toml(&text)
            .with_context(|| format!("{}: not a valid training configuration", path.display()))
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
        if !(0.0..=1.0).contains(&self.error_fraction) {
            return bad("error_fraction", "must be in [0, 1]");
        }
        if !(self.flash_view_weight.is_finite() && self.flash_view_weight > 0.0) {
            return bad("flash_view_weight", "must be a positive number");
        }
        if self.foreground_fraction + self.silhouette_fraction + self.error_fraction > 1.0 {
            return bad(
                "silhouette_fraction",
                "foreground_fraction + silhouette_fraction + error_fraction must be at most 1",
            );
        }
        for (name, v) in [
            ("error_from", self.error_from),
            ("loss.color_l2_start", self.loss.color_l2_start),
            (
                "loss.binary_metallic_start",
                self.loss.binary_metallic_start,
            ),
            (
                "loss.binary_metallic_ceiling",
                self.loss.binary_metallic_ceiling,
            ),
            ("loss.binary_metallic_end", self.loss.binary_metallic_end),
            ("optim.metallic_hold", self.optim.metallic_hold),
            ("optim.average_from", self.optim.average_from),
            (
                "loss.smoothness_saturation_start",
                self.loss.smoothness_saturation_start,
            ),
            (
                "model.ambient_flash_gradient_late_from",
                self.model.ambient_flash_gradient_late_from,
            ),
        ] {
            if v > 1.0 {
                return bad(name, "must be a fraction of the run, at most 1");
            }
        }
        if self.optim.average_every == 0 {
            return bad("optim.average_every", "must be at least 1");
        }
        if self.error_fraction > 0.0 && self.error_tile == 0 {
            return bad("error_tile", "must be at least 1 when error_fraction > 0");
        }
        if self.silhouette_fraction > 0.0 && self.silhouette_band == 0 {
            return bad(
                "silhouette_band",
                "must be at least 1 when silhouette_fraction > 0",
            );
        }
        for (name, v) in [
            ("loss.color", self.loss.color),
            ("loss.color_l2", self.loss.color_l2),
            ("loss.color_l2_start", self.loss.color_l2_start),
            (
                "loss.binary_metallic_start",
                self.loss.binary_metallic_start,
            ),
            ("loss.binary_metallic_end", self.loss.binary_metallic_end),
            ("loss.eikonal", self.loss.eikonal),
            ("loss.mask", self.loss.mask),
            ("loss.material_smoothness", self.loss.material_smoothness),
            ("loss.smoothness_radius", self.loss.smoothness_radius),
            (
                "loss.smoothness_saturation",
                self.loss.smoothness_saturation,
            ),
            (
                "loss.smoothness_saturation_start",
                self.loss.smoothness_saturation_start,
            ),
            (
                "loss.wide_smoothness_radius",
                self.loss.wide_smoothness_radius,
            ),
            (
                "loss.smoothness_radius_start",
                self.loss.smoothness_radius_start,
            ),
            (
                "loss.material_smoothness_final",
                self.loss.material_smoothness_final,
            ),
            ("loss.normal_smoothness", self.loss.normal_smoothness),
            (
                "loss.normal_smoothness_radius",
                self.loss.normal_smoothness_radius,
            ),
            (
                "loss.normal_smoothness_final",
                self.loss.normal_smoothness_final,
            ),
            (
                "loss.normal_smoothness_relax",
                self.loss.normal_smoothness_relax,
            ),
            ("loss.binary_metallic", self.loss.binary_metallic),
            (
                "loss.binary_metallic_ceiling",
                self.loss.binary_metallic_ceiling,
            ),
            ("error_from", self.error_from),
            ("loss.visual_hull", self.loss.visual_hull),
            ("optim.metallic_hold", self.optim.metallic_hold),
            ("optim.average_from", self.optim.average_from),
            (
                "model.ambient_flash_gradient_late_from",
                self.model.ambient_flash_gradient_late_from,
            ),
        ]
        .into_iter()
        .chain(self.loss.smoothness_factors.named())
        {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, "must be finite and ≥ 0");
            }
        }
        for (setting, names) in [
            (
                "loss.wide_smoothness_parameters",
                &self.loss.wide_smoothness_parameters,
            ),
            (
                "loss.smoothness_saturated_parameters",
                &self.loss.smoothness_saturated_parameters,
            ),
        ] {
            if let Some(name) = names
                .iter()
                .find(|n| SmoothnessFactors::indices(n).is_none())
            {
                return bad(
                    setting,
                    &format!(
                        "unknown parameter {name:?} (use the names of [loss.smoothness_factors])"
                    ),
                );
            }
        }
        if !self.loss.wide_smoothness_parameters.is_empty()
            && self.loss.wide_smoothness_radius == 0.0
        {
            return bad(
                "loss.wide_smoothness_parameters",
                "names parameters but loss.wide_smoothness_radius is 0",
            );
        }
        for (name, v) in [
            ("optim.lr_grid", self.optim.lr_grid),
            ("optim.lr_mlp", self.optim.lr_mlp),
            ("optim.lr_sharpness", self.optim.lr_sharpness),
            ("optim.lr_gain", self.optim.lr_gain),
            ("optim.grid_lr_factors.sdf", self.optim.grid_lr_factors.sdf),
            (
                "optim.grid_lr_factors.material",
                self.optim.grid_lr_factors.material,
            ),
            (
                "optim.grid_lr_factors.ambient",
                self.optim.grid_lr_factors.ambient,
            ),
            ("optim.mlp_lr_factors.sdf", self.optim.mlp_lr_factors.sdf),
            (
                "optim.mlp_lr_factors.material",
                self.optim.mlp_lr_factors.material,
            ),
            (
                "optim.mlp_lr_factors.ambient",
                self.optim.mlp_lr_factors.ambient,
            ),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(name, "must be finite and ≥ 0");
            }
        }
        if self
            .model
            .init_material
            .iter()
            .any(|v| !(*v > 0.0 && *v < 1.0))
        {
            return bad("model.init_material", "every value must be in (0, 1)");
        }
        for (name, v) in [
            (
                "model.ambient_flash_gradient",
                self.model.ambient_flash_gradient,
            ),
            (
                "model.ambient_flash_gradient_late",
                self.model.ambient_flash_gradient_late,
            ),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return bad(name, "must be in [0, 1]");
            }
        }
        if !(1..=4).contains(&self.model.ambient_sh_bands) {
            return bad("model.ambient_sh_bands", "must be 1, 2, 3 or 4");
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
        // The error share counts towards the whole batch too, and needs tiles.
        let c = TrainConfig {
            error_fraction: 0.2,
            ..TrainConfig::default()
        };
        assert!(c.validate().unwrap_err().contains("at most 1"));
        let c = TrainConfig {
            foreground_fraction: 0.5,
            error_fraction: 0.2,
            error_tile: 0,
            ..TrainConfig::default()
        };
        assert!(c.validate().unwrap_err().contains("error_tile"));
        let c = TrainConfig {
            error_fraction: 1.5,
            ..TrainConfig::default()
        };
        assert!(c.validate().unwrap_err().contains("error_fraction"));
        // The binary-metallic prior's start is a fraction of the run.
        let mut c = TrainConfig::default();
        c.loss.binary_metallic_start = 1.5;
        let err = c.validate().unwrap_err();
        assert!(
            err.contains("loss.binary_metallic_start") && err.contains("fraction"),
            "{err}"
        );
        c.loss.binary_metallic_start = -0.1;
        assert!(
            c.validate()
                .unwrap_err()
                .contains("loss.binary_metallic_start")
        );
        c.loss.binary_metallic_start = 0.5;
        c.loss.binary_metallic_ceiling = 1.2;
        assert!(
            c.validate()
                .unwrap_err()
                .contains("loss.binary_metallic_ceiling")
        );
        c.loss.binary_metallic_ceiling = 0.5;
        // The prior's end and the error-guided draws' start are fractions too.
        let rejected = |c: &TrainConfig, name: &str| c.validate().unwrap_err().contains(name);
        for bad in [1.5, -0.1, f64::NAN] {
            let mut end = c.clone();
            end.loss.binary_metallic_end = bad;
            assert!(rejected(&end, "loss.binary_metallic_end"));
            let mut from = c.clone();
            from.error_from = bad;
            assert!(rejected(&from, "error_from"));
        }
        for bad_factor in [-0.5, 1.5, f64::NAN] {
            c.model.ambient_flash_gradient = bad_factor;
            assert!(
                c.validate()
                    .unwrap_err()
                    .contains("model.ambient_flash_gradient")
            );
        }
        c.model.ambient_flash_gradient = 0.0;
        for bad_factor in [-0.5, 1.5, f64::NAN] {
            c.model.ambient_flash_gradient_late = bad_factor;
            assert!(
                c.validate()
                    .unwrap_err()
                    .contains("model.ambient_flash_gradient_late")
            );
        }
        c.model.ambient_flash_gradient_late = 0.0;
        for bad_share in [-0.1, 1.1, f64::NAN] {
            c.model.ambient_flash_gradient_late_from = bad_share;
            assert!(
                c.validate()
                    .unwrap_err()
                    .contains("model.ambient_flash_gradient_late_from")
            );
        }
        c.model.ambient_flash_gradient_late_from = 0.8;
        for bad_share in [-0.1, 1.1] {
            c.optim.metallic_hold = bad_share;
            assert!(c.validate().unwrap_err().contains("optim.metallic_hold"));
        }
        c.optim.metallic_hold = 0.5;
        for bad_scale in [-0.1, f64::INFINITY, f64::NAN] {
            c.loss.smoothness_saturation = bad_scale;
            assert!(
                c.validate()
                    .unwrap_err()
                    .contains("loss.smoothness_saturation")
            );
        }
        c.loss.smoothness_saturation = 0.1;
        for bad_share in [-0.1, 1.1] {
            c.loss.smoothness_saturation_start = bad_share;
            assert!(
                c.validate()
                    .unwrap_err()
                    .contains("loss.smoothness_saturation_start")
            );
        }
        c.loss.smoothness_saturation_start = 0.5;
        assert!(c.validate().is_ok());
    }

    /// The smoothness factors read from their own table, fill Θ's order,
    /// and a negative one is refused by name.
    #[test]
    fn smoothness_factors_in_theta_order() {
        let c = TrainConfig::from_toml(
            "[loss.smoothness_factors]\nbase_color = 0.5\nroughness = 3\nclearcoat = 0\n",
        )
        .unwrap();
        let w = c.loss.smoothness_factors.per_parameter();
        for (i, name) in wildlight_material::PARAM_NAMES.iter().enumerate() {
            let expected = match *name {
                "base_color_r" | "base_color_g" | "base_color_b" => 0.5,
                "roughness" => 3.0,
                "clearcoat" => 0.0,
                _ => 1.0,
            };
            assert_eq!(w[i], expected, "{name}");
        }
        assert!(c.validate().is_ok());
        assert_eq!(
            TrainConfig::default()
                .loss
                .smoothness_factors
                .per_parameter(),
            [1.0; PARAM_COUNT]
        );
        let mut bad = TrainConfig::default();
        bad.loss.smoothness_factors.metallic = -1.0;
        let err = bad.validate().unwrap_err();
        assert!(err.contains("loss.smoothness_factors.metallic"), "{err}");
    }

    /// `wide_smoothness_parameters` moves the named factors to the wide
    /// pairs (base colour all three channels), keeps their values, and
    /// refuses unknown names and a zero wide radius.
    #[test]
    fn wide_smoothness_parameters_split_the_factors() {
        let c = TrainConfig::from_toml(
            "[loss]\nwide_smoothness_radius = 0.03\nwide_smoothness_parameters = [\"base_color\", \"metallic\"]\n[loss.smoothness_factors]\nmetallic = 2\n",
        )
        .unwrap();
        assert!(c.validate().is_ok());
        let (near, far) = c
            .loss
            .smoothness_factors
            .split(&c.loss.wide_smoothness_parameters);
        let wide = [BASE_COLOR, BASE_COLOR + 1, BASE_COLOR + 2, METALLIC];
        for i in 0..PARAM_COUNT {
            let w = if i == METALLIC { 2.0 } else { 1.0 };
            if wide.contains(&i) {
                assert_eq!((near[i], far[i]), (0.0, w), "{i}");
            } else {
                assert_eq!((near[i], far[i]), (w, 0.0), "{i}");
            }
        }
        let d = TrainConfig::default();
        assert_eq!(d.loss.smoothness_factors.split(&[]).1, [0.0; PARAM_COUNT]);
        let mut bad = c.clone();
        bad.loss.wide_smoothness_parameters.push("shininess".into());
        let err = bad.validate().unwrap_err();
        assert!(err.contains("\"shininess\""), "{err}");
        let mut bad = c.clone();
        bad.loss.wide_smoothness_radius = 0.0;
        let err = bad.validate().unwrap_err();
        assert!(err.contains("loss.wide_smoothness_parameters"), "{err}");
        bad.loss.wide_smoothness_radius = -0.1;
        assert!(
            bad.validate()
                .unwrap_err()
                .contains("loss.wide_smoothness_radius")
        );
    }

    /// The saturation scale reaches every parameter by default and only the
    /// named ones otherwise; an unknown name is refused by name.
    #[test]
    fn saturated_parameters_by_name() {
        let d = TrainConfig::default();
        let all = SmoothnessFactors::scales_of(&d.loss.smoothness_saturated_parameters, 0.1);
        assert_eq!(all, [0.1; PARAM_COUNT]);
        let c = TrainConfig::from_toml(
            "[loss]\nsmoothness_saturation = 0.05\nsmoothness_saturated_parameters = [\"roughness\", \"metallic\"]\n",
        )
        .unwrap();
        assert!(c.validate().is_ok());
        let scales = SmoothnessFactors::scales_of(
            &c.loss.smoothness_saturated_parameters,
            c.loss.smoothness_saturation,
        );
        for (i, v) in scales.iter().enumerate() {
            let want = if i == ROUGHNESS || i == METALLIC {
                0.05
            } else {
                0.0
            };
            assert_eq!(*v, want, "{i}");
        }
        let mut bad = c.clone();
        bad.loss
            .smoothness_saturated_parameters
            .push("gloss".into());
        let err = bad.validate().unwrap_err();
        assert!(
            err.contains("loss.smoothness_saturated_parameters") && err.contains("\"gloss\""),
            "{err}"
        );
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
