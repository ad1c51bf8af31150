//! Errors of the fields crate.

use std::path::PathBuf;

/// Everything that can go wrong when building fields or reading/writing checkpoints.
#[derive(Debug, thiserror::Error)]
pub enum FieldError {
    /// A configuration value is out of range.
    #[error("invalid field configuration: {0}")]
    InvalidConfig(String),
    /// Reading or writing a checkpoint file failed.
    #[error("checkpoint {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// The checkpoint is not a valid safetensors file or lacks our metadata.
    #[error("checkpoint {path}: {message}")]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The checkpoint was written by an incompatible format version.
    #[error(
        "checkpoint {path}: format version {found} is not supported (this build reads version {expected})"
    )]
    Version {
        /// The file.
        path: PathBuf,
        /// Version stored in the file.
        found: String,
        /// Version this build reads.
        expected: u32,
    },
    /// A tensor is missing from the checkpoint.
    #[error("checkpoint {path}: tensor '{name}' is missing")]
    MissingTensor {
        /// The file.
        path: PathBuf,
        /// Tensor name.
        name: String,
    },
    /// A tensor has a different shape or dtype than the model expects.
    #[error(
        "checkpoint {path}: tensor '{name}' has shape {found:?} (dtype {dtype}), expected {expected:?} (F32)"
    )]
    Shape {
        /// The file.
        path: PathBuf,
        /// Tensor name.
        name: String,
        /// Shape in the file.
        found: Vec<usize>,
        /// Shape the model needs.
        expected: Vec<usize>,
        /// Dtype in the file.
        dtype: String,
    },
}
