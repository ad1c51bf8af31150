//! Rendering one view of a synthetic capture with its ground-truth maps.
//!
//! Every pixel is shaded along the camera ray through its centre (SPEC §5):
//!
//! - **ambient**: the environment light reflected by the general BRDF
//!   ([`crate::general_brdf`]) with shadows, estimated by Monte Carlo with
//!   `spp` samples split between environment sampling and BRDF sampling
//!   and combined with the balance heuristic (multi-sample MIS), the
//!   sample pairs stratified on a jittered grid;
//! - **flash** (flash views only): exactly the flash term of SPEC §2,
//!   f = E ⊙ ρ(n, h; Θ) · max(0, n·h) / |x − o|² with h = (o − x)/|o − x|,
//!   ρ the SPEC §3 model, n the shading normal written to the normal map;
//! - pixels that see no surface show the environment behind the object.
//!
//! Masks are the object's pixel coverage > 0.5, measured with 4×4 rays
//! per pixel where the centre hits of neighbouring pixels disagree.
//! Random numbers come from a generator seeded by (seed, view, pixel), so
//! the result does not depend on the thread schedule.

use glam::DVec3;
use rand::Rng;
use rand_pcg::Pcg32;
use rayon::prelude::*;
use wildlight_data::{Camera, Mask, RgbImage};
use wildlight_material::{BrdfSettings, METALLIC, PARAM_COUNT, ROUGHNESS};
use wildlight_mesh::TriMesh;

use crate::brdf_sampling::LobeMixture;
use crate::bvh::Bvh;
use crate::env_map::EnvMap;
use crate::error::SynthError;
use crate::general_brdf;
use crate::ground_truth::MaterialDefinition;
use crate::scenes::hash64;

/// A mesh ready for ray casting, with its material, in the normalized frame.
#[derive(Clone, Debug)]
pub struct RenderScene {
    bvh: Bvh,
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    face_normals: Vec<DVec3>,
    material: MaterialDefinition,
}

/// A camera ray's hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// Ray parameter (normalized-frame distance, the ray direction is unit).
    pub t: f64,
    /// Hit position (normalized frame).
    pub position: DVec3,
    /// Unit shading normal (interpolated vertex normals), facing the ray
    /// origin's side, leaning towards the face normal where the
    /// interpolated one turns away from the viewer (see `facing_viewer`).
    pub normal: DVec3,
    /// Unit face normal, facing the ray origin.
    pub geometric_normal: DVec3,
}

impl RenderScene {
    /// Prepares `mesh` (normalized frame). Vertex normals are taken from
    /// the mesh when present, else averaged from the faces.
    pub fn new(mesh: &TriMesh, material: MaterialDefinition) -> RenderScene {
        let positions: Vec<DVec3> = mesh.positions.iter().map(|p| p.as_dvec3()).collect();
        let normals = match &mesh.normals {
            Some(n) if n.len() == positions.len() => n.clone(),
            _ => mesh.vertex_normals_from_faces(),
        };
        let normals = normals
            .iter()
            .map(|n| n.as_dvec3().try_normalize().unwrap_or(DVec3::Z))
            .collect();
        let face_normals = mesh
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| positions[v as usize]);
                (b - a).cross(c - a).try_normalize().unwrap_or(DVec3::Z)
            })
            .collect();
        let bvh = Bvh::new(&positions, &mesh.triangles);
        RenderScene {
            bvh,
            positions,
            normals,
            triangles: mesh.triangles.clone(),
            face_normals,
            material,
        }
    }

    /// The material definition.
    pub fn material(&self) -> &MaterialDefinition {
        &self.material
    }

    /// The first surface point along the ray (unit `dir`), if any.
    pub fn trace(&self, origin: DVec3, dir: DVec3) -> Option<SurfacePoint> {
        let hit = self.bvh.intersect(origin, dir, 0.0, f64::INFINITY)?;
        let hit = self.bvh.refine(origin, dir, hit);
        let tri = self.triangles[hit.triangle as usize];
        let [a, b, c] = tri.map(|v| self.positions[v as usize]);
        let w0 = 1.0 - hit.u - hit.v;
        let position = a * w0 + b * hit.u + c * hit.v;
        let [na, nb, nc] = tri.map(|v| self.normals[v as usize]);
        let mut normal = (na * w0 + nb * hit.u + nc * hit.v)
            .try_normalize()
            .unwrap_or(self.face_normals[hit.triangle as usize]);
        let mut geometric_normal = self.face_normals[hit.triangle as usize];
        if geometric_normal.dot(dir) > 0.0 {
            // seen from behind (open or inconsistently oriented mesh)
            geometric_normal = -geometric_normal;
            normal = -normal;
        }
        Some(SurfacePoint {
            t: hit.t,
            position,
            normal: facing_viewer(normal, geometric_normal, -dir),
            geometric_normal,
        })
    }

    /// Whether the ray from `origin` along unit `dir` hits anything with
    /// t < `t_max`.
    pub fn occluded(&self, origin: DVec3, dir: DVec3, t_max: f64) -> bool {
        self.bvh.occluded(origin, dir, 0.0, t_max)
    }
}

/// Below this cosine between the interpolated normal and the direction to
/// the viewer, the shading normal leans towards the face normal.
const GRAZING_COSINE: f64 = 0.1;

/// The shading normal at a visible point: the interpolated vertex normal
/// `shading`, except where it turns away from the viewer `v` (unit).
///
/// Interpolated normals are smooth across a crease that the triangles
/// themselves turn sharply at (the kettle's lid groove, where the handle
/// meets the body), so a triangle beside the crease that faces the camera
/// can carry a shading normal that faces away from it; the BRDF is then
/// zero for every light, and the pixel is exactly black in both the
/// ambient and the flash image: no real surface looks like that, and no
/// reconstruction whose normals are its own geometry's can fit it. Where
/// c = n_s·v is below [`GRAZING_COSINE`] the normal is blended towards the
/// face normal `geometric` (which faces the viewer, since the ray hit its
/// front): normalize(w n_s + (1 − w) n_g) with w = max(c, 0) / [`GRAZING_COSINE`],
/// continuous in c, and equal to n_s on any surface whose triangles agree
/// with their vertex normals, as they do on a smooth part seen at a grazing
/// angle.
fn facing_viewer(shading: DVec3, geometric: DVec3, v: DVec3) -> DVec3 {
    let c = shading.dot(v);
    if c >= GRAZING_COSINE {
        return shading;
    }
    let w = (c / GRAZING_COSINE).clamp(0.0, 1.0);
    (shading * w + geometric * (1.0 - w))
        .try_normalize()
        .unwrap_or(geometric)
}

/// Settings of the image formation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadingSettings {
    /// Ambient samples per pixel.
    pub spp: usize,
    /// Material model settings (clearcoat Fresnel).
    pub brdf: BrdfSettings,
    /// Sensor noise: Gaussian with standard deviation noise·sqrt(value + 0.01) per channel (0 = off).
    pub noise: f64,
    /// Saturation cap: image values are clipped to [0, cap] (None = no clipping).
    pub saturation: Option<f64>,
    /// Random seed.
    pub seed: u64,
}

/// A rendered view: the photo and every ground-truth map.
#[derive(Clone, Debug)]
pub struct ViewImages {
    /// The photo (ambient + flash, with noise and clipping).
    pub image: RgbImage,
    /// Ambient-only radiance (no noise, no clipping; the environment where no surface).
    pub ambient: RgbImage,
    /// Flash-only radiance (no noise, no clipping).
    pub flash: RgbImage,
    /// Linear base colour.
    pub base_color: RgbImage,
    /// Roughness in all three channels.
    pub roughness: RgbImage,
    /// Metallic in all three channels.
    pub metallic: RgbImage,
    /// Unit shading normal (normalized frame), zero where no surface.
    pub normal: RgbImage,
    /// Distance along the ray to the surface in WORLD units, zero where no surface.
    pub depth: RgbImage,
    /// The 9 material parameters per pixel.
    pub params: Vec<[f32; PARAM_COUNT]>,
    /// Coverage > 0.5.
    pub mask: Mask,
}

/// Seed of the random numbers of one pixel (independent of the schedule).
fn pixel_rng(seed: u64, view: usize, pixel: usize, stream: u64) -> Pcg32 {
    let h = hash64(seed ^ hash64(view as u64 ^ hash64(pixel as u64 ^ (stream << 48))));
    Pcg32::new(h, hash64(h) | 1)
}

/// The largest divisor of `n` not above sqrt(n) (the grid of strata).
fn strata_columns(n: usize) -> usize {
    let mut best = 1;
    let mut d = 1;
    while d * d <= n {
        if n.is_multiple_of(d) {
            best = d;
        }
        d += 1;
    }
    best
}

/// Estimates the ambient radiance leaving `sp` towards `v`.
fn ambient(
    scene: &RenderScene,
    env: &EnvMap,
    sp: &SurfacePoint,
    v: DVec3,
    params: &[f64; 9],
    settings: &ShadingSettings,
    rng: &mut Pcg32,
) -> DVec3 {
    let spp = settings.spp.max(1);
    let n = sp.normal;
    let mix = LobeMixture::new(params, &settings.brdf);
    let n_env = spp.div_ceil(2) as f64;
    let n_brdf = (spp / 2) as f64;
    let cols = strata_columns(spp);
    let rows = spp / cols;
    let origin = sp.position + sp.geometric_normal * (2e-4 * (1.0 + sp.position.length()));
    let mut sum = DVec3::ZERO;
    for k in 0..spp {
        let u1 = ((k % cols) as f64 + rng.random::<f64>()) / cols as f64;
        let u2 = ((k / cols) as f64 + rng.random::<f64>()) / rows as f64;
        let l = if k % 2 == 0 {
            env.sample(u1, u2).0
        } else {
            match mix.sample(n, v, rng.random::<f64>(), u1, u2) {
                Some(l) => l,
                None => continue,
            }
        };
        let cl = n.dot(l);
        if cl <= 0.0 || sp.geometric_normal.dot(l) <= 0.0 {
            continue;
        }
        let f = general_brdf::eval(params, n, l, v, &settings.brdf);
        let radiance = env.radiance(l);
        let value = DVec3::from(f) * radiance * cl;
        if value.max_element() <= 0.0 {
            continue;
        }
        // balance heuristic over both strategies (multi-sample MIS)
        let pdf_sum = n_env * env.pdf(l) + n_brdf * mix.pdf(n, v, l);
        if !(pdf_sum > 0.0) || scene.occluded(origin, l, f64::INFINITY) {
            continue;
        }
        sum += value / pdf_sum;
    }
    sum
}

/// Estimates the environment (ambient) radiance leaving `sp` towards `v`
/// (unit, towards the viewer) for the material `params`: the estimator
/// every synthetic view uses (MIS of environment and BRDF sampling, with
/// shadows from `scene`), for renderers of other surfaces, e.g. an
/// exported asset whose `params` and `sp.normal` come from its textures.
pub fn ambient_radiance(
    scene: &RenderScene,
    env: &EnvMap,
    sp: &SurfacePoint,
    v: DVec3,
    params: &[f64; 9],
    settings: &ShadingSettings,
    rng: &mut Pcg32,
) -> DVec3 {
    ambient(scene, env, sp, v, params, settings, rng)
}

/// The flash term of SPEC §2 for a surface point seen by a camera at
/// distance `t` along `dir`: E ⊙ ρ(n, h; Θ) max(0, n·h) / t², h = −dir.
pub fn flash_term(
    energy: [f64; 3],
    params: &[f64; 9],
    normal: DVec3,
    dir: DVec3,
    t: f64,
    brdf: &BrdfSettings,
) -> DVec3 {
    let c = normal.dot(-dir);
    if c <= 0.0 {
        return DVec3::ZERO;
    }
    let rho = wildlight_material::brdf::eval(params, c, brdf);
    DVec3::from(energy) * DVec3::from(rho) * (c / (t * t))
}

/// Renders `camera` (a view of the capture numbered `view` for seeding).
/// `env` must already include the exposure; `camera.light_energy` is the
/// flash energy. `on_row` is called after each image row.
pub fn render_view(
    scene: &RenderScene,
    env: &EnvMap,
    camera: &Camera,
    view: usize,
    settings: &ShadingSettings,
    world_scale: f64,
    on_row: &(dyn Fn() + Sync),
) -> Result<ViewImages, SynthError> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    // Pass 1: centre hits.
    let hits: Vec<Option<SurfacePoint>> = (0..h)
        .into_par_iter()
        .flat_map_iter(|y| {
            (0..w).map(move |x| {
                let ray = camera.ray(x as f64, y as f64);
                scene.trace(ray.origin, ray.dir)
            })
        })
        .collect();
    // Pass 2: coverage and shading.
    struct Pixel {
        image: DVec3,
        ambient: DVec3,
        flash: DVec3,
        normal: DVec3,
        depth: f64,
        params: [f64; 9],
        mask: bool,
    }
    let energy = camera.light_energy;
    let flash_on = camera.flash();
    let rows: Vec<Vec<Pixel>> = (0..h)
        .into_par_iter()
        .map(|y| {
            let row = (0..w)
                .map(|x| {
                    let i = y * w + x;
                    let centre = hits[i].is_some();
                    let mut edge = false;
                    for (dx, dy) in [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)] {
                        let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                        if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                            edge |= hits[ny as usize * w + nx as usize].is_some() != centre;
                        }
                    }
                    let mask = if edge {
                        let mut covered = 0;
                        for s in 0..16 {
                            let sx = x as f64 - 0.5 + ((s % 4) as f64 + 0.5) / 4.0;
                            let sy = y as f64 - 0.5 + ((s / 4) as f64 + 0.5) / 4.0;
                            let ray = camera.ray(sx, sy);
                            covered += scene.bvh.occluded(ray.origin, ray.dir, 0.0, f64::INFINITY)
                                as usize;
                        }
                        covered > 8
                    } else {
                        centre
                    };
                    let ray = camera.ray(x as f64, y as f64);
                    let mut rng = pixel_rng(settings.seed, view, i, 0);
                    let (ambient_l, flash_l, normal, depth, params) = match &hits[i] {
                        None => (
                            env.radiance(ray.dir),
                            DVec3::ZERO,
                            DVec3::ZERO,
                            0.0,
                            [0.0; 9],
                        ),
                        Some(sp) => {
                            let params = scene.material.eval(sp.position).to_array::<f64>();
                            let v = -ray.dir;
                            let a = ambient(scene, env, sp, v, &params, settings, &mut rng);
                            let f = if flash_on {
                                flash_term(
                                    energy,
                                    &params,
                                    sp.normal,
                                    ray.dir,
                                    sp.t,
                                    &settings.brdf,
                                )
                            } else {
                                DVec3::ZERO
                            };
                            (a, f, sp.normal, sp.t * world_scale, params)
                        }
                    };
                    let mut image = ambient_l + flash_l;
                    if settings.noise > 0.0 {
                        let mut nrng = pixel_rng(settings.seed, view, i, 1);
                        for c in 0..3 {
                            let std = settings.noise * (image[c].max(0.0) + 0.01).sqrt();
                            image[c] += std * gaussian(&mut nrng);
                        }
                    }
                    if let Some(cap) = settings.saturation {
                        image = image.clamp(DVec3::ZERO, DVec3::splat(cap));
                    } else if settings.noise > 0.0 {
                        image = image.max(DVec3::ZERO);
                    }
                    Pixel {
                        image,
                        ambient: ambient_l,
                        flash: flash_l,
                        normal,
                        depth,
                        params,
                        mask,
                    }
                })
                .collect();
            on_row();
            row
        })
        .collect();
    let (wu, hu) = (camera.width, camera.height);
    let mut out = ViewImages {
        image: RgbImage::new(wu, hu),
        ambient: RgbImage::new(wu, hu),
        flash: RgbImage::new(wu, hu),
        base_color: RgbImage::new(wu, hu),
        roughness: RgbImage::new(wu, hu),
        metallic: RgbImage::new(wu, hu),
        normal: RgbImage::new(wu, hu),
        depth: RgbImage::new(wu, hu),
        params: vec![[0.0; PARAM_COUNT]; w * h],
        mask: Mask::new(wu, hu),
    };
    let f3 = |v: DVec3| [v.x as f32, v.y as f32, v.z as f32];
    for (y, row) in rows.into_iter().enumerate() {
        for (x, p) in row.into_iter().enumerate() {
            let (xu, yu) = (x as u32, y as u32);
            out.image.set(xu, yu, f3(p.image));
            out.ambient.set(xu, yu, f3(p.ambient));
            out.flash.set(xu, yu, f3(p.flash));
            out.base_color.set(
                xu,
                yu,
                [p.params[0] as f32, p.params[1] as f32, p.params[2] as f32],
            );
            out.roughness.set(xu, yu, [p.params[ROUGHNESS] as f32; 3]);
            out.metallic.set(xu, yu, [p.params[METALLIC] as f32; 3]);
            out.normal.set(xu, yu, f3(p.normal));
            out.depth.set(xu, yu, [p.depth as f32; 3]);
            out.params[y * w + x] = p.params.map(|v| v as f32);
            out.mask.set(xu, yu, p.mask);
        }
    }
    Ok(out)
}

/// A standard normal number (Box–Muller).
fn gaussian(rng: &mut Pcg32) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A shading normal that faces away from the viewer gives way to the
    /// face normal; the blend is continuous at both ends of the grazing
    /// band and leaves normals that face the viewer alone.
    #[test]
    fn shading_normals_never_face_away_from_the_viewer() {
        let v = DVec3::Z;
        let geometric = DVec3::new(0.6, 0.0, 0.8);
        let at = |c: f64| {
            let s = (1.0 - c * c).sqrt();
            facing_viewer(DVec3::new(-s, 0.0, c), geometric, v)
        };
        assert_eq!(at(0.5), DVec3::new(-(0.75f64).sqrt(), 0.0, 0.5));
        assert_eq!(at(-0.3), geometric);
        assert_eq!(at(0.0), geometric);
        // continuous at the top of the band, facing the viewer inside it
        assert!((at(GRAZING_COSINE - 1e-9) - at(GRAZING_COSINE)).length() < 1e-6);
        for k in 0..=20 {
            let n = at(-0.1 + 0.01 * k as f64);
            assert!((n.length() - 1.0).abs() < 1e-12 && n.dot(v) > 0.0, "{n}");
        }
    }

    #[test]
    fn strata_grid_divides_the_sample_count() {
        assert_eq!(strata_columns(64), 8);
        assert_eq!(strata_columns(32), 4);
        assert_eq!(strata_columns(7), 1);
        assert_eq!(strata_columns(1), 1);
    }

    /// A white furnace: a constant environment of radiance 1 and a white
    /// Lambertian-like sphere seen head-on reflects about its albedo,
    /// independently of the strategy split (checks the MIS weights).
    #[test]
    fn furnace_sphere_reflects_its_albedo() {
        let mesh = crate::mesher::mesh_sdf(&|p| crate::sdf::sphere(p, 0.5), 0.7, 40);
        let material = MaterialDefinition::Constant {
            material: wildlight_material::Material {
                base_color: [1.0; 3],
                roughness: 1.0,
                dielectric: 0.0,
                ..Default::default()
            },
        };
        let scene = RenderScene::new(&mesh, material);
        let env = EnvMap::from_texels(8, 4, vec![[1.0; 3]; 32]).unwrap();
        let sp = scene.trace(DVec3::new(0.0, 0.0, 3.0), -DVec3::Z).unwrap();
        let params = scene.material().eval(sp.position).to_array::<f64>();
        let mut values = Vec::new();
        for spp in [1, 2, 64] {
            let settings = ShadingSettings {
                spp,
                brdf: BrdfSettings::default(),
                noise: 0.0,
                saturation: None,
                seed: 1,
            };
            let mut mean = 0.0;
            let trials = 4000 / spp;
            for k in 0..trials {
                let mut rng = pixel_rng(9, 0, k, 0);
                mean += ambient(&scene, &env, &sp, DVec3::Z, &params, &settings, &mut rng).x;
            }
            values.push(mean / trials as f64);
        }
        // ∫ ρ cos dω for this material at normal incidence (quadrature)
        let n = 400;
        let mut albedo = 0.0;
        for i in 0..n {
            for j in 0..n {
                let ct = (i as f64 + 0.5) / n as f64;
                let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / n as f64;
                let st = (1.0 - ct * ct).sqrt();
                let l = DVec3::new(st * phi.cos(), st * phi.sin(), ct);
                albedo +=
                    general_brdf::eval(&params, DVec3::Z, l, DVec3::Z, &BrdfSettings::default())[0]
                        * ct;
            }
        }
        albedo *= 2.0 * std::f64::consts::PI / (n * n) as f64;
        for v in values {
            assert!((v - albedo).abs() < 0.03 * albedo, "{v} vs {albedo}");
        }
    }
}
