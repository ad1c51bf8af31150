//! Writing a dataset in the WildLight/NeuS layout (SPEC §5) plus the
//! ground-truth maps of the shared conventions (`<split>/gt/<kind>/NNN.exr`).
//!
//! Every file is written atomically (temporary file, then rename). Images
//! are linear float32 EXR (`image/NNN.exr`), masks 8-bit PNG
//! (`mask/NNN.png`, 255 = object), cameras `cameras_sphere.npz` (float64).

use std::path::{Path, PathBuf};

use crate::camera::Camera;
use crate::error::DataError;
use crate::exr_io::{write_exr_channels, write_exr_rgb};
use crate::image::{Mask, RgbImage};
use crate::npz::write_cameras_npz;
use crate::png_io::write_mask_png;

/// The file name of image `index` with extension `ext`: `007.exr`
/// (3 digits, more when needed).
pub fn indexed_file_name(index: usize, ext: &str) -> String {
    format!("{index:03}.{ext}")
}

/// Writes the files of one dataset folder (or of its `val/` split).
#[derive(Clone, Debug)]
pub struct DatasetWriter {
    root: PathBuf,
}

fn create_dir(path: &Path) -> Result<(), DataError> {
    std::fs::create_dir_all(path).map_err(|e| DataError::io(path, "creating folder", e))
}

impl DatasetWriter {
    /// Creates `root` (and its `image/` and `mask/` folders) if needed.
    pub fn create(root: &Path) -> Result<DatasetWriter, DataError> {
        create_dir(&root.join("image"))?;
        create_dir(&root.join("mask"))?;
        Ok(DatasetWriter {
            root: root.to_path_buf(),
        })
    }

    /// A writer for the held-out split `root/val/`.
    pub fn val(&self) -> Result<DatasetWriter, DataError> {
        DatasetWriter::create(&self.root.join("val"))
    }

    /// The dataset folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// `root/image/NNN.exr`.
    pub fn image_path(&self, index: usize) -> PathBuf {
        self.root
            .join("image")
            .join(indexed_file_name(index, "exr"))
    }

    /// `root/mask/NNN.png`.
    pub fn mask_path(&self, index: usize) -> PathBuf {
        self.root.join("mask").join(indexed_file_name(index, "png"))
    }

    /// `root/gt/<kind>/NNN.exr` (shared conventions: ground-truth maps).
    pub fn map_path(&self, kind: &str, index: usize) -> PathBuf {
        self.root
            .join("gt")
            .join(kind)
            .join(indexed_file_name(index, "exr"))
    }

    /// Writes `root/cameras_sphere.npz` for `cameras` (their `world_mat`,
    /// `scale_mat` and `light_energy`), with `max_intensity` when given.
    pub fn write_cameras(
        &self,
        cameras: &[Camera],
        max_intensity: Option<f64>,
    ) -> Result<PathBuf, DataError> {
        let path = self.root.join("cameras_sphere.npz");
        let arrays: Vec<_> = cameras.iter().map(Camera::to_arrays).collect();
        write_cameras_npz(&path, &arrays, max_intensity)?;
        Ok(path)
    }

    /// Writes `root/image/NNN.exr`.
    pub fn write_image(&self, index: usize, image: &RgbImage) -> Result<PathBuf, DataError> {
        let path = self.image_path(index);
        write_exr_rgb(&path, image)?;
        Ok(path)
    }

    /// Writes `root/mask/NNN.png`.
    pub fn write_mask(&self, index: usize, mask: &Mask) -> Result<PathBuf, DataError> {
        let path = self.mask_path(index);
        write_mask_png(&path, mask)?;
        Ok(path)
    }

    /// Writes the 3-channel ground-truth map `root/gt/<kind>/NNN.exr`.
    pub fn write_map(
        &self,
        kind: &str,
        index: usize,
        map: &RgbImage,
    ) -> Result<PathBuf, DataError> {
        let path = self.map_path(kind, index);
        if let Some(dir) = path.parent() {
            create_dir(dir)?;
        }
        write_exr_rgb(&path, map)?;
        Ok(path)
    }

    /// Writes an N-channel ground-truth map `root/gt/<kind>/NNN.exr` (for
    /// example `params` with channels `p0`..`p8`).
    pub fn write_map_channels(
        &self,
        kind: &str,
        index: usize,
        width: u32,
        height: u32,
        channels: &[(&str, &[f32])],
    ) -> Result<PathBuf, DataError> {
        let path = self.map_path(kind, index);
        if let Some(dir) = path.parent() {
            create_dir(dir)?;
        }
        write_exr_channels(&path, width, height, channels)?;
        Ok(path)
    }

    /// Writes a whole split: the cameras, and for each view its image and
    /// (when given) its mask. Checks that every image has its camera's size
    /// and every mask its image's size, and that indices are distinct.
    pub fn write_views(
        &self,
        views: &[ViewToWrite<'_>],
        max_intensity: Option<f64>,
    ) -> Result<(), DataError> {
        for v in views {
            let (w, h) = (v.camera.width, v.camera.height);
            if (v.image.width, v.image.height) != (w, h)
                || v.image.data.len() != 3 * v.image.pixel_count()
            {
                return Err(DataError::InvalidArgument {
                    what: self.image_path(v.camera.index).display().to_string(),
                    problem: format!(
                        "image is {}x{} ({} values) but camera {} is {w}x{h}",
                        v.image.width,
                        v.image.height,
                        v.image.data.len(),
                        v.camera.index
                    ),
                });
            }
            if let Some(m) = v.mask
                && ((m.width, m.height) != (w, h) || m.data.len() != (w * h) as usize)
            {
                return Err(DataError::InvalidArgument {
                    what: self.mask_path(v.camera.index).display().to_string(),
                    problem: format!("mask is {}x{} but its image is {w}x{h}", m.width, m.height),
                });
            }
        }
        let cameras: Vec<Camera> = views.iter().map(|v| v.camera.clone()).collect();
        self.write_cameras(&cameras, max_intensity)?;
        for v in views {
            self.write_image(v.camera.index, v.image)?;
            if let Some(m) = v.mask {
                self.write_mask(v.camera.index, m)?;
            }
        }
        Ok(())
    }
}

/// One view handed to [`DatasetWriter::write_views`].
#[derive(Clone, Copy, Debug)]
pub struct ViewToWrite<'a> {
    /// The camera (its index names the files).
    pub camera: &'a Camera,
    /// The linear RGB image.
    pub image: &'a RgbImage,
    /// The object mask, if any.
    pub mask: Option<&'a Mask>,
}
