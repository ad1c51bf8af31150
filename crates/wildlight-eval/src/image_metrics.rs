//! PSNR and SSIM of one image pair over a mask.
//!
//! Both images are first clipped to `[0, cap]` (the saturation cap of the
//! capture, SPEC §5; only clipped below at 0 when there is no cap). The
//! peak value is the cap, or 1 when there is none.
//!
//! **PSNR over a mask**: MSE = mean of (p − g)² over the mask pixels and
//! the three channels; PSNR = 10·log10(peak² / MSE). An MSE below
//! peak²·1e-10 is raised to it, so a perfect match reads 100 dB (JSON has
//! no infinity).
//!
//! **SSIM over a mask** (Wang et al. 2004, standard constants): pixels
//! outside the mask are set to 0 in both images (so the background does not
//! matter), each channel is filtered with an 11×11 Gaussian window of
//! σ = 1.5 (weights renormalized where the window leaves the image) to get
//! local means μ, variances σ² and covariance σ_pg, and
//! SSIM = ((2 μ_p μ_g + C1)(2 σ_pg + C2)) / ((μ_p² + μ_g² + C1)(σ_p² + σ_g² + C2))
//! with C1 = (0.01·peak)², C2 = (0.03·peak)². The reported value is the mean
//! of this map over the mask pixels and the three channels.

use wildlight_data::{Mask, RgbImage};

/// The highest PSNR reported (MSE floor of peak²·1e-10).
pub const MAX_PSNR: f64 = 100.0;

/// Side of the SSIM window in pixels.
const WINDOW: usize = 11;
/// Standard deviation of the SSIM window in pixels.
const WINDOW_SIGMA: f64 = 1.5;

/// Clipping and peak used by the metrics.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// The saturation cap; `None` = no upper clipping.
    pub cap: Option<f32>,
}

impl Range {
    /// The peak value: the cap, or 1 without a cap.
    pub fn peak(&self) -> f64 {
        self.cap.map_or(1.0, |c| c as f64)
    }

    fn clip(&self, v: f32) -> f64 {
        let v = v.max(0.0);
        match self.cap {
            Some(c) => v.min(c) as f64,
            None => v as f64,
        }
    }
}

/// Checks that prediction, ground truth and mask have the same size.
fn same_size(pred: &RgbImage, gt: &RgbImage, mask: Option<&Mask>) -> Result<(), String> {
    if (pred.width, pred.height) != (gt.width, gt.height) {
        return Err(format!(
            "prediction is {}×{} but ground truth is {}×{}",
            pred.width, pred.height, gt.width, gt.height
        ));
    }
    if let Some(m) = mask
        && (m.width, m.height) != (gt.width, gt.height)
    {
        return Err(format!(
            "mask is {}×{} but the image is {}×{}",
            m.width, m.height, gt.width, gt.height
        ));
    }
    Ok(())
}

/// MSE over the mask pixels (all pixels when `mask` is `None`) and the
/// three channels, after clipping; `None` when the mask is empty.
pub fn masked_mse(
    pred: &RgbImage,
    gt: &RgbImage,
    mask: Option<&Mask>,
    range: Range,
) -> Result<Option<f64>, String> {
    same_size(pred, gt, mask)?;
    let (mut sum, mut count) = (0.0f64, 0usize);
    for i in 0..(gt.width as usize * gt.height as usize) {
        if mask.is_some_and(|m| !m.data[i]) {
            continue;
        }
        for c in 0..3 {
            let d = range.clip(pred.data[3 * i + c]) - range.clip(gt.data[3 * i + c]);
            sum += d * d;
        }
        count += 3;
    }
    Ok((count > 0).then(|| sum / count as f64))
}

/// PSNR (dB) from an MSE and a peak value, capped at [`MAX_PSNR`].
pub fn psnr_from_mse(mse: f64, peak: f64) -> f64 {
    let floor = peak * peak * 10f64.powf(-MAX_PSNR / 10.0);
    10.0 * (peak * peak / mse.max(floor)).log10()
}

/// PSNR over a mask (see the module documentation); `None` for an empty mask.
pub fn masked_psnr(
    pred: &RgbImage,
    gt: &RgbImage,
    mask: Option<&Mask>,
    range: Range,
) -> Result<Option<f64>, String> {
    Ok(masked_mse(pred, gt, mask, range)?.map(|mse| psnr_from_mse(mse, range.peak())))
}

/// The normalized 1-D Gaussian of the SSIM window.
fn gaussian_window() -> [f64; WINDOW] {
    let mut w = [0.0; WINDOW];
    let half = (WINDOW / 2) as f64;
    for (i, v) in w.iter_mut().enumerate() {
        let x = i as f64 - half;
        *v = (-x * x / (2.0 * WINDOW_SIGMA * WINDOW_SIGMA)).exp();
    }
    let sum: f64 = w.iter().sum();
    w.map(|v| v / sum)
}

/// Separable Gaussian filtering of a `width`×`height` plane with the window
/// renormalized where it leaves the image.
fn blur(plane: &[f64], width: usize, height: usize, window: &[f64; WINDOW]) -> Vec<f64> {
    let half = WINDOW as isize / 2;
    let pass = |src: &[f64], along_x: bool| -> Vec<f64> {
        let mut out = vec![0.0; src.len()];
        for y in 0..height {
            for x in 0..width {
                let (mut acc, mut weight) = (0.0, 0.0);
                for (k, w) in window.iter().enumerate() {
                    let o = k as isize - half;
                    let (sx, sy) = if along_x {
                        (x as isize + o, y as isize)
                    } else {
                        (x as isize, y as isize + o)
                    };
                    if sx < 0 || sy < 0 || sx >= width as isize || sy >= height as isize {
                        continue;
                    }
                    acc += w * src[sy as usize * width + sx as usize];
                    weight += w;
                }
                out[y * width + x] = acc / weight;
            }
        }
        out
    };
    pass(&pass(plane, true), false)
}

/// The SSIM map (mean over the three channels at every pixel) of the
/// clipped images with pixels outside `mask` set to 0 in both (see the
/// module documentation). Pixels outside the mask are also in the map.
pub fn ssim_map(
    pred: &RgbImage,
    gt: &RgbImage,
    mask: Option<&Mask>,
    range: Range,
) -> Result<Vec<f64>, String> {
    same_size(pred, gt, mask)?;
    let (width, height) = (gt.width as usize, gt.height as usize);
    let n = width * height;
    let inside = |i: usize| mask.is_none_or(|m| m.data[i]);
    let peak = range.peak();
    let (c1, c2) = ((0.01 * peak).powi(2), (0.03 * peak).powi(2));
    let window = gaussian_window();
    let mut map = vec![0.0; n];
    for c in 0..3 {
        let plane = |img: &RgbImage| -> Vec<f64> {
            (0..n)
                .map(|i| {
                    if inside(i) {
                        range.clip(img.data[3 * i + c])
                    } else {
                        0.0
                    }
                })
                .collect()
        };
        let (p, g) = (plane(pred), plane(gt));
        let product =
            |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).collect::<Vec<_>>();
        let mu_p = blur(&p, width, height, &window);
        let mu_g = blur(&g, width, height, &window);
        let pp = blur(&product(&p, &p), width, height, &window);
        let gg = blur(&product(&g, &g), width, height, &window);
        let pg = blur(&product(&p, &g), width, height, &window);
        for (i, value) in map.iter_mut().enumerate() {
            let var_p = pp[i] - mu_p[i] * mu_p[i];
            let var_g = gg[i] - mu_g[i] * mu_g[i];
            let cov = pg[i] - mu_p[i] * mu_g[i];
            *value += ((2.0 * mu_p[i] * mu_g[i] + c1) * (2.0 * cov + c2))
                / ((mu_p[i].powi(2) + mu_g[i].powi(2) + c1) * (var_p + var_g + c2))
                / 3.0;
        }
    }
    Ok(map)
}

/// SSIM over a mask (see the module documentation); `None` for an empty mask.
pub fn masked_ssim(
    pred: &RgbImage,
    gt: &RgbImage,
    mask: Option<&Mask>,
    range: Range,
) -> Result<Option<f64>, String> {
    let map = ssim_map(pred, gt, mask, range)?;
    let (sum, count) = map
        .iter()
        .enumerate()
        .filter(|(i, _)| mask.is_none_or(|m| m.data[*i]))
        .fold((0.0, 0usize), |(s, c), (_, v)| (s + v, c + 1));
    Ok((count > 0).then(|| sum / count as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(width: u32, height: u32, f: impl Fn(u32, u32, usize) -> f32) -> RgbImage {
        let mut data = Vec::new();
        for y in 0..height {
            for x in 0..width {
                for c in 0..3 {
                    data.push(f(x, y, c));
                }
            }
        }
        RgbImage {
            width,
            height,
            data,
        }
    }

    fn half_mask(width: u32, height: u32) -> Mask {
        Mask {
            width,
            height,
            data: (0..width * height).map(|i| i % width < width / 2).collect(),
        }
    }

    const NO_CAP: Range = Range { cap: None };

    #[test]
    fn psnr_of_a_constant_offset() {
        // MSE = 0.1² → PSNR = 20 dB with peak 1.
        let g = image(8, 8, |x, y, _| (x + y) as f32 / 20.0);
        let p = image(8, 8, |x, y, _| (x + y) as f32 / 20.0 + 0.1);
        let psnr = masked_psnr(&p, &g, None, NO_CAP).unwrap().unwrap();
        assert!((psnr - 20.0).abs() < 1e-5, "{psnr}");
        // Peak = cap: with cap 2 the same error reads 20 + 20·log10(2) dB.
        let capped = masked_psnr(&p, &g, None, Range { cap: Some(2.0) })
            .unwrap()
            .unwrap();
        assert!(
            (capped - (20.0 + 20.0 * 2f64.log10())).abs() < 1e-5,
            "{capped}"
        );
        assert_eq!(masked_psnr(&g, &g, None, NO_CAP).unwrap(), Some(MAX_PSNR));
    }

    #[test]
    fn mask_excludes_pixels_and_cap_clips() {
        // Error 0.5 only in the right half (outside the mask): perfect inside.
        let g = image(8, 4, |_, _, _| 0.25);
        let p = image(8, 4, |x, _, _| if x >= 4 { 0.75 } else { 0.25 });
        let m = half_mask(8, 4);
        assert_eq!(masked_mse(&p, &g, Some(&m), NO_CAP).unwrap(), Some(0.0));
        assert_eq!(masked_mse(&p, &g, None, NO_CAP).unwrap(), Some(0.125));
        // Both above the cap: no error after clipping. One channel below: error.
        let g = image(4, 4, |_, _, c| if c == 0 { 3.0 } else { 0.5 });
        let p = image(4, 4, |_, _, c| if c == 0 { 7.0 } else { 0.5 });
        let capped = Range { cap: Some(1.0) };
        assert_eq!(masked_mse(&p, &g, None, capped).unwrap(), Some(0.0));
        let p = image(4, 4, |_, _, c| if c == 0 { 0.7 } else { 0.5 });
        let mse = masked_mse(&p, &g, None, capped).unwrap().unwrap();
        assert!((mse - 0.09 / 3.0).abs() < 1e-7);
        let empty = Mask::new(4, 4);
        assert_eq!(masked_psnr(&p, &g, Some(&empty), capped).unwrap(), None);
        assert_eq!(masked_ssim(&p, &g, Some(&empty), capped).unwrap(), None);
    }

    #[test]
    fn ssim_is_one_for_identical_images_and_matches_closed_form_for_constants() {
        let g = image(16, 16, |x, y, c| {
            ((x * 7 + y * 3 + c as u32) % 11) as f32 / 10.0
        });
        let s = masked_ssim(&g, &g, Some(&half_mask(16, 16)), NO_CAP)
            .unwrap()
            .unwrap();
        assert!((s - 1.0).abs() < 1e-12, "{s}");
        // Two constant images a and b: σ = 0 everywhere, so
        // SSIM = (2ab + C1) / (a² + b² + C1) at every pixel.
        let (a, b) = (0.4f64, 0.6f64);
        let p = image(16, 16, |_, _, _| a as f32);
        let q = image(16, 16, |_, _, _| b as f32);
        let c1 = 0.01f64.powi(2);
        let expected = (2.0 * a * b + c1) / (a * a + b * b + c1);
        let s = masked_ssim(&p, &q, None, NO_CAP).unwrap().unwrap();
        assert!((s - expected).abs() < 1e-6, "{s} vs {expected}");
    }

    #[test]
    fn ssim_of_noise_against_its_scaled_copy_matches_the_formula() {
        // g and p = k·g: away from the borders μ_p = k μ_g, σ_p² = k² σ_g²,
        // σ_pg = k σ_g², so SSIM = (2k μ² + C1)(2k σ² + C2) /
        // ((1 + k²) μ² + C1)((1 + k²) σ² + C2) with the local μ, σ of g.
        // Checked on one interior pixel of a smooth image where the window
        // statistics are computed independently here.
        let f = |x: u32, y: u32| 0.3 + 0.2 * ((x as f64 * 0.7).sin() * (y as f64 * 0.4).cos());
        let g = image(31, 31, |x, y, _| f(x, y) as f32);
        let k = 0.8;
        let p = image(31, 31, |x, y, _| (k * f(x, y)) as f32);
        let window = gaussian_window();
        let (cx, cy) = (15i32, 15i32);
        let (mut mu, mut m2) = (0.0, 0.0);
        for (j, wy) in window.iter().enumerate() {
            for (i, wx) in window.iter().enumerate() {
                let v = f((cx + i as i32 - 5) as u32, (cy + j as i32 - 5) as u32) as f32 as f64;
                mu += wx * wy * v;
                m2 += wx * wy * v * v;
            }
        }
        let var = m2 - mu * mu;
        let (c1, c2) = (1e-4, 9e-4);
        let expected = (2.0 * k * mu * mu + c1) * (2.0 * k * var + c2)
            / (((1.0 + k * k) * mu * mu + c1) * ((1.0 + k * k) * var + c2));
        let s = ssim_map(&p, &g, None, NO_CAP).unwrap()[(cy * 31 + cx) as usize];
        assert!((s - expected).abs() < 2e-4, "{s} vs {expected}");
        assert!(s < 0.999);
    }

    #[test]
    fn size_mismatch_is_reported() {
        let a = image(4, 4, |_, _, _| 0.0);
        let b = image(5, 4, |_, _, _| 0.0);
        assert!(
            masked_psnr(&a, &b, None, NO_CAP)
                .unwrap_err()
                .contains("4×4")
        );
    }
}
