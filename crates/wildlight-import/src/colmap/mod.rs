//! COLMAP: the subprocess runner ([`runner`]) and the sparse-model reader
//! for both the text and the binary formats ([`model`]).

pub mod model;
pub mod runner;

pub use model::{CameraModel, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint};
pub use runner::{ColmapRun, ColmapSettings, find_colmap, find_colmap_in, run_colmap};
