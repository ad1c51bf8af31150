//! Rendering one view of a synthetic capture with its ground-truth maps.
//!
//! Every pixel is shaded along the camera ray through its centre (SPEC §5):
//!
//! - **ambient**: the environment light reflected by the general BRDF
//!   ([`wildlight_pathtrace::general_brdf`]) with shadows, estimated by
//!   Monte Carlo with `spp` samples split between environment sampling and
//!   BRDF sampling and combined with the balance heuristic (multi-sample
//!   MIS), the sample pairs stratified on a jittered grid
//!   ([`wildlight_pathtrace::ambient_radiance`]);
//! - **flash** (flash views only): exactly the flash term of SPEC §2
//!   ([`wildlight_pathtrace::flash_term`]),
//!   f = E ⊙ ρ(n, h; Θ) · max(0, n·h) / |x − o|² with h = (o − x)/|o − x|,
//!   ρ the SPEC §3 model, n the shading normal written to the normal map;
//! - pixels whose ray misses the object show the background
//!   ([`crate::background`]): the environment in the ray's direction
//!   (room), the Lambertian table top under the environment with the
//!   object's shadows ([`TableLight`]) and the flash (SPEC §2) or that
//!   environment (table), or 0 (none).
//!
//! Masks are the object's pixel coverage > 0.5 (the fraction of a pixel's
//! rays whose first hit is the object), measured with 4×4 rays per pixel
//! where the centre hits of neighbouring pixels disagree.
//! Random numbers come from a generator seeded by (seed, view, pixel)
//! ([`wildlight_pathtrace::pixel_rng`]), so the result does not depend on
//! the thread schedule.

use glam::DVec3;
use rand::Rng;
use rand_pcg::Pcg32;
use rayon::prelude::*;
use wildlight_data::{Camera, Mask, RgbImage};
use wildlight_material::{BrdfSettings, METALLIC, PARAM_COUNT, ROUGHNESS};
use wildlight_mesh::TriMesh;
use wildlight_pathtrace::{
    AmbientSettings, EnvMap, Scene, SurfacePoint, ambient_radiance, flash_term, pixel_rng,
};

use crate::background::{Background, OnTable, Table, TableLight};
use crate::error::SynthError;
use crate::ground_truth::MaterialDefinition;

/// A mesh ready for ray casting, with its material, in the normalized frame.
#[derive(Clone, Debug)]
pub struct RenderScene {
    scene: Scene,
    material: MaterialDefinition,
    background: Background,
    /// A sphere (centre, radius) that holds the mesh.
    bound: (DVec3, f64),
}

impl RenderScene {
    /// Prepares `mesh` (normalized frame) in front of the room
    /// ([`Background::Room`]). Vertex normals are taken from the mesh when
    /// present, else averaged from the faces.
    pub fn new(mesh: &TriMesh, material: MaterialDefinition) -> RenderScene {
        let centre = mesh
            .bounding_box()
            .map(|b| b.center().as_dvec3())
            .unwrap_or(DVec3::ZERO);
        let radius = mesh
            .positions
            .iter()
            .map(|p| (p.as_dvec3() - centre).length())
            .fold(0.0, f64::max);
        RenderScene {
            scene: Scene::new(mesh),
            material,
            background: Background::Room,
            // a margin for the f32 vertices' rounding
            bound: (centre, radius * (1.0 + 1e-6) + 1e-6),
        }
    }

    /// The same object in front of `background`.
    pub fn with_background(mut self, background: Background) -> RenderScene {
        self.background = background;
        self
    }

    /// The background.
    pub fn background(&self) -> &Background {
        &self.background
    }

    /// The material definition.
    pub fn material(&self) -> &MaterialDefinition {
        &self.material
    }

    /// The mesh ready for ray casting.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The first point of the object along the ray (unit `dir`), if any
    /// (the background is not traced).
    pub fn trace(&self, origin: DVec3, dir: DVec3) -> Option<SurfacePoint> {
        self.scene.trace(origin, dir)
    }

    /// Whether the ray from `origin` along unit `dir` hits the object with
    /// t < `t_max` (the background is not traced).
    pub fn occluded(&self, origin: DVec3, dir: DVec3, t_max: f64) -> bool {
        self.scene.occluded(origin, dir, t_max)
    }

    /// The object's point along the camera ray if the object is the first
    /// surface the ray hits (the table, if any, not in front of it).
    fn trace_object_first(&self, origin: DVec3, dir: DVec3) -> Option<SurfacePoint> {
        let hit = self.scene.trace(origin, dir)?;
        match &self.background {
            Background::Table(table) if table.intersect(origin, dir, hit.t).is_some() => None,
            _ => Some(hit),
        }
    }

    /// Whether the first surface the camera ray hits is the object.
    fn object_first(&self, origin: DVec3, dir: DVec3) -> bool {
        let t_max = match &self.background {
            Background::Table(table) => table
                .intersect(origin, dir, f64::INFINITY)
                .unwrap_or(f64::INFINITY),
            _ => f64::INFINITY,
        };
        self.scene.occluded(origin, dir, t_max)
    }
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
    /// Ambient-only radiance (no noise, no clipping; where the ray misses
    /// the object, the background's: the environment, the table, or 0).
    pub ambient: RgbImage,
    /// Flash-only radiance (no noise, no clipping; the table's where the
    /// ray sees the table).
    pub flash: RgbImage,
    /// Linear base colour (this and the following maps are the object's
    /// alone: zero where the ray misses the object).
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
                scene.trace_object_first(ray.origin, ray.dir)
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
    let table_light = scene
        .background
        .table()
        .map(|_| TableLight::new(env, scene.bound.0, scene.bound.1));
    let ambient_settings = AmbientSettings {
        spp: settings.spp,
        brdf: settings.brdf,
    };
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
                            covered += scene.object_first(ray.origin, ray.dir) as usize;
                        }
                        covered > 8
                    } else {
                        centre
                    };
                    let ray = camera.ray(x as f64, y as f64);
                    let mut rng = pixel_rng(settings.seed, view, i, 0);
                    let (ambient_l, flash_l, normal, depth, params) = match &hits[i] {
                        None => {
                            let (a, f) = match &scene.background {
                                Background::Room => (env.radiance(ray.dir), DVec3::ZERO),
                                Background::None => (DVec3::ZERO, DVec3::ZERO),
                                Background::Table(table) => shade_table(
                                    scene,
                                    table,
                                    table_light.as_ref().expect("built for a table"),
                                    env,
                                    camera,
                                    (x, y),
                                    settings.spp,
                                    &mut rng,
                                ),
                            };
                            (a, f, DVec3::ZERO, 0.0, [0.0; 9])
                        }
                        Some(sp) => {
                            let params = scene.material.eval(sp.position).to_array::<f64>();
                            let v = -ray.dir;
                            let a = match &scene.background {
                                Background::Table(table) => ambient_radiance(
                                    &OnTable {
                                        scene: &scene.scene,
                                        table,
                                    },
                                    env,
                                    sp,
                                    v,
                                    &params,
                                    &ambient_settings,
                                    &mut rng,
                                ),
                                _ => ambient_radiance(
                                    &scene.scene,
                                    env,
                                    sp,
                                    v,
                                    &params,
                                    &ambient_settings,
                                    &mut rng,
                                ),
                            };
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

/// The ambient and flash radiance that the camera ray through pixel
/// `(x, y)` receives from the table, or the environment where the ray
/// misses the table (above the horizon, beyond the disc).
///
/// The table is Lambertian with the albedo of its checker box-filtered over
/// the pixel's footprint on the plane (from the rays through the next pixel
/// along x and along y): ambient albedo/π · E(p), E the irradiance with the
/// object's shadows ([`TableLight`], `spp` samples), and the flash term of
/// SPEC §2 with ρ = albedo/π.
#[allow(clippy::too_many_arguments)]
fn shade_table(
    scene: &RenderScene,
    table: &Table,
    light: &TableLight,
    env: &EnvMap,
    camera: &Camera,
    (x, y): (usize, usize),
    spp: usize,
    rng: &mut Pcg32,
) -> (DVec3, DVec3) {
    let ray = camera.ray(x as f64, y as f64);
    let Some(t) = table.intersect(ray.origin, ray.dir, f64::INFINITY) else {
        return (env.radiance(ray.dir), DVec3::ZERO);
    };
    let p = ray.origin + t * ray.dir;
    // the pixel's footprint: where the neighbouring pixels' rays meet the plane
    let on_plane = |sx: f64, sy: f64| {
        let r = camera.ray(sx, sy);
        let t = (table.height - r.origin.y) / r.dir.y;
        (t > 0.0 && t.is_finite()).then(|| r.origin + t * r.dir)
    };
    let footprint = match (
        on_plane(x as f64 + 1.0, y as f64),
        on_plane(x as f64, y as f64 + 1.0),
    ) {
        (Some(px), Some(py)) => {
            let (dx, dy) = (px - p, py - p);
            [dx.x.abs().max(dy.x.abs()), dx.z.abs().max(dy.z.abs())]
        }
        // a neighbour above the horizon: the pixel spans the far table
        _ => [table.radius; 2],
    };
    let rho = DVec3::from(table.albedo(p, footprint)) / std::f64::consts::PI;
    // The rig keeps the cameras above the table (Background::check_cameras):
    // the ray meets its upper side, n = +y.
    let ambient = rho * light.irradiance(p, &scene.scene, spp, rng);
    let flash = if camera.flash() {
        // SPEC §2: f = E ⊙ ρ · max(0, n·h) / |x − o|², h = −dir, |x − o| = t
        let c = (-ray.dir.y).max(0.0);
        DVec3::from(camera.light_energy) * rho * (c / (t * t))
    } else {
        DVec3::ZERO
    };
    (ambient, flash)
}

/// A standard normal number (Box–Muller).
fn gaussian(rng: &mut Pcg32) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>();
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}
