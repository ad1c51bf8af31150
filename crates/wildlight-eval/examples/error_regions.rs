//! Where a reconstruction's image error is, by kind of pixel: on the
//! held-out views of a synthetic capture, each mask pixel is put in one of
//! four regions, and each region gets its share of the pixels, its share of
//! the squared image error (values clipped at 1) and its own PSNR, for the
//! flash and the no-flash views:
//!
//! - **silhouette**: within 2 pixels of a pixel outside the mask;
//! - **clipped**: elsewhere, where the photo reaches 1 in some channel (the
//!   flash's highlights, and bright reflections of the room);
//! - **turning**: elsewhere, where the true normal changes by more than
//!   0.05 in some component towards a neighbour (grooves, rims, creases, and
//!   parts curved more tightly than about 20 pixels per radian: at the
//!   default kettle's 256² views the body turns by about 0.02 per pixel, its
//!   knob, spout, handle, lid groove and foot by more);
//! - **smooth**: the rest.
//!
//! A second table splits the flash views' error between the two terms of
//! SPEC §2: it scores the flash views as rendered, with the true ambient
//! term in place of the model's (so only the flash term's error is left),
//! and with the true flash term in place of the model's (only the ambient
//! term's error left), from the `ambient` and `flash` maps of the rendering
//! and of the capture's `val/gt`; and it gives the share of each one's
//! squared error held by the 1 % of pixels where it is largest.
//!
//! A third table splits the flash term's error (the second row above) by
//! how far the rendering's normal is from the capture's at the pixel:
//! within 0.5°, 0.5–2°, 2–8° and beyond 8° ([`ANGLE_BINS`]). A fourth
//! splits each of those bins' pixels between the four regions above.
//!
//! With a third argument, writes a PNG of one held-out view (the first, or
//! the view index given as a fourth argument): the photo, the rendering
//! (both clipped at 1) and each mask pixel's RMS error (×4) in red
//! (silhouette), yellow (clipped), green (turning) or blue (smooth), side
//! by side.
//!
//! ```sh
//! wildlight render --run RUN --data CAPTURE --split val --out RENDER
//! cargo run --release -p wildlight-eval --example error_regions -- RENDER CAPTURE [OUT.png [VIEW]]
//! ```

use anyhow::{Context, Result, bail};
use std::path::Path;
use wildlight_data::exr_io::read_exr_rgb;
use wildlight_data::png_io::{read_mask_png, write_png_srgb};
use wildlight_data::{Mask, RgbImage};
use wildlight_eval::rendered_views::read_views;

/// Pixels this close to the outside of the mask are silhouette pixels.
const SILHOUETTE_BAND: i64 = 2;
/// A normal component change above this towards a neighbour marks a turning pixel.
const TURN: f32 = 0.05;

const REGIONS: [&str; 4] = ["silhouette", "clipped", "turning", "smooth"];
/// A photo value at or above this counts as clipped.
const CLIP: f32 = 0.999;

/// The flash views scored three ways: as rendered, with the true ambient
/// term, with the true flash term.
const TERM_ROWS: [&str; 3] = [
    "as rendered",
    "true ambient + model flash",
    "model ambient + true flash",
];

/// Upper edges (degrees) of the normal-error bins of the third table; the
/// last bin is open.
const ANGLE_BINS: [f32; 3] = [0.5, 2.0, 8.0];
const ANGLE_NAMES: [&str; 4] = ["< 0.5°", "0.5–2°", "2–8°", "> 8°"];

/// Squared error and pixel count of each region, flash and no flash.
#[derive(Default)]
struct Tally {
    sq: [[f64; 4]; 2],
    pixels: [[usize; 4]; 2],
    /// Per flash-view mask pixel, its squared error in each [`TERM_ROWS`] way.
    terms: [Vec<f64>; 3],
    /// The flash term's squared error and pixel count per normal-error bin.
    by_angle: [(f64, usize); 4],
    /// Pixels of each normal-error bin (rows) in each region (columns).
    angle_regions: [[usize; 4]; 4],
}

fn read(dir: &Path, kind: &str, index: usize) -> Result<RgbImage> {
    let path = dir.join(kind).join(format!("{index:03}.exr"));
    read_exr_rgb(&path).with_context(|| format!("reading {}", path.display()))
}

/// The region of pixel (x, y) of the mask, given the photo and the true
/// normals (an index into [`REGIONS`]).
fn region(mask: &Mask, photo: &RgbImage, normal: &RgbImage, x: i64, y: i64) -> usize {
    let (w, h) = (mask.width as i64, mask.height as i64);
    let inside =
        |x: i64, y: i64| x >= 0 && y >= 0 && x < w && y < h && mask.data[(y * w + x) as usize];
    let b = SILHOUETTE_BAND;
    if (-b..=b).any(|dy| (-b..=b).any(|dx| !inside(x + dx, y + dy))) {
        return 0;
    }
    let j = (y * w + x) as usize;
    if (0..3).any(|c| photo.data[3 * j + c] >= CLIP) {
        return 1;
    }
    let turning = (-1..=1).any(|dy| {
        (-1..=1).any(|dx| {
            let k = ((y + dy) * w + x + dx) as usize;
            (0..3).any(|c| (normal.data[3 * k + c] - normal.data[3 * j + c]).abs() > TURN)
        })
    });
    if turning { 2 } else { 3 }
}

fn psnr(sq: f64, values: usize) -> f64 {
    10.0 * (values as f64 / sq).log10()
}

/// Fails unless every named image of view `i` is the size of its mask.
fn ensure_mask_size(i: usize, mask: &Mask, images: &[(&str, &RgbImage)]) -> Result<()> {
    for (what, image) in images {
        if (image.width, image.height) != (mask.width, mask.height) {
            bail!("view {i}: the {what} is not the size of the mask");
        }
    }
    Ok(())
}

/// The squared error of pixel `j` summed over its channels, both sides
/// clipped at 1; `value(k)` is the predicted value of channel entry `k`.
fn pixel_sq(photo: &RgbImage, j: usize, value: impl Fn(usize) -> f32) -> f64 {
    (0..3)
        .map(|c| {
            let k = 3 * j + c;
            f64::from(value(k).min(1.0) - photo.data[k].min(1.0)).powi(2)
        })
        .sum()
}

/// What the caller has read or worked out for one held-out view.
struct ViewMaps<'a> {
    photo: &'a RgbImage,
    mask: &'a Mask,
    /// The capture's normal map.
    true_normal: &'a RgbImage,
    /// Each pixel's region (index into [`REGIONS`]); `None` outside the mask.
    regions: &'a [Option<usize>],
}

/// Adds flash view `i`'s squared error per mask pixel with the true
/// ambient term and with the true flash term (the last two
/// [`TERM_ROWS`]) to the tally, and the flash term's error by normal-error
/// bin against the capture's normal map, with each bin's pixels by region;
/// the caller adds the first row, as rendered.
fn add_terms(
    tally: &mut Tally,
    render: &Path,
    val: &Path,
    i: usize,
    view: &ViewMaps,
) -> Result<()> {
    let ViewMaps {
        photo,
        mask,
        true_normal,
        regions,
    } = *view;
    let gt = val.join("gt");
    let (model_ambient, model_flash) = (read(render, "ambient", i)?, read(render, "flash", i)?);
    let (true_ambient, true_flash) = (read(&gt, "ambient", i)?, read(&gt, "flash", i)?);
    let model_normal = read(render, "normal", i)?;
    ensure_mask_size(
        i,
        mask,
        &[
            ("model's ambient map", &model_ambient),
            ("model's flash map", &model_flash),
            ("true ambient map", &true_ambient),
            ("true flash map", &true_flash),
            ("model's normal map", &model_normal),
        ],
    )?;
    let swapped = [(&true_ambient, &model_flash), (&model_ambient, &true_flash)];
    for (j, _) in mask.data.iter().enumerate().filter(|(_, on)| **on) {
        let sq =
            swapped.map(|(ambient, flash)| pixel_sq(photo, j, |k| ambient.data[k] + flash.data[k]));
        tally.terms[1].push(sq[0]);
        tally.terms[2].push(sq[1]);
        let unit =
            |im: &RgbImage| glam::Vec3::from_slice(&im.data[3 * j..3 * j + 3]).normalize_or_zero();
        let cos = unit(&model_normal).dot(unit(true_normal)).clamp(-1.0, 1.0);
        let degrees = cos.acos().to_degrees();
        let bin = ANGLE_BINS.iter().filter(|&&edge| degrees >= edge).count();
        tally.by_angle[bin].0 += sq[0];
        tally.by_angle[bin].1 += 1;
        tally.angle_regions[bin][regions[j].expect("a mask pixel has a region")] += 1;
    }
    Ok(())
}

/// The share of the total held by the largest 1 % of `values`.
fn top_percent_share(values: &[f64]) -> f64 {
    let mut sorted = values.to_vec();
    sorted.sort_by(|a, b| b.total_cmp(a));
    let top = (sorted.len() / 100).max(1).min(sorted.len());
    let total: f64 = sorted.iter().sum();
    sorted[..top].iter().sum::<f64>() / total.max(f64::MIN_POSITIVE)
}

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: error_regions RENDER_DIR CAPTURE_DIR [OUT.png [VIEW]]";
    let (render, capture, png, picture_view) = match args.as_slice() {
        [_, r, c] => (r, c, None, None),
        [_, r, c, p] => (r, c, Some(Path::new(p)), None),
        [_, r, c, p, v] => (
            r,
            c,
            Some(Path::new(p)),
            Some(v.parse::<usize>().context(usage)?),
        ),
        _ => bail!(usage),
    };
    let (render, val) = (Path::new(render), Path::new(capture).join("val"));
    let mut tally = Tally::default();
    let mut first = true;
    for view in read_views(render)?.iter().filter(|v| v.is_val()) {
        let i = view.index;
        let flash = usize::from(view.flash == Some(true));
        let (photo, rendering, normal) = (
            read(&val, "image", i)?,
            read(render, "image", i)?,
            read(&val.join("gt"), "normal", i)?,
        );
        let mask_path = val.join("mask").join(format!("{i:03}.png"));
        let mask = read_mask_png(&mask_path)
            .with_context(|| format!("reading {}", mask_path.display()))?;
        ensure_mask_size(
            i,
            &mask,
            &[
                ("photo", &photo),
                ("rendering", &rendering),
                ("normal map", &normal),
            ],
        )?;
        let w = mask.width;
        // Each mask pixel's region, once per view (the tables and the
        // picture read it).
        let regions: Vec<Option<usize>> = (0..mask.data.len())
            .map(|j| {
                let (x, y) = ((j % w as usize) as i64, (j / w as usize) as i64);
                mask.data[j].then(|| region(&mask, &photo, &normal, x, y))
            })
            .collect();
        if flash == 1 {
            let view = ViewMaps {
                photo: &photo,
                mask: &mask,
                true_normal: &normal,
                regions: &regions,
            };
            add_terms(&mut tally, render, &val, i, &view)?;
        }
        let mut picture = RgbImage::new(3 * w, mask.height);
        for y in 0..mask.height as i64 {
            for x in 0..mask.width as i64 {
                let j = (y * mask.width as i64 + x) as usize;
                let clipped = |im: &RgbImage| [0, 1, 2].map(|c| im.data[3 * j + c].min(1.0));
                picture.set(x as u32, y as u32, clipped(&photo));
                picture.set(w + x as u32, y as u32, clipped(&rendering));
                let Some(r) = regions[j] else {
                    continue;
                };
                let sq = pixel_sq(&photo, j, |k| rendering.data[k]);
                tally.sq[flash][r] += sq;
                tally.pixels[flash][r] += 1;
                if flash == 1 {
                    tally.terms[0].push(sq);
                }
                let e = (4.0 * (sq / 3.0).sqrt()) as f32;
                let colour = match r {
                    0 => [e, 0.0, 0.0],
                    1 => [e, e, 0.0],
                    2 => [0.0, e, 0.0],
                    _ => [0.0, 0.0, e],
                };
                picture.set(2 * w + x as u32, y as u32, colour);
            }
        }
        let wanted = picture_view.map_or(first, |v| v == i);
        if let (true, Some(out)) = (wanted, png) {
            write_png_srgb(out, &picture).with_context(|| format!("writing {}", out.display()))?;
        }
        first = false;
    }
    if first {
        bail!("{}: no held-out view", render.display());
    }
    println!(
        "{:>9} {:>11} {:>8} {:>8} {:>9}",
        "views", "region", "pixels%", "error%", "PSNR dB"
    );
    for (flash, name) in [(1, "flash"), (0, "no flash")] {
        let (sq, px) = (&tally.sq[flash], &tally.pixels[flash]);
        let (sq_all, px_all) = (sq.iter().sum::<f64>(), px.iter().sum::<usize>());
        if px_all == 0 {
            continue;
        }
        for (r, region) in REGIONS.iter().enumerate() {
            println!(
                "{:>9} {:>11} {:>8.1} {:>8.1} {:>9.2}",
                name,
                region,
                100.0 * px[r] as f64 / px_all as f64,
                100.0 * sq[r] / sq_all.max(f64::MIN_POSITIVE),
                psnr(sq[r], 3 * px[r]),
            );
        }
        println!(
            "{:>9} {:>11} {:>8.1} {:>8.1} {:>9.2}",
            name,
            "all",
            100.0,
            100.0,
            psnr(sq_all, 3 * px_all)
        );
    }
    if !tally.terms[0].is_empty() {
        println!();
        println!(
            "{:>28} {:>9} {:>13}",
            "flash views", "PSNR dB", "top 1% share"
        );
        for (row, name) in TERM_ROWS.iter().enumerate() {
            let sq = &tally.terms[row];
            println!(
                "{:>28} {:>9.2} {:>12.1}%",
                name,
                psnr(sq.iter().sum(), 3 * sq.len()),
                100.0 * top_percent_share(sq),
            );
        }
        println!();
        println!(
            "{:>28} {:>8} {:>8} {:>9}",
            "flash term, normal off by", "pixels%", "error%", "PSNR dB"
        );
        let px_all: usize = tally.by_angle.iter().map(|b| b.1).sum();
        let sq_all: f64 = tally.by_angle.iter().map(|b| b.0).sum();
        for (name, (sq, px)) in ANGLE_NAMES.iter().zip(tally.by_angle) {
            println!(
                "{:>28} {:>8.1} {:>8.1} {:>9.2}",
                name,
                100.0 * px as f64 / px_all.max(1) as f64,
                100.0 * sq / sq_all.max(f64::MIN_POSITIVE),
                psnr(sq, 3 * px),
            );
        }
        println!();
        print!("{:>28}", "normal off by, % in region");
        for region in REGIONS {
            print!(" {region:>10}");
        }
        println!();
        for (name, counts) in ANGLE_NAMES.iter().zip(tally.angle_regions) {
            print!("{name:>28}");
            let total = counts.iter().sum::<usize>().max(1) as f64;
            for c in counts {
                print!(" {:>10.1}", 100.0 * c as f64 / total);
            }
            println!();
        }
    }
    Ok(())
}
