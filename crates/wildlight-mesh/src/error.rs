//! Errors of mesh reading and writing.

use std::path::PathBuf;

/// Everything that can go wrong while reading or writing a mesh file.
///
/// Every variant names the file; parse errors of text formats also name the
/// line (1-based).
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file could not be opened or read.
    #[error("{path}: {source}")]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// A text line (OBJ or ascii PLY, including the PLY header) is malformed.
    #[error("{path}: line {line}: {message}")]
    Line {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// The file is malformed in a way not tied to one text line (binary PLY
    /// body, index out of range, truncated data, ...).
    #[error("{path}: {message}")]
    Invalid {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
    /// The file could not be written (its temporary file created, written,
    /// synced or renamed onto it).
    #[error(transparent)]
    Write(#[from] wildlight_data::DataError),
    /// The file name has no extension this crate reads or writes.
    #[error("{path}: unknown mesh format (expected a .ply or .obj file)")]
    UnknownFormat {
        /// The file concerned.
        path: PathBuf,
    },
}

impl MeshError {
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        MeshError::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    pub(crate) fn line(path: &std::path::Path, line: usize, message: impl Into<String>) -> Self {
        MeshError::Line {
            path: path.to_path_buf(),
            line,
            message: message.into(),
        }
    }

    pub(crate) fn invalid(path: &std::path::Path, message: impl Into<String>) -> Self {
        MeshError::Invalid {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }
}
