//! Dataset IO for WildLight/NeuS captures (SPEC §5): `cameras_sphere.npz`,
//! cameras and rays, images and masks, loading a dataset folder, writing
//! one, and the summary behind `wildlight info`.
//!
//! Reading: [`Dataset::load`] (a folder, with its `val/` split) or
//! [`Dataset::load_cameras`] (cameras only). Each [`View`] holds a
//! [`Camera`] (intrinsics, pose and centre in the normalized frame,
//! [`Camera::ray`] through any pixel, [`Camera::project`]), an
//! [`RgbImage`] and an optional [`Mask`].
//!
//! Writing: [`DatasetWriter`] writes `cameras_sphere.npz`, `image/NNN.exr`,
//! `mask/NNN.png` and ground-truth maps `gt/<kind>/NNN.exr`, every file
//! atomically; cameras for it come from [`Camera::look_at`] or
//! [`Camera::from_krt`] with [`camera::intrinsics_from_fov_x`].
//!
//! Rendering: [`ViewMaps`], every map a renderer produces for one view
//! (a trained run's or an exported asset's), in one layout.
//!
//! Every error is a [`DataError`] naming the file (and the npz key or the
//! pixel) and the problem.

#![warn(missing_docs)]

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
pub mod view_maps;
pub mod writer;

pub use camera::Camera;
pub use dataset::{Dataset, LoadOptions, View};
pub use error::DataError;
pub use image::{Mask, RgbImage};
pub use info::DatasetInfo;
pub use npz::{CameraArrays, CamerasNpz};
pub use ray::Ray;
pub use view_maps::ViewMaps;
pub use writer::DatasetWriter;
