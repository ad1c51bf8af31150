//! Rendering an exported asset with a capture's cameras — its flash term
//! (SPEC §2) and, optionally, an environment light estimated like the
//! synthetic captures' ([`wildlight_pathtrace::ambient_radiance`]) — with the
//! textures sampled bilinearly at each hit's UV and the normal map applied;
//! and ray tracing the flash term of a [`FieldSource`] (sphere tracing of
//! its SDF). Comparing the two flash terms measures an export's round trip.

use glam::{DVec3, Mat3, Mat4, Vec2, Vec3};
use rayon::prelude::*;
use wildlight_data::{Camera, RgbImage, ViewMaps};
use wildlight_material::{BrdfSettings, PARAM_COUNT, brdf};
use wildlight_pathtrace::{
    AmbientSettings, EnvMap, Scene, SurfacePoint, ambient_radiance, pixel_rng,
};

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

/// Where a camera ray meets an exported asset, with what its textures say
/// there (everything in the normalized frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AssetHit {
    /// The surface point: ray parameter (normalized units, unit direction),
    /// position, normal-mapped shading normal and face normal, both facing
    /// the ray's origin.
    pub surface: SurfacePoint,
    /// The 9 material parameters sampled from the textures.
    pub params: [f32; PARAM_COUNT],
}

/// How an asset is lit by [`AssetTracer::render_view`].
#[derive(Clone, Debug)]
pub struct LightingSettings {
    /// The flash term's settings (BRDF settings and gain γ).
    pub flash: FlashSettings,
    /// The environment light, radiance already scaled (None: no ambient
    /// light; the ambient map is zero).
    pub env: Option<EnvMap>,
    /// Environment samples per pixel.
    pub spp: usize,
    /// Seed of the environment samples (with the view and pixel index).
    pub seed: u64,
}

impl Default for LightingSettings {
    fn default() -> Self {
        LightingSettings {
            flash: FlashSettings::default(),
            env: None,
            spp: 64,
            seed: 0,
        }
    }
}

/// An exported asset prepared for ray casting in the normalized frame.
pub struct AssetTracer<'a> {
    asset: &'a Asset,
    /// The asset's mesh in the normalized frame: its BVH for camera rays
    /// (the attributes come from the asset) and shadow rays.
    scene: Scene,
    to_normalized: Mat4,
}

impl<'a> AssetTracer<'a> {
    /// Builds the ray-casting structures. `asset_to_normalized` maps the
    /// asset's frame to the normalized frame (the inverse of scale_mat for
    /// a world-unit export).
    pub fn new(asset: &'a Asset, asset_to_normalized: Mat4) -> Result<Self, ExportError> {
        let mesh = &asset.mesh;
        if mesh.triangles.is_empty() {
            return Err(ExportError::stage(
                "ray tracing",
                "the asset has no triangles",
            ));
        }
        let n = mesh.positions.len();
        if mesh.normals.len() != n || mesh.tangents.len() != n || mesh.uvs.len() != n {
            return Err(ExportError::stage(
                "ray tracing",
                "the asset's normals, tangents and UVs do not match its vertices",
            ));
        }
        if let Some(t) = mesh
            .triangles
            .iter()
            .find(|t| t.iter().any(|&v| v as usize >= n))
        {
            return Err(ExportError::stage(
                "ray tracing",
                format!("triangle {t:?} refers to a vertex beyond the {n} vertices"),
            ));
        }
        let normalized = wildlight_mesh::TriMesh::new(
            mesh.positions
                .iter()
                .map(|p| asset_to_normalized.transform_point3(*p))
                .collect(),
            mesh.triangles.clone(),
        );
        Ok(AssetTracer {
            asset,
            scene: Scene::new(&normalized),
            to_normalized: asset_to_normalized,
        })
    }

    /// The first hit of the ray from `origin` along unit `dir` (normalized
    /// frame), with the textures sampled there.
    pub fn trace(&self, origin: DVec3, dir: DVec3) -> Option<AssetHit> {
        let bvh = self.scene.bvh();
        let hit = bvh.intersect(origin, dir, 0.0, f64::INFINITY)?;
        let hit = bvh.refine(origin, dir, hit);
        let mesh = &self.asset.mesh;
        let [ia, ib, ic] = mesh.triangles[hit.triangle as usize].map(|v| v as usize);
        let (wa, wb, wc) = ((1.0 - hit.u - hit.v) as f32, hit.u as f32, hit.v as f32);
        let uv: Vec2 = mesh.uvs[ia] * wa + mesh.uvs[ib] * wb + mesh.uvs[ic] * wc;
        let n = mesh.normals[ia] * wa + mesh.normals[ib] * wb + mesh.normals[ic] * wc;
        let tan = mesh.tangents[ia] * wa + mesh.tangents[ib] * wb + mesh.tangents[ic] * wc;
        let texel = self.asset.textures.sample(uv);
        let local = Vec3::new(texel[NORMAL], texel[NORMAL + 1], texel[NORMAL + 2]);
        // Normals follow the inverse transpose of the frame change.
        let normal_map = Mat3::from_mat4(self.to_normalized.inverse()).transpose();
        let shading = (normal_map * from_tangent_space(local, n, tan.truncate(), tan.w))
            .normalize_or_zero()
            .as_dvec3();
        let [a, b, c] = [ia, ib, ic].map(|v| {
            self.to_normalized
                .transform_point3(mesh.positions[v])
                .as_dvec3()
        });
        let mut face = (b - a).cross(c - a).normalize_or_zero();
        let mut shading = if shading == DVec3::ZERO {
            face
        } else {
            shading
        };
        if face.dot(dir) > 0.0 {
            // seen from behind
            face = -face;
            shading = -shading;
        }
        let mut params = [0.0f32; PARAM_COUNT];
        params.copy_from_slice(&texel[..PARAM_COUNT]);
        Some(AssetHit {
            surface: SurfacePoint {
                t: hit.t,
                position: origin + dir * hit.t,
                normal: shading,
                geometric_normal: face,
            },
            params,
        })
    }

    /// Renders the flash term of the view of `camera` (its rays, flash
    /// energy and pixel grid).
    pub fn render_flash(&self, camera: &Camera, settings: &FlashSettings) -> FlashImage {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let pixels: Vec<Option<[f32; 3]>> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let ray = camera.ray((i % w) as f64, (i / w) as f64);
                let hit = self.trace(ray.origin, ray.dir)?;
                Some(flash_radiance(
                    &hit.params,
                    hit.surface.normal.as_vec3(),
                    -ray.dir.as_vec3(),
                    hit.surface.t as f32,
                    camera.light_energy,
                    settings,
                ))
            })
            .collect();
        to_flash_image(camera, pixels)
    }

    /// Renders every map of the view of `camera` at `scale` × its
    /// resolution (pixel centres mapped into the camera's own pixel grid as
    /// the run renderer does), with the flash energy `energy` (zero: no
    /// flash) and the lighting of `settings`. `view` seeds the
    /// environment samples together with `settings.seed` and the pixel.
    pub fn render_view(
        &self,
        camera: &Camera,
        energy: [f64; 3],
        scale: f64,
        view: usize,
        settings: &LightingSettings,
    ) -> ViewMaps {
        let width = ((camera.width as f64 * scale).round() as u32).max(1);
        let height = ((camera.height as f64 * scale).round() as u32).max(1);
        let (sx, sy) = (
            camera.width as f64 / width as f64,
            camera.height as f64 / height as f64,
        );
        let ambient_settings = AmbientSettings {
            spp: settings.spp.max(1),
            brdf: settings.flash.brdf,
        };
        let w = width as usize;
        let pixels: Vec<Pixel> = (0..w * height as usize)
            .into_par_iter()
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                let ray = camera.ray((x + 0.5) * sx - 0.5, (y + 0.5) * sy - 0.5);
                let dir = ray.dir.normalize();
                let Some(hit) = self.trace(ray.origin, dir) else {
                    let background = settings
                        .env
                        .as_ref()
                        .map_or([0.0; 3], |env| env.radiance(dir).as_vec3().to_array());
                    return Pixel {
                        ambient: background,
                        ..Pixel::default()
                    };
                };
                let sp = hit.surface;
                let flash = flash_radiance(
                    &hit.params,
                    sp.normal.as_vec3(),
                    -dir.as_vec3(),
                    sp.t as f32,
                    energy,
                    &settings.flash,
                );
                let ambient = settings.env.as_ref().map_or([0.0; 3], |env| {
                    let mut rng = pixel_rng(settings.seed, view, i, 0);
                    let params = hit.params.map(f64::from);
                    ambient_radiance(
                        &self.scene,
                        env,
                        &sp,
                        -dir,
                        &params,
                        &ambient_settings,
                        &mut rng,
                    )
                    .as_vec3()
                    .to_array()
                });
                Pixel {
                    flash,
                    ambient,
                    normal: sp.normal.as_vec3().to_array(),
                    depth: sp.t as f32,
                    params: hit.params,
                    hit: true,
                }
            })
            .collect();
        let mut out = ViewMaps::with_capacity(width, height);
        for p in pixels {
            out.rgb.push([0, 1, 2].map(|c| p.ambient[c] + p.flash[c]));
            out.flash.push(p.flash);
            out.ambient.push(p.ambient);
            out.normal.push(p.normal);
            out.depth.push(p.depth);
            out.acc.push(if p.hit { 1.0 } else { 0.0 });
            out.params.push(p.params);
        }
        out
    }
}

/// One pixel of [`AssetTracer::render_view`].
#[derive(Clone, Copy, Default)]
struct Pixel {
    flash: [f32; 3],
    ambient: [f32; 3],
    normal: [f32; 3],
    depth: f32,
    params: [f32; PARAM_COUNT],
    hit: bool,
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
