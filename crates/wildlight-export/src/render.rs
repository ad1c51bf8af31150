//! Ray tracing the flash term of SPEC §2 — of an exported asset (textures
//! sampled bilinearly at the hit's UV, normal-mapped normal) and of a
//! [`FieldSource`] (sphere tracing of its SDF) — with a dataset's cameras.
//! Comparing the two measures an export's round trip.
//!
//! Only the flash term is rendered; lighting an asset with an environment
//! map is not implemented here.

use glam::{DVec3, Mat3, Mat4, Vec2, Vec3};
use parry3d::query::Ray;
use parry3d::shape::CompositeShapeRef;
use rayon::prelude::*;
use wildlight_data::{Camera, RgbImage};
use wildlight_material::{BrdfSettings, PARAM_COUNT, brdf};

use crate::ExportError;
use crate::bake::{NORMAL, from_tangent_space};
use crate::gltf::Asset;
use crate::source::{FieldSource, MAX_BATCH, bounded_sdf};

/// Settings of the flash term.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlashSettings {
    /// BRDF settings (clearcoat Fresnel).
    pub brdf: BrdfSettings,
    /// The flash gain γ of SPEC §2 (default 1).
    pub gain: f32,
}

impl Default for FlashSettings {
    fn default() -> Self {
        FlashSettings {
            brdf: BrdfSettings::default(),
            gain: 1.0,
        }
    }
}

/// A rendered flash image and which pixels hit the surface.
#[derive(Clone, Debug, PartialEq)]
pub struct FlashImage {
    /// Linear RGB flash radiance (zero where nothing is hit).
    pub image: RgbImage,
    /// Per pixel (row-major): whether the ray hit the surface.
    pub hit: Vec<bool>,
}

/// The flash radiance of SPEC §2 at a surface point with unit normal `n`
/// (normalized frame), seen from a camera at distance `dist` in direction
/// `h` (unit, towards the camera):
/// f = γ · E ⊙ ρ(n·h; Θ) · max(0, n·h) / dist².
pub fn flash_radiance(
    params: &[f32; PARAM_COUNT],
    n: Vec3,
    h: Vec3,
    dist: f32,
    energy: [f64; 3],
    settings: &FlashSettings,
) -> [f32; 3] {
    let c = n.dot(h);
    if c <= 0.0 {
        return [0.0; 3];
    }
    let rho = brdf::eval(params, c, &settings.brdf);
    let k = settings.gain * c / (dist * dist);
    [0, 1, 2].map(|i| energy[i] as f32 * rho[i] * k)
}

/// An exported asset prepared for ray casting (a parry3d BVH).
pub struct AssetTracer<'a> {
    asset: &'a Asset,
    shape: parry3d::shape::TriMesh,
    from_normalized: Mat4,
}

impl<'a> AssetTracer<'a> {
    /// Builds the BVH. `asset_to_normalized` maps the asset's frame to the
    /// normalized frame (the inverse of scale_mat for a world-unit export).
    pub fn new(asset: &'a Asset, asset_to_normalized: Mat4) -> Result<Self, ExportError> {
        let positions: Vec<parry3d::math::Vector> = asset
            .mesh
            .positions
            .iter()
            .map(|p| parry3d::math::Vector::new(p.x, p.y, p.z))
            .collect();
        let shape = parry3d::shape::TriMesh::new(positions, asset.mesh.triangles.clone())
            .map_err(|e| ExportError::stage("ray tracing", format!("cannot build the BVH: {e}")))?;
        Ok(AssetTracer {
            asset,
            shape,
            from_normalized: asset_to_normalized.inverse(),
        })
    }

    /// Renders the flash term of the view of `camera` (its rays, flash
    /// energy and pixel grid).
    pub fn render_flash(&self, camera: &Camera, settings: &FlashSettings) -> FlashImage {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let normal_to_normalized = Mat3::from_mat4(self.from_normalized).transpose();
        let mesh = &self.asset.mesh;
        let pixels: Vec<Option<[f32; 3]>> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let ray = camera.ray((i % w) as f64, (i / w) as f64);
                let (_, far) = ray.near_far_unit_sphere()?;
                let o = self.from_normalized.transform_point3(ray.origin.as_vec3());
                let d = self.from_normalized.transform_vector3(ray.dir.as_vec3());
                // With the direction mapped (not re-normalized), the hit
                // parameter is the normalized-frame distance along the ray.
                let pray = Ray::new(
                    parry3d::math::Vector::new(o.x, o.y, o.z),
                    parry3d::math::Vector::new(d.x, d.y, d.z),
                );
                let (tri, hit) = CompositeShapeRef(&self.shape).cast_local_ray_and_get_normal(
                    &pray,
                    (far * 1.5 + 1.0) as f32,
                    true,
                )?;
                let t = hit.time_of_impact;
                let p = o + d * t;
                let [ia, ib, ic] = mesh.triangles[tri as usize].map(|v| v as usize);
                let bary = barycentric(
                    p,
                    mesh.positions[ia],
                    mesh.positions[ib],
                    mesh.positions[ic],
                );
                let uv: Vec2 =
                    mesh.uvs[ia] * bary.x + mesh.uvs[ib] * bary.y + mesh.uvs[ic] * bary.z;
                let n = mesh.normals[ia] * bary.x
                    + mesh.normals[ib] * bary.y
                    + mesh.normals[ic] * bary.z;
                let tan = mesh.tangents[ia] * bary.x
                    + mesh.tangents[ib] * bary.y
                    + mesh.tangents[ic] * bary.z;
                let texel = self.asset.textures.sample(uv);
                let local = Vec3::new(texel[NORMAL], texel[NORMAL + 1], texel[NORMAL + 2]);
                let n_asset = from_tangent_space(local, n, tan.truncate(), tan.w);
                let n_norm = (normal_to_normalized * n_asset).normalize_or_zero();
                let mut params = [0.0f32; PARAM_COUNT];
                params.copy_from_slice(&texel[..PARAM_COUNT]);
                Some(flash_radiance(
                    &params,
                    n_norm,
                    -ray.dir.as_vec3(),
                    t,
                    camera.light_energy,
                    settings,
                ))
            })
            .collect();
        to_flash_image(camera, pixels)
    }
}

/// Barycentric coordinates of `p` (on or near the triangle's plane).
fn barycentric(p: Vec3, a: Vec3, b: Vec3, c: Vec3) -> Vec3 {
    let (v0, v1, v2) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (v0.dot(v0), v0.dot(v1), v1.dot(v1));
    let (d20, d21) = (v2.dot(v0), v2.dot(v1));
    let denom = d00 * d11 - d01 * d01;
    if denom.abs() < 1e-20 {
        return Vec3::new(1.0, 0.0, 0.0);
    }
    let v = (d11 * d20 - d01 * d21) / denom;
    let w = (d00 * d21 - d01 * d20) / denom;
    Vec3::new(1.0 - v - w, v, w)
}

fn to_flash_image(camera: &Camera, pixels: Vec<Option<[f32; 3]>>) -> FlashImage {
    let mut image = RgbImage::new(camera.width, camera.height);
    let mut hit = vec![false; pixels.len()];
    for (i, px) in pixels.into_iter().enumerate() {
        if let Some(rgb) = px {
            image.set(i as u32 % camera.width, i as u32 / camera.width, rgb);
            hit[i] = true;
        }
    }
    FlashImage { image, hit }
}

/// Renders the flash term of `source` itself: sphere tracing of its SDF
/// (restricted to the unit sphere) to |φ| < 1e-5, normal = normalized
/// gradient, material at the hit.
pub fn render_source_flash<S: FieldSource + ?Sized>(
    source: &S,
    camera: &Camera,
    settings: &FlashSettings,
) -> FlashImage {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let indices: Vec<usize> = (0..w * h).collect();
    let pixels: Vec<Option<[f32; 3]>> = indices
        .par_chunks(MAX_BATCH)
        .flat_map_iter(|chunk| {
            let rays: Vec<_> = chunk
                .iter()
                .map(|&i| camera.ray((i % w) as f64, (i / w) as f64))
                .collect();
            let mut t: Vec<f64> = Vec::with_capacity(rays.len());
            let mut far: Vec<f64> = Vec::with_capacity(rays.len());
            let mut state: Vec<u8> = Vec::with_capacity(rays.len()); // 0 marching, 1 hit, 2 miss
            for r in &rays {
                match r.near_far_unit_sphere() {
                    Some((n, f)) => {
                        t.push(n);
                        far.push(f);
                        state.push(0);
                    }
                    None => {
                        t.push(0.0);
                        far.push(0.0);
                        state.push(2);
                    }
                }
            }
            for _ in 0..1000 {
                let active: Vec<usize> = (0..rays.len()).filter(|&k| state[k] == 0).collect();
                if active.is_empty() {
                    break;
                }
                let pts: Vec<[f32; 3]> = active
                    .iter()
                    .map(|&k| rays[k].at(t[k]).as_vec3().to_array())
                    .collect();
                let mut phi = vec![0.0f32; pts.len()];
                source.sdf(&pts, &mut phi);
                for ((&k, f), p) in active.iter().zip(&phi).zip(&pts) {
                    let f = bounded_sdf(*f, *p) as f64;
                    if f.abs() < 1e-5 {
                        state[k] = 1;
                    } else {
                        t[k] += f * 0.9;
                        if t[k] > far[k] {
                            state[k] = 2;
                        }
                    }
                }
            }
            let hits: Vec<usize> = (0..rays.len()).filter(|&k| state[k] == 1).collect();
            let pts: Vec<[f32; 3]> = hits
                .iter()
                .map(|&k| rays[k].at(t[k]).as_vec3().to_array())
                .collect();
            let mut grad = vec![[0.0f32; 3]; pts.len()];
            let mut mat = vec![[0.0f32; PARAM_COUNT]; pts.len()];
            source.gradient(&pts, &mut grad);
            source.material(&pts, &mut mat);
            let mut out: Vec<Option<[f32; 3]>> = vec![None; rays.len()];
            for (j, &k) in hits.iter().enumerate() {
                let n = Vec3::from_array(grad[j]).normalize_or_zero();
                let dir: DVec3 = rays[k].dir;
                out[k] = Some(flash_radiance(
                    &mat[j],
                    n,
                    -dir.as_vec3(),
                    t[k] as f32,
                    camera.light_energy,
                    settings,
                ));
            }
            out
        })
        .collect();
    to_flash_image(camera, pixels)
}

/// PSNR in dB of `test` against `reference` over the pixels where either
/// hit the surface, with the peak the largest reference value there:
/// 10·log10(peak² / MSE). `None` when no pixel counts or the peak is zero.
pub fn flash_psnr(test: &FlashImage, reference: &FlashImage) -> Option<f64> {
    let mut peak = 0.0f64;
    let mut sum = 0.0f64;
    let mut count = 0usize;
    for (i, (a, b)) in test.hit.iter().zip(&reference.hit).enumerate() {
        if !(*a || *b) {
            continue;
        }
        for c in 0..3 {
            let x = test.image.data[i * 3 + c] as f64;
            let y = reference.image.data[i * 3 + c] as f64;
            peak = peak.max(y);
            sum += (x - y) * (x - y);
            count += 1;
        }
    }
    if count == 0 || peak <= 0.0 {
        return None;
    }
    let mse = sum / count as f64;
    Some(if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (peak * peak / mse).log10()
    })
}
