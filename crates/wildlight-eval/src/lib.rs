//! Evaluation metrics of wildlight.
//!
//! - Geometry: the surface-to-surface distance of SPEC §7 (appendix eq. 16)
//!   with adaptive stopping ([`surface_distance`]), optionally restricted to
//!   the surface the capture's cameras see ([`visibility`], [`cameras`]),
//!   combined in [`mesh_eval`].
//! - Images: PSNR and SSIM over masks ([`image_metrics`]) of rendered views
//!   against a capture, by flash / no-flash / all views ([`image_eval`]).
//! - Materials: base colour, roughness, metallic and normal errors against
//!   a synthetic capture's ground-truth maps ([`material_eval`]), or against
//!   truth given per vertex of the true mesh ([`vertex_materials`]); the
//!   base colour's alignment up to the flash gain is [`colour_fit`].
//! - Synthetic meshes for tests and benchmarks ([`shapes`]).

pub mod cameras;
pub mod colour_fit;
mod error;
pub mod image_eval;
pub mod image_metrics;
pub mod material_eval;
pub mod mesh_eval;
pub mod rendered_views;
pub mod shapes;
pub mod surface_distance;
pub mod surface_sampler;
pub mod vertex_materials;
pub mod visibility;

pub use colour_fit::ColourFit;
pub use error::EvalError;
pub use image_eval::{ImageEvaluation, Pixels, evaluate_images};
pub use material_eval::{
    MaterialEvaluation, NORMAL_THRESHOLDS_DEG, NormalWithin, Split, evaluate_materials,
};
pub use mesh_eval::{MeshEvaluation, evaluate_meshes};
pub use surface_distance::{SurfaceDistance, SurfaceDistanceOptions, surface_distance};
pub use vertex_materials::{VertexMaterialEvaluation, VertexTruth, evaluate_vertex_materials};
pub use visibility::{Frustum, Viewpoint, restrict_to_visible, visible_triangles};
