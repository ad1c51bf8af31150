//! Loading a dataset folder in the WildLight/NeuS layout (SPEC §5):
//!
//! ```text
//! cameras_sphere.npz
//! image/000.exr ... | image/000.png ... | images.npy
//! mask/000.png ...          (optional; missing masks for some views are allowed)
//! val/                      (optional held-out views, same layout)
//! ```
//!
//! Image files are matched to cameras by the number in their name
//! (`007.exr` ↔ `world_mat_7`). When the names are not numbers, files
//! sorted by name are matched to cameras sorted by index, provided the
//! counts agree.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

use ndarray::{ArrayD, Axis};
use rayon::prelude::*;

use crate::camera::Camera;
use crate::error::DataError;
use crate::exr_io::{exr_dimensions, read_exr_rgb};
use crate::image::{Mask, RgbImage};
use crate::npz::{CamerasNpz, read_cameras_npz};
use crate::png_io::{PNG_SATURATION, PngDecoding, png_dimensions, read_mask_png, read_png_rgb};

/// The saturation cap of `images.npy` data after rescaling (SPEC §5).
pub const NPY_SATURATION: f32 = 5.0;

/// How to load a dataset.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadOptions {
    /// How PNG values become linear floats (default value/256).
    pub png_decoding: PngDecoding,
    /// Whether to load the `val/` split when present (default true).
    pub load_val: bool,
    /// Overrides the saturation cap: `Some(None)` = no cap, `Some(Some(c))` = cap c.
    pub saturation_override: Option<Option<f32>>,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions {
            png_decoding: PngDecoding::Linear256,
            load_val: true,
            saturation_override: None,
        }
    }
}

/// Where a dataset's pixels come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ImageSource {
    /// `image/*.exr` (linear float).
    Exr,
    /// `image/*.png` (8/16-bit).
    Png,
    /// `image/` holding both EXR and PNG files.
    Mixed,
    /// `images.npy`.
    Npy,
}

impl ImageSource {
    /// A short description for reports.
    pub fn describe(&self) -> &'static str {
        match self {
            ImageSource::Exr => "EXR (linear float)",
            ImageSource::Png => "PNG (8/16-bit)",
            ImageSource::Mixed => "EXR and PNG",
            ImageSource::Npy => "images.npy",
        }
    }
}

/// One view: its camera, its photo and its optional mask.
#[derive(Clone, Debug, PartialEq)]
pub struct View {
    /// Camera of this view (its size is the image's).
    pub camera: Camera,
    /// Linear RGB image.
    pub image: RgbImage,
    /// Object mask, when the dataset has one for this view.
    pub mask: Option<Mask>,
    /// The file the image came from (`images.npy` for packed data).
    pub image_path: PathBuf,
    /// This view's saturation cap (SPEC §4, §5): the image's own
    /// `max_intensity_i` when the npz has one (captures from `wildlight
    /// import`, whose photos clip at different levels after exposure
    /// scaling), else the dataset's [`Dataset::saturation`]; a
    /// `saturation_override` applies to every view. `None` = no cap.
    pub saturation: Option<f32>,
}

/// A loaded dataset folder.
#[derive(Clone, Debug, PartialEq)]
pub struct Dataset {
    /// The folder.
    pub root: PathBuf,
    /// The views, sorted by camera index.
    pub views: Vec<View>,
    /// The global saturation cap (SPEC §4, §5); `None` = no cap. Views may
    /// have their own ([`View::saturation`], [`Dataset::saturation_of`]).
    pub saturation: Option<f32>,
    /// The format the images were read from.
    pub source: ImageSource,
    /// The held-out split from `val/`, when present and requested.
    pub val: Option<Box<Dataset>>,
}

/// An image file found in `image/` (or a mask in `mask/`).
#[derive(Clone, Debug, PartialEq)]
struct FoundFile {
    index: usize,
    path: PathBuf,
}

fn list_files(dir: &Path, exts: &[&str]) -> Result<Vec<PathBuf>, DataError> {
    let entries = std::fs::read_dir(dir).map_err(|e| DataError::io(dir, "listing folder", e))?;
    let mut files = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| DataError::io(dir, "listing folder", e))?;
        let path = entry.path();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if path.is_file() && ext.as_deref().is_some_and(|e| exts.contains(&e)) {
            files.push(path);
        }
    }
    files.sort();
    Ok(files)
}

fn fmt_indices(set: &BTreeSet<usize>) -> String {
    let v: Vec<String> = set.iter().take(12).map(|i| i.to_string()).collect();
    let more = if set.len() > 12 {
        format!(" and {} more", set.len() - 12)
    } else {
        String::new()
    };
    format!("[{}]{more}", v.join(", "))
}

/// Matches files to camera indices (by number in the name, else by sorted order).
fn match_files(
    folder: &Path,
    npz: &Path,
    files: Vec<PathBuf>,
    camera_indices: &[usize],
    require_all: bool,
) -> Result<Vec<FoundFile>, DataError> {
    let numbered: Option<Vec<(usize, PathBuf)>> = files
        .iter()
        .map(|p| {
            let stem = p.file_stem()?.to_str()?;
            (!stem.is_empty() && stem.bytes().all(|b| b.is_ascii_digit()))
                .then(|| stem.parse().ok().map(|i| (i, p.clone())))
                .flatten()
        })
        .collect();
    let cams: BTreeSet<usize> = camera_indices.iter().copied().collect();
    let Some(numbered) = numbered else {
        if files.len() != camera_indices.len() {
            return Err(DataError::IndexMismatch {
                folder: folder.to_path_buf(),
                npz: npz.to_path_buf(),
                problem: format!(
                    "file names are not numbers, and there are {} files for {} cameras",
                    files.len(),
                    camera_indices.len()
                ),
            });
        }
        let mut sorted: Vec<usize> = camera_indices.to_vec();
        sorted.sort_unstable();
        return Ok(sorted
            .into_iter()
            .zip(files)
            .map(|(index, path)| FoundFile { index, path })
            .collect());
    };
    let mut by_index: BTreeMap<usize, PathBuf> = BTreeMap::new();
    for (index, path) in numbered {
        if let Some(other) = by_index.insert(index, path.clone()) {
            return Err(DataError::IndexMismatch {
                folder: folder.to_path_buf(),
                npz: npz.to_path_buf(),
                problem: format!(
                    "{} and {} both claim index {index}",
                    other.file_name().unwrap_or_default().to_string_lossy(),
                    path.file_name().unwrap_or_default().to_string_lossy()
                ),
            });
        }
    }
    let found: BTreeSet<usize> = by_index.keys().copied().collect();
    let extra: BTreeSet<usize> = found.difference(&cams).copied().collect();
    let missing: BTreeSet<usize> = cams.difference(&found).copied().collect();
    if !extra.is_empty() || (require_all && !missing.is_empty()) {
        let mut parts = Vec::new();
        if require_all && !missing.is_empty() {
            parts.push(format!(
                "no file for camera indices {}",
                fmt_indices(&missing)
            ));
        }
        if !extra.is_empty() {
            parts.push(format!(
                "files with no world_mat_<i>: indices {}",
                fmt_indices(&extra)
            ));
        }
        return Err(DataError::IndexMismatch {
            folder: folder.to_path_buf(),
            npz: npz.to_path_buf(),
            problem: parts.join("; "),
        });
    }
    Ok(by_index
        .into_iter()
        .map(|(index, path)| FoundFile { index, path })
        .collect())
}

/// The image files of a dataset, before their pixels are read.
enum ImageFiles {
    Files(Vec<FoundFile>, ImageSource),
    Npy(PathBuf),
}

fn find_images(dir: &Path, cams: &CamerasNpz) -> Result<ImageFiles, DataError> {
    let image_dir = dir.join("image");
    let indices: Vec<usize> = cams.cameras.iter().map(|c| c.index).collect();
    if image_dir.is_dir() {
        let files = list_files(&image_dir, &["exr", "png"])?;
        if !files.is_empty() {
            let is_ext =
                |p: &PathBuf, e: &str| p.extension().is_some_and(|x| x.eq_ignore_ascii_case(e));
            let source = match (
                files.iter().any(|p| is_ext(p, "exr")),
                files.iter().any(|p| is_ext(p, "png")),
            ) {
                (true, false) => ImageSource::Exr,
                (false, true) => ImageSource::Png,
                _ => ImageSource::Mixed,
            };
            let found = match_files(&image_dir, &cams.path, files, &indices, true)?;
            return Ok(ImageFiles::Files(found, source));
        }
    }
    let npy = dir.join("images.npy");
    if npy.is_file() {
        return Ok(ImageFiles::Npy(npy));
    }
    Err(DataError::NoImages {
        path: dir.to_path_buf(),
    })
}

fn is_exr(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("exr"))
}

fn read_image_file(path: &Path, decoding: PngDecoding) -> Result<RgbImage, DataError> {
    let image = if is_exr(path) {
        read_exr_rgb(path)?
    } else {
        read_png_rgb(path, decoding)?
    };
    image.check_finite(path)?;
    Ok(image)
}

fn check_dir(dir: &Path) -> Result<(), DataError> {
    if !dir.is_dir() {
        return Err(DataError::MissingFolder {
            path: dir.to_path_buf(),
        });
    }
    Ok(())
}

/// Reads `images.npy`: (N, H, W, 3) of float32/float64/uint8/uint16, one
/// slice per camera in index order, scaled by 5 / max_intensity (SPEC §5;
/// when the npz has no `max_intensity`, the largest value of the array is
/// used).
fn read_images_npy(path: &Path, cams: &CamerasNpz) -> Result<Vec<RgbImage>, DataError> {
    let bad = |m: String| DataError::BadImage {
        path: path.to_path_buf(),
        format: "npy",
        message: m,
    };
    let file = std::fs::File::open(path).map_err(|e| DataError::io(path, "opening", e))?;
    let mut reader = std::io::BufReader::new(file);
    use ndarray_npy::{ReadNpyError, ReadNpyExt};
    use std::io::Seek;
    macro_rules! try_type {
        ($t:ty) => {{
            match ArrayD::<$t>::read_npy(&mut reader) {
                Ok(a) => Some(a.mapv(|v| v as f32)),
                Err(ReadNpyError::WrongDescriptor(_)) => {
                    reader
                        .rewind()
                        .map_err(|e| DataError::io(path, "reading", e))?;
                    None
                }
                Err(e) => return Err(bad(e.to_string())),
            }
        }};
    }
    let array = match try_type!(f32) {
        Some(a) => a,
        None => match try_type!(f64) {
            Some(a) => a,
            None => match try_type!(u8) {
                Some(a) => a,
                None => try_type!(u16).ok_or_else(|| {
                    bad("unsupported dtype (expected float32/float64/uint8/uint16)".into())
                })?,
            },
        },
    };
    let shape = array.shape().to_vec();
    if shape.len() != 4 || shape[3] != 3 {
        return Err(bad(format!("shape {shape:?}, expected (N, H, W, 3)")));
    }
    if shape[0] != cams.cameras.len() {
        return Err(DataError::IndexMismatch {
            folder: path.to_path_buf(),
            npz: cams.path.clone(),
            problem: format!("{} images for {} cameras", shape[0], cams.cameras.len()),
        });
    }
    let (h, w) = (shape[1] as u32, shape[2] as u32);
    let mut images = Vec::with_capacity(shape[0]);
    for (i, slice) in array.axis_iter(Axis(0)).enumerate() {
        let image = RgbImage {
            width: w,
            height: h,
            data: slice.iter().copied().collect(),
        };
        image.check_finite(&path.join(format!("[{i}]")))?;
        images.push(image);
    }
    let max_intensity = match cams.max_intensity {
        Some(m) => m as f32,
        None => images.iter().map(RgbImage::max_value).fold(0.0, f32::max),
    };
    if max_intensity > 0.0 {
        let scale = NPY_SATURATION / max_intensity;
        for image in &mut images {
            image.data.iter_mut().for_each(|v| *v *= scale);
        }
    }
    Ok(images)
}

impl Dataset {
    /// Loads the dataset folder `dir` (SPEC §5). Every problem is an error
    /// naming the file and what is wrong: missing folder or npz, bad
    /// cameras, image files not matching the cameras, images of different
    /// sizes, masks of another size than their image, NaN/inf pixels,
    /// unreadable EXR/PNG.
    pub fn load(dir: &Path, opts: &LoadOptions) -> Result<Dataset, DataError> {
        check_dir(dir)?;
        let cams = read_cameras_npz(&dir.join("cameras_sphere.npz"))?;
        let (paths, images, source) = match find_images(dir, &cams)? {
            ImageFiles::Files(found, source) => {
                let images = found
                    .par_iter()
                    .map(|f| read_image_file(&f.path, opts.png_decoding))
                    .collect::<Result<Vec<_>, _>>()?;
                (
                    found.into_iter().map(|f| f.path).collect::<Vec<_>>(),
                    images,
                    source,
                )
            }
            ImageFiles::Npy(path) => {
                let images = read_images_npy(&path, &cams)?;
                (vec![path; images.len()], images, ImageSource::Npy)
            }
        };
        let (width, height) = (images[0].width, images[0].height);
        for (path, image) in paths.iter().zip(&images) {
            if (image.width, image.height) != (width, height) {
                return Err(DataError::ImageSizeMismatch {
                    path: path.clone(),
                    found_width: image.width,
                    found_height: image.height,
                    first: paths[0].clone(),
                    width,
                    height,
                });
            }
        }
        let masks = load_masks(dir, &cams, width, height)?;
        let mut views = Vec::with_capacity(images.len());
        for ((arrays, image), image_path) in cams.cameras.iter().zip(images).zip(paths) {
            let camera = Camera::from_arrays(arrays, width, height, &cams.path)?;
            let mask = masks.get(&arrays.index).cloned();
            views.push(View {
                camera,
                image,
                mask,
                image_path,
                saturation: None,
            });
        }
        let saturation = match opts.saturation_override {
            Some(s) => s,
            None => match (source, cams.max_intensity) {
                (ImageSource::Npy, _) => Some(NPY_SATURATION),
                (_, Some(m)) => Some(m as f32),
                (ImageSource::Exr, None) => None,
                (_, None) => Some(match opts.png_decoding {
                    PngDecoding::Linear256 => PNG_SATURATION,
                    PngDecoding::Srgb => 1.0 - 0.001,
                }),
            },
        };
        for (view, arrays) in views.iter_mut().zip(&cams.cameras) {
            // Per-image caps apply to image files (images.npy is rescaled to cap 5).
            let own = arrays.max_intensity.filter(|_| source != ImageSource::Npy);
            view.saturation = match (opts.saturation_override, own) {
                (Some(s), _) => s,
                (None, Some(m)) => Some(m as f32),
                (None, None) => saturation,
            };
        }
        let val_dir = dir.join("val");
        let val = if opts.load_val && val_dir.is_dir() {
            let val_opts = LoadOptions {
                load_val: false,
                ..opts.clone()
            };
            Some(Box::new(Dataset::load(&val_dir, &val_opts)?))
        } else {
            None
        };
        Ok(Dataset {
            root: dir.to_path_buf(),
            views,
            saturation,
            source,
            val,
        })
    }

    /// Reads only the cameras of a dataset folder or of a
    /// `cameras_sphere.npz` file (for rendering or evaluating from a
    /// capture's cameras). The image size comes from the image headers
    /// when the folder has images; otherwise it is estimated from the
    /// principal point as (2·cx + 1, 2·cy + 1), rounded.
    pub fn load_cameras(path: &Path) -> Result<Vec<Camera>, DataError> {
        let (dir, npz) = if path.is_dir() {
            (Some(path.to_path_buf()), path.join("cameras_sphere.npz"))
        } else if path.is_file() {
            (None, path.to_path_buf())
        } else {
            return Err(DataError::MissingFile {
                path: path.to_path_buf(),
                what: "dataset folder or cameras_sphere.npz".into(),
            });
        };
        let cams = read_cameras_npz(&npz)?;
        let size = match dir.as_deref().map(|d| find_images(d, &cams)) {
            Some(Ok(ImageFiles::Files(found, _))) => {
                let p = &found[0].path;
                Some(if is_exr(p) {
                    exr_dimensions(p)?
                } else {
                    png_dimensions(p)?
                })
            }
            Some(Ok(ImageFiles::Npy(p))) => Some(npy_image_size(&p)?),
            Some(Err(DataError::NoImages { .. })) | None => None,
            Some(Err(e)) => return Err(e),
        };
        cams.cameras
            .iter()
            .map(|arrays| {
                let cam = Camera::from_arrays(arrays, 0, 0, &cams.path)?;
                let (w, h) = size.unwrap_or_else(|| {
                    (
                        (2.0 * cam.cx() + 1.0).round().max(1.0) as u32,
                        (2.0 * cam.cy() + 1.0).round().max(1.0) as u32,
                    )
                });
                Ok(Camera {
                    width: w,
                    height: h,
                    ..cam
                })
            })
            .collect()
    }

    /// The saturation cap of view `view` (a position in [`Dataset::views`]):
    /// its own `max_intensity_i` when the capture has one, else the global
    /// [`Dataset::saturation`]. Same as `self.views[view].saturation`.
    pub fn saturation_of(&self, view: usize) -> Option<f32> {
        self.views[view].saturation
    }

    /// Image width (all views share it).
    pub fn width(&self) -> u32 {
        self.views.first().map_or(0, |v| v.image.width)
    }

    /// Image height (all views share it).
    pub fn height(&self) -> u32 {
        self.views.first().map_or(0, |v| v.image.height)
    }

    /// Number of views with the flash on.
    pub fn flash_count(&self) -> usize {
        self.views.iter().filter(|v| v.camera.flash()).count()
    }

    /// Whether at least one view has a mask.
    pub fn has_masks(&self) -> bool {
        self.views.iter().any(|v| v.mask.is_some())
    }

    /// The cameras of all views, in index order.
    pub fn cameras(&self) -> Vec<Camera> {
        self.views.iter().map(|v| v.camera.clone()).collect()
    }
}

/// Reads the (W, H) of `images.npy` from its header.
fn npy_image_size(path: &Path) -> Result<(u32, u32), DataError> {
    let bad = |m: String| DataError::BadImage {
        path: path.to_path_buf(),
        format: "npy",
        message: m,
    };
    let bytes = std::fs::read(path).map_err(|e| DataError::io(path, "reading", e))?;
    // The header is an ASCII Python dict right after the magic and lengths.
    let header = String::from_utf8_lossy(&bytes[..bytes.len().min(4096)]).to_string();
    let start = header
        .find("'shape': (")
        .ok_or_else(|| bad("no shape in the npy header".into()))?
        + 10;
    let end = header[start..]
        .find(')')
        .ok_or_else(|| bad("malformed npy header".into()))?
        + start;
    let dims: Vec<u32> = header[start..end]
        .split(',')
        .filter_map(|s| s.trim().parse().ok())
        .collect();
    match dims.as_slice() {
        [_, h, w, 3] => Ok((*w, *h)),
        _ => Err(bad(format!(
            "shape ({}) , expected (N, H, W, 3)",
            &header[start..end]
        ))),
    }
}

fn load_masks(
    dir: &Path,
    cams: &CamerasNpz,
    width: u32,
    height: u32,
) -> Result<BTreeMap<usize, Mask>, DataError> {
    let mask_dir = dir.join("mask");
    if !mask_dir.is_dir() {
        return Ok(BTreeMap::new());
    }
    let files = list_files(&mask_dir, &["png"])?;
    if files.is_empty() {
        return Ok(BTreeMap::new());
    }
    let indices: Vec<usize> = cams.cameras.iter().map(|c| c.index).collect();
    let found = match_files(&mask_dir, &cams.path, files, &indices, false)?;
    let masks = found
        .par_iter()
        .map(|f| {
            let mask = read_mask_png(&f.path)?;
            if (mask.width, mask.height) != (width, height) {
                return Err(DataError::MaskSizeMismatch {
                    path: f.path.clone(),
                    found_width: mask.width,
                    found_height: mask.height,
                    width,
                    height,
                });
            }
            Ok((f.index, mask))
        })
        .collect::<Result<Vec<_>, _>>()?;
    Ok(masks.into_iter().collect())
}
