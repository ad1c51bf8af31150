//! Turning linear HDR maps into the 8-bit tiles of the preview images
//! (`demo`'s preview.png, `reconstruct`'s relit preview): an exposure from
//! the 99th percentile, clipping, the sRGB curve, and a grey backdrop where
//! nothing covers a pixel.

/// Display value (8-bit) of pixels outside the object: a mid-dark grey.
pub const BACKDROP: f32 = 64.0 / 255.0;

/// Linear HDR value to an 8-bit display value: multiply by `exposure`,
/// clip to [0, 1], encode with the sRGB curve.
pub fn tone_map(v: f32, exposure: f32) -> f32 {
    wildlight_data::png_io::linear_to_srgb((v * exposure).clamp(0.0, 1.0))
}

/// One preview tile: `value(pixel)` gives the display colour in [0, 1]
/// of a covered pixel and `coverage(pixel)` in [0, 1] how much of the pixel
/// the object covers; the rest shows the backdrop.
pub fn tile(
    width: u32,
    height: u32,
    value: impl Fn(usize) -> [f32; 3],
    coverage: impl Fn(usize) -> f32,
) -> image::RgbImage {
    image::RgbImage::from_fn(width, height, |x, y| {
        let i = (y * width + x) as usize;
        let a = coverage(i).clamp(0.0, 1.0);
        let v = if a > 0.0 { value(i) } else { [0.0; 3] };
        image::Rgb(v.map(|c| ((a * c + (1.0 - a) * BACKDROP) * 255.0).round() as u8))
    })
}

/// The exposure that maps the 99th percentile of `values` to 1 (1 when
/// there is nothing bright to measure).
pub fn exposure_for(mut values: Vec<f32>) -> f32 {
    values.retain(|v| v.is_finite() && *v > 0.0);
    if values.is_empty() {
        return 1.0;
    }
    let k = ((values.len() - 1) as f64 * 0.99).round() as usize;
    let (_, p99, _) = values.select_nth_unstable_by(k, f32::total_cmp);
    1.0 / *p99
}

/// Pixel `i` of a linear RGB image.
pub fn rgb(img: &wildlight_data::RgbImage, i: usize) -> [f32; 3] {
    [img.data[3 * i], img.data[3 * i + 1], img.data[3 * i + 2]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tone_map_exposes_clips_and_encodes_srgb() {
        assert_eq!(tone_map(0.0, 3.0), 0.0);
        assert_eq!(tone_map(-1.0, 1.0), 0.0);
        assert!((tone_map(2.0, 1.0) - 1.0).abs() < 1e-6);
        assert_eq!(tone_map(2.0, 1.0), tone_map(1.0, 1.0));
        // 0.1 · 2 = 0.2 linear is 0.4845 in sRGB (IEC 61966-2-1)
        assert!((tone_map(0.1, 2.0) - 0.48453).abs() < 1e-4);
    }

    #[test]
    fn exposure_maps_the_99th_percentile_to_one() {
        let values: Vec<f32> = (1..=1000).map(|i| i as f32 / 100.0).collect();
        // the 99th percentile of 0.01..10 is 9.90 (index 989 of 0..999)
        assert!((exposure_for(values) - 1.0 / 9.9).abs() < 1e-6);
        assert_eq!(exposure_for(vec![0.0, f32::NAN]), 1.0);
    }

    #[test]
    fn tiles_blend_the_backdrop_by_coverage() {
        let t = tile(2, 1, |_| [1.0, 0.0, 0.0], |i| [1.0, 0.0][i]);
        assert_eq!(t.get_pixel(0, 0).0, [255, 0, 0]);
        assert_eq!(t.get_pixel(1, 0).0, [64, 64, 64]);
    }
}
