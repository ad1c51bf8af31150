//! Dataset IO for WildLight/NeuS captures (SPEC §5): `cameras_sphere.npz`,
//! cameras and rays, images and masks, loading a dataset folder, writing
//! one, and the summary behind `wildlight info`.

pub mod atomic;
pub mod camera;
pub mod dataset;
pub mod error;
pub mod exr_io;
pub mod image;
pub mod info;
pub mod npz;
pub mod png_io;
pub mod ray;
pub mod writer;

pub use camera::Camera;
pub use dataset::{Dataset, LoadOptions, View};
pub use error::DataError;
pub use image::{Mask, RgbImage};
pub use info::DatasetInfo;
pub use npz::{CameraArrays, CamerasNpz};
pub use ray::Ray;
pub use writer::DatasetWriter;
