//! The background of a run without masks (SPEC §6): a field over the
//! contracted point beyond the unit sphere, rendered along each ray behind
//! the object, with its backward pass.
//!
//! The field ([`crate::model::Model::background`]) reads the contracted
//! position u = (x/|x|)(2 − 1/|x|) of a sample (the shell 1 ≤ |u| < 2, on a
//! hash grid over [−2, 2]³) and SH(d) of the ray's direction, and gives
//! through a softplus each sample's density σ, ambient radiance a (RGB) and
//! flash response ρ (RGB). The samples, their volume rendering
//! (c_j = a_j + γ E ρ_j / t_j², the object's flash gain γ) and the
//! compositing C = C_object + (1 − Σw) B are `wildlight_render`'s
//! ([`wildlight_render::background`]).

use crate::float::Float;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use wildlight_fields::{FieldContext, FieldGrads, NeuralField};
use wildlight_render::{
    BackgroundGrads, BackgroundInputs, BackgroundSamples, BackgroundSettings, SH_DEG4_LEN,
    add_background, add_background_backward, background_backward, background_depth_quantile,
    background_forward, sh_deg4,
};

/// Outputs of the background field per sample: σ, a (RGB), ρ (RGB).
pub const BACKGROUND_OUTPUTS: usize = 7;

/// Columns of the background field's extra input: SH(d) of the ray's direction.
pub const BACKGROUND_EXTRA: usize = SH_DEG4_LEN;

/// Where the background field starts, wherever its hidden layer is near
/// zero (softplus outputs): a thin density (the first sections, about 0.03
/// long, start nearly transparent; the sky at 1000 radii is opaque), a mid
/// grey radiance, and a small flash response.
pub const BACKGROUND_INIT: [f64; 3] = [0.1, 0.2, 0.01];

/// The softplus⁻¹ of `y > 0` (the bias that gives `y` through a softplus).
pub fn softplus_inverse(y: f64) -> f64 {
    y.exp_m1().ln()
}

/// A mix of `seed` into the background's jitter stream (the sampler of the
/// object draws from `seed` itself).
fn jitter_stream(seed: u64) -> u64 {
    let mut x = seed ^ 0x6A09_E667_F3BC_C909;
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// Buffers and results of the background in a pass.
#[derive(Default)]
pub struct BackgroundPass<T> {
    /// The samples of the last pass.
    pub samples: BackgroundSamples<T>,
    extra: Vec<T>,
    ctx: FieldContext<T>,
    density: Vec<T>,
    ambient: Vec<[T; 3]>,
    flash_response: Vec<[T; 3]>,
    weights: Vec<T>,
    /// The background radiance B of each ray (before the object's 1 − Σw).
    pub colour: Vec<[T; 3]>,
    /// Its ambient part Σ_j w_j a_j (the rest, B minus it, is the flash's).
    pub ambient_colour: Vec<[T; 3]>,
    grads: BackgroundGrads<T>,
    d_background: Vec<[T; 3]>,
    d_out: Vec<T>,
    /// Wall time spent in [`BackgroundPass::forward`] and
    /// [`BackgroundPass::backward`] since the last
    /// [`BackgroundPass::take_seconds`].
    seconds: f64,
}

impl<T: Float + Default> BackgroundPass<T> {
    /// Places the background samples of the rays (jittered from
    /// `jitter_seed`, bin middles without), evaluates the field, renders B
    /// and adds (1 − Σw) B to `colour`.
    #[allow(clippy::too_many_arguments)]
    pub fn forward(
        &mut self,
        field: &NeuralField<T>,
        log_gain: T,
        origins: &[[T; 3]],
        dirs: &[[T; 3]],
        energy: &[[T; 3]],
        settings: &BackgroundSettings,
        jitter_seed: Option<u64>,
        acc_weight: &[T],
        colour: &mut [[T; 3]],
    ) {
        let start = std::time::Instant::now();
        match jitter_seed {
            Some(seed) => {
                let mut rng = Pcg64::seed_from_u64(jitter_stream(seed));
                let mut next = || rng.random::<f64>();
                self.samples.place(origins, dirs, settings, Some(&mut next));
            }
            None => self.samples.place(origins, dirs, settings, None),
        }
        let per_ray = self.samples.per_ray;
        let n = self.samples.len();
        self.extra.clear();
        self.extra.reserve(n * BACKGROUND_EXTRA);
        for d in dirs {
            let sh = sh_deg4(*d);
            for _ in 0..per_ray {
                self.extra.extend_from_slice(&sh);
            }
        }
        field.forward(&self.samples.points, &self.extra, &mut self.ctx);
        self.density.clear();
        self.ambient.clear();
        self.flash_response.clear();
        for row in self.ctx.output().chunks_exact(BACKGROUND_OUTPUTS) {
            self.density.push(row[0]);
            self.ambient.push([row[1], row[2], row[3]]);
            self.flash_response.push([row[4], row[5], row[6]]);
        }
        self.colour.clear();
        self.colour.resize(dirs.len(), [T::ZERO; 3]);
        let inputs = BackgroundInputs {
            samples: &self.samples,
            density: &self.density,
            ambient: &self.ambient,
            flash_response: &self.flash_response,
            light_energy: energy,
        };
        background_forward(&inputs, log_gain, &mut self.colour, &mut self.weights);
        self.ambient_colour.clear();
        for r in 0..dirs.len() {
            let mut sum = [T::ZERO; 3];
            for k in r * per_ray..(r + 1) * per_ray {
                for (s, a) in sum.iter_mut().zip(self.ambient[k]) {
                    *s += self.weights[k] * a;
                }
            }
            self.ambient_colour.push(sum);
        }
        add_background(acc_weight, &self.colour, colour);
        self.seconds += start.elapsed().as_secs_f64();
    }

    /// Backward pass of the last [`BackgroundPass::forward`] from ∂L/∂C
    /// per ray: ADDS ∂L/∂(Σw) into `d_acc_weight`, the field's parameter
    /// gradients into `field_grads`, and returns ∂L/∂g of the flash gain.
    #[allow(clippy::too_many_arguments)]
    pub fn backward(
        &mut self,
        field: &NeuralField<T>,
        log_gain: T,
        energy: &[[T; 3]],
        acc_weight: &[T],
        d_colour: &[[T; 3]],
        d_acc_weight: &mut [T],
        field_grads: &mut FieldGrads<T>,
    ) -> T {
        let start = std::time::Instant::now();
        self.d_background.clear();
        self.d_background.resize(d_colour.len(), [T::ZERO; 3]);
        add_background_backward(
            acc_weight,
            &self.colour,
            d_colour,
            d_acc_weight,
            Some(&mut self.d_background),
        );
        let inputs = BackgroundInputs {
            samples: &self.samples,
            density: &self.density,
            ambient: &self.ambient,
            flash_response: &self.flash_response,
            light_energy: energy,
        };
        background_backward(
            &inputs,
            log_gain,
            &self.weights,
            &self.d_background,
            &mut self.grads,
        );
        self.d_out.clear();
        self.d_out.reserve(self.samples.len() * BACKGROUND_OUTPUTS);
        for k in 0..self.samples.len() {
            self.d_out.push(self.grads.density[k]);
            self.d_out.extend_from_slice(&self.grads.ambient[k]);
            self.d_out.extend_from_slice(&self.grads.flash_response[k]);
        }
        field.backward(&mut self.ctx, &self.d_out, field_grads, None, None);
        self.seconds += start.elapsed().as_secs_f64();
        self.grads.log_gain
    }

    /// The wall time of the forward and backward passes since the last
    /// call (seconds), and starts counting again.
    pub fn take_seconds(&mut self) -> f64 {
        std::mem::take(&mut self.seconds)
    }

    /// The depth of each ray's background in the last pass: where its
    /// weights reach `fraction` of their sum
    /// ([`wildlight_render::background_depth_quantile`]).
    pub fn depth_quantile(&self, fraction: f64) -> Vec<Option<f64>> {
        background_depth_quantile(&self.samples, &self.weights, fraction)
    }

    /// Forgets the last pass (a pass of a model without a background).
    pub fn clear(&mut self) {
        self.colour.clear();
        self.ambient_colour.clear();
    }
}

/// The background field's initial output bias (see [`BACKGROUND_INIT`]).
pub fn background_init_bias() -> [f64; BACKGROUND_OUTPUTS] {
    let [sigma, a, rho] = BACKGROUND_INIT.map(softplus_inverse);
    [sigma, a, a, a, rho, rho, rho]
}
