//! Undistortion and resizing in linear light: every pixel of the working
//! image (a PINHOLE camera, at most `--max-size` pixels on its longer side)
//! is traced through the photo's distorted camera and sampled bilinearly
//! from the linear photo (box-filtered first when shrinking by 2 or more).
//! A channel that any of its samples took from a saturated photo channel
//! stays saturated: it is set to at least the photo's clip level.
//!
//! COLMAP's pixel coordinates put the top-left pixel's centre at
//! (0.5, 0.5); SPEC §5 at (0, 0): `cx_spec = cx_colmap − 0.5`.

use glam::{DMat3, DVec2, DVec3};
use rayon::prelude::*;
use wildlight_data::RgbImage;

use crate::colmap::ColmapCamera;
use crate::linear::LinearImage;

/// A pinhole camera of the output images (COLMAP pixel coordinates).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Pinhole {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Focal length in x.
    pub fx: f64,
    /// Focal length in y.
    pub fy: f64,
    /// Principal point x (COLMAP coordinates).
    pub cx: f64,
    /// Principal point y (COLMAP coordinates).
    pub cy: f64,
}

impl Pinhole {
    /// The pinhole of a PINHOLE or SIMPLE_PINHOLE camera.
    pub fn of(cam: &ColmapCamera) -> Option<Pinhole> {
        if !cam.is_pinhole() {
            return None;
        }
        let (fx, fy) = cam.focal();
        let (cx, cy) = cam.principal_point();
        Some(Pinhole {
            width: cam.width,
            height: cam.height,
            fx,
            fy,
            cx,
            cy,
        })
    }

    /// The same view at most `max_size` pixels on the longer side (never
    /// enlarged); K scales with the size (exact in COLMAP coordinates).
    pub fn resized(&self, max_size: u32) -> Pinhole {
        let long = self.width.max(self.height);
        if long <= max_size {
            return *self;
        }
        let s = max_size as f64 / long as f64;
        let width = ((self.width as f64 * s).round() as u32).max(1);
        let height = ((self.height as f64 * s).round() as u32).max(1);
        let (sx, sy) = (
            width as f64 / self.width as f64,
            height as f64 / self.height as f64,
        );
        Pinhole {
            width,
            height,
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: self.cx * sx,
            cy: self.cy * sy,
        }
    }

    /// K in SPEC §5's convention (pixel centres at integer coordinates).
    pub fn k_spec(&self) -> DMat3 {
        DMat3::from_cols(
            DVec3::new(self.fx, 0.0, 0.0),
            DVec3::new(0.0, self.fy, 0.0),
            DVec3::new(self.cx - 0.5, self.cy - 0.5, 1.0),
        )
    }

    /// A pinhole without blank borders for a distorted camera, at the
    /// camera's size: the image borders are undistorted and the largest
    /// axis-aligned rectangle inside them fills the output (what COLMAP's
    /// `image_undistorter` does with `blank_pixels 0`). `None` for models
    /// the import cannot invert.
    pub fn undistorted(cam: &ColmapCamera) -> Option<Pinhole> {
        let (w, h) = (cam.width as f64, cam.height as f64);
        let steps = 64;
        let (mut left, mut right) = (f64::NEG_INFINITY, f64::INFINITY);
        let (mut top, mut bottom) = (f64::NEG_INFINITY, f64::INFINITY);
        for i in 0..=steps {
            let t = i as f64 / steps as f64;
            left = left.max(cam.unproject(DVec2::new(0.0, t * h))?.x);
            right = right.min(cam.unproject(DVec2::new(w, t * h))?.x);
            top = top.max(cam.unproject(DVec2::new(t * w, 0.0))?.y);
            bottom = bottom.min(cam.unproject(DVec2::new(t * w, h))?.y);
        }
        if !(right > left && bottom > top) {
            return None;
        }
        let fx = w / (right - left);
        let fy = h / (bottom - top);
        Some(Pinhole {
            width: cam.width,
            height: cam.height,
            fx,
            fy,
            cx: -left * fx,
            cy: -top * fy,
        })
    }
}

/// Averages `n`×`n` blocks (n ≥ 2); the camera coordinates u map to u / n.
fn box_shrink(src: &LinearImage, n: u32) -> LinearImage {
    let (w, h) = (src.width / n, src.height / n);
    let sw = src.width as usize;
    let has_sat = !src.saturated.is_empty();
    let rows: Vec<(Vec<f32>, Vec<u8>)> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut data = Vec::with_capacity(3 * w as usize);
            let mut sat = Vec::with_capacity(if has_sat { w as usize } else { 0 });
            for x in 0..w {
                let mut acc = [0.0f32; 3];
                let mut bits = 0u8;
                for dy in 0..n {
                    for dx in 0..n {
                        let p = (y * n + dy) as usize * sw + (x * n + dx) as usize;
                        for (c, a) in acc.iter_mut().enumerate() {
                            *a += src.data[3 * p + c];
                        }
                        if has_sat {
                            bits |= src.saturated[p];
                        }
                    }
                }
                let k = 1.0 / (n * n) as f32;
                data.extend(acc.map(|a| a * k));
                if has_sat {
                    sat.push(bits);
                }
            }
            (data, sat)
        })
        .collect();
    let mut out = LinearImage {
        width: w,
        height: h,
        data: Vec::with_capacity(3 * (w * h) as usize),
        saturated: Vec::new(),
    };
    for (d, s) in rows {
        out.data.extend(d);
        out.saturated.extend(s);
    }
    out
}

/// The working image: `src` (the photo in linear light, seen by the
/// distorted camera `cam`) resampled into the pinhole `target`. Channels
/// that took a saturated sample are raised to `clip`. Returns the image
/// and the per-pixel saturated bits (empty when `src` has none).
pub fn resample(
    src: &LinearImage,
    cam: &ColmapCamera,
    target: &Pinhole,
    clip: f32,
) -> (RgbImage, Vec<u8>) {
    let (fsrc, _) = cam.focal();
    let shrink = (fsrc / target.fx.max(1e-9)).floor() as u32;
    let shrunk;
    let (img, n) = if shrink >= 2 {
        shrunk = box_shrink(src, shrink);
        (&shrunk, shrink as f64)
    } else {
        (src, 1.0)
    };
    let (sw, sh) = (img.width as i64, img.height as i64);
    let has_sat = !img.saturated.is_empty();
    let rows: Vec<(Vec<f32>, Vec<u8>)> = (0..target.height)
        .into_par_iter()
        .map(|y| {
            let mut data = Vec::with_capacity(3 * target.width as usize);
            let mut sat = Vec::new();
            for x in 0..target.width {
                let uv = DVec2::new(
                    (x as f64 + 0.5 - target.cx) / target.fx,
                    (y as f64 + 0.5 - target.cy) / target.fy,
                );
                let p = cam
                    .project(uv.extend(1.0))
                    .unwrap_or(DVec2::splat(f64::NAN));
                // integer-centred source coordinates
                let sx = (p.x / n - 0.5).clamp(0.0, (sw - 1) as f64);
                let sy = (p.y / n - 0.5).clamp(0.0, (sh - 1) as f64);
                let (sx, sy) = if sx.is_finite() && sy.is_finite() {
                    (sx, sy)
                } else {
                    (0.0, 0.0)
                };
                let (x0, y0) = (sx.floor() as i64, sy.floor() as i64);
                let (tx, ty) = ((sx - x0 as f64) as f32, (sy - y0 as f64) as f32);
                let (x1, y1) = ((x0 + 1).min(sw - 1), (y0 + 1).min(sh - 1));
                let taps = [
                    (x0, y0, (1.0 - tx) * (1.0 - ty)),
                    (x1, y0, tx * (1.0 - ty)),
                    (x0, y1, (1.0 - tx) * ty),
                    (x1, y1, tx * ty),
                ];
                let mut acc = [0.0f32; 3];
                let mut bits = 0u8;
                for (tx_, ty_, wgt) in taps {
                    if wgt <= 0.0 {
                        continue;
                    }
                    let i = (ty_ * sw + tx_) as usize;
                    for (c, a) in acc.iter_mut().enumerate() {
                        *a += wgt * img.data[3 * i + c];
                    }
                    if has_sat {
                        bits |= img.saturated[i];
                    }
                }
                for (c, a) in acc.iter_mut().enumerate() {
                    if bits & (1 << c) != 0 {
                        *a = a.max(clip);
                    }
                }
                data.extend(acc);
                if has_sat {
                    sat.push(bits);
                }
            }
            (data, sat)
        })
        .collect();
    let mut out = RgbImage::new(target.width, target.height);
    out.data.clear();
    let mut saturated = Vec::new();
    for (d, s) in rows {
        out.data.extend(d);
        saturated.extend(s);
    }
    (out, saturated)
}
