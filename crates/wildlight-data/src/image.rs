//! In-memory image types: linear RGB float images and binary masks.

use std::path::Path;

use crate::error::DataError;

/// A linear RGB image, row-major, channels interleaved (`data[3·(y·W + x) + c]`).
#[derive(Clone, Debug, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 · width · height` values.
    pub data: Vec<f32>,
}

impl RgbImage {
    /// A black image.
    pub fn new(width: u32, height: u32) -> RgbImage {
        RgbImage {
            width,
            height,
            data: vec![0.0; 3 * width as usize * height as usize],
        }
    }

    /// Wraps `data`; fails when its length is not `3 · width · height`.
    pub fn from_data(width: u32, height: u32, data: Vec<f32>) -> Result<RgbImage, DataError> {
        let expected = 3 * width as usize * height as usize;
        if data.len() != expected {
            return Err(DataError::InvalidArgument {
                what: format!("{width}x{height} RGB image"),
                problem: format!("{} values given, {expected} needed", data.len()),
            });
        }
        Ok(RgbImage {
            width,
            height,
            data,
        })
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The RGB value of pixel (x, y). Panics when out of range.
    pub fn get(&self, x: u32, y: u32) -> [f32; 3] {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }

    /// Sets the RGB value of pixel (x, y). Panics when out of range.
    pub fn set(&mut self, x: u32, y: u32, rgb: [f32; 3]) {
        let i = 3 * (y as usize * self.width as usize + x as usize);
        self.data[i..i + 3].copy_from_slice(&rgb);
    }

    /// The largest channel value (−∞ for an empty image).
    pub fn max_value(&self) -> f32 {
        self.data.iter().copied().fold(f32::NEG_INFINITY, f32::max)
    }

    /// Fails with [`DataError::NonFinitePixel`] naming `path` and the first
    /// pixel that is NaN or infinite.
    pub fn check_finite(&self, path: &Path) -> Result<(), DataError> {
        if let Some(i) = self.data.iter().position(|v| !v.is_finite()) {
            let p = i / 3;
            return Err(DataError::NonFinitePixel {
                path: path.to_path_buf(),
                x: (p % self.width as usize) as u32,
                y: (p / self.width as usize) as u32,
                channel: i % 3,
                value: self.data[i],
            });
        }
        Ok(())
    }
}

/// A binary object mask, row-major (`data[y·W + x]`), `true` = object.
#[derive(Clone, Debug, PartialEq)]
pub struct Mask {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width · height` flags.
    pub data: Vec<bool>,
}

impl Mask {
    /// An empty (all background) mask.
    pub fn new(width: u32, height: u32) -> Mask {
        Mask {
            width,
            height,
            data: vec![false; width as usize * height as usize],
        }
    }

    /// Whether pixel (x, y) is object. Panics when out of range.
    pub fn get(&self, x: u32, y: u32) -> bool {
        self.data[y as usize * self.width as usize + x as usize]
    }

    /// Sets pixel (x, y). Panics when out of range.
    pub fn set(&mut self, x: u32, y: u32, value: bool) {
        self.data[y as usize * self.width as usize + x as usize] = value;
    }

    /// Number of object pixels.
    pub fn count(&self) -> usize {
        self.data.iter().filter(|v| **v).count()
    }

    /// Fraction of object pixels (0 for an empty mask).
    pub fn coverage(&self) -> f64 {
        if self.data.is_empty() {
            0.0
        } else {
            self.count() as f64 / self.data.len() as f64
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixel_layout_is_row_major_interleaved() {
        let mut img = RgbImage::new(3, 2);
        img.set(2, 1, [1.0, 2.0, 3.0]);
        assert_eq!(&img.data[15..18], &[1.0, 2.0, 3.0]);
        assert_eq!(img.get(2, 1), [1.0, 2.0, 3.0]);
        assert_eq!(img.max_value(), 3.0);
        assert!(RgbImage::from_data(3, 2, vec![0.0; 17]).is_err());
    }

    #[test]
    fn non_finite_pixel_is_located() {
        let mut img = RgbImage::new(4, 3);
        img.data[3 * (2 * 4 + 1) + 2] = f32::NAN;
        let err = img
            .check_finite(Path::new("x/007.exr"))
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("x/007.exr") && err.contains("x=1, y=2") && err.contains("channel 2"),
            "{err}"
        );
    }

    #[test]
    fn mask_coverage() {
        let mut m = Mask::new(4, 2);
        m.set(1, 1, true);
        m.set(3, 0, true);
        assert!(m.get(1, 1) && !m.get(0, 0));
        assert_eq!(m.count(), 2);
        assert_eq!(m.coverage(), 0.25);
    }
}
