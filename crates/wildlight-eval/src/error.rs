//! Errors of the evaluation crate.

use std::path::PathBuf;

/// Everything that can make an evaluation fail.
#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    /// A mesh could not be read.
    #[error(transparent)]
    Mesh(#[from] wildlight_mesh::MeshError),
    /// A dataset, image, mask or camera file could not be read.
    #[error(transparent)]
    Data(#[from] wildlight_data::DataError),
    /// A mesh cannot be evaluated (no triangles, zero area, nothing visible).
    #[error("{what}: {problem}")]
    UnusableMesh {
        /// Which mesh (file name or role).
        what: String,
        /// What is wrong with it.
        problem: String,
    },
    /// A file or folder a metric needs is missing or inconsistent.
    #[error("{path}: {problem}")]
    Input {
        /// The file or folder concerned.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}
