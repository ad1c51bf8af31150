//! The whole geometry evaluation: optional visibility restriction of both
//! meshes, then appendix eq. 16.

use crate::visibility::{Viewpoint, visible_triangles};
use crate::{EvalError, SurfaceDistance, SurfaceDistanceOptions, surface_distance};
use serde::Serialize;
use wildlight_mesh::TriMesh;

/// Result of [`evaluate_meshes`]: eq. 16 plus what was evaluated.
#[derive(Clone, Debug, Serialize)]
pub struct MeshEvaluation {
    /// The eq. 16 statistics (mean, median, pairs, std_of_mean, ...).
    #[serde(flatten)]
    pub distance: SurfaceDistance,
    /// Triangles of the predicted mesh as read.
    pub triangles_pred: usize,
    /// Triangles of the ground-truth mesh as read.
    pub triangles_gt: usize,
    /// Triangles of the predicted mesh that took part (visible ones).
    pub triangles_pred_used: usize,
    /// Triangles of the ground-truth mesh that took part (visible ones).
    pub triangles_gt_used: usize,
    /// Number of cameras used for the visibility restriction (0: none).
    pub cameras: usize,
}

/// Restricts `pred` and `gt` to the triangles the `viewpoints` see (when
/// given; each mesh occludes only itself) and computes eq. 16 between them.
pub fn evaluate_meshes(
    pred: &TriMesh,
    gt: &TriMesh,
    viewpoints: Option<&[Viewpoint]>,
    options: &SurfaceDistanceOptions,
) -> Result<MeshEvaluation, EvalError> {
    let restrict = |mesh: &TriMesh, what: &str| -> Result<TriMesh, EvalError> {
        let Some(viewpoints) = viewpoints else {
            return Ok(mesh.clone());
        };
        let visible = visible_triangles(mesh, viewpoints)?;
        if !visible.iter().any(|v| *v) {
            return Err(EvalError::UnusableMesh {
                what: what.to_string(),
                problem: format!(
                    "no triangle is visible from the {} cameras (is --frame right?)",
                    viewpoints.len()
                ),
            });
        }
        Ok(mesh.select_triangles(&visible))
    };
    let (pred_used, gt_used) = rayon::join(
        || restrict(pred, "predicted mesh"),
        || restrict(gt, "ground-truth mesh"),
    );
    let (pred_used, gt_used) = (pred_used?, gt_used?);
    let distance = surface_distance(&pred_used, &gt_used, options)?;
    Ok(MeshEvaluation {
        distance,
        triangles_pred: pred.triangles.len(),
        triangles_gt: gt.triangles.len(),
        triangles_pred_used: pred_used.triangles.len(),
        triangles_gt_used: gt_used.triangles.len(),
        cameras: viewpoints.map_or(0, <[Viewpoint]>::len),
    })
}
