//! The environment light: an equirectangular radiance map with importance
//! sampling proportional to luminance × solid angle.
//!
//! Directions are in the world (= normalized frame) axes with +y up. The
//! pixel column grows with the azimuth φ = atan2(x, −z) (φ = 0 at the
//! image centre, looking along −z) and the row with the polar angle
//! θ = acos(y) (row 0 is the zenith):
//! d = (sin θ sin φ, cos θ, −sin θ cos φ). Radiance is piecewise constant
//! per pixel, so lookups and sampling densities agree exactly.

use std::f64::consts::PI;
use std::path::Path;

use glam::DVec3;

use crate::error::EnvMapError;

/// An equirectangular environment map ready for sampling.
#[derive(Clone, Debug)]
pub struct EnvMap {
    width: usize,
    height: usize,
    /// Linear RGB radiance, row-major.
    texels: Vec<[f32; 3]>,
    /// Cumulative row probabilities (length height + 1).
    row_cdf: Vec<f64>,
    /// Per row, cumulative column probabilities (height × (width + 1)).
    col_cdf: Vec<f64>,
    /// Probability of each pixel.
    pixel_pdf: Vec<f64>,
}

fn luminance(c: [f32; 3]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

/// Smallest |sin θ| used in densities (the poles have zero solid angle).
const MIN_SIN: f64 = 1e-6;

impl EnvMap {
    /// Wraps linear RGB texels (row-major, `width × height`), all finite
    /// and non-negative, and builds the sampling tables.
    pub fn from_texels(
        width: usize,
        height: usize,
        texels: Vec<[f32; 3]>,
    ) -> Result<EnvMap, String> {
        if width < 2 || height < 2 || texels.len() != width * height {
            return Err(format!(
                "need at least 2x2 texels, got {width}x{height} with {} values",
                texels.len()
            ));
        }
        if let Some(i) = texels
            .iter()
            .position(|t| t.iter().any(|v| !v.is_finite() || *v < 0.0))
        {
            return Err(format!(
                "texel ({}, {}) is negative or not finite: {:?}",
                i % width,
                i / width,
                texels[i]
            ));
        }
        let mut weights = vec![0.0f64; width * height];
        for r in 0..height {
            let sin = (PI * (r as f64 + 0.5) / height as f64).sin();
            for c in 0..width {
                weights[r * width + c] = luminance(texels[r * width + c]) * sin;
            }
        }
        let total: f64 = weights.iter().sum();
        if !(total > 0.0) {
            return Err("the map is black everywhere".into());
        }
        let mut row_cdf = vec![0.0; height + 1];
        let mut col_cdf = vec![0.0; height * (width + 1)];
        for r in 0..height {
            let row = &weights[r * width..(r + 1) * width];
            let row_sum: f64 = row.iter().sum();
            row_cdf[r + 1] = row_cdf[r] + row_sum / total;
            let cdf = &mut col_cdf[r * (width + 1)..(r + 1) * (width + 1)];
            for c in 0..width {
                cdf[c + 1] = cdf[c]
                    + if row_sum > 0.0 {
                        row[c] / row_sum
                    } else {
                        1.0 / width as f64
                    };
            }
            cdf[width] = 1.0;
        }
        row_cdf[height] = 1.0;
        let pixel_pdf = weights.iter().map(|w| w / total).collect();
        Ok(EnvMap {
            width,
            height,
            texels,
            row_cdf,
            col_cdf,
            pixel_pdf,
        })
    }

    /// Reads an equirectangular `.exr` or `.hdr` file (by extension).
    pub fn load(path: &Path) -> Result<EnvMap, EnvMapError> {
        let err = |problem: String| EnvMapError {
            path: path.to_path_buf(),
            problem,
        };
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .map(|e| e.to_ascii_lowercase());
        let (w, h, texels) = match ext.as_deref() {
            Some("exr") => {
                let img = exr::prelude::read_first_rgba_layer_from_file(
                    path,
                    |res, _| (res.width(), vec![[0.0f32; 3]; res.width() * res.height()]),
                    |(w, px): &mut (usize, Vec<[f32; 3]>),
                     pos,
                     (r, g, b, _a): (f32, f32, f32, f32)| {
                        px[pos.y() * *w + pos.x()] = [r, g, b];
                    },
                )
                .map_err(|e| err(e.to_string()))?;
                let size = img.layer_data.size;
                (
                    size.width(),
                    size.height(),
                    img.layer_data.channel_data.pixels.1,
                )
            }
            Some("hdr") => {
                let img = image::ImageReader::open(path)
                    .map_err(|e| err(e.to_string()))?
                    .decode()
                    .map_err(|e| err(e.to_string()))?
                    .into_rgb32f();
                let (w, h) = (img.width() as usize, img.height() as usize);
                let texels = img.pixels().map(|p| [p.0[0], p.0[1], p.0[2]]).collect();
                (w, h, texels)
            }
            _ => return Err(err("unknown extension (expected .exr or .hdr)".into())),
        };
        let texels = texels
            .into_iter()
            .map(|t: [f32; 3]| t.map(|v| if v.is_finite() { v.max(0.0) } else { 0.0 }))
            .collect();
        EnvMap::from_texels(w, h, texels).map_err(err)
    }

    /// The default light: a blue sky brightening towards the horizon, a
    /// dim brown ground and a sun of angular radius 2.5° at 45° elevation.
    /// The sun gives about as much irradiance as the sky.
    pub fn procedural_sky() -> EnvMap {
        let (w, h) = (1024usize, 512usize);
        let sun_dir = direction_from_angles(45f64.to_radians(), 40f64.to_radians());
        let sun_cos = 2.5f64.to_radians().cos();
        let zenith = DVec3::new(0.22, 0.38, 0.8);
        let horizon = DVec3::new(0.85, 0.88, 0.95);
        let ground = DVec3::new(0.2, 0.17, 0.14);
        let sun = DVec3::new(1.0, 0.93, 0.82) * 420.0;
        let mut texels = vec![[0.0f32; 3]; w * h];
        const SUB: usize = 4;
        for r in 0..h {
            for c in 0..w {
                let mut acc = DVec3::ZERO;
                for s in 0..SUB * SUB {
                    let u = (c as f64 + ((s % SUB) as f64 + 0.5) / SUB as f64) / w as f64;
                    let v = (r as f64 + ((s / SUB) as f64 + 0.5) / SUB as f64) / h as f64;
                    let d = direction_from_uv(u, v);
                    let sky = if d.y >= 0.0 {
                        let t = (1.0 - d.y).powi(3);
                        zenith.lerp(horizon, t)
                    } else {
                        ground.lerp(horizon * 0.5, (1.0 + d.y).powi(12))
                    };
                    let cos_sun = d.dot(sun_dir);
                    let glow = 0.8 * (-(1.0 - cos_sun) / 0.02).exp();
                    let disk = if cos_sun >= sun_cos { sun } else { DVec3::ZERO };
                    acc += sky + glow * DVec3::new(1.0, 0.9, 0.7) + disk;
                }
                // overall level: a mid-grey diffuse surface facing up reads about 0.3
                let a = 0.6 * acc / (SUB * SUB) as f64;
                texels[r * w + c] = [a.x as f32, a.y as f32, a.z as f32];
            }
        }
        EnvMap::from_texels(w, h, texels).expect("the procedural sky is valid")
    }

    /// Multiplies every texel by `factor` (> 0).
    pub fn scaled(mut self, factor: f64) -> EnvMap {
        for t in &mut self.texels {
            for v in t.iter_mut() {
                *v = (*v as f64 * factor) as f32;
            }
        }
        self
    }

    /// Width and height in texels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    fn texel_index(&self, d: DVec3) -> usize {
        let (u, v) = uv_from_direction(d);
        let c = ((u * self.width as f64) as usize).min(self.width - 1);
        let r = ((v * self.height as f64) as usize).min(self.height - 1);
        r * self.width + c
    }

    /// Radiance arriving from direction `d` (unit).
    pub fn radiance(&self, d: DVec3) -> DVec3 {
        let t = self.texels[self.texel_index(d)];
        DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64)
    }

    /// Solid-angle density with which [`EnvMap::sample`] picks `d`.
    pub fn pdf(&self, d: DVec3) -> f64 {
        let sin = (1.0 - d.y * d.y).max(0.0).sqrt().max(MIN_SIN);
        self.pixel_pdf[self.texel_index(d)] * (self.width * self.height) as f64
            / (2.0 * PI * PI * sin)
    }

    /// Draws a direction with density ∝ luminance (per solid angle) from
    /// two uniform numbers in [0, 1); returns the direction and its density.
    pub fn sample(&self, u1: f64, u2: f64) -> (DVec3, f64) {
        let (r, fr) = sample_cdf(&self.row_cdf, u1);
        let cdf = &self.col_cdf[r * (self.width + 1)..(r + 1) * (self.width + 1)];
        let (c, fc) = sample_cdf(cdf, u2);
        let u = (c as f64 + fc) / self.width as f64;
        let v = (r as f64 + fr) / self.height as f64;
        let d = direction_from_uv(u, v);
        (d, self.pdf(d))
    }

    /// The mean radiance weighted by solid angle (for tests and reports).
    pub fn mean_radiance(&self) -> DVec3 {
        let mut acc = DVec3::ZERO;
        let mut wsum = 0.0;
        for r in 0..self.height {
            let sin = (PI * (r as f64 + 0.5) / self.height as f64).sin();
            for c in 0..self.width {
                let t = self.texels[r * self.width + c];
                acc += DVec3::new(t[0] as f64, t[1] as f64, t[2] as f64) * sin;
                wsum += sin;
            }
        }
        acc / wsum
    }
}

/// Picks the bin of `u` in a cumulative table and the position inside it.
fn sample_cdf(cdf: &[f64], u: f64) -> (usize, f64) {
    let n = cdf.len() - 1;
    let i = cdf.partition_point(|&c| c <= u).clamp(1, n) - 1;
    let width = cdf[i + 1] - cdf[i];
    let f = if width > 0.0 {
        ((u - cdf[i]) / width).clamp(0.0, 1.0 - 1e-12)
    } else {
        0.5
    };
    (i, f)
}

/// Direction of the map coordinates (u, v) ∈ [0, 1]².
pub fn direction_from_uv(u: f64, v: f64) -> DVec3 {
    let phi = (u - 0.5) * 2.0 * PI;
    let theta = v * PI;
    DVec3::new(
        theta.sin() * phi.sin(),
        theta.cos(),
        -theta.sin() * phi.cos(),
    )
}

/// Map coordinates (u, v) ∈ [0, 1]² of a unit direction.
pub fn uv_from_direction(d: DVec3) -> (f64, f64) {
    let u = 0.5 + d.x.atan2(-d.z) / (2.0 * PI);
    let v = d.y.clamp(-1.0, 1.0).acos() / PI;
    (u.clamp(0.0, 1.0), v)
}

/// Unit direction at `elevation` above the horizon and azimuth φ (as in the map).
pub fn direction_from_angles(elevation: f64, azimuth: f64) -> DVec3 {
    let theta = 0.5 * PI - elevation;
    DVec3::new(
        theta.sin() * azimuth.sin(),
        theta.cos(),
        -theta.sin() * azimuth.cos(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn uv_round_trip() {
        for (u, v) in [(0.1, 0.2), (0.5, 0.5), (0.93, 0.77), (0.3, 0.99)] {
            let (u2, v2) = uv_from_direction(direction_from_uv(u, v));
            assert!((u - u2).abs() < 1e-12 && (v - v2).abs() < 1e-12);
        }
    }

    /// The density integrates to one over the sphere, and the sampler draws
    /// with that density: E[L/pdf] over samples equals ∫ L dω.
    #[test]
    fn sampling_density_is_consistent() {
        let mut texels = vec![[0.0f32; 3]; 32 * 16];
        for (i, t) in texels.iter_mut().enumerate() {
            let v = 0.1 + ((i * 37) % 11) as f32;
            *t = [v, 0.5 * v, 1.0];
        }
        let env = EnvMap::from_texels(32, 16, texels).unwrap();
        // ∫ pdf dω by a fine (u, v) quadrature: dω = 2π² sin θ du dv
        let n = 400;
        let mut total = 0.0;
        let mut integral = DVec3::ZERO;
        for i in 0..n {
            for j in 0..n {
                let u = (i as f64 + 0.5) / n as f64;
                let v = (j as f64 + 0.5) / n as f64;
                let d = direction_from_uv(u, v);
                let dw = 2.0 * PI * PI * (v * PI).sin() / (n * n) as f64;
                total += env.pdf(d) * dw;
                integral += env.radiance(d) * dw;
            }
        }
        assert!((total - 1.0).abs() < 2e-3, "∫pdf = {total}");
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        let m = 200_000;
        let mut est = DVec3::ZERO;
        for _ in 0..m {
            let (d, pdf) = env.sample(rng.random(), rng.random());
            assert!((pdf - env.pdf(d)).abs() <= 1e-9 * pdf);
            est += env.radiance(d) / pdf;
        }
        est /= m as f64;
        assert!(
            (est.x - integral.x).abs() < 0.01 * integral.x,
            "{est} vs {integral}"
        );
        assert!((est.y - integral.y).abs() < 0.01 * integral.y);
    }

    #[test]
    fn sky_is_bright_above_and_has_a_sun() {
        let sky = EnvMap::procedural_sky();
        let up = sky.radiance(DVec3::Y);
        let down = sky.radiance(-DVec3::Y);
        assert!(up.z > up.x && up.z > down.z);
        let sun = sky.radiance(direction_from_angles(
            45f64.to_radians(),
            40f64.to_radians(),
        ));
        assert!(sun.x > 100.0, "{sun}");
    }

    #[test]
    fn bad_texels_are_reported() {
        assert!(
            EnvMap::from_texels(2, 2, vec![[0.0; 3]; 4])
                .unwrap_err()
                .contains("black")
        );
        assert!(
            EnvMap::from_texels(2, 2, vec![[f32::NAN, 0.0, 0.0]; 4])
                .unwrap_err()
                .contains("(0, 0)")
        );
    }
}
