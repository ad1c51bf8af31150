//! The material model of wildlight: the 9-parameter principled BRDF of
//! WildLight (SPEC §3, appendix eqs. 1–15) for a light co-located with the
//! camera, in `f32` and `f64`, with exact derivatives with respect to every
//! parameter and to c = n·h.
//!
//! ```
//! use wildlight_material::{brdf, BrdfSettings, Material};
//! let m = Material { base_color: [0.8, 0.2, 0.1], roughness: 0.5, ..Material::default() };
//! let rho = brdf::eval(&m.to_array::<f64>(), 0.9, &BrdfSettings::default());
//! assert!(rho[0] > rho[1]);
//! ```

pub mod brdf;
pub mod material;

pub use brdf::{BrdfJacobian, BrdfSettings};
pub use material::{
    BASE_COLOR, CLEARCOAT, CLEARCOAT_GLOSS, DIELECTRIC, METALLIC, Material, PARAM_COUNT,
    PARAM_NAMES, ROUGHNESS, SUBSURFACE,
};
