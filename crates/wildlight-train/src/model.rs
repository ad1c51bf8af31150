//! The WildLight model (SPEC §2): an SDF field, a material field, an ambient
//! radiance field, the NeuS sharpness and the flash gain, with their
//! gradient buffers and optimiser groups.

use crate::config::ModelConfig;
use wildlight_fields::{Activation, FieldGrads, NeuralField, NeuralFieldConfig, SdfField};
use wildlight_material::PARAM_COUNT;
use wildlight_render::SH_DEG4_LEN;

/// Number of extra per-point inputs of the ambient field besides its own
/// encoding: geometry features, unit normal, SH-encoded view direction and
/// the material parameters.
pub fn ambient_extra_inputs(geometry_features: usize) -> usize {
    geometry_features + 3 + SH_DEG4_LEN + PARAM_COUNT
}

/// The learned model.
#[derive(Clone, Debug)]
pub struct Model {
    /// Its settings.
    pub config: ModelConfig,
    /// Signed distance φ and geometry features.
    pub sdf: SdfField<f32>,
    /// Material parameters Θ = sigmoid(outputs) (SPEC §3).
    pub material: NeuralField<f32>,
    /// Ambient radiance a ≥ 0 (softplus outputs).
    pub ambient: NeuralField<f32>,
    /// NeuS sharpness parameter v, s = exp(10 v).
    pub sharpness: f32,
    /// Flash gain parameter g, γ = exp(g) > 0.
    pub log_gain: f32,
}

/// Gradients of every parameter of a [`Model`].
#[derive(Clone, Debug)]
pub struct ModelGrads {
    /// Of the SDF field.
    pub sdf: FieldGrads<f32>,
    /// Of the material field.
    pub material: FieldGrads<f32>,
    /// Of the ambient field.
    pub ambient: FieldGrads<f32>,
    /// Of v.
    pub sharpness: f32,
    /// Of g.
    pub log_gain: f32,
}

impl ModelGrads {
    /// Sets every gradient to zero.
    pub fn zero(&mut self) {
        self.sdf.zero();
        self.material.zero();
        self.ambient.zero();
        self.sharpness = 0.0;
        self.log_gain = 0.0;
    }

    /// Whether every gradient is finite.
    pub fn all_finite(&self) -> bool {
        let f = |g: &FieldGrads<f32>| {
            g.grid.iter().all(|v| v.is_finite()) && g.mlp.iter().all(|v| v.is_finite())
        };
        f(&self.sdf)
            && f(&self.material)
            && f(&self.ambient)
            && self.sharpness.is_finite()
            && self.log_gain.is_finite()
    }
}

impl Model {
    /// A freshly initialised model (the SDF starts as a sphere).
    pub fn new(config: &ModelConfig, seed: u64) -> anyhow::Result<Self> {
        let sdf = SdfField::new(&config.sdf_field(), seed)?;
        let material = NeuralField::new(
            &NeuralFieldConfig {
                grid: config.material.grid(),
                bound: 1.0,
                include_position: false,
                n_extra: 0,
                hidden: config.material.hidden.clone(),
                hidden_activation: Activation::Relu,
                n_output: PARAM_COUNT,
                output_activation: Activation::Sigmoid,
            },
            seed.wrapping_add(1),
        )?;
        let ambient = NeuralField::new(
            &NeuralFieldConfig {
                grid: config.ambient.grid(),
                bound: 1.0,
                include_position: false,
                n_extra: ambient_extra_inputs(config.geometry_features),
                hidden: config.ambient.hidden.clone(),
                hidden_activation: Activation::Relu,
                n_output: 3,
                output_activation: Activation::Softplus { beta: 1.0 },
            },
            seed.wrapping_add(2),
        )?;
        Ok(Self {
            config: config.clone(),
            sdf,
            material,
            ambient,
            sharpness: config.init_sharpness,
            log_gain: config.init_log_gain,
        })
    }

    /// Zeroed gradient buffers shaped like the parameters.
    pub fn new_grads(&self) -> ModelGrads {
        ModelGrads {
            sdf: self.sdf.new_grads(),
            material: self.material.new_grads(),
            ambient: self.ambient.new_grads(),
            sharpness: 0.0,
            log_gain: 0.0,
        }
    }

    /// The NeuS sharpness s = exp(10 v).
    pub fn s(&self) -> f32 {
        wildlight_render::sharpness(self.sharpness).0
    }

    /// The flash gain γ = exp(g).
    pub fn gamma(&self) -> f32 {
        wildlight_render::gain(self.log_gain)
    }

    /// Sets how many hash levels of every field are active (coarse-to-fine).
    pub fn set_active_levels(&mut self, sdf_levels: usize, material_levels: usize) {
        self.sdf.field.active_levels = sdf_levels.min(self.config.sdf.levels);
        self.material.active_levels = material_levels.min(self.config.material.levels);
    }

    /// Whether every parameter is finite.
    pub fn all_finite(&self) -> bool {
        let f = |n: &NeuralField<f32>| {
            n.grid.params.iter().all(|v| v.is_finite())
                && n.mlp.params.iter().all(|v| v.is_finite())
        };
        f(&self.sdf.field)
            && f(&self.material)
            && f(&self.ambient)
            && self.sharpness.is_finite()
            && self.log_gain.is_finite()
    }
}
