//! `wildlight eval images`: PSNR and SSIM of rendered views against a
//! capture's photos, over the masks (the object) or over the whole image
//! ([`Pixels`]), for flash, no-flash and all views.
//!
//! Per view the metrics of [`crate::image_metrics`] are computed with the
//! saturation cap of the split the view belongs to (dataset or `val/`).
//! A group's value (flash, no-flash, all) is the mean of its views' values
//! (views whose mask is empty are left out). A view counts as a flash view
//! when its ground-truth camera has a non-zero `light_energy`.

use crate::EvalError;
use crate::image_metrics::{Range, masked_psnr, masked_ssim};
use crate::rendered_views::{RenderedView, read_views};
use rayon::prelude::*;
use serde::Serialize;
use std::path::Path;
use wildlight_data::exr_io::read_exr_rgb;
use wildlight_data::{Dataset, LoadOptions};

/// Which pixels of a view are scored.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pixels {
    /// Those of the view's mask (the object; all of them without a mask).
    Mask,
    /// All of them (the object and what the photo shows around it).
    WholeImage,
}

/// Scores of one view.
#[derive(Clone, Debug, Serialize)]
pub struct ViewScore {
    /// Camera index.
    pub index: usize,
    /// `"val"` or `"train"`.
    pub split: String,
    /// Whether the ground-truth view had the flash on.
    pub flash: bool,
    /// PSNR (dB) over the mask; `None` for an empty mask.
    pub psnr: Option<f64>,
    /// SSIM over the mask; `None` for an empty mask.
    pub ssim: Option<f64>,
    /// Number of pixels scored: the mask's, or all pixels when the view has
    /// no mask or the whole image is scored.
    pub mask_pixels: usize,
}

/// Result of [`evaluate_images`]. Group values are `None` when the group has
/// no view.
#[derive(Clone, Debug, Serialize)]
pub struct ImageEvaluation {
    /// Mean PSNR (dB) of the flash views.
    pub psnr_flash: Option<f64>,
    /// Mean PSNR (dB) of the no-flash views.
    pub psnr_noflash: Option<f64>,
    /// Mean PSNR (dB) of all views.
    pub psnr_all: Option<f64>,
    /// Mean SSIM of the flash views.
    pub ssim_flash: Option<f64>,
    /// Mean SSIM of the no-flash views.
    pub ssim_noflash: Option<f64>,
    /// Mean SSIM of all views.
    pub ssim_all: Option<f64>,
    /// Number of flash views scored.
    pub views_flash: usize,
    /// Number of no-flash views scored.
    pub views_noflash: usize,
    /// Every view's scores.
    pub per_view: Vec<ViewScore>,
}

/// Mean of the present values, `None` if there are none.
fn mean(values: impl Iterator<Item = Option<f64>>) -> Option<f64> {
    let v: Vec<f64> = values.flatten().collect();
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// Groups per-view scores into flash / no-flash / all means.
pub fn summarize(per_view: Vec<ViewScore>) -> ImageEvaluation {
    let group = |flash: Option<bool>| {
        per_view
            .iter()
            .filter(move |v| flash.is_none_or(|f| v.flash == f))
    };
    ImageEvaluation {
        psnr_flash: mean(group(Some(true)).map(|v| v.psnr)),
        psnr_noflash: mean(group(Some(false)).map(|v| v.psnr)),
        psnr_all: mean(group(None).map(|v| v.psnr)),
        ssim_flash: mean(group(Some(true)).map(|v| v.ssim)),
        ssim_noflash: mean(group(Some(false)).map(|v| v.ssim)),
        ssim_all: mean(group(None).map(|v| v.ssim)),
        views_flash: group(Some(true)).filter(|v| v.psnr.is_some()).count(),
        views_noflash: group(Some(false)).filter(|v| v.psnr.is_some()).count(),
        per_view,
    }
}

/// Scores the views listed in `pred_dir/views.json` (images in
/// `pred_dir/image/NNN.exr`) against the dataset folder `gt_dir`, over
/// `pixels`.
pub fn evaluate_images(
    pred_dir: &Path,
    gt_dir: &Path,
    pixels: Pixels,
) -> Result<ImageEvaluation, EvalError> {
    let views = read_views(pred_dir)?;
    if views.is_empty() {
        return Err(EvalError::Input {
            path: pred_dir.join("views.json"),
            problem: "lists no views".into(),
        });
    }
    let dataset = Dataset::load(gt_dir, &LoadOptions::default())?;
    let per_view = views
        .par_iter()
        .map(|view| score_view(view, pred_dir, &dataset, pixels))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(summarize(per_view))
}

fn score_view(
    view: &RenderedView,
    pred_dir: &Path,
    dataset: &Dataset,
    pixels: Pixels,
) -> Result<ViewScore, EvalError> {
    let split = if view.is_val() {
        dataset.val.as_deref().ok_or_else(|| EvalError::Input {
            path: dataset.root.join("val"),
            problem: format!(
                "view {} is a val view but the dataset has no val/ folder",
                view.index
            ),
        })?
    } else {
        dataset
    };
    let gt = split
        .views
        .iter()
        .find(|v| v.camera.index == view.index)
        .ok_or_else(|| EvalError::Input {
            path: split.root.clone(),
            problem: format!("no view with index {}", view.index),
        })?;
    let pred_path = view.map_path(pred_dir, "image");
    let pred = read_exr_rgb(&pred_path)?;
    let range = Range {
        cap: split.saturation,
    };
    let mask = match pixels {
        Pixels::Mask => gt.mask.as_ref(),
        Pixels::WholeImage => None,
    };
    let bad = |problem: String| EvalError::Input {
        path: pred_path.clone(),
        problem,
    };
    let psnr = masked_psnr(&pred, &gt.image, mask, range).map_err(bad)?;
    let ssim = masked_ssim(&pred, &gt.image, mask, range).map_err(bad)?;
    Ok(ViewScore {
        index: view.index,
        split: if view.is_val() { "val" } else { "train" }.into(),
        flash: gt.camera.flash(),
        psnr,
        ssim,
        mask_pixels: mask.map_or(gt.image.pixel_count(), |m| m.count()),
    })
}
