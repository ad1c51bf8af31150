//! Linear light: sRGB codes to linear values, exposure normalization, and
//! saturated pixels.
//!
//! - 8- and 16-bit sRGB codes are decoded with the sRGB curve
//!   (c ≤ 0.04045 ? c/12.92 : ((c + 0.055)/1.055)^2.4); EXR is linear already.
//! - Each photo is divided by its relative exposure t · ISO / N² (EXIF
//!   ExposureTime, PhotographicSensitivity, FNumber), relative to the median
//!   photo, so that the room light has one brightness in every image: the
//!   photo's `exposure_scale` is median / exposure. Without these tags on
//!   every photo nothing is scaled (and the import warns).
//! - A channel at a top code value (≥ 250/255) is saturated: its value is
//!   raised to the photo's clip level (code 255, i.e. `exposure_scale`) and
//!   the photo's saturation cap `max_intensity_i` is the linear value of
//!   code 250 times `exposure_scale`, so every saturated channel is at or
//!   above its photo's cap and every other channel below it (SPEC §4's
//!   rule then leaves them out of the colour loss).

use crate::photos::{Decoded, Pixels};

/// The lowest 8-bit code value counted as saturated.
pub const SATURATED_CODE: u8 = 250;

/// The lowest 16-bit code value counted as saturated (250/255 of 65535).
pub const SATURATED_CODE16: u16 = 64250;

/// sRGB-encoded value in [0, 1] to linear.
pub fn srgb_to_linear(c: f32) -> f32 {
    wildlight_data::png_io::srgb_to_linear(c)
}

/// The linear value of every 8-bit code.
pub fn srgb8_table() -> [f32; 256] {
    std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0))
}

/// The saturation cap of a photo scaled by `exposure_scale`: the linear
/// value of code 250 times the scale.
pub fn saturation_cap(exposure_scale: f64) -> f64 {
    srgb_to_linear(SATURATED_CODE as f32 / 255.0) as f64 * exposure_scale
}

/// Share of pixels with at least one channel at a top code value (0 for EXR).
pub fn saturated_share(pixels: &Pixels) -> f64 {
    let (count, total) = match pixels {
        Pixels::Srgb8(d) => (
            d.chunks_exact(3)
                .filter(|p| p.iter().any(|c| *c >= SATURATED_CODE))
                .count(),
            d.len() / 3,
        ),
        Pixels::Srgb16(d) => (
            d.chunks_exact(3)
                .filter(|p| p.iter().any(|c| *c >= SATURATED_CODE16))
                .count(),
            d.len() / 3,
        ),
        Pixels::Linear(_) => (0, 1),
    };
    count as f64 / total.max(1) as f64
}

/// A photo in linear light, exposure-normalized, with its saturated channels.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearImage {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// RGB, interleaved, row-major.
    pub data: Vec<f32>,
    /// Per pixel, bit c set when channel c is saturated (empty for EXR).
    pub saturated: Vec<u8>,
}

/// Decodes `photo` to linear light and multiplies it by `exposure_scale`;
/// saturated channels are set to the clip level (`exposure_scale`).
pub fn to_linear(photo: &Decoded, exposure_scale: f32) -> LinearImage {
    let n = (photo.width * photo.height) as usize;
    let mut data = Vec::with_capacity(3 * n);
    let mut saturated = Vec::new();
    match &photo.pixels {
        Pixels::Srgb8(d) => {
            let table = srgb8_table();
            saturated = vec![0u8; n];
            for (p, (px, sat)) in d.chunks_exact(3).zip(saturated.iter_mut()).enumerate() {
                let _ = p;
                for (c, code) in px.iter().enumerate() {
                    if *code >= SATURATED_CODE {
                        *sat |= 1 << c;
                        data.push(exposure_scale);
                    } else {
                        data.push(table[*code as usize] * exposure_scale);
                    }
                }
            }
        }
        Pixels::Srgb16(d) => {
            saturated = vec![0u8; n];
            for (px, sat) in d.chunks_exact(3).zip(saturated.iter_mut()) {
                for (c, code) in px.iter().enumerate() {
                    if *code >= SATURATED_CODE16 {
                        *sat |= 1 << c;
                        data.push(exposure_scale);
                    } else {
                        data.push(srgb_to_linear(*code as f32 / 65535.0) * exposure_scale);
                    }
                }
            }
        }
        Pixels::Linear(d) => data.extend(d.iter().map(|v| v * exposure_scale)),
    }
    LinearImage {
        width: photo.width,
        height: photo.height,
        data,
        saturated,
    }
}

/// The exposure normalization of a set of photos.
#[derive(Clone, Debug, PartialEq)]
pub struct ExposureScales {
    /// Per photo, the factor its linear image is multiplied by.
    pub scales: Vec<f64>,
    /// Per photo, its relative exposure t · ISO / N², when known.
    pub exposures: Vec<Option<f64>>,
    /// Why nothing was scaled, when so.
    pub warning: Option<String>,
}

/// `median / exposure` for every photo when all have an exposure (the
/// median is the exposure of the middle photo, the lower one of an even
/// count, so one photo keeps scale 1); all 1 with a warning naming the
/// photos without when some lack it.
pub fn exposure_scales(exposures: &[Option<f64>], files: &[String]) -> ExposureScales {
    let missing: Vec<&str> = exposures
        .iter()
        .zip(files)
        .filter(|(e, _)| e.is_none())
        .map(|(_, f)| f.as_str())
        .collect();
    if !missing.is_empty() {
        return ExposureScales {
            scales: vec![1.0; exposures.len()],
            exposures: exposures.to_vec(),
            warning: Some(format!(
                "{} of {} photos have no exposure EXIF (ExposureTime and ISO): {}; no photo is \
                 scaled for exposure, so the room light must have been captured at one fixed \
                 exposure (lock exposure on the phone)",
                missing.len(),
                exposures.len(),
                crate::error::list_some(&missing, 8)
            )),
        };
    }
    let mut sorted: Vec<f64> = exposures.iter().map(|e| e.unwrap_or(1.0)).collect();
    sorted.sort_by(f64::total_cmp);
    let median = sorted[(sorted.len() - 1) / 2];
    ExposureScales {
        scales: exposures
            .iter()
            .map(|e| median / e.unwrap_or(median))
            .collect(),
        exposures: exposures.to_vec(),
        warning: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn table_matches_the_curve() {
        let t = srgb8_table();
        assert_eq!(t[0], 0.0);
        assert!((t[255] - 1.0).abs() < 1e-6);
        // 10/255 = 0.0392 is on the linear segment
        assert!((t[10] - 10.0 / 255.0 / 12.92).abs() < 1e-7);
        // 128/255: ((0.50196 + 0.055) / 1.055)^2.4 = 0.21586
        assert!((t[128] - 0.215_861).abs() < 1e-5);
    }
}
