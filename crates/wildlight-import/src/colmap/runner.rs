//! Running COLMAP 3.8 headless on the CPU as a subprocess: feature
//! extraction with one shared camera, exhaustive matching, mapping, the
//! model with the most registered images, and `image_undistorter` to a
//! PINHOLE camera.
//!
//! Both SIFT stages get `use_gpu 0`: with the default, a build without CUDA
//! but with OpenGL creates a Qt application and wants a display; the
//! environment also gets `QT_QPA_PLATFORM=offscreen`.
//!
//! The default settings were chosen by measurement on the shared
//! mitsuba-phone capture (40 JPEGs, 800×600, 2 busy vCPUs): see
//! [`ColmapSettings::default`].

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::Instant;

use crate::colmap::model::ColmapModel;
use crate::error::ImportError;

/// The COLMAP options of each stage (beyond the ones the runner always
/// passes: database, image folder, single camera, CPU).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ColmapSettings {
    /// Camera model of the shared camera (`SIMPLE_RADIAL`).
    pub camera_model: String,
    /// Extra `feature_extractor` options.
    pub extractor: Vec<String>,
    /// Extra `exhaustive_matcher` options.
    pub matcher: Vec<String>,
    /// Extra `mapper` options.
    pub mapper: Vec<String>,
}

fn strings(v: &[&str]) -> Vec<String> {
    v.iter().map(|s| s.to_string()).collect()
}

impl Default for ColmapSettings {
    /// Affine-shape SIFT (COLMAP's default feature count), exhaustive
    /// guided matching, and the mapper's relaxed absolute-pose thresholds
    /// (12 inliers, ratio 0.15).
    ///
    /// Measured on mitsuba-phone (40 photos, 800×600, 2 vCPUs shared with
    /// other builds at load 6–9), camera accuracy after a similarity
    /// alignment to the truth (centres in % of the object distance,
    /// rotations, medians):
    ///
    /// | extraction      | matching | mapper  | registered | centres | rot.  | time  |
    /// |-----------------|----------|---------|-----------:|--------:|------:|------:|
    /// | default         | default  | default | 20         | 0.09 %  | 0.31° | 100 s |
    /// | default         | default  | relaxed | 38 wrong   | 38 %    | 13.6° | 130 s |
    /// | default         | guided   | relaxed | 40 wrong   | 30 %    | 9.9°  | 130 s |
    /// | DSP             | default  | relaxed | 39 wrong   | 22 %    | 11.4° | 100 s |
    /// | affine          | default  | relaxed | 38         | 1.4 %   | 0.64° | 75 s  |
    /// | affine          | guided   | default | 33         | 0.47 %  | 0.71° | 90 s  |
    /// | **affine**      | **guided** | **relaxed** | **40** | **0.77 %** | **0.68°** | **90 s** |
    /// | affine+DSP+16k  | guided   | relaxed | 40         | 0.37 %  | 0.34° | 237 s |
    ///
    /// Without the affine shape, the relaxed mapper registers nearly every
    /// photo into a consistently wrong model (every camera ~10° off): more
    /// registered photos is not the measure. The heavy settings of the
    /// notes are the most accurate but take 4 minutes; domain-size pooling
    /// doubles the extraction time.
    fn default() -> Self {
        ColmapSettings {
            camera_model: "SIMPLE_RADIAL".into(),
            extractor: strings(&["--SiftExtraction.estimate_affine_shape", "1"]),
            matcher: strings(&["--SiftMatching.guided_matching", "1"]),
            mapper: strings(&[
                "--Mapper.abs_pose_min_num_inliers",
                "12",
                "--Mapper.abs_pose_min_inlier_ratio",
                "0.15",
                "--Mapper.ba_refine_principal_point",
                "0",
            ]),
        }
    }
}

/// The `colmap` executable on PATH.
pub fn find_colmap() -> Result<PathBuf, ImportError> {
    find_colmap_in(&std::env::var_os("PATH").unwrap_or_default())
}

/// The `colmap` executable in the folders of `path` (PATH's syntax).
pub fn find_colmap_in(path: &std::ffi::OsStr) -> Result<PathBuf, ImportError> {
    std::env::split_paths(path)
        .map(|dir| dir.join("colmap"))
        .find(|p| p.is_file())
        .ok_or(ImportError::ColmapMissing)
}

/// What a COLMAP run produced.
#[derive(Clone, Debug)]
pub struct ColmapRun {
    /// The mapper's model with the most registered images (distorted camera).
    pub model_dir: PathBuf,
    /// How many models the mapper wrote.
    pub model_count: usize,
    /// The undistorted model (PINHOLE camera) from `image_undistorter`.
    pub undistorted_dir: PathBuf,
    /// Seconds per stage.
    pub timings: Vec<(String, f64)>,
}

/// Runs COLMAP in `work` on the images of `images` (JPEG/PNG, one size).
/// `camera_params` (for example `f,cx,cy,k` of SIMPLE_RADIAL) is the prior
/// of the shared camera, when known from EXIF. `progress` gets a line per
/// stage.
pub fn run_colmap(
    exe: &Path,
    images: &Path,
    work: &Path,
    settings: &ColmapSettings,
    camera_params: Option<&str>,
    progress: &(dyn Fn(&str) + Sync),
) -> Result<ColmapRun, ImportError> {
    let db = work.join("database.db");
    let sparse = work.join("sparse");
    let undist = work.join("undistorted");
    std::fs::create_dir_all(&sparse).map_err(|e| ImportError::io(&sparse, "creating", e))?;
    let mut timings = Vec::new();
    let mut stage = |name: &str, what: &str, args: Vec<String>| -> Result<(), ImportError> {
        progress(&format!("COLMAP {name}: {what}"));
        let start = Instant::now();
        run_stage(exe, work, name, &args)?;
        let secs = start.elapsed().as_secs_f64();
        progress(&format!("COLMAP {name}: done in {secs:.0} s"));
        timings.push((name.to_string(), secs));
        Ok(())
    };
    let p = |p: &Path| p.display().to_string();

    let mut args = strings(&["--database_path"]);
    args.push(p(&db));
    args.extend(["--image_path".into(), p(images)]);
    args.extend(strings(&["--ImageReader.single_camera", "1"]));
    args.extend([
        "--ImageReader.camera_model".into(),
        settings.camera_model.clone(),
    ]);
    if let Some(params) = camera_params {
        args.extend(["--ImageReader.camera_params".into(), params.to_string()]);
    }
    args.extend(strings(&["--SiftExtraction.use_gpu", "0"]));
    args.extend(settings.extractor.iter().cloned());
    stage("feature_extractor", "SIFT features of every photo", args)?;

    let mut args = vec!["--database_path".into(), p(&db)];
    args.extend(strings(&["--SiftMatching.use_gpu", "0"]));
    args.extend(settings.matcher.iter().cloned());
    stage("exhaustive_matcher", "matching every pair of photos", args)?;

    let mut args = vec!["--database_path".into(), p(&db)];
    args.extend(["--image_path".into(), p(images)]);
    args.extend(["--output_path".into(), p(&sparse)]);
    args.extend(settings.mapper.iter().cloned());
    match stage("mapper", "camera poses and sparse points", args) {
        // COLMAP 3.8 exits with an error when it finds no initial pair.
        Err(ImportError::ColmapFailed { .. }) if largest_model(&sparse).is_err() => {
            return Err(ImportError::NoModel {
                path: sparse.clone(),
            });
        }
        r => r?,
    }
    let (model_dir, model_count) = largest_model(&sparse)?;

    let args = vec![
        "--image_path".into(),
        p(images),
        "--input_path".into(),
        p(&model_dir),
        "--output_path".into(),
        p(&undist),
        "--output_type".into(),
        "COLMAP".into(),
    ];
    stage("image_undistorter", "PINHOLE camera", args)?;
    Ok(ColmapRun {
        model_dir,
        model_count,
        undistorted_dir: undist.join("sparse"),
        timings,
    })
}

/// The model folder under `sparse` (`0`, `1`, ...) with the most
/// registered images, and how many models there are.
pub fn largest_model(sparse: &Path) -> Result<(PathBuf, usize), ImportError> {
    let mut best: Option<(usize, PathBuf)> = None;
    let mut count = 0;
    let entries = std::fs::read_dir(sparse).map_err(|e| ImportError::io(sparse, "listing", e))?;
    let mut dirs: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir() && ColmapModel::format_of(p).is_some())
        .collect();
    dirs.sort();
    for dir in dirs {
        let model = ColmapModel::read(&dir)?;
        count += 1;
        if best.as_ref().is_none_or(|(n, _)| model.images.len() > *n) {
            best = Some((model.images.len(), dir));
        }
    }
    match best {
        Some((_, dir)) => Ok((dir, count)),
        None => Err(ImportError::NoModel {
            path: sparse.to_path_buf(),
        }),
    }
}

/// Runs `colmap <stage> <args>` with its output in `work/<stage>.log`.
fn run_stage(exe: &Path, work: &Path, stage: &str, args: &[String]) -> Result<(), ImportError> {
    let log = work.join(format!("{stage}.log"));
    let out = std::fs::File::create(&log).map_err(|e| ImportError::io(&log, "creating", e))?;
    let err = out
        .try_clone()
        .map_err(|e| ImportError::io(&log, "opening", e))?;
    let status = Command::new(exe)
        .arg(stage)
        .args(args)
        .env("QT_QPA_PLATFORM", "offscreen")
        .stdin(Stdio::null())
        .stdout(out)
        .stderr(err)
        .status()
        .map_err(|e| ImportError::io(exe, "running", e))?;
    if status.success() {
        return Ok(());
    }
    let text = std::fs::read_to_string(&log).unwrap_or_default();
    let lines: Vec<&str> = text.lines().filter(|l| !l.trim().is_empty()).collect();
    let tail = lines[lines.len().saturating_sub(12)..].join("\n");
    Err(ImportError::ColmapFailed {
        stage: stage.to_string(),
        status: status.to_string(),
        log,
        tail,
    })
}
