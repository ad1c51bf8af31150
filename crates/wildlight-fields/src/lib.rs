//! Differentiable neural fields on the CPU, with hand-written forward and
//! backward kernels in the tiny-cuda-nn style:
//!
//! - [`hash_grid`]: multi-resolution hash encoding (Instant-NGP);
//! - [`mlp`]: small MLPs on the column-major layer kernels of [`dense`]
//!   (measured faster than `matrixmultiply` GEMMs on these narrow shapes,
//!   which pay for packing every call);
//! - [`neural_field`]: encoding + MLP with extra per-point inputs (colour,
//!   material and ambient fields are built from it);
//! - [`sdf_field`]: signed distance + geometry features, geometric init,
//!   finite-difference normals differentiable w.r.t. all parameters;
//! - [`adam`]: Adam with parameter groups and learning-rate schedules;
//! - [`checkpoint`]: versioned safetensors checkpoints;
//!
//! Every kernel is generic over [`wildlight_real::Real`] (`f32` for
//! training, `f64` for gradient checks). Parallel work uses rayon over fixed
//! chunks of [`CHUNK_ROWS`] points and reductions in a fixed order: results
//! are bit-identical for the same seed, whatever the thread count.
//!
//! # Calling pattern (one training step)
//!
//! Each part has `forward(inputs, &mut context)` and `backward(&mut context,
//! d_outputs, &mut grads, …)`; parameter gradients are *accumulated* into flat
//! buffers laid out like the parameters, so each flat parameter vector is one
//! Adam group. Contexts keep their buffers between steps.
//!
//! ```
//! use wildlight_fields::*;
//! let cfg = SdfFieldConfig {
//!     grid: HashGridConfig { n_levels: 4, log2_table_size: 10, finest_resolution: 64, ..HashGridConfig::default() },
//!     ..SdfFieldConfig::default()
//! };
//! let mut sdf = SdfField::<f32>::new(&cfg, 0).unwrap();
//! let mut adam = Adam::new();
//! let g_grid = adam.add_group("sdf.grid", sdf.field.grid.n_params(), AdamConfig { lr: 1e-2, ..AdamConfig::default() });
//! let g_mlp = adam.add_group("sdf.mlp", sdf.field.mlp.n_params(), AdamConfig { lr: 1e-2, ..AdamConfig::default() });
//! let mut ctx = NormalContext::new();
//! let mut grads = sdf.new_grads();
//! let x = vec![[0.1f32, 0.2, 0.3], [0.5, -0.2, 0.1]];
//! // sdf, features and the finite-difference gradient of every sample
//! let method = NormalMethod::FiniteDifference { scheme: FdScheme::Tetrahedral, step: sdf.field.cell_size(3) };
//! sdf.forward_with_normals(&x, method, &mut ctx);
//! // upstream gradients from the renderer / losses (here: eikonal only)
//! let d_sdf = vec![0.0; x.len()];
//! let d_features = vec![0.0; x.len() * cfg.n_features];
//! let d_gradient: Vec<[f32; 3]> = ctx.gradient.iter().map(|g| {
//!     let n = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
//!     let k = 2.0 * (n - 1.0) / n / x.len() as f32; // d/dg of mean (|g| − 1)²
//!     [k * g[0], k * g[1], k * g[2]]
//! }).collect();
//! grads.zero();
//! sdf.backward_with_normals(&mut ctx, &d_sdf, &d_features, &d_gradient, &mut grads);
//! adam.step(g_grid, &mut sdf.field.grid.params, &grads.grid, 1.0);
//! adam.step(g_mlp, &mut sdf.field.mlp.params, &grads.mlp, 1.0);
//! ```
//!
//! Colour, material and ambient fields are [`NeuralField`]s with extra
//! per-point inputs (geometry features, directions encoded in spherical
//! harmonics by `wildlight_render::sh_deg4`, normals…):
//! `forward(&x, &extra, &mut ctx)`, `backward(&mut ctx, &d_out, &mut grads,
//! Some(&mut d_extra), None)` returns the gradient w.r.t. the extras, which the
//! caller passes on (e.g. into `d_features` of the SDF field).

// Kernels index small fixed-size arrays (corners, axes, features) in step,
// as the formulas do; iterator zips would obscure them.
#![allow(clippy::needless_range_loop)]

pub mod activation;
pub mod adam;
pub mod bench;
pub mod checkpoint;
pub mod dense;
pub mod error;
pub mod hash_grid;
pub mod memory;
pub mod mlp;
pub mod neural_field;
pub mod real;
pub mod sdf_field;
pub mod sdf_gradient;

pub use activation::Activation;
pub use adam::{Adam, AdamConfig, AdamGroup, Decay, LrSchedule};
pub use checkpoint::{CHECKPOINT_FORMAT_VERSION, Checkpoint, CheckpointWriter, Checkpointable};
pub use error::FieldError;
pub use hash_grid::{HashGrid, HashGridConfig, Interpolation};
pub use mlp::{CHUNK_ROWS, Mlp, MlpChunk, MlpConfig, MlpContext, MlpScratch};
pub use neural_field::{FieldContext, FieldGrads, NeuralField, NeuralFieldConfig};
pub use real::all_finite;
pub use sdf_field::{FdScheme, NormalContext, NormalMethod, SdfField, SdfFieldConfig};
pub use sdf_gradient::{BatchedGradientContext, GradientContext, second_derivative_from_output};
