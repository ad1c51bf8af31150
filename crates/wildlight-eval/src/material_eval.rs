//! `wildlight eval materials`: a reconstruction's per-view material maps
//! against a synthetic dataset's ground truth.
//!
//! Maps (conventions): ground truth in `<split>/gt/<kind>/NNN.exr`,
//! predictions in `PRED/<kind>/NNN.exr`, for kinds `base_color`,
//! `roughness`, `metallic` (scalars read from the R channel) and `normal`.
//! Pixels count when the split's mask `<split>/mask/NNN.png` is set, or,
//! without a mask file, where the ground-truth normal is non-zero. All
//! counted pixels of all views are pooled:
//!
//! - `base_color_psnr`: PSNR (peak 1) of the MSE over pixels × RGB channels;
//! - `base_color_psnr_aligned`: the same after scaling each predicted channel
//!   by the least-squares factor s_c = Σ p_c g_c / Σ p_c² (the flash power is
//!   learned only up to a gain, which multiplies the recovered base colour);
//!   the factors are reported as `base_color_scale`;
//! - `roughness_mae`, `metallic_mae`: mean |p − g|;
//! - `normal_error_deg`: mean angle between the unit normals, over the
//!   counted pixels where both normals are non-zero; `normal_coverage` is the
//!   fraction of counted pixels where the prediction has a normal;
//! - `normal_error_median_deg` and `normal_within`: the median of those
//!   angles, and the fraction of them at or below each of
//!   [`NORMAL_THRESHOLDS_DEG`]. A mean alone cannot tell a few badly wrong
//!   pixels (a crease the reconstruction rounded off, a groove it missed)
//!   from a small error everywhere; the median and the shares can.
//!
//! The views are those of `PRED/views.json` in the chosen split, or, without
//! that file, every `PRED/base_color/NNN.exr`. A kind whose prediction
//! folder is missing is reported as `null`.

use crate::EvalError;
use crate::colour_fit::ColourFit;
use crate::rendered_views::{map_path, read_views};
use crate::surface_distance::median;
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};
use wildlight_data::RgbImage;
use wildlight_data::exr_io::read_exr_rgb;
use wildlight_data::png_io::read_mask_png;

/// Which ground-truth split to compare with.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    /// The dataset folder itself (training views).
    Train,
    /// The dataset's `val/` folder.
    Val,
}

impl Split {
    /// The split's name, as in JSON and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Val => "val",
        }
    }

    /// The folder of this split inside the dataset folder.
    pub fn folder(self, dataset: &Path) -> PathBuf {
        match self {
            Split::Train => dataset.to_path_buf(),
            Split::Val => dataset.join("val"),
        }
    }
}

/// The angles (degrees) of `normal_within`: 1° and 5° for fine
/// reconstruction, and 11.25°, 22.5° and 30°, the usual thresholds of
/// surface-normal benchmarks.
pub const NORMAL_THRESHOLDS_DEG: [f64; 5] = [1.0, 5.0, 11.25, 22.5, 30.0];

/// The share of normals within one angle of the truth.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct NormalWithin {
    /// The angle, in degrees.
    pub deg: f64,
    /// Fraction of the compared normals whose error is at most `deg`.
    pub fraction: f64,
}

/// Result of [`evaluate_materials`].
#[derive(Clone, Debug, Serialize)]
pub struct MaterialEvaluation {
    /// The split compared with.
    pub split: Split,
    /// Number of views.
    pub views: usize,
    /// Number of counted (surface) pixels over all views.
    pub pixels: usize,
    /// Base-colour PSNR (dB), raw.
    pub base_color_psnr: Option<f64>,
    /// Base-colour PSNR (dB) after per-channel least-squares scaling.
    pub base_color_psnr_aligned: Option<f64>,
    /// The per-channel scale factors of the alignment.
    pub base_color_scale: Option<[f64; 3]>,
    /// Mean absolute roughness error.
    pub roughness_mae: Option<f64>,
    /// Mean absolute metallic error.
    pub metallic_mae: Option<f64>,
    /// Mean normal angular error in degrees.
    pub normal_error_deg: Option<f64>,
    /// Fraction of counted pixels where the prediction has a normal.
    pub normal_coverage: Option<f64>,
    /// Median normal angular error in degrees.
    pub normal_error_median_deg: Option<f64>,
    /// Share of normals within each of [`NORMAL_THRESHOLDS_DEG`].
    pub normal_within: Option<Vec<NormalWithin>>,
}

/// Sums gathered over the counted pixels of some views (mergeable).
#[derive(Clone, Debug, Default)]
struct Sums {
    pixels: usize,
    /// Base colour against the truth.
    base: ColourFit,
    roughness_abs: f64,
    roughness_pixels: usize,
    metallic_abs: f64,
    metallic_pixels: usize,
    /// Every compared pixel's normal error (degrees): their count, mean,
    /// median and shares.
    angles_deg: Vec<f64>,
    normal_counted: usize,
}

impl Sums {
    fn merge(mut self, o: Sums) -> Sums {
        self.pixels += o.pixels;
        self.base = self.base.merge(o.base);
        self.roughness_abs += o.roughness_abs;
        self.roughness_pixels += o.roughness_pixels;
        self.metallic_abs += o.metallic_abs;
        self.metallic_pixels += o.metallic_pixels;
        self.angles_deg.extend(o.angles_deg);
        self.normal_counted += o.normal_counted;
        self
    }
}

/// Reads a map, or `None` when its kind folder does not exist.
fn read_optional(dir: &Path, kind: &str, index: usize) -> Result<Option<RgbImage>, EvalError> {
    if !dir.join(kind).is_dir() {
        return Ok(None);
    }
    Ok(Some(read_exr_rgb(&map_path(dir, kind, index))?))
}

fn check_size(image: &RgbImage, width: u32, height: u32, path: PathBuf) -> Result<(), EvalError> {
    if (image.width, image.height) != (width, height) {
        return Err(EvalError::Input {
            path,
            problem: format!(
                "is {}×{} but the ground truth is {width}×{height}",
                image.width, image.height
            ),
        });
    }
    Ok(())
}

fn view_sums(pred_dir: &Path, split_dir: &Path, index: usize) -> Result<Sums, EvalError> {
    let gt_dir = split_dir.join("gt");
    let gt_normal = read_exr_rgb(&map_path(&gt_dir, "normal", index))?;
    let (w, h) = (gt_normal.width, gt_normal.height);
    let mask_path = split_dir.join("mask").join(format!("{index:03}.png"));
    let counted: Vec<bool> = if mask_path.is_file() {
        let mask = read_mask_png(&mask_path)?;
        if (mask.width, mask.height) != (w, h) {
            return Err(EvalError::Input {
                path: mask_path,
                problem: format!("is {}×{} but the maps are {w}×{h}", mask.width, mask.height),
            });
        }
        mask.data
    } else {
        gt_normal
            .data
            .chunks(3)
            .map(|n| n.iter().any(|v| *v != 0.0))
            .collect()
    };
    let mut sums = Sums {
        pixels: counted.iter().filter(|c| **c).count(),
        ..Sums::default()
    };
    let pixels = || {
        counted
            .iter()
            .enumerate()
            .filter(|(_, c)| **c)
            .map(|(i, _)| i)
    };

    let pair = |kind: &str| -> Result<Option<(RgbImage, RgbImage)>, EvalError> {
        let Some(pred) = read_optional(pred_dir, kind, index)? else {
            return Ok(None);
        };
        check_size(&pred, w, h, map_path(pred_dir, kind, index))?;
        let gt = read_exr_rgb(&map_path(&gt_dir, kind, index))?;
        check_size(&gt, w, h, map_path(&gt_dir, kind, index))?;
        Ok(Some((pred, gt)))
    };

    if let Some((p, g)) = pair("base_color")? {
        for i in pixels() {
            let rgb = |img: &RgbImage| [0, 1, 2].map(|c| img.data[3 * i + c] as f64);
            sums.base.add(rgb(&p), rgb(&g));
        }
    }
    if let Some((p, g)) = pair("roughness")? {
        for i in pixels() {
            sums.roughness_abs += (p.data[3 * i] as f64 - g.data[3 * i] as f64).abs();
            sums.roughness_pixels += 1;
        }
    }
    if let Some((p, g)) = pair("metallic")? {
        for i in pixels() {
            sums.metallic_abs += (p.data[3 * i] as f64 - g.data[3 * i] as f64).abs();
            sums.metallic_pixels += 1;
        }
    }
    if let Some(p) = read_optional(pred_dir, "normal", index)? {
        check_size(&p, w, h, map_path(pred_dir, "normal", index))?;
        for i in pixels() {
            let n = |img: &RgbImage| {
                glam::DVec3::new(
                    img.data[3 * i] as f64,
                    img.data[3 * i + 1] as f64,
                    img.data[3 * i + 2] as f64,
                )
            };
            let (np, ng) = (n(&p), n(&gt_normal));
            sums.normal_counted += 1;
            if np.length_squared() > 0.0 && ng.length_squared() > 0.0 {
                let cos = np.normalize().dot(ng.normalize()).clamp(-1.0, 1.0);
                sums.angles_deg.push(cos.acos().to_degrees());
            }
        }
    }
    Ok(sums)
}

/// The view indices to evaluate (see the module documentation).
fn view_indices(pred_dir: &Path, split: Split) -> Result<Vec<usize>, EvalError> {
    if pred_dir.join("views.json").is_file() {
        return Ok(read_views(pred_dir)?
            .into_iter()
            .filter(|v| v.is_val() == (split == Split::Val))
            .map(|v| v.index)
            .collect());
    }
    let dir = pred_dir.join("base_color");
    let entries = std::fs::read_dir(&dir).map_err(|e| EvalError::Input {
        path: dir.clone(),
        problem: format!("cannot list ({e}); need views.json or base_color/NNN.exr"),
    })?;
    let mut indices: Vec<usize> = entries
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let path = e.path();
            let is_exr = path
                .extension()
                .is_some_and(|x| x.eq_ignore_ascii_case("exr"));
            is_exr.then(|| path.file_stem()?.to_str()?.parse().ok())?
        })
        .collect();
    indices.sort_unstable();
    Ok(indices)
}

/// Compares `pred_dir`'s maps with the ground truth of `split` in the
/// dataset folder `gt_dir`.
pub fn evaluate_materials(
    pred_dir: &Path,
    gt_dir: &Path,
    split: Split,
) -> Result<MaterialEvaluation, EvalError> {
    let split_dir = split.folder(gt_dir);
    if !split_dir.join("gt").is_dir() {
        return Err(EvalError::Input {
            path: split_dir.join("gt"),
            problem: "no ground-truth maps (only synthetic datasets have them)".into(),
        });
    }
    let indices = view_indices(pred_dir, split)?;
    if indices.is_empty() {
        return Err(EvalError::Input {
            path: pred_dir.to_path_buf(),
            problem: format!("no predicted views of the {split:?} split"),
        });
    }
    let sums = indices
        .par_iter()
        .map(|&i| view_sums(pred_dir, &split_dir, i))
        .try_reduce(Sums::default, |a, b| Ok(a.merge(b)))?;
    Ok(summarize(split, indices.len(), sums))
}

fn summarize(split: Split, views: usize, mut s: Sums) -> MaterialEvaluation {
    s.angles_deg.sort_unstable_by(f64::total_cmp);
    let normal_pixels = s.angles_deg.len();
    let normal_error_median_deg = (normal_pixels > 0).then(|| median(&mut s.angles_deg));
    let normal_within = (normal_pixels > 0).then(|| {
        NORMAL_THRESHOLDS_DEG
            .iter()
            .map(|&deg| NormalWithin {
                deg,
                // `angles_deg` is sorted: count the prefix at or below `deg`.
                fraction: s.angles_deg.partition_point(|a| *a <= deg) as f64 / normal_pixels as f64,
            })
            .collect()
    });
    let ratio = |num: f64, den: usize| (den > 0).then(|| num / den as f64);
    MaterialEvaluation {
        split,
        views,
        pixels: s.pixels,
        base_color_psnr: s.base.psnr(),
        base_color_psnr_aligned: s.base.psnr_aligned(),
        base_color_scale: s.base.scale(),
        roughness_mae: ratio(s.roughness_abs, s.roughness_pixels),
        metallic_mae: ratio(s.metallic_abs, s.metallic_pixels),
        normal_error_deg: ratio(s.angles_deg.iter().sum(), normal_pixels),
        normal_coverage: ratio(normal_pixels as f64, s.normal_counted),
        normal_error_median_deg,
        normal_within,
    }
}
