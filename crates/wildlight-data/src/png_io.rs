//! PNG reading (images and masks) and mask writing.
//!
//! Image values are read as value/256 without sRGB decoding by default,
//! which is what the published WildLight/NeuS datasets expect (SPEC §5);
//! [`PngDecoding::Srgb`] decodes the sRGB curve instead (for phone photos).
//! 16-bit files are read as value/65536 (or sRGB-decoded from value/65535).

use std::path::Path;

use image::{DynamicImage, ImageEncoder};

use crate::atomic::write_bytes_atomically;
use crate::error::DataError;
use crate::image::{Mask, RgbImage};

/// How 8-bit (or 16-bit) PNG values become linear floats.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum PngDecoding {
    /// value / 256 (value / 65536 for 16-bit): what NeuS/WildLight datasets expect.
    #[default]
    Linear256,
    /// The sRGB transfer curve applied to value / 255 (value / 65535).
    Srgb,
}

/// The saturation cap of PNG data read with value/256 (SPEC §5): 255/256 − 0.001.
pub const PNG_SATURATION: f32 = 255.0 / 256.0 - 0.001;

/// The sRGB electro-optical transfer function: encoded value in [0, 1] to linear.
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear value in [0, 1] to its sRGB encoding (inverse of [`srgb_to_linear`]).
pub fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.0031308 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

fn bad_png(path: &Path, err: impl std::fmt::Display) -> DataError {
    DataError::BadImage {
        path: path.to_path_buf(),
        format: "PNG",
        message: err.to_string(),
    }
}

fn open(path: &Path, what: &str) -> Result<DynamicImage, DataError> {
    if !path.is_file() {
        return Err(DataError::MissingFile {
            path: path.to_path_buf(),
            what: what.into(),
        });
    }
    let reader = image::ImageReader::open(path).map_err(|e| DataError::io(path, "opening", e))?;
    let reader = reader
        .with_guessed_format()
        .map_err(|e| DataError::io(path, "reading", e))?;
    reader.decode().map_err(|e| bad_png(path, e))
}

fn is_16_bit(img: &DynamicImage) -> bool {
    matches!(
        img,
        DynamicImage::ImageLuma16(_)
            | DynamicImage::ImageLumaA16(_)
            | DynamicImage::ImageRgb16(_)
            | DynamicImage::ImageRgba16(_)
    )
}

/// Reads an 8- or 16-bit PNG (grey, grey+alpha, RGB or RGBA; alpha is
/// ignored) as a linear RGB image.
pub fn read_png_rgb(path: &Path, decoding: PngDecoding) -> Result<RgbImage, DataError> {
    let img = open(path, "PNG image")?;
    let (width, height) = (img.width(), img.height());
    let data: Vec<f32> = if is_16_bit(&img) {
        let raw = img.to_rgb16().into_raw();
        match decoding {
            PngDecoding::Linear256 => raw.iter().map(|v| *v as f32 / 65536.0).collect(),
            PngDecoding::Srgb => raw
                .iter()
                .map(|v| srgb_to_linear(*v as f32 / 65535.0))
                .collect(),
        }
    } else {
        let raw = img.to_rgb8().into_raw();
        match decoding {
            PngDecoding::Linear256 => raw.iter().map(|v| *v as f32 / 256.0).collect(),
            PngDecoding::Srgb => {
                let table: Vec<f32> = (0..256).map(|v| srgb_to_linear(v as f32 / 255.0)).collect();
                raw.iter().map(|v| table[*v as usize]).collect()
            }
        }
    };
    Ok(RgbImage {
        width,
        height,
        data,
    })
}

/// Reads a mask PNG: a pixel is object where its value is > 127 (SPEC §5);
/// for colour masks the largest of R, G, B is compared (alpha is ignored).
pub fn read_mask_png(path: &Path) -> Result<Mask, DataError> {
    let img = open(path, "mask")?;
    let (width, height) = (img.width(), img.height());
    let rgb = img.to_rgb8();
    let data = rgb
        .pixels()
        .map(|p| p.0.iter().copied().max().unwrap_or(0) > 127)
        .collect();
    Ok(Mask {
        width,
        height,
        data,
    })
}

/// The size (width, height) of a PNG, read from its header only.
pub fn png_dimensions(path: &Path) -> Result<(u32, u32), DataError> {
    if !path.is_file() {
        return Err(DataError::MissingFile {
            path: path.to_path_buf(),
            what: "PNG image".into(),
        });
    }
    image::image_dimensions(path).map_err(|e| bad_png(path, e))
}

/// Writes a mask as an 8-bit grey PNG (255 = object, 0 = background), atomically.
pub fn write_mask_png(path: &Path, mask: &Mask) -> Result<(), DataError> {
    let pixels: Vec<u8> = mask.data.iter().map(|m| if *m { 255 } else { 0 }).collect();
    write_png_bytes(
        path,
        mask.width,
        mask.height,
        &pixels,
        image::ExtendedColorType::L8,
    )
}

/// Writes an 8-bit sRGB-encoded RGB PNG of a linear image (values clamped
/// to [0, 1]), atomically. For previews; datasets store linear EXR.
pub fn write_png_srgb(path: &Path, image: &RgbImage) -> Result<(), DataError> {
    let pixels: Vec<u8> = image
        .data
        .iter()
        .map(|v| (linear_to_srgb(v.clamp(0.0, 1.0)) * 255.0).round() as u8)
        .collect();
    write_png_bytes(
        path,
        image.width,
        image.height,
        &pixels,
        image::ExtendedColorType::Rgb8,
    )
}

fn write_png_bytes(
    path: &Path,
    width: u32,
    height: u32,
    pixels: &[u8],
    color: image::ExtendedColorType,
) -> Result<(), DataError> {
    let mut encoded = Vec::new();
    image::codecs::png::PngEncoder::new(&mut encoded)
        .write_image(pixels, width, height, color)
        .map_err(|e| DataError::WriteImage {
            path: path.to_path_buf(),
            format: "PNG",
            message: e.to_string(),
        })?;
    write_bytes_atomically(path, &encoded)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_curve_round_trip_and_known_values() {
        assert_eq!(srgb_to_linear(0.0), 0.0);
        assert!((srgb_to_linear(1.0) - 1.0).abs() < 1e-6);
        // sRGB 0.5 is linear 0.21404 (IEC 61966-2-1 curve).
        assert!((srgb_to_linear(0.5) - 0.214_041).abs() < 1e-5);
        for v in [0.001f32, 0.02, 0.3, 0.9] {
            assert!((linear_to_srgb(srgb_to_linear(v)) - v).abs() < 1e-5);
        }
    }

    #[test]
    fn mask_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("m.png");
        let mut m = Mask::new(7, 4);
        m.set(0, 0, true);
        m.set(6, 3, true);
        m.set(2, 1, true);
        write_mask_png(&path, &m).unwrap();
        assert_eq!(png_dimensions(&path).unwrap(), (7, 4));
        assert_eq!(read_mask_png(&path).unwrap(), m);
    }

    #[test]
    fn png_values_are_divided_by_256_or_srgb_decoded() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("i.png");
        let pixels = [0u8, 128, 255, 10, 20, 30];
        write_png_bytes(&path, 2, 1, &pixels, image::ExtendedColorType::Rgb8).unwrap();
        let lin = read_png_rgb(&path, PngDecoding::Linear256).unwrap();
        assert_eq!(
            lin.data,
            vec![
                0.0,
                0.5,
                255.0 / 256.0,
                10.0 / 256.0,
                20.0 / 256.0,
                30.0 / 256.0
            ]
        );
        let srgb = read_png_rgb(&path, PngDecoding::Srgb).unwrap();
        assert!((srgb.data[2] - 1.0).abs() < 1e-6);
        assert!((srgb.data[1] - srgb_to_linear(128.0 / 255.0)).abs() < 1e-7);
    }
}
