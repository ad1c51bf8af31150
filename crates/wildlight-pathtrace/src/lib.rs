//! A CPU path tracer for a triangle mesh under an environment light, in
//! double precision: what both the synthetic captures (`wildlight-synth`)
//! and the renderings of an exported asset (`wildlight-export`) shade
//! with.
//!
//! - [`bvh`]: a bounding volume hierarchy for closest-hit and shadow rays;
//! - [`scene`]: a mesh ready for ray casting ([`Scene`]) and its surface
//!   points ([`SurfacePoint`]: position, shading and face normals);
//! - [`env_map`]: an equirectangular environment light ([`EnvMap`]) with
//!   importance sampling;
//! - [`general_brdf`]: the principled BRDF of SPEC §3 for separate light
//!   and view directions, and [`brdf_sampling`]: its importance sampling;
//! - [`integrator`]: the environment light reflected towards the viewer
//!   ([`ambient_radiance`], multiple importance sampling with shadows from
//!   an [`Occluder`]) and
//!   the flash term of SPEC §2 ([`flash_term`]), with per-pixel random
//!   numbers that do not depend on the thread schedule ([`pixel_rng`]).
//!
//! ```
//! use glam::DVec3;
//! use wildlight_material::Material;
//! use wildlight_pathtrace::{AmbientSettings, EnvMap, Scene, ambient_radiance, pixel_rng};
//! // One triangle facing +z, under a uniform sky.
//! let mesh = wildlight_mesh::TriMesh::new(
//!     vec![[-1.0, -1.0, 0.0].into(), [1.0, -1.0, 0.0].into(), [0.0, 1.0, 0.0].into()],
//!     vec![[0, 1, 2]],
//! );
//! let scene = Scene::new(&mesh);
//! let env = EnvMap::from_texels(8, 4, vec![[1.0; 3]; 32]).unwrap();
//! let sp = scene.trace(DVec3::new(0.0, 0.0, 2.0), -DVec3::Z).unwrap();
//! let settings = AmbientSettings { spp: 16, brdf: Default::default() };
//! let params = Material::default().to_array::<f64>();
//! let l = ambient_radiance(&scene, &env, &sp, DVec3::Z, &params, &settings, &mut pixel_rng(0, 0, 0, 0));
//! assert!(l.x > 0.0);
//! ```

// `!(x > 0.0)` is used on purpose: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod brdf_sampling;
pub mod bvh;
pub mod env_map;
pub mod error;
pub mod general_brdf;
pub mod integrator;
pub mod scene;

pub use env_map::EnvMap;
pub use error::EnvMapError;
pub use integrator::{AmbientSettings, Occluder, ambient_radiance, flash_term, hash64, pixel_rng};
pub use scene::{Scene, SurfacePoint};

/// A sphere of radius `r` about the origin (an icosphere of 5120 faces),
/// for the tests.
#[cfg(test)]
fn test_sphere(r: f32) -> wildlight_mesh::TriMesh {
    let mut mesh = wildlight_eval::shapes::icosphere(4);
    for p in &mut mesh.positions {
        *p *= r;
    }
    mesh
}
