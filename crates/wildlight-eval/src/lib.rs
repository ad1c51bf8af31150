//! Evaluation metrics of wildlight.
//!
//! - Geometry: the surface-to-surface distance of SPEC §7 (appendix eq. 16)
//!   with adaptive stopping, optionally restricted to the surface the
//!   capture's cameras see ([`surface_distance`], [`visibility`]).
//! - Synthetic test meshes for tests and benchmarks ([`shapes`]).

mod error;
pub mod mesh_eval;
pub mod shapes;
pub mod surface_distance;
pub mod surface_sampler;
pub mod visibility;

pub use error::EvalError;
pub use mesh_eval::{MeshEvaluation, evaluate_meshes};
pub use surface_distance::{SurfaceDistance, SurfaceDistanceOptions, surface_distance};
pub use visibility::{Frustum, Viewpoint, restrict_to_visible, visible_triangles};
