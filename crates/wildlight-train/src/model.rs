//! The WildLight model (SPEC §2): an SDF field, a material field, an ambient
//! radiance field, the NeuS sharpness and the flash gain, with their
//! gradient buffers and optimiser groups.

use crate::ambient::ambient_extra_inputs;
use crate::background::{BACKGROUND_EXTRA, BACKGROUND_OUTPUTS, background_init_bias};
use crate::config::{AmbientModel, FieldSize, ModelConfig, ROOM_FEATURES, SdfNormals};
use crate::float::{Float, finite};
use wildlight_fields::{
    Activation, FdScheme, FieldContext, FieldGrads, NeuralField, NeuralFieldConfig, NormalMethod,
    SdfField,
};
use wildlight_material::PARAM_COUNT;

/// The learned model, generic over the float type: `f32` for training and
/// rendering, `f64` for the finite-difference checks of the whole pipeline.
#[derive(Clone, Debug)]
pub struct Model<T = f32> {
    /// Its settings.
    pub config: ModelConfig,
    /// Signed distance φ and geometry features.
    pub sdf: SdfField<T>,
    /// Material parameters Θ = sigmoid(outputs) (SPEC §3).
    pub material: NeuralField<T>,
    /// Ambient radiance a ≥ 0 (softplus outputs).
    pub ambient: NeuralField<T>,
    /// The room: the reflected-direction features of
    /// [`AmbientModel::NeuralRoom`], inputs of the ambient field (`None` for
    /// [`AmbientModel::Neural`]).
    pub room: Option<NeuralField<T>>,
    /// NeuS sharpness parameter v, s = exp(10 v).
    pub sharpness: T,
    /// Flash gain parameter g, γ = exp(g) > 0.
    pub log_gain: T,
    /// The scene beyond the unit sphere (`crate::background`): σ, a, ρ of
    /// the contracted point and the view direction; only in runs without
    /// masks (SPEC §6).
    pub background: Option<NeuralField<T>>,
}

/// Gradients of every parameter of a [`Model`].
#[derive(Clone, Debug)]
pub struct ModelGrads<T = f32> {
    /// Of the SDF field.
    pub sdf: FieldGrads<T>,
    /// Of the material field.
    pub material: FieldGrads<T>,
    /// Of the ambient field.
    pub ambient: FieldGrads<T>,
    /// Of the room, when the model has one.
    pub room: Option<FieldGrads<T>>,
    /// Of v.
    pub sharpness: T,
    /// Of g.
    pub log_gain: T,
    /// Of the background field, when the model has one.
    pub background: Option<FieldGrads<T>>,
}

impl<T: Float> ModelGrads<T> {
    /// Sets every gradient to zero.
    pub fn zero(&mut self) {
        self.sdf.zero();
        self.material.zero();
        self.ambient.zero();
        if let Some(g) = &mut self.room {
            g.zero();
        }
        if let Some(g) = &mut self.background {
            g.zero();
        }
        self.sharpness = T::ZERO;
        self.log_gain = T::ZERO;
    }

    /// Whether every gradient is finite.
    pub fn all_finite(&self) -> bool {
        let f = FieldGrads::all_finite;
        f(&self.sdf)
            && f(&self.material)
            && f(&self.ambient)
            && self.room.as_ref().is_none_or(f)
            && self.background.as_ref().is_none_or(f)
            && finite(self.sharpness)
            && finite(self.log_gain)
    }
}

/// A field of a hash grid of the position (sized by `size`) and an MLP with
/// `n_extra` extra inputs, ReLU hidden layers and `n_output` outputs.
fn grid_mlp_field<T: Float>(
    size: &FieldSize,
    n_extra: usize,
    n_output: usize,
    output_activation: Activation,
    seed: u64,
) -> anyhow::Result<NeuralField<T>> {
    Ok(NeuralField::new(
        &NeuralFieldConfig {
            grid: size.grid(),
            bound: 1.0,
            include_position: false,
            n_extra,
            hidden: size.hidden.clone(),
            hidden_activation: Activation::Relu,
            n_output,
            output_activation,
        },
        seed,
    )?)
}

/// A field with three softplus outputs (a non-negative radiance).
fn radiance_field<T: Float>(
    size: &FieldSize,
    n_extra: usize,
    seed: u64,
) -> anyhow::Result<NeuralField<T>> {
    grid_mlp_field(size, n_extra, 3, Activation::Softplus { beta: 1.0 }, seed)
}

/// The logit of a probability, the inverse of the sigmoid.
fn logit(p: f32) -> f64 {
    let p = (p as f64).clamp(1e-4, 1.0 - 1e-4);
    (p / (1.0 - p)).ln()
}

/// Sets the bias of a field's output layer (so a sigmoid output starts at
/// chosen values wherever the hidden layer is near zero).
fn set_output_bias<T: Float>(field: &mut NeuralField<T>, bias: &[f64]) -> anyhow::Result<()> {
    let layer = *field
        .mlp
        .layers()
        .last()
        .expect("an MLP has an output layer");
    anyhow::ensure!(
        layer.n_out == bias.len(),
        "the output layer has {} values, the prior {}",
        layer.n_out,
        bias.len()
    );
    for (j, b) in bias.iter().enumerate() {
        field.mlp.params[layer.bias_offset + j] = T::from_f64(*b);
    }
    Ok(())
}

impl<T: Float> Model<T> {
    /// A freshly initialised model (the SDF starts as a sphere), without a
    /// background (a run with masks).
    pub fn new(config: &ModelConfig, seed: u64) -> anyhow::Result<Self> {
        Self::build(config, seed, false)
    }

    /// [`Model::new`] with a background field (a run without masks, SPEC §6).
    pub fn with_background(config: &ModelConfig, seed: u64) -> anyhow::Result<Self> {
        Self::build(config, seed, true)
    }

    fn build(config: &ModelConfig, seed: u64, with_background: bool) -> anyhow::Result<Self> {
        let sdf = SdfField::new(&config.sdf_field(), seed)?;
        let mut material = grid_mlp_field(
            &config.material,
            0,
            PARAM_COUNT,
            Activation::Sigmoid,
            seed.wrapping_add(1),
        )?;
        set_output_bias(&mut material, &config.init_material.map(logit))?;
        let ambient = radiance_field(
            &config.ambient,
            ambient_extra_inputs(config.ambient_model, config.geometry_features),
            seed.wrapping_add(2),
        )?;
        let room = match config.ambient_model {
            AmbientModel::Neural => None,
            // its grid encodes ω (a point of the unit sphere), not a position
            AmbientModel::NeuralRoom => Some(grid_mlp_field(
                &config.ambient_room,
                0,
                ROOM_FEATURES,
                Activation::None,
                seed.wrapping_add(3),
            )?),
        };
        let background = if with_background {
            let size = &config.background;
            let mut field = NeuralField::new(
                &NeuralFieldConfig {
                    grid: size.grid(),
                    // the contracted points fill the shell 1 ≤ |u| < 2
                    bound: 2.0,
                    include_position: false,
                    n_extra: BACKGROUND_EXTRA,
                    hidden: size.hidden.clone(),
                    hidden_activation: Activation::Relu,
                    n_output: BACKGROUND_OUTPUTS,
                    output_activation: Activation::Softplus { beta: 1.0 },
                },
                seed.wrapping_add(4),
            )?;
            set_output_bias(&mut field, &background_init_bias())?;
            Some(field)
        } else {
            None
        };
        Ok(Self {
            config: config.clone(),
            sdf,
            material,
            ambient,
            room,
            sharpness: T::from_f64(config.init_sharpness as f64),
            log_gain: T::from_f64(config.init_log_gain as f64),
            background,
        })
    }

    /// Zeroed gradient buffers shaped like the parameters.
    pub fn new_grads(&self) -> ModelGrads<T> {
        ModelGrads {
            sdf: self.sdf.new_grads(),
            material: self.material.new_grads(),
            ambient: self.ambient.new_grads(),
            room: self.room.as_ref().map(|f| f.new_grads()),
            sharpness: T::ZERO,
            log_gain: T::ZERO,
            background: self.background.as_ref().map(|f| f.new_grads()),
        }
    }

    /// The NeuS sharpness s = exp(10 v).
    pub fn s(&self) -> T {
        wildlight_render::sharpness(self.sharpness).0
    }

    /// The flash gain γ = exp(g).
    pub fn gamma(&self) -> T {
        wildlight_render::gain(self.log_gain)
    }

    /// The material parameters Θ at each of `points` (normalized frame).
    pub fn material_at(&self, points: &[[T; 3]]) -> Vec<[T; PARAM_COUNT]>
    where
        T: Default,
    {
        let mut ctx = FieldContext::new();
        self.material.forward(points, &[], &mut ctx);
        ctx.output()
            .chunks_exact(PARAM_COUNT)
            .map(|row| row.try_into().expect("PARAM_COUNT parameters"))
            .collect()
    }

    /// Sets how many hash levels of every field are active (coarse-to-fine).
    pub fn set_active_levels(&mut self, sdf_levels: usize, material_levels: usize) {
        self.sdf.field.active_levels = sdf_levels.min(self.config.sdf.levels);
        self.material.active_levels = material_levels.min(self.material.grid.levels().len());
    }

    /// The cell size of the finest active SDF level (normalized units; it
    /// shrinks as levels activate): the step of finite-difference normals.
    pub fn fd_step(&self) -> f64 {
        let f = &self.sdf.field;
        f.cell_size(f.active_levels.max(1) - 1)
    }

    /// How passes compute ∇φ now ([`crate::config::ModelConfig::sdf_normals`]):
    /// with [`SdfNormals::Analytic`], analytically once every SDF level is
    /// active, by finite differences of the shrinking step before.
    pub fn normal_method(&self) -> NormalMethod {
        let all_levels = self.sdf.field.active_levels >= self.config.sdf.levels;
        match self.config.sdf_normals {
            SdfNormals::Analytic if all_levels => NormalMethod::Analytic,
            _ => NormalMethod::FiniteDifference {
                scheme: FdScheme::Tetrahedral,
                step: self.fd_step(),
            },
        }
    }

    /// Whether every parameter is finite.
    pub fn all_finite(&self) -> bool {
        let f = NeuralField::all_finite;
        f(&self.sdf.field)
            && f(&self.material)
            && f(&self.ambient)
            && self.room.as_ref().is_none_or(f)
            && self.background.as_ref().is_none_or(f)
            && finite(self.sharpness)
            && finite(self.log_gain)
    }
}
