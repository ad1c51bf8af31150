//! The light a surface point sends to the viewer:
//!
//! - [`ambient_radiance`]: the environment light reflected by the general
//!   BRDF ([`crate::general_brdf`]) with shadows, estimated by Monte Carlo
//!   with `spp` samples split between environment sampling and BRDF
//!   sampling and combined with the balance heuristic (multi-sample MIS),
//!   the sample pairs stratified on a jittered grid;
//! - [`flash_term`]: exactly the flash term of SPEC §2,
//!   f = E ⊙ ρ(n, h; Θ) · max(0, n·h) / |x − o|² with h = (o − x)/|o − x|,
//!   ρ the SPEC §3 model.
//!
//! Random numbers come from a generator seeded by (seed, view, pixel)
//! ([`pixel_rng`]), so a rendering does not depend on the thread schedule.

use glam::DVec3;
use rand::Rng;
use rand_pcg::Pcg32;
use wildlight_material::BrdfSettings;

use crate::brdf_sampling::LobeMixture;
use crate::env_map::EnvMap;
use crate::general_brdf;
use crate::scene::{Scene, SurfacePoint};

/// Settings of the environment-light estimator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AmbientSettings {
    /// Samples per estimate (at least 1).
    pub spp: usize,
    /// Material model settings (clearcoat Fresnel).
    pub brdf: BrdfSettings,
}

/// SplitMix64 finalizer: a well-mixed 64-bit hash.
pub fn hash64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

/// The random numbers of one pixel of a view (`stream` tells apart
/// independent uses in one pixel, e.g. shading and sensor noise),
/// independent of the thread schedule.
pub fn pixel_rng(seed: u64, view: usize, pixel: usize, stream: u64) -> Pcg32 {
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

/// What blocks the environment light: the shadow rays of
/// [`ambient_radiance`] ask it whether a direction is blocked. A [`Scene`]
/// is one; a renderer adds other surfaces (e.g. the table of a synthetic
/// capture) by implementing it for a scene and those surfaces together.
pub trait Occluder {
    /// Whether the ray from `origin` along unit `dir` hits anything with
    /// t < `t_max`.
    fn occluded(&self, origin: DVec3, dir: DVec3, t_max: f64) -> bool;
}

impl Occluder for Scene {
    fn occluded(&self, origin: DVec3, dir: DVec3, t_max: f64) -> bool {
        Scene::occluded(self, origin, dir, t_max)
    }
}

/// Estimates the environment (ambient) radiance leaving `sp` towards `v`
/// (unit, towards the viewer) for the material `params` (MIS of
/// environment and BRDF sampling, with shadows from `scene`, usually a
/// [`Scene`]). `sp.normal` is the shading normal, so a renderer may take it
/// (and `params`) from textures, e.g. for an exported asset.
pub fn ambient_radiance<O: Occluder + ?Sized>(
    scene: &O,
    env: &EnvMap,
    sp: &SurfacePoint,
    v: DVec3,
    params: &[f64; 9],
    settings: &AmbientSettings,
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn strata_grid_divides_the_sample_count() {
        assert_eq!(strata_columns(64), 8);
        assert_eq!(strata_columns(32), 4);
        assert_eq!(strata_columns(7), 1);
        assert_eq!(strata_columns(1), 1);
    }

    /// Blocks every direction below the horizontal plane through the origin.
    struct LowerHalf;

    impl Occluder for LowerHalf {
        fn occluded(&self, _origin: DVec3, dir: DVec3, _t_max: f64) -> bool {
            dir.y < 0.0
        }
    }

    /// Any occluder shadows the estimate: a point facing +x under a uniform
    /// sky, seen along its normal, gets half its light (the BRDF is
    /// symmetric about the plane y = 0) when the lower half of the
    /// directions is blocked, and the unblocked estimate is the scene's.
    #[test]
    fn an_occluder_that_blocks_the_lower_half_halves_the_light() {
        let env = EnvMap::from_texels(16, 8, vec![[1.0; 3]; 128]).unwrap();
        let sp = SurfacePoint {
            t: 1.0,
            position: DVec3::ZERO,
            normal: DVec3::X,
            geometric_normal: DVec3::X,
        };
        let params = wildlight_material::Material::default().to_array::<f64>();
        let settings = AmbientSettings {
            spp: 64,
            brdf: BrdfSettings::default(),
        };
        // a scene far behind the viewer blocks nothing
        let mut far = crate::test_sphere(0.1);
        for p in &mut far.positions {
            p.z += 100.0;
        }
        let nothing = Scene::new(&far);
        let (mut open, mut half) = (0.0, 0.0);
        let trials = 400;
        for k in 0..trials {
            let mut rng = pixel_rng(5, 0, k, 0);
            open += ambient_radiance(&nothing, &env, &sp, DVec3::X, &params, &settings, &mut rng).x;
            let mut rng = pixel_rng(5, 0, k, 0);
            half += ambient_radiance(
                &LowerHalf,
                &env,
                &sp,
                DVec3::X,
                &params,
                &settings,
                &mut rng,
            )
            .x;
        }
        let ratio = half / open;
        assert!((ratio - 0.5).abs() < 0.02, "{ratio}");
    }

    /// A white furnace: a constant environment of radiance 1 and a white
    /// Lambertian-like sphere seen head-on reflects about its albedo,
    /// independently of the strategy split (checks the MIS weights).
    #[test]
    fn furnace_sphere_reflects_its_albedo() {
        let mesh = crate::test_sphere(0.5);
        let material = wildlight_material::Material {
            base_color: [1.0; 3],
            roughness: 1.0,
            dielectric: 0.0,
            ..Default::default()
        };
        let scene = Scene::new(&mesh);
        let env = EnvMap::from_texels(8, 4, vec![[1.0; 3]; 32]).unwrap();
        let sp = scene.trace(DVec3::new(0.0, 0.0, 3.0), -DVec3::Z).unwrap();
        let params = material.to_array::<f64>();
        let mut values = Vec::new();
        for spp in [1, 2, 64] {
            let settings = AmbientSettings {
                spp,
                brdf: BrdfSettings::default(),
            };
            let mut mean = 0.0;
            let trials = 4000 / spp;
            for k in 0..trials {
                let mut rng = pixel_rng(9, 0, k, 0);
                mean +=
                    ambient_radiance(&scene, &env, &sp, DVec3::Z, &params, &settings, &mut rng).x;
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
