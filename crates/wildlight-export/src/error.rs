//! Errors of the export pipeline and of reading exported assets.

use std::path::PathBuf;

/// Everything that can go wrong while exporting or reading an asset.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// A file or folder could not be created or read.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A file could not be written (its temporary file created, written,
    /// synced or renamed onto it).
    #[error(transparent)]
    Write(#[from] wildlight_data::DataError),
    /// A mesh file could not be written.
    #[error(transparent)]
    Mesh(#[from] wildlight_mesh::MeshError),
    /// An option is out of its valid range.
    #[error("invalid option {name}: {problem}")]
    InvalidOption {
        /// The option's name.
        name: &'static str,
        /// What is wrong with it.
        problem: String,
    },
    /// The field's zero level set has no surface inside the unit sphere.
    #[error("the SDF has no zero level set inside the unit sphere at resolution {resolution}")]
    EmptySurface {
        /// The marching-cubes resolution used.
        resolution: u32,
    },
    /// A stage of the pipeline failed (UV unwrapping, tangents, simplification).
    #[error("{stage}: {message}")]
    Stage {
        /// The stage that failed.
        stage: &'static str,
        /// What went wrong.
        message: String,
    },
    /// An image could not be encoded or decoded.
    #[error("{path}: image: {message}")]
    Image {
        /// The file (or embedded image) concerned.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A .glb file is malformed or uses something this reader does not support.
    #[error("{path}: {message}")]
    BadAsset {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}

impl ExportError {
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        ExportError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn bad_asset(path: &std::path::Path, message: impl Into<String>) -> Self {
        ExportError::BadAsset {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    pub(crate) fn stage(stage: &'static str, message: impl Into<String>) -> Self {
        ExportError::Stage {
            stage,
            message: message.into(),
        }
    }
}
