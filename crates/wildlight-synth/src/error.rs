//! The error type of `wildlight-synth`.

use std::path::PathBuf;

/// Everything that can go wrong while building a scene or writing a capture.
#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    /// No built-in scene has this name.
    #[error("unknown scene '{name}' (built-in scenes: {known})")]
    UnknownScene {
        /// The name that was asked for.
        name: String,
        /// The built-in scene names, comma separated.
        known: String,
    },
    /// An option has a value the synthesizer cannot use.
    #[error("invalid {what}: {problem}")]
    InvalidOption {
        /// The option concerned.
        what: String,
        /// What is wrong with it.
        problem: String,
    },
    /// A mesh could not be read or written.
    #[error(transparent)]
    Mesh(#[from] wildlight_mesh::MeshError),
    /// Writing the dataset failed.
    #[error(transparent)]
    Data(#[from] wildlight_data::DataError),
    /// A mesh given with `--mesh` cannot be rendered.
    #[error("{path}: {problem}")]
    BadMesh {
        /// The mesh file.
        path: PathBuf,
        /// What is wrong with it.
        problem: String,
    },
    /// An environment map could not be read.
    #[error(transparent)]
    EnvMap(#[from] wildlight_pathtrace::EnvMapError),
    /// A material definition (`gt/material.json` or `--material`) is invalid.
    #[error("{source_name}: invalid material definition: {problem}")]
    Material {
        /// The file, or "--material".
        source_name: String,
        /// What is wrong with it.
        problem: String,
    },
    /// An operating-system error on a file.
    #[error("{path}: {action} failed: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// What was being done.
        action: &'static str,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}
