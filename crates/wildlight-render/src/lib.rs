//! The differentiable renderer of wildlight: NeuS volume rendering of an SDF
//! with flash + ambient shading (SPEC §2), with explicit forward and
//! backward kernels, and the samplers that feed it.
//!
//! - [`packing`]: rays with varying sample counts in flat arrays;
//! - [`neus`]: NeuS alphas and weights, forward/backward (∂φ, ∂∇φ, ∂v);
//! - [`mod@composite`]: Σ w_k c_k of any per-sample attribute, forward/backward,
//!   and per-ray depth/normal/mask maps;
//! - [`flash`]: the co-located flash term, forward/backward (∂Θ, ∂∇φ, ∂γ);
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

#![deny(missing_docs)]

pub mod composite;
pub mod error;
pub mod flash;
pub mod neus;
pub mod occupancy;
pub mod packing;
pub mod real;
pub mod sampler;
pub mod sh;

pub use composite::{RayMaps, acc_weight_backward, composite, composite_backward, ray_maps};
pub use error::RenderError;
pub use flash::{FlashInputs, flash_backward, flash_forward, gain};
pub use neus::{NeusInputs, NeusSettings, NeusWeights, cos_anneal_ratio, sharpness};
pub use occupancy::{CellState, OccupancyGrid, OccupancySettings, RefreshMode};
pub use packing::RAY_CHUNK;
pub use real::Scalar;
pub use sampler::{
    CoarseSamples, RaySamples, Rays, Sampler, SamplerSettings, dense_samples, sphere_chord,
};
pub use sh::{SH_DEG4_LEN, sh_deg4};
