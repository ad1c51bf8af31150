//! The import itself: photos → COLMAP → region of interest → capture.
//! See the crate documentation for the steps and the format.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{DMat3, DVec3};
use rayon::prelude::*;
use wildlight_data::npz::write_cameras_npz;
use wildlight_data::{Camera, RgbImage};

use crate::colmap::{ColmapCamera, ColmapModel, ColmapSettings, find_colmap, run_colmap};
use crate::error::{ImportError, list_some};
use crate::linear::{ExposureScales, exposure_scales, saturation_cap, to_linear};
use crate::photos::{
    PhotoFormat, PhotoInfo, check_sizes, decode, flash_labels, list_photos, scan_photos,
};
use crate::preview::{PreviewView, render_preview};
use crate::report::{ColmapReport, ImportReport, PhotoReport, RoiReport};
use crate::resample::{Pinhole, resample};
use crate::roi::{Roi, RoiCamera, cameras_inside, estimate_roi};

/// Fewer registered photos than this gives a warning.
pub const FEW_PHOTOS: usize = 20;

/// The default longer side of the capture's images.
pub const DEFAULT_MAX_SIZE: u32 = 1000;

/// Albedo of the surface assumed when choosing the flash energy.
pub const ASSUMED_ALBEDO: f64 = 0.5;

/// What to import and how.
#[derive(Clone, Debug)]
pub struct ImportOptions {
    /// The photo folder.
    pub photos: PathBuf,
    /// The capture folder to write.
    pub out: PathBuf,
    /// `--flash`: photos with the flash on (globs or names, comma separated).
    pub flash: Option<String>,
    /// `--no-flash`: photos with the flash off.
    pub no_flash: Option<String>,
    /// `--colmap`: an existing sparse model instead of running COLMAP.
    pub colmap_model: Option<PathBuf>,
    /// `--center`/`--radius`: the region of interest, in world units.
    pub roi: Option<Roi>,
    /// Longer side of the capture's images, in pixels.
    pub max_size: u32,
    /// COLMAP's settings.
    pub colmap: ColmapSettings,
}

impl ImportOptions {
    /// The defaults for `photos` → `out`.
    pub fn new(photos: impl Into<PathBuf>, out: impl Into<PathBuf>) -> ImportOptions {
        ImportOptions {
            photos: photos.into(),
            out: out.into(),
            flash: None,
            no_flash: None,
            colmap_model: None,
            roi: None,
            max_size: DEFAULT_MAX_SIZE,
            colmap: ColmapSettings::default(),
        }
    }
}

/// The minimum number of registered photos: 3, or a quarter of the photos.
pub fn min_registered(total: usize) -> usize {
    3.max(total.div_ceil(4))
}

/// The hidden sibling folder everything is written to; renamed onto the
/// output at the end, removed when the import fails.
struct Staging {
    dir: PathBuf,
    out: PathBuf,
    committed: bool,
}

impl Staging {
    fn new(out: &Path) -> Result<Staging, ImportError> {
        let name = out
            .file_name()
            .ok_or_else(|| ImportError::InvalidArgument {
                what: format!("--out {}", out.display()),
                problem: "is not a folder name".into(),
            })?
            .to_string_lossy()
            .into_owned();
        if out.exists() {
            if !out.is_dir() {
                return Err(ImportError::InvalidArgument {
                    what: format!("--out {}", out.display()),
                    problem: "exists and is not a folder".into(),
                });
            }
            let empty = std::fs::read_dir(out)
                .map_err(|e| ImportError::io(out, "listing", e))?
                .next()
                .is_none();
            if !empty && !out.join("import.json").is_file() {
                return Err(ImportError::OutputExists {
                    path: out.to_path_buf(),
                });
            }
        }
        let parent = match out.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        std::fs::create_dir_all(&parent).map_err(|e| ImportError::io(&parent, "creating", e))?;
        let dir = parent.join(format!(".{name}.importing-{}", std::process::id()));
        if dir.exists() {
            std::fs::remove_dir_all(&dir).map_err(|e| ImportError::io(&dir, "removing", e))?;
        }
        std::fs::create_dir_all(dir.join("image"))
            .map_err(|e| ImportError::io(&dir, "creating", e))?;
        Ok(Staging {
            dir,
            out: out.to_path_buf(),
            committed: false,
        })
    }

    /// Moves the finished capture onto the output folder (replacing an
    /// earlier import there).
    fn commit(mut self) -> Result<(), ImportError> {
        let old = self.dir.with_file_name(format!(
            "{}.old",
            self.dir.file_name().unwrap_or_default().to_string_lossy()
        ));
        if self.out.exists() {
            std::fs::rename(&self.out, &old)
                .map_err(|e| ImportError::io(&self.out, "moving aside", e))?;
        }
        std::fs::rename(&self.dir, &self.out)
            .map_err(|e| ImportError::io(&self.out, "renaming the finished capture onto", e))?;
        self.committed = true;
        if old.exists() {
            let _ = std::fs::remove_dir_all(&old);
        }
        Ok(())
    }
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.dir);
        }
    }
}

/// The photos as COLMAP sees them: `work/images/` holds a link to each
/// JPEG/PNG with orientation 1, and an oriented 8-bit PNG copy
/// (`<file>.png`) of the others. Returns each photo's name there.
fn prepare_colmap_images(photos: &[PhotoInfo], dir: &Path) -> Result<Vec<String>, ImportError> {
    std::fs::create_dir_all(dir).map_err(|e| ImportError::io(dir, "creating", e))?;
    photos
        .par_iter()
        .map(|p| {
            let as_is = p.format != PhotoFormat::Exr && p.exif.orientation == 1;
            if as_is {
                let link = dir.join(&p.file);
                let src = std::fs::canonicalize(&p.path)
                    .map_err(|e| ImportError::io(&p.path, "resolving", e))?;
                link_or_copy(&src, &link)?;
                return Ok(p.file.clone());
            }
            let name = format!("{}.png", p.file);
            let decoded = decode(&p.path, p.exif.orientation)?;
            let rgb: Vec<u8> = match decoded.pixels {
                crate::photos::Pixels::Srgb8(d) => d,
                crate::photos::Pixels::Srgb16(d) => d.iter().map(|v| (v >> 8) as u8).collect(),
                crate::photos::Pixels::Linear(d) => d
                    .iter()
                    .map(|v| {
                        (wildlight_data::png_io::linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0).round()
                            as u8
                    })
                    .collect(),
            };
            let img =
                image::RgbImage::from_raw(decoded.width, decoded.height, rgb).ok_or_else(|| {
                    ImportError::InvalidArgument {
                        what: p.file.clone(),
                        problem: "decoded size does not match its pixels".into(),
                    }
                })?;
            let path = dir.join(&name);
            img.save(&path).map_err(|e| ImportError::InvalidArgument {
                what: path.display().to_string(),
                problem: format!("cannot write the oriented copy for COLMAP: {e}"),
            })?;
            Ok(name)
        })
        .collect()
}

fn link_or_copy(src: &Path, link: &Path) -> Result<(), ImportError> {
    #[cfg(unix)]
    if std::os::unix::fs::symlink(src, link).is_ok() {
        return Ok(());
    }
    std::fs::copy(src, link)
        .map(|_| ())
        .map_err(|e| ImportError::io(link, "copying a photo for COLMAP", e))
}

/// The shared camera's prior `f,cx,cy,k` (SIMPLE_RADIAL) from
/// FocalLengthIn35mmFilm (35 mm film's 43.27 mm diagonal ↔ the image
/// diagonal), when a photo has it.
fn camera_prior(photos: &[PhotoInfo], width: u32, height: u32, model: &str) -> Option<String> {
    if model != "SIMPLE_RADIAL" {
        return None;
    }
    let f35 = photos.iter().find_map(|p| p.exif.focal_length_35mm)?;
    let diag = (width as f64).hypot(height as f64);
    let f = f35 / 36f64.hypot(24.0) * diag;
    Some(format!(
        "{f:.3},{:.3},{:.3},0",
        width as f64 / 2.0,
        height as f64 / 2.0
    ))
}

/// A registered photo, ready to be written.
struct Registered {
    photo: usize,
    image_id: u32,
    index: usize,
    distorted: ColmapCamera,
    target: Pinhole,
    r: DMat3,
    t: DVec3,
}

/// The photo an image name of a model refers to: its file name, the
/// oriented copy `<file>.png`, or a unique file with the same stem.
fn match_name(
    name: &str,
    files: &BTreeMap<String, usize>,
    stems: &BTreeMap<String, Vec<usize>>,
) -> Option<usize> {
    let base = name.rsplit(['/', '\\']).next().unwrap_or(name);
    if let Some(i) = files.get(base) {
        return Some(*i);
    }
    if let Some(stripped) = base.strip_suffix(".png")
        && let Some(i) = files.get(stripped)
    {
        return Some(*i);
    }
    let stem = Path::new(base).file_stem()?.to_string_lossy().into_owned();
    match stems.get(&stem).map(Vec::as_slice) {
        Some([i]) => Some(*i),
        _ => None,
    }
}

/// `cam` scaled to `width`×`height` when the aspect ratio agrees (a model
/// made on resized photos); `None` otherwise.
fn scaled_camera(cam: &ColmapCamera, width: u32, height: u32) -> Option<ColmapCamera> {
    if (cam.width, cam.height) == (width, height) {
        return Some(cam.clone());
    }
    let sx = width as f64 / cam.width as f64;
    let sy = height as f64 / cam.height as f64;
    if (sx / sy - 1.0).abs() > 0.01 {
        return None;
    }
    let mut c = cam.clone();
    c.width = width;
    c.height = height;
    let s = 0.5 * (sx + sy);
    let scaled: &[usize] = if c.has_single_focal() {
        &[0, 1, 2]
    } else {
        &[0, 1, 2, 3]
    };
    for i in scaled {
        c.params[*i] *= s;
    }
    Some(c)
}

/// The luminance (mean of RGB) median in a square window.
fn window_median(img: &RgbImage, cx: f64, cy: f64, half: f64) -> Option<f64> {
    let x0 = (cx - half).floor().max(0.0) as u32;
    let y0 = (cy - half).floor().max(0.0) as u32;
    let x1 = ((cx + half).ceil() as i64).min(img.width as i64 - 1);
    let y1 = ((cy + half).ceil() as i64).min(img.height as i64 - 1);
    if x1 < x0 as i64 || y1 < y0 as i64 {
        return None;
    }
    let mut v = Vec::new();
    for y in y0..=y1 as u32 {
        for x in x0..=x1 as u32 {
            let p = img.get(x, y);
            v.push((p[0] + p[1] + p[2]) as f64 / 3.0);
        }
    }
    v.sort_by(f64::total_cmp);
    v.get(v.len() / 2).copied()
}

fn median(mut v: Vec<f64>) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[(v.len() - 1) / 2])
}

/// Runs the import. `progress` gets one line per stage.
pub fn import(
    opts: &ImportOptions,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<ImportReport, ImportError> {
    let started = Instant::now();
    if opts.max_size < 32 {
        return Err(ImportError::InvalidArgument {
            what: format!("--max-size {}", opts.max_size),
            problem: "must be at least 32 pixels".into(),
        });
    }
    if let Some(roi) = &opts.roi
        && !(roi.radius > 0.0 && roi.radius.is_finite() && roi.center.is_finite())
    {
        return Err(ImportError::InvalidArgument {
            what: format!("--radius {}", roi.radius),
            problem: "must be a positive number".into(),
        });
    }
    let mut warnings = Vec::new();

    // 1. Photos and EXIF.
    let paths = list_photos(&opts.photos)?;
    progress(&format!(
        "reading {} photos in {}",
        paths.len(),
        opts.photos.display()
    ));
    let photos = scan_photos(&paths)?;
    for p in &photos {
        if let Some(w) = &p.warning {
            warnings.push(format!("{}: {w}", p.file));
        }
    }
    let (width, height) = check_sizes(&photos)?;
    let labels = flash_labels(&photos, opts.flash.as_deref(), opts.no_flash.as_deref())?;
    let files: Vec<String> = photos.iter().map(|p| p.file.clone()).collect();
    let on = labels.iter().filter(|l| l.0).count();
    progress(&format!(
        "{} photos of {width}x{height}: {on} with the flash, {} without",
        photos.len(),
        photos.len() - on
    ));

    // 2. Exposure.
    let exposures: Vec<Option<f64>> = photos
        .iter()
        .map(|p| match p.format {
            PhotoFormat::Exr => None,
            _ => p.exif.exposure(),
        })
        .collect();
    let all_exr = photos.iter().all(|p| p.format == PhotoFormat::Exr);
    let ExposureScales {
        scales, warning, ..
    } = if all_exr {
        ExposureScales {
            scales: vec![1.0; photos.len()],
            exposures: exposures.clone(),
            warning: None,
        }
    } else {
        exposure_scales(&exposures, &files)
    };
    if let Some(w) = warning {
        warnings.push(w);
    }

    let staging = Staging::new(&opts.out)?;

    // 3–4. Poses.
    let (model, undistorted, colmap_report) = match &opts.colmap_model {
        Some(dir) => {
            progress(&format!("reading the COLMAP model {}", dir.display()));
            let model = ColmapModel::read(dir)?;
            let report = ColmapReport {
                ran: false,
                model: dir.display().to_string(),
                models: 1,
                camera_model: model
                    .cameras
                    .values()
                    .next()
                    .map_or("?".into(), |c| c.model.name().to_string()),
                settings: None,
                seconds: Vec::new(),
            };
            (model, None, report)
        }
        None => {
            let exe = find_colmap()?;
            let work = staging.dir.join("colmap-work");
            let images = work.join("images");
            progress("preparing the photos for COLMAP");
            prepare_colmap_images(&photos, &images)?;
            let prior = camera_prior(&photos, width, height, &opts.colmap.camera_model);
            let run = run_colmap(
                &exe,
                &images,
                &work,
                &opts.colmap,
                prior.as_deref(),
                progress,
            )
            .map_err(|e| keep_log(e, &opts.out))?;
            let model = ColmapModel::read(&run.model_dir)?;
            let undistorted = ColmapModel::read(&run.undistorted_dir)?;
            let report = ColmapReport {
                ran: true,
                model: "colmap/sparse".into(),
                models: run.model_count,
                camera_model: opts.colmap.camera_model.clone(),
                settings: Some(opts.colmap.clone()),
                seconds: run.timings.clone(),
            };
            (model, Some(undistorted), report)
        }
    };

    // Match the model's images to the photos.
    let by_file: BTreeMap<String, usize> = files
        .iter()
        .enumerate()
        .map(|(i, f)| (f.clone(), i))
        .collect();
    let mut by_stem: BTreeMap<String, Vec<usize>> = BTreeMap::new();
    for (i, f) in files.iter().enumerate() {
        let stem = Path::new(f)
            .file_stem()
            .unwrap_or_default()
            .to_string_lossy()
            .into_owned();
        by_stem.entry(stem).or_default().push(i);
    }
    let mut image_of: Vec<Option<u32>> = vec![None; photos.len()];
    let mut unknown = Vec::new();
    for im in model.images.values() {
        match match_name(&im.name, &by_file, &by_stem) {
            Some(i) => image_of[i] = Some(im.id),
            None => unknown.push(im.name.clone()),
        }
    }
    if !unknown.is_empty() {
        warnings.push(format!(
            "{} image(s) of the COLMAP model are not among the photos and are left out: {}",
            unknown.len(),
            list_some(&unknown, 6)
        ));
    }
    let registered_count = image_of.iter().filter(|i| i.is_some()).count();
    let needed = min_registered(photos.len());
    if registered_count < needed {
        let missing: Vec<&str> = files
            .iter()
            .zip(&image_of)
            .filter(|(_, i)| i.is_none())
            .map(|(f, _)| f.as_str())
            .collect();
        return Err(ImportError::TooFewRegistered {
            registered: registered_count,
            total: photos.len(),
            needed,
            files: list_some(&missing, 20),
        });
    }

    // The cameras: the distorted one and the pinhole target of each photo.
    let mut registered = Vec::new();
    for (i, image_id) in image_of.iter().enumerate() {
        let Some(id) = image_id else { continue };
        let im = &model.images[id];
        let cam = &model.cameras[&im.camera_id];
        let distorted = scaled_camera(cam, width, height).ok_or_else(|| ImportError::Model {
            path: opts.colmap_model.clone().unwrap_or_default(),
            message: format!(
                "camera {} is {}x{} but the photo {} is {width}x{height} (another aspect ratio)",
                cam.id, cam.width, cam.height, files[i]
            ),
        })?;
        if !distorted.model.is_supported() {
            return Err(ImportError::Model {
                path: opts.colmap_model.clone().unwrap_or_default(),
                message: format!(
                    "camera {} uses the {} model, which the import cannot undistort; use a \
                     perspective model (SIMPLE_RADIAL, RADIAL, OPENCV, PINHOLE) or pass the \
                     output of `colmap image_undistorter`",
                    cam.id,
                    cam.model.name()
                ),
            });
        }
        let target = match &undistorted {
            Some(u) => {
                let ui = u.images.get(id).ok_or_else(|| ImportError::Model {
                    path: PathBuf::from("undistorted/sparse"),
                    message: format!("image {} ({}) is missing", id, im.name),
                })?;
                Pinhole::of(&u.cameras[&ui.camera_id]).ok_or_else(|| ImportError::Model {
                    path: PathBuf::from("undistorted/sparse"),
                    message: "image_undistorter did not write a pinhole camera".into(),
                })?
            }
            None => match Pinhole::of(&distorted) {
                Some(p) => p,
                None => Pinhole::undistorted(&distorted).ok_or_else(|| ImportError::Model {
                    path: opts.colmap_model.clone().unwrap_or_default(),
                    message: format!(
                        "cannot undistort camera {} (its distortion does not invert)",
                        cam.id
                    ),
                })?,
            },
        }
        .resized(opts.max_size);
        registered.push(Registered {
            photo: i,
            image_id: *id,
            index: registered.len(),
            distorted,
            target,
            r: im.rotation(),
            t: im.translation(),
        });
    }

    // 5. Region of interest.
    let centers: Vec<DVec3> = registered
        .iter()
        .map(|r| -(r.r.transpose() * r.t))
        .collect();
    let points_all: Vec<DVec3> = model.points.iter().map(|p| p.xyz).collect();
    let points_good: Vec<DVec3> = model
        .points
        .iter()
        .filter(|p| p.track.len() >= 3)
        .map(|p| p.xyz)
        .collect();
    let points = if points_good.len() >= 20 {
        &points_good
    } else {
        &points_all
    };
    let (roi, roi_source, axes_point, points_used) = match opts.roi {
        Some(roi) => (roi, "override", None, 0),
        None => {
            let cams: Vec<RoiCamera> = registered
                .iter()
                .zip(&centers)
                .map(|(r, c)| RoiCamera {
                    center: *c,
                    axis: r.r.transpose() * DVec3::Z,
                    half_fov: (0.5 * r.target.width as f64 / r.target.fx)
                        .min(0.5 * r.target.height as f64 / r.target.fy)
                        .atan(),
                })
                .collect();
            let est = estimate_roi(&cams, points).ok_or_else(|| ImportError::InvalidArgument {
                what: "region of interest".into(),
                problem: "cannot be found automatically (the cameras' optical axes do not meet \
                          in front of them); pass --center X,Y,Z --radius R in the units of the \
                          COLMAP model (colmap/sparse of a previous import, or your model)"
                    .into(),
            })?;
            (est.roi, "auto", Some(est.axes_point), est.points_used)
        }
    };
    let inside = cameras_inside(&roi, &centers);
    if !inside.is_empty() {
        let names: Vec<String> = inside
            .iter()
            .map(|(k, d)| format!("{} (at {d:.2} radii)", files[registered[*k].photo]))
            .collect();
        return Err(ImportError::CamerasInside {
            center: format!(
                "{:.4},{:.4},{:.4}",
                roi.center.x, roi.center.y, roi.center.z
            ),
            radius: format!("{:.4}", roi.radius),
            count: inside.len(),
            cameras: list_some(&names, 10),
        });
    }
    let nearest = centers
        .iter()
        .map(|c| (*c - roi.center).length() / roi.radius)
        .fold(f64::INFINITY, f64::min);
    let points_inside = points_all
        .iter()
        .filter(|p| (**p - roi.center).length() <= roi.radius)
        .count();
    progress(&format!(
        "region of interest ({roi_source}): centre ({:.3}, {:.3}, {:.3}), radius {:.3}; nearest camera at {nearest:.2} radii",
        roi.center.x, roi.center.y, roi.center.z, roi.radius
    ));

    // 6. Images.
    progress(&format!(
        "writing {} images of {}x{} (linear EXR)",
        registered.len(),
        registered[0].target.width,
        registered[0].target.height
    ));
    let preview_count = registered.len().min(4);
    let preview_pick: Vec<usize> = (0..preview_count)
        .map(|k| k * registered.len() / preview_count)
        .collect();
    let image_dir = staging.dir.join("image");
    struct Written {
        window: Option<f64>,
        cap: Option<f64>,
        preview: Option<RgbImage>,
    }
    let mut written: Vec<Written> = Vec::with_capacity(registered.len());
    for chunk in registered.chunks(rayon::current_num_threads().max(1)) {
        let out: Vec<Result<Written, ImportError>> = chunk
            .par_iter()
            .map(|reg| {
                let p = &photos[reg.photo];
                let decoded = decode(&p.path, p.exif.orientation)?;
                let scale = scales[reg.photo];
                let linear = to_linear(&decoded, scale as f32);
                drop(decoded);
                let (image, _) = resample(&linear, &reg.distorted, &reg.target, scale as f32);
                let path =
                    image_dir.join(wildlight_data::writer::indexed_file_name(reg.index, "exr"));
                wildlight_data::exr_io::write_exr_rgb(&path, &image)?;
                // the object's brightness: a window around the ROI centre
                let c = reg.r * roi.center + reg.t;
                let k = reg.target.k_spec();
                let window = (c.z > 0.0)
                    .then(|| {
                        let q = k * (c / c.z);
                        let half = 0.3 * roi.radius * reg.target.fx / c.length();
                        window_median(&image, q.x, q.y, half.max(2.0))
                    })
                    .flatten();
                let cap = (p.format != PhotoFormat::Exr).then(|| saturation_cap(scale));
                Ok(Written {
                    window,
                    cap,
                    preview: preview_pick.contains(&reg.index).then_some(image),
                })
            })
            .collect();
        for w in out {
            written.push(w?);
        }
    }

    // 7. Flash energy (normalized units).
    let flash_of = |reg: &Registered| labels[reg.photo].0;
    let dist_norm = |k: usize| (centers[k] - roi.center).length() / roi.radius;
    let no_flash_level = median(
        registered
            .iter()
            .zip(&written)
            .filter(|(r, _)| !flash_of(r))
            .filter_map(|(_, w)| w.window)
            .collect(),
    );
    // A surface point about 0.6 radii in front of the centre, Lambertian
    // with albedo ASSUMED_ALBEDO: pixel ≈ E · (albedo / π) / d².
    let brdf = ASSUMED_ALBEDO / std::f64::consts::PI;
    let surface_d = |k: usize| (dist_norm(k) - 0.6).max(0.2);
    // (energy from the flash's share, energy if all the light were the flash's)
    let flash_parts: Vec<(f64, f64)> = registered
        .iter()
        .enumerate()
        .zip(&written)
        .filter(|((_, r), _)| flash_of(r))
        .filter_map(|((k, _), w)| {
            let v = w.window?;
            let d2 = surface_d(k).powi(2);
            Some((
                (v - no_flash_level.unwrap_or(0.0)) * d2 / brdf,
                v * d2 / brdf,
            ))
        })
        .collect();
    let flash_count = registered.iter().filter(|r| flash_of(r)).count();
    let (light_energy, light_energy_note) = {
        let parts = median(flash_parts.iter().map(|p| p.0).collect());
        let totals = median(flash_parts.iter().map(|p| p.1).collect());
        match (parts, totals, no_flash_level) {
            (Some(e), _, Some(_)) if e > 0.0 => (
                e,
                format!(
                    "flash photos' brightness at the object minus the no-flash photos', times d² \
                     · π / {ASSUMED_ALBEDO} (an albedo-{ASSUMED_ALBEDO} surface 0.6 radii in front of the centre)"
                ),
            ),
            (_, Some(t), _) if t > 0.0 => {
                if no_flash_level.is_some() {
                    warnings.push(
                        "the flash photos are not brighter than the no-flash photos at the \
                         object: was the flash on? The flash energy is a guess from the flash \
                         photos' brightness"
                            .into(),
                    );
                }
                (
                    0.5 * t,
                    format!(
                        "half the flash photos' brightness at the object, times d² · π / {ASSUMED_ALBEDO}"
                    ),
                )
            }
            _ => (1.0, "no flash photos: unused".into()),
        }
    };

    // Cameras.
    let scale_mat = roi.scale_mat();
    let mut arrays = Vec::with_capacity(registered.len());
    for (reg, w) in registered.iter().zip(&written) {
        let energy = if flash_of(reg) {
            [light_energy; 3]
        } else {
            [0.0; 3]
        };
        let cam = Camera::from_krt(
            reg.index,
            reg.target.width,
            reg.target.height,
            reg.target.k_spec(),
            reg.r,
            reg.t,
            scale_mat,
            energy,
        )?;
        let mut a = cam.to_arrays();
        a.max_intensity = w.cap;
        arrays.push(a);
    }
    let global_cap = written
        .iter()
        .filter_map(|w| w.cap)
        .fold(None, |m: Option<f64>, c| Some(m.map_or(c, |m| m.min(c))));

    // 8. Report.
    let index_of: BTreeMap<usize, usize> = registered.iter().map(|r| (r.photo, r.index)).collect();
    let photo_reports: Vec<PhotoReport> = photos
        .iter()
        .enumerate()
        .map(|(i, p)| PhotoReport {
            file: p.file.clone(),
            index: index_of.get(&i).copied(),
            flash: labels[i].0,
            flash_source: labels[i].1,
            exposure_scale: scales[i],
            exposure: exposures[i],
            orientation: p.exif.orientation,
            saturated_share: p.saturated_share,
            max_intensity: index_of.get(&i).and_then(|k| written[*k].cap),
            dropped: (!index_of.contains_key(&i)).then(|| {
                if opts.colmap_model.is_some() {
                    "not in the COLMAP model".to_string()
                } else {
                    "not registered by COLMAP".to_string()
                }
            }),
        })
        .collect();
    let dropped: Vec<&str> = photo_reports
        .iter()
        .filter(|p| p.dropped.is_some())
        .map(|p| p.file.as_str())
        .collect();
    if !dropped.is_empty() {
        warnings.push(format!(
            "{} photo(s) not registered and left out: {}",
            dropped.len(),
            list_some(&dropped, 12)
        ));
    }
    if registered.len() < FEW_PHOTOS {
        warnings.push(format!(
            "only {} photos registered; 20 or more (40-60 is good) give a much better reconstruction",
            registered.len()
        ));
    }
    if flash_count == 0 {
        warnings.push(
            "no flash photos: the materials cannot be separated from the room light; take about \
             half of the photos with the flash (or torch) on"
                .into(),
        );
    } else if flash_count == registered.len() {
        warnings.push(
            "every photo has the flash on: take some without it too (about half), so the room \
             light can be told apart"
                .into(),
        );
    }
    let saturation_share = registered
        .iter()
        .map(|r| photos[r.photo].saturated_share)
        .sum::<f64>()
        / registered.len() as f64;
    if saturation_share > 0.05 {
        warnings.push(format!(
            "{:.1} % of the pixels are saturated: lower the exposure (or move the flash further away)",
            100.0 * saturation_share
        ));
    }
    let target0 = registered[0].target;
    let report = ImportReport {
        photos_dir: opts.photos.display().to_string(),
        capture: opts.out.display().to_string(),
        photos: photo_reports,
        photo_count: photos.len(),
        registered: registered.len(),
        flash_count,
        no_flash_count: registered.len() - flash_count,
        mean_reprojection_error_px: model.mean_reprojection_error(),
        sparse_points: model.points.len(),
        saturation_share,
        photo_size: [width, height],
        image_size: [target0.width, target0.height],
        roi: RoiReport {
            center: roi.center.to_array(),
            radius: roi.radius,
            source: roi_source.into(),
            axes_point: axes_point.map(|p| p.to_array()),
            points_used,
            points_inside,
            nearest_camera: nearest,
        },
        light_energy,
        light_energy_note,
        max_intensity: global_cap,
        colmap: colmap_report,
        seconds: started.elapsed().as_secs_f64(),
        warnings,
    };

    // 9. Files: the preview, the model, the report, the cameras last.
    let views: Vec<PreviewView<'_>> = registered
        .iter()
        .zip(&written)
        .filter_map(|(r, w)| {
            w.preview.as_ref().map(|image| PreviewView {
                image,
                k: r.target.k_spec(),
                r: r.r,
                t: r.t,
                points: model
                    .points
                    .iter()
                    .filter(|p| p.track.iter().any(|(id, _)| *id == r.image_id))
                    .map(|p| p.xyz)
                    .collect(),
            })
        })
        .collect();
    let png = render_preview(&views, &roi);
    let png_path = staging.dir.join("roi.png");
    png.save(&png_path)
        .map_err(|e| ImportError::InvalidArgument {
            what: png_path.display().to_string(),
            problem: format!("cannot write: {e}"),
        })?;
    model.write_text(&staging.dir.join("colmap").join("sparse"))?;
    let work = staging.dir.join("colmap-work");
    if work.exists() {
        std::fs::remove_dir_all(&work).map_err(|e| ImportError::io(&work, "removing", e))?;
    }
    let json = serde_json::to_string_pretty(&report).map_err(|e| ImportError::InvalidArgument {
        what: "import.json".into(),
        problem: e.to_string(),
    })?;
    let json_path = staging.dir.join("import.json");
    std::fs::write(&json_path, json + "\n")
        .map_err(|e| ImportError::io(&json_path, "writing", e))?;
    write_cameras_npz(&staging.dir.join("cameras_sphere.npz"), &arrays, global_cap)?;
    staging.commit()?;
    Ok(report)
}

/// Keeps a failed COLMAP stage's log beside the output folder (the
/// staging folder it was in is removed) and points the error at it.
fn keep_log(err: ImportError, out: &Path) -> ImportError {
    match err {
        ImportError::ColmapFailed {
            stage,
            status,
            log,
            tail,
        } => {
            let kept = out.with_file_name(format!(
                "{}.colmap-{stage}.log",
                out.file_name().unwrap_or_default().to_string_lossy()
            ));
            let log = if std::fs::copy(&log, &kept).is_ok() {
                kept
            } else {
                log
            };
            ImportError::ColmapFailed {
                stage,
                status,
                log,
                tail,
            }
        }
        e => e,
    }
}
