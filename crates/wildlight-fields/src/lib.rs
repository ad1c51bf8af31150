//! Differentiable neural fields on the CPU, with hand-written forward and
//! backward kernels in the tiny-cuda-nn style:
//!
//! - [`hash_grid`]: multi-resolution hash encoding (Instant-NGP);
//! - [`mlp`]: small MLPs on `matrixmultiply` GEMMs;
//! - [`neural_field`]: encoding + MLP with extra per-point inputs (colour,
//!   material and ambient fields are built from it);
//! - [`sdf_field`]: signed distance + geometry features, geometric init,
//!   finite-difference normals differentiable w.r.t. all parameters;
//! - [`adam`]: Adam with parameter groups and learning-rate schedules;
//! - [`checkpoint`]: versioned safetensors checkpoints;
//! - [`sh`]: spherical-harmonics direction encoding.
//!
//! Every kernel is generic over [`Real`] (`f32` for training, `f64` for
//! gradient checks). Parallel work uses rayon over fixed chunks and
//! reductions in a fixed order: results are bit-identical for the same seed,
//! whatever the thread count.

// Kernels index small fixed-size arrays (corners, axes, features) in step,
// as the formulas do; iterator zips would obscure them.
#![allow(clippy::needless_range_loop)]

pub mod activation;
pub mod adam;
pub mod bench;
pub mod checkpoint;
pub mod error;
pub mod hash_grid;
pub mod memory;
pub mod mlp;
pub mod neural_field;
pub mod real;
pub mod sdf_field;
pub mod sh;

pub use activation::Activation;
pub use adam::{Adam, AdamConfig, AdamGroup, Decay, LrSchedule};
pub use checkpoint::{CHECKPOINT_FORMAT_VERSION, Checkpoint, CheckpointWriter, Checkpointable};
pub use error::FieldError;
pub use hash_grid::{HashGrid, HashGridConfig};
pub use mlp::{CHUNK_ROWS, Mlp, MlpChunk, MlpConfig, MlpContext, MlpScratch};
pub use neural_field::{FieldContext, FieldGrads, NeuralField, NeuralFieldConfig};
pub use real::Real;
pub use sdf_field::{FdScheme, NormalContext, SdfField, SdfFieldConfig};
pub use sh::{sh_encode, sh_len};
