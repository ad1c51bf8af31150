//! Where a reconstruction's errors are, material by material: on the
//! held-out views of a synthetic capture, the mask's pixels are grouped by
//! their ground-truth material (base colour, roughness and metallic rounded
//! to 0.05), and each group gets its mean base colour (truth and
//! prediction, after the per-channel scale alignment of `eval materials`),
//! its mean roughness and metallic, its share of the base colour's squared
//! error, and its share of the squared image error (values clipped at 1) in
//! the flash and the no-flash views. A second table gives, per group, the
//! other parameters of Θ (dielectric specular, clearcoat, clearcoat gloss,
//! subsurface), truth and prediction, read from the `params` maps, and the
//! median angle between the predicted and the true normals with the share
//! of pixels more than 5° off (a sharp lobe needs normals accurate to about
//! its width, so a group with poor normals settles on rougher, darker
//! metal). A third
//! and a fourth give, per group, the means of the two terms of SPEC §2 and
//! of the image clipped at 1, truth and prediction (the `ambient`, `flash`
//! and `image` maps, averaged over the channels), in the flash and in the
//! no-flash views: whether the ambient field takes up light that the flash
//! term should explain, and how much light the clipping hides.
//!
//! ```sh
//! wildlight render --run RUN --data CAPTURE --split val --out RENDER
//! cargo run --release -p wildlight-eval --example material_breakdown -- RENDER CAPTURE
//! ```

use anyhow::{Context, Result, bail};
use std::collections::BTreeMap;
use std::path::Path;
use wildlight_data::RgbImage;
use wildlight_data::exr_io::{read_exr_channels, read_exr_rgb};
use wildlight_data::png_io::read_mask_png;
use wildlight_eval::material_eval::{Split, evaluate_materials};
use wildlight_eval::rendered_views::read_views;
use wildlight_material::{
    BASE_COLOR, CLEARCOAT, CLEARCOAT_GLOSS, DIELECTRIC, METALLIC, PARAM_COUNT, ROUGHNESS,
    SUBSURFACE,
};

/// Groups covering less than this share of the pixels are pooled as "other".
const MIN_SHARE: f64 = 0.005;

/// The parameters of the second table: (index in Θ, column title).
const OTHER_PARAMS: [(usize, &str); 4] = [
    (DIELECTRIC, "dielectric"),
    (CLEARCOAT, "clearcoat"),
    (CLEARCOAT_GLOSS, "cc gloss"),
    (SUBSURFACE, "subsurface"),
];

/// One mask pixel of one view.
struct Pixel {
    /// Θ of the ground truth.
    gt: [f64; PARAM_COUNT],
    /// Θ of the reconstruction.
    pred: [f64; PARAM_COUNT],
    /// Squared image error summed over the channels.
    image_sq: f64,
    /// Angle between the predicted and the true normal, in degrees (none
    /// where either map has no normal).
    normal_deg: Option<f64>,
    flash: bool,
    /// Channel means of the ambient term, the flash term and the image
    /// clipped at 1: truth, prediction.
    terms: [[f64; 2]; 3],
}

/// The channel mean of every pixel of an RGB map.
fn channel_means(path: &Path) -> Result<(u32, u32, Vec<f64>)> {
    let im = read_exr_rgb(path).with_context(|| format!("reading {}", path.display()))?;
    let means = im
        .data
        .chunks_exact(3)
        .map(|c| c.iter().map(|v| *v as f64).sum::<f64>() / 3.0)
        .collect();
    Ok((im.width, im.height, means))
}

/// The nine parameter planes of a `params` map (channels p0..p8).
fn read_params(path: &Path) -> Result<(u32, u32, Vec<Vec<f32>>)> {
    let exr = read_exr_channels(path).with_context(|| format!("reading {}", path.display()))?;
    let planes = (0..PARAM_COUNT)
        .map(|c| {
            exr.channel(&format!("p{c}"))
                .map(<[f32]>::to_vec)
                .with_context(|| {
                    format!("{}: no channel p{c} (has {})", path.display(), exr.names())
                })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok((exr.width, exr.height, planes))
}

fn read_view_pixels(render: &Path, val: &Path, index: usize, flash: bool) -> Result<Vec<Pixel>> {
    let name = format!("{index:03}.exr");
    let read = |dir: &Path| {
        let path = dir.join("image").join(&name);
        read_exr_rgb(&path).with_context(|| format!("reading {}", path.display()))
    };
    let (gt_image, pred_image) = (read(val)?, read(render)?);
    let gt = read_params(&val.join("gt").join("params").join(&name))?;
    let pred = read_params(&render.join("params").join(&name))?;
    let normals = [val.join("gt"), render.to_path_buf()].map(|dir| {
        let path = dir.join("normal").join(&name);
        read_exr_rgb(&path).with_context(|| format!("reading {}", path.display()))
    });
    let [gt_normal, pred_normal] = normals;
    let (gt_normal, pred_normal) = (gt_normal?, pred_normal?);
    let mask_path = val.join("mask").join(format!("{index:03}.png"));
    let mask =
        read_mask_png(&mask_path).with_context(|| format!("reading {}", mask_path.display()))?;
    let size = (mask.width, mask.height);
    let term = |dir: &Path, term: &str| channel_means(&dir.join(term).join(&name));
    let terms = [
        [term(&val.join("gt"), "ambient")?, term(render, "ambient")?],
        [term(&val.join("gt"), "flash")?, term(render, "flash")?],
    ];
    for (what, dims) in [
        ("true ambient map", (terms[0][0].0, terms[0][0].1)),
        ("predicted ambient map", (terms[0][1].0, terms[0][1].1)),
        ("true flash map", (terms[1][0].0, terms[1][0].1)),
        ("predicted flash map", (terms[1][1].0, terms[1][1].1)),
        ("true parameter map", (gt.0, gt.1)),
        ("predicted parameter map", (pred.0, pred.1)),
        ("photo", (gt_image.width, gt_image.height)),
        ("true normal map", (gt_normal.width, gt_normal.height)),
        (
            "predicted normal map",
            (pred_normal.width, pred_normal.height),
        ),
        ("rendering", (pred_image.width, pred_image.height)),
    ] {
        if dims != size {
            bail!("view {index}: the {what} is not the size of the mask");
        }
    }
    let theta = |planes: &[Vec<f32>], j: usize| std::array::from_fn(|c| planes[c][j] as f64);
    Ok(mask
        .data
        .iter()
        .enumerate()
        .filter(|(_, inside)| **inside)
        .map(|(j, _)| Pixel {
            gt: theta(&gt.2, j),
            pred: theta(&pred.2, j),
            image_sq: (0..3)
                .map(|c| {
                    let clip = |im: &RgbImage| im.data[3 * j + c].min(1.0) as f64;
                    (clip(&pred_image) - clip(&gt_image)).powi(2)
                })
                .sum(),
            normal_deg: {
                let n = |im: &RgbImage| {
                    glam::DVec3::from_array(std::array::from_fn(|c| im.data[3 * j + c] as f64))
                };
                let (a, b) = (n(&gt_normal), n(&pred_normal));
                (a.length_squared() > 0.0 && b.length_squared() > 0.0).then(|| {
                    let cos = a.normalize().dot(b.normalize()).clamp(-1.0, 1.0);
                    cos.acos().to_degrees()
                })
            },
            flash,
            terms: {
                let clip = |im: &RgbImage| {
                    (0..3)
                        .map(|c| im.data[3 * j + c].min(1.0) as f64)
                        .sum::<f64>()
                        / 3.0
                };
                let [a, f] = terms.each_ref().map(|t| t.each_ref().map(|m| m.2[j]));
                [a, f, [clip(&gt_image), clip(&pred_image)]]
            },
        })
        .collect())
}

/// The material key: base colour, roughness and metallic in steps of 0.05.
fn key(p: &Pixel) -> [i32; 5] {
    let q = |v: f64| (v / 0.05).round() as i32;
    [
        q(p.gt[BASE_COLOR]),
        q(p.gt[BASE_COLOR + 1]),
        q(p.gt[BASE_COLOR + 2]),
        q(p.gt[ROUGHNESS]),
        q(p.gt[METALLIC]),
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
            .map(|c| (scale[c] * p.pred[BASE_COLOR + c] - p.gt[BASE_COLOR + c]).powi(2))
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
        let gt = [0, 1, 2].map(|c| mean(&|p| p.gt[BASE_COLOR + c]));
        let pred = [0, 1, 2].map(|c| mean(&|p| scale[c] * p.pred[BASE_COLOR + c]));
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
            mean(&|p| p.gt[ROUGHNESS]),
            mean(&|p| p.pred[ROUGHNESS]),
            mean(&|p| p.gt[METALLIC]),
            mean(&|p| p.pred[METALLIC]),
            share(members.iter().map(|p| base_sq(p)).sum(), total_base),
            image_share(true, flash_total),
            image_share(false, plain_total),
            if k.is_none() { "  (other)" } else { "" },
        );
    }
    // The rest of Θ, group by group in the same order (true / predicted
    // means; the dielectric specular and the clearcoat scale the flash term
    // with the gain, so compare them across groups rather than absolutely).
    print!("\n{:>7} {:>20}", "pixels", "base truth");
    for (_, title) in OTHER_PARAMS {
        print!(" {:>13}", format!("{title} t / p"));
    }
    println!(" {:>15}", "normal° med >5°");
    for (k, members) in &groups {
        let n = members.len() as f64;
        let mean = |f: &dyn Fn(&Pixel) -> f64| members.iter().map(|p| f(p)).sum::<f64>() / n;
        let gt = [0, 1, 2].map(|c| mean(&|p| p.gt[BASE_COLOR + c]));
        print!(
            "{:>7} {:>20}",
            members.len(),
            format!("{:.2} {:.2} {:.2}", gt[0], gt[1], gt[2])
        );
        for (i, _) in OTHER_PARAMS {
            print!(" {:>6.3} {:.3}", mean(&|p| p.gt[i]), mean(&|p| p.pred[i]));
        }
        let mut angles: Vec<f64> = members.iter().filter_map(|p| p.normal_deg).collect();
        angles.sort_by(f64::total_cmp);
        let off = angles.iter().filter(|a| **a > 5.0).count() as f64;
        print!(
            " {:>7.2} {:>6.1}%",
            angles.get(angles.len() / 2).copied().unwrap_or(f64::NAN),
            100.0 * off / angles.len().max(1) as f64
        );
        println!("{}", if k.is_none() { "  (other)" } else { "" });
    }
    // The terms of SPEC §2 and the clipped image, group by group, in the
    // flash and then in the no-flash views.
    for flash in [true, false] {
        println!(
            "\n{:>7} {:>20} {:>15} {:>15} {:>15}   ({} views, channel means)",
            "pixels",
            "base truth",
            "ambient t / p",
            "flash t / p",
            "clipped t / p",
            if flash { "flash" } else { "no-flash" }
        );
        for (k, members) in &groups {
            let chosen: Vec<&&Pixel> = members.iter().filter(|p| p.flash == flash).collect();
            let n = chosen.len().max(1) as f64;
            let mean = |t: usize, i: usize| chosen.iter().map(|p| p.terms[t][i]).sum::<f64>() / n;
            let gt = [0, 1, 2].map(|c| {
                members.iter().map(|p| p.gt[BASE_COLOR + c]).sum::<f64>() / members.len() as f64
            });
            println!(
                "{:>7} {:>20} {:>7.4} {:.4} {:>7.4} {:.4} {:>7.4} {:.4}{}",
                chosen.len(),
                format!("{:.2} {:.2} {:.2}", gt[0], gt[1], gt[2]),
                mean(0, 0),
                mean(0, 1),
                mean(1, 0),
                mean(1, 1),
                mean(2, 0),
                mean(2, 1),
                if k.is_none() { "  (other)" } else { "" },
            );
        }
    }
    Ok(())
}
