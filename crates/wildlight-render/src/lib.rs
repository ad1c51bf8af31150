//! The differentiable renderer of wildlight: NeuS volume rendering of an SDF
//! with flash + ambient shading (SPEC §2), with explicit forward and
//! backward kernels, and the samplers that feed it.
//!
//! - [`packing`]: rays with varying sample counts in flat arrays;
//! - [`neus`]: NeuS alphas and weights, forward/backward (∂φ, ∂∇φ, ∂v);
//! - [`mod@composite`]: Σ w_k c_k of any per-sample attribute, forward/backward,
//!   and per-ray depth/normal/mask maps;
//! - [`flash`]: the co-located flash term, forward/backward (∂Θ, ∂∇φ, ∂γ);
//! - [`background`]: the scene beyond the unit sphere (SPEC §6): samples
//!   uniform in inverse radius, their volume rendering with an ambient and
//!   a flash term, forward/backward (∂σ, ∂a, ∂ρ, ∂γ);
//! - [`sh`]: spherical-harmonics encoding of view directions;
//! - [`occupancy`]: the occupancy grid for empty-space skipping;
//! - [`sampler`]: the fast sampler (grid + hierarchical refinement) and the
//!   dense uniform reference.
//!
//! The renderer never sees a field implementation: the SDF enters as
//! batched closures (samplers, grid) or as per-sample arrays (kernels).
//!
//! A training step, in order:
//!
//! 1. [`sampler::Sampler::coarse`] → evaluate φ at the coarse points →
//!    [`sampler::Sampler::refine`] → sample positions, t, δ;
//! 2. fields at the positions: φ, ∇φ, Θ, ambient a;
//!    [`neus::NeusWeights::forward`], [`flash::flash_forward`], c = a + f,
//!    [`composite::composite`] → pixel colours, Σ w;
//! 3. losses → ∂L/∂C, ∂L/∂(Σ w); [`composite::composite_backward`] (→ ∂w, ∂c),
//!    [`flash::flash_backward`] (∂c → ∂Θ, ∂∇φ, ∂g),
//!    [`neus::NeusWeights::backward`] (∂w, ∂Σw → ∂φ, ∂∇φ, ∂v);
//!    then the fields' backward passes.
//!
//! ```
//! use wildlight_material::BrdfSettings;
//! use wildlight_render::*;
//!
//! // A sphere of radius 0.5 stands in for the SDF field.
//! let sdf = |p: [f32; 3]| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.5;
//! let sdf_batch = |pts: &[[f32; 3]], out: &mut [f32]| {
//!     for (o, &p) in out.iter_mut().zip(pts) { *o = sdf(p); }
//! };
//! let v = 0.6f32; // NeuS sharpness parameter, s = exp(10 v)
//! let (s, _) = sharpness(v);
//! let mut grid = OccupancyGrid::new(OccupancySettings::default()).unwrap();
//! grid.refresh(sdf_batch, s, RefreshMode::Full);
//!
//! let origins = vec![[0.0, 0.0, 2.0f32]; 2];
//! let dirs = vec![[0.0, 0.0, -1.0f32], [0.0, 0.6, -0.8]];
//! let rays = Rays { origins: &origins, dirs: &dirs };
//! let mut sampler = Sampler::new(SamplerSettings::default()).unwrap();
//! let (mut coarse, mut samples) = (CoarseSamples::default(), RaySamples::default());
//! sampler.sample(&grid, &rays, sdf_batch, s, Some(0), &mut coarse, &mut samples);
//!
//! // Field values at the samples (a real field evaluates these in batch).
//! let phi: Vec<f32> = samples.positions.iter().map(|&p| sdf(p)).collect();
//! let grad: Vec<[f32; 3]> = samples.positions.iter().map(|p| p.map(|x| 2.0 * x)).collect();
//! let theta = vec![[0.5f32; 9]; samples.len()];
//! let ambient = vec![[0.1f32; 3]; samples.len()];
//! let energy = vec![[1.0f32; 3]; rays.len()];
//!
//! let ninp = NeusInputs { offsets: &samples.offsets, ray_dirs: &dirs, sdf: &phi,
//!                         sdf_grad: &grad, delta: &samples.delta };
//! let mut w = NeusWeights::new();
//! w.forward(&ninp, v, &NeusSettings::default());
//! let finp = FlashInputs { offsets: &samples.offsets, ray_dirs: &dirs, light_energy: &energy,
//!                          t: &samples.t, sdf_grad: &grad, params: &theta };
//! let log_gain = 0.0f32;
//! let mut flash = vec![[0.0f32; 3]; samples.len()];
//! let mut cache = FlashCache::new();
//! flash_forward(&finp, log_gain, &BrdfSettings::default(), &mut flash, Some(&mut cache));
//! let c: Vec<[f32; 3]> = ambient.iter().zip(&flash)
//!     .map(|(a, f)| [a[0] + f[0], a[1] + f[1], a[2] + f[2]]).collect();
//! let mut colour = vec![[0.0f32; 3]; rays.len()];
//! composite(&samples.offsets, &w.weight, &c, &mut colour);
//! assert!(w.acc_weight[0] > 0.99 && w.acc_weight[1] < 0.01); // hit, miss
//!
//! // Backward from ∂L/∂C and ∂L/∂(Σw).
//! let d_colour = vec![[1.0f32; 3]; rays.len()];
//! let d_acc = vec![0.5f32; rays.len()];
//! let n = samples.len();
//! let (mut d_w, mut d_c) = (vec![0.0f32; n], vec![[0.0f32; 3]; n]);
//! composite_backward(&samples.offsets, &w.weight, &c, &d_colour, &mut d_w, Some(&mut d_c));
//! let (mut d_theta, mut d_grad, mut d_phi) = (vec![[0.0f32; 9]; n], vec![[0.0f32; 3]; n], vec![0.0f32; n]);
//! let d_log_gain = flash_backward(&finp, log_gain, &BrdfSettings::default(), Some(&cache), &d_c,
//!                                 &mut d_theta, &mut d_grad);
//! let d_v = w.backward(&ninp, v, &NeusSettings::default(), &d_w, Some(&d_acc),
//!                      &mut d_phi, &mut d_grad);
//! // ∂L/∂a_k = d_c[k] (ambient), ∂L/∂Θ_k = d_theta[k], ∂L/∂φ_k = d_phi[k], ∂L/∂∇φ_k = d_grad[k].
//! assert!(d_log_gain > 0.0 && d_v.is_finite());
//! ```

#![deny(missing_docs)]

pub mod background;
pub mod composite;
pub mod error;
pub mod flash;
pub mod neus;
pub mod occupancy;
pub mod packing;
pub mod real;
pub mod sampler;
pub mod sh;

/// A seeded xorshift64 stream of uniform numbers in [0, 1) for the unit
/// tests (integration tests use `rand`).
#[cfg(test)]
pub(crate) fn test_uniform(mut state: u64) -> impl FnMut() -> f64 {
    move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    }
}

pub use background::{
    BackgroundGrads, BackgroundInputs, BackgroundSamples, BackgroundSettings, background_backward,
    background_depth_quantile, background_forward,
};
pub use composite::{
    RayMaps, acc_weight_backward, add_background, add_background_backward, composite,
    composite_backward, ray_maps,
};
pub use error::RenderError;
pub use flash::{FlashCache, FlashInputs, flash_backward, flash_forward, gain};
pub use neus::{NeusInputs, NeusSettings, NeusWeights, cos_anneal_ratio, sharpness};
pub use occupancy::{CellState, OccupancyGrid, OccupancySettings, OccupancySnapshot, RefreshMode};
pub use packing::RAY_CHUNK;
pub use sampler::{
    CoarseSamples, RaySamples, Rays, Sampler, SamplerSettings, dense_samples, sphere_chord,
};
pub use sh::{SH_DEG4_LEN, sh_deg4, sh_deg4_jacobian};
