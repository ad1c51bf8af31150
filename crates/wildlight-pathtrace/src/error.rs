//! The error type of `wildlight-pathtrace`.

use std::path::PathBuf;

/// An environment map that could not be read ([`crate::EnvMap::load`]).
#[derive(Debug, thiserror::Error)]
#[error("{path}: cannot read environment map: {problem}")]
pub struct EnvMapError {
    /// The image file.
    pub path: PathBuf,
    /// What went wrong.
    pub problem: String,
}
