//! Where a reconstruction's errors are, material by material: on the
//! held-out views of a synthetic capture, the mask's pixels are grouped by
//! their ground-truth material (base colour, roughness and metallic rounded
//! to 0.05), and each group gets its mean base colour (truth and
//! prediction, after the per-channel scale alignment of `eval materials`),
//! its mean roughness and metallic, its share of the base colour's squared
//! error, and its share of the squared image error (values clipped at 1) in
//! the flash and the no-flash views.
//!
//! ```sh
//! wildlight render --run RUN --data CAPTURE --split val --out RENDER
//! cargo run --release -p wildlight-eval --example material_breakdown -- RENDER CAPTURE
//! ```

use anyhow::{Context, Result, bail};
use std::collections::BTreeMap;
use std::path::Path;
use wildlight_data::RgbImage;
use wildlight_data::exr_io::read_exr_rgb;
use wildlight_data::png_io::read_mask_png;
use wildlight_eval::material_eval::{Split, evaluate_materials};
use wildlight_eval::rendered_views::read_views;

/// Groups covering less than this share of the pixels are pooled as "other".
const MIN_SHARE: f64 = 0.005;

/// One mask pixel of one view.
struct Pixel {
    gt_base: [f64; 3],
    pred_base: [f64; 3],
    gt_rough: f64,
    pred_rough: f64,
    gt_metal: f64,
    pred_metal: f64,
    /// Squared image error summed over the channels.
    image_sq: f64,
    flash: bool,
}

fn rgb(image: &RgbImage, j: usize) -> [f64; 3] {
    [0, 1, 2].map(|c| image.data[3 * j + c] as f64)
}

fn read_view_pixels(render: &Path, val: &Path, index: usize, flash: bool) -> Result<Vec<Pixel>> {
    let name = format!("{index:03}.exr");
    let read = |dir: &Path, kind: &str| {
        let path = dir.join(kind).join(&name);
        read_exr_rgb(&path).with_context(|| format!("reading {}", path.display()))
    };
    let gt = val.join("gt");
    let (gt_base, gt_rough, gt_metal) = (
        read(&gt, "base_color")?,
        read(&gt, "roughness")?,
        read(&gt, "metallic")?,
    );
    let (pred_base, pred_rough, pred_metal) = (
        read(render, "base_color")?,
        read(render, "roughness")?,
        read(render, "metallic")?,
    );
    let (gt_image, pred_image) = (read(val, "image")?, read(render, "image")?);
    let mask_path = val.join("mask").join(format!("{index:03}.png"));
    let mask =
        read_mask_png(&mask_path).with_context(|| format!("reading {}", mask_path.display()))?;
    for (what, image) in [
        ("true base colour", &gt_base),
        ("true roughness", &gt_rough),
        ("true metallic", &gt_metal),
        ("predicted base colour", &pred_base),
        ("predicted roughness", &pred_rough),
        ("predicted metallic", &pred_metal),
        ("photo", &gt_image),
        ("rendering", &pred_image),
    ] {
        if (image.width, image.height) != (mask.width, mask.height) {
            bail!("view {index}: the {what} is not the size of the mask");
        }
    }
    Ok(mask
        .data
        .iter()
        .enumerate()
        .filter(|(_, inside)| **inside)
        .map(|(j, _)| Pixel {
            gt_base: rgb(&gt_base, j),
            pred_base: rgb(&pred_base, j),
            gt_rough: gt_rough.data[3 * j] as f64,
            pred_rough: pred_rough.data[3 * j] as f64,
            gt_metal: gt_metal.data[3 * j] as f64,
            pred_metal: pred_metal.data[3 * j] as f64,
            image_sq: (0..3)
                .map(|c| {
                    let clip = |im: &RgbImage| im.data[3 * j + c].min(1.0) as f64;
                    (clip(&pred_image) - clip(&gt_image)).powi(2)
                })
                .sum(),
            flash,
        })
        .collect())
}

/// The material key: base colour, roughness and metallic in steps of 0.05.
fn key(p: &Pixel) -> [i32; 5] {
    let q = |v: f64| (v / 0.05).round() as i32;
    [
        q(p.gt_base[0]),
        q(p.gt_base[1]),
        q(p.gt_base[2]),
        q(p.gt_rough),
        q(p.gt_metal),
    ]
}

fn psnr(sq: f64, values: usize) -> f64 {
    10.0 * (values as f64 / sq).log10()
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let [_, render, capture] = args.as_slice() else {
        bail!("usage: material_breakdown RENDER_DIR CAPTURE_DIR");
    };
    let (render, val) = (Path::new(render), Path::new(capture).join("val"));
    let mut pixels = Vec::new();
    for view in read_views(render)?.iter().filter(|v| v.is_val()) {
        pixels.extend(read_view_pixels(
            render,
            &val,
            view.index,
            view.flash == Some(true),
        )?);
    }
    if pixels.is_empty() {
        bail!("{}: no held-out view with mask pixels", render.display());
    }
    // The per-channel scale of the metric itself (`eval materials`).
    let scale = evaluate_materials(render, Path::new(capture), Split::Val)?
        .base_color_scale
        .context("no base colour pixels to align")?;
    let base_sq = |p: &Pixel| {
        (0..3)
            .map(|c| (scale[c] * p.pred_base[c] - p.gt_base[c]).powi(2))
            .sum::<f64>()
    };
    let total_base: f64 = pixels.iter().map(base_sq).sum();
    let image_total = |flash: bool| {
        pixels
            .iter()
            .filter(|p| p.flash == flash)
            .map(|p| p.image_sq)
            .sum::<f64>()
    };
    let (flash_total, plain_total) = (image_total(true), image_total(false));
    let flash_pixels = pixels.iter().filter(|p| p.flash).count();
    println!(
        "{} pixels; scale {scale:.3?}; base colour {:.2} dB; images flash {:.2} dB, no flash {:.2} dB (pooled)",
        pixels.len(),
        psnr(total_base, 3 * pixels.len()),
        psnr(flash_total, 3 * flash_pixels),
        psnr(plain_total, 3 * (pixels.len() - flash_pixels)),
    );
    let mut groups: BTreeMap<Option<[i32; 5]>, Vec<&Pixel>> = BTreeMap::new();
    let mut counts: BTreeMap<[i32; 5], usize> = BTreeMap::new();
    for p in &pixels {
        *counts.entry(key(p)).or_default() += 1;
    }
    for p in &pixels {
        let k = key(p);
        let large = counts[&k] as f64 >= MIN_SHARE * pixels.len() as f64;
        groups.entry(large.then_some(k)).or_default().push(p);
    }
    println!(
        "{:>7} {:>20} {:>20} {:>13} {:>11} {:>6} {:>6} {:>6}",
        "pixels",
        "base truth",
        "base aligned",
        "rough t / p",
        "metal t / p",
        "base%",
        "flash%",
        "plain%"
    );
    for (k, members) in &groups {
        let n = members.len() as f64;
        let mean = |f: &dyn Fn(&Pixel) -> f64| members.iter().map(|p| f(p)).sum::<f64>() / n;
        let gt = [0, 1, 2].map(|c| mean(&|p| p.gt_base[c]));
        let pred = [0, 1, 2].map(|c| mean(&|p| scale[c] * p.pred_base[c]));
        let share = |sum: f64, total: f64| 100.0 * sum / total.max(f64::MIN_POSITIVE);
        let image_share = |flash: bool, total: f64| {
            share(
                members
                    .iter()
                    .filter(|p| p.flash == flash)
                    .map(|p| p.image_sq)
                    .sum(),
                total,
            )
        };
        println!(
            "{:>7} {:>20} {:>20} {:>6.3} {:.3} {:>5.2} {:.2} {:>6.1} {:>6.1} {:>6.1}{}",
            members.len(),
            format!("{:.2} {:.2} {:.2}", gt[0], gt[1], gt[2]),
            format!("{:.2} {:.2} {:.2}", pred[0], pred[1], pred[2]),
            mean(&|p| p.gt_rough),
            mean(&|p| p.pred_rough),
            mean(&|p| p.gt_metal),
            mean(&|p| p.pred_metal),
            share(members.iter().map(|p| base_sq(p)).sum(), total_base),
            image_share(true, flash_total),
            image_share(false, plain_total),
            if k.is_none() { "  (other)" } else { "" },
        );
    }
    Ok(())
}
