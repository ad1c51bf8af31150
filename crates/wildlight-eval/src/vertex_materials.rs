//! `wildlight eval vertex-materials`: a model's materials against truth
//! given per vertex of the ground-truth mesh, for captures that have no
//! per-pixel material maps — such as the Mitsuba 3 torus
//! (`crates/wildlight-data/tests/fixtures/mitsuba-torus`).
//!
//! The capture folder holds `gt_mesh_normalized.ply` (the true surface in
//! the normalized frame), `gt_albedo_vertex.npy` (an `n × 3` float32 array,
//! linear RGB base colour per vertex of that mesh) and `meta.json`, whose
//! `material.roughness` and `material.metallic` hold for the whole object.
//! The model's material is read at every vertex of a triangle that a capture
//! camera sees ([`crate::visible_triangles`]); the base colour is compared as
//! `eval materials` compares it ([`ColourFit`]: plain, and aligned per channel
//! up to the flash gain), roughness and metallic by their mean and mean
//! absolute error.

use std::path::Path;

use ndarray::Array2;
use ndarray_npy::ReadNpyExt;
use wildlight_material::{BASE_COLOR, METALLIC, PARAM_COUNT, ROUGHNESS};
use wildlight_mesh::TriMesh;

use crate::visibility::{Viewpoint, visible_triangles};
use crate::{ColourFit, EvalError};

/// The file names of the truth in a capture folder.
pub const MESH_FILE: &str = "gt_mesh_normalized.ply";
/// See [`MESH_FILE`].
pub const ALBEDO_FILE: &str = "gt_albedo_vertex.npy";
/// See [`MESH_FILE`].
pub const META_FILE: &str = "meta.json";

/// Material truth per vertex of a mesh (normalized frame).
#[derive(Clone, Debug)]
pub struct VertexTruth {
    /// The true surface.
    pub mesh: TriMesh,
    /// Linear RGB base colour of each vertex.
    pub albedo: Vec<[f32; 3]>,
    /// Roughness of the whole object.
    pub roughness: f64,
    /// Metallic of the whole object.
    pub metallic: f64,
}

impl VertexTruth {
    /// Reads the truth of a capture folder (see the module documentation).
    pub fn read(capture: &Path) -> Result<Self, EvalError> {
        let input = |path: &Path, problem: String| EvalError::Input {
            path: path.to_path_buf(),
            problem,
        };
        let mesh = TriMesh::read(capture.join(MESH_FILE))?;
        let path = capture.join(ALBEDO_FILE);
        let file =
            std::fs::File::open(&path).map_err(|e| input(&path, format!("cannot open: {e}")))?;
        let array = Array2::<f32>::read_npy(file)
            .map_err(|e| input(&path, format!("not an n × 3 float32 array: {e}")))?;
        if array.dim() != (mesh.positions.len(), 3) {
            return Err(input(
                &path,
                format!(
                    "{:?} values for the {} vertices of {MESH_FILE}",
                    array.dim(),
                    mesh.positions.len()
                ),
            ));
        }
        let albedo = array
            .rows()
            .into_iter()
            .map(|r| [r[0], r[1], r[2]])
            .collect();
        let path = capture.join(META_FILE);
        let text = std::fs::read_to_string(&path)
            .map_err(|e| input(&path, format!("cannot read: {e}")))?;
        let meta: serde_json::Value =
            serde_json::from_str(&text).map_err(|e| input(&path, format!("not JSON: {e}")))?;
        let value = |key: &str| {
            meta["material"][key]
                .as_f64()
                .ok_or_else(|| input(&path, format!("no number material.{key}")))
        };
        Ok(Self {
            mesh,
            albedo,
            roughness: value("roughness")?,
            metallic: value("metallic")?,
        })
    }
}

/// What `eval vertex-materials` measures.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct VertexMaterialEvaluation {
    /// Vertices compared (those of a visible triangle).
    pub vertices: usize,
    /// Vertices of the mesh.
    pub vertices_total: usize,
    /// Base colour PSNR (peak 1) over vertices × channels.
    pub base_color_psnr: f64,
    /// The same after the per-channel least-squares scale.
    pub base_color_psnr_aligned: f64,
    /// The per-channel scale of the alignment.
    pub base_color_scale: [f64; 3],
    /// Mean predicted roughness, the truth, and the mean absolute error.
    pub roughness_mean: f64,
    /// See [`Self::roughness_mean`].
    pub roughness_true: f64,
    /// See [`Self::roughness_mean`].
    pub roughness_mae: f64,
    /// Mean predicted metallic, the truth, and the mean absolute error.
    pub metallic_mean: f64,
    /// See [`Self::metallic_mean`].
    pub metallic_true: f64,
    /// See [`Self::metallic_mean`].
    pub metallic_mae: f64,
}

/// Compares `material` (the nine parameters at each of a batch of points)
/// with `truth` at the vertices `viewpoints` see.
pub fn evaluate_vertex_materials(
    truth: &VertexTruth,
    viewpoints: &[Viewpoint],
    material: impl FnOnce(&[[f32; 3]]) -> Vec<[f32; PARAM_COUNT]>,
) -> Result<VertexMaterialEvaluation, EvalError> {
    let visible = visible_triangles(&truth.mesh, viewpoints)?;
    let mut seen = vec![false; truth.mesh.positions.len()];
    for (tri, v) in truth.mesh.triangles.iter().zip(&visible) {
        if *v {
            for &i in tri {
                seen[i as usize] = true;
            }
        }
    }
    let used: Vec<usize> = (0..seen.len()).filter(|&i| seen[i]).collect();
    if used.is_empty() {
        return Err(EvalError::UnusableMesh {
            what: MESH_FILE.into(),
            problem: "no camera sees any of its triangles".into(),
        });
    }
    let points: Vec<[f32; 3]> = used
        .iter()
        .map(|&i| truth.mesh.positions[i].to_array())
        .collect();
    let theta = material(&points);
    assert_eq!(theta.len(), used.len(), "one material per point");
    let mut base = ColourFit::default();
    let (mut rough, mut rough_err, mut metal, mut metal_err) = (0.0, 0.0, 0.0, 0.0);
    for (t, &i) in theta.iter().zip(&used) {
        let p = [0, 1, 2].map(|c| t[BASE_COLOR + c] as f64);
        base.add(p, truth.albedo[i].map(f64::from));
        let (r, m) = (t[ROUGHNESS] as f64, t[METALLIC] as f64);
        rough += r;
        rough_err += (r - truth.roughness).abs();
        metal += m;
        metal_err += (m - truth.metallic).abs();
    }
    let n = used.len() as f64;
    Ok(VertexMaterialEvaluation {
        vertices: used.len(),
        vertices_total: truth.mesh.positions.len(),
        base_color_psnr: base.psnr().expect("vertices were added"),
        base_color_psnr_aligned: base.psnr_aligned().expect("vertices were added"),
        base_color_scale: base.scale().expect("vertices were added"),
        roughness_mean: rough / n,
        roughness_true: truth.roughness,
        roughness_mae: rough_err / n,
        metallic_mean: metal / n,
        metallic_true: truth.metallic,
        metallic_mae: metal_err / n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::image_metrics::MAX_PSNR;
    use glam::DVec3;

    /// A sphere whose truth varies with position, seen from one side only.
    fn sphere_truth() -> (VertexTruth, Vec<Viewpoint>) {
        let mesh = crate::shapes::icosphere(2);
        let albedo = mesh
            .positions
            .iter()
            .map(|p| [0.5 + 0.4 * p.x, 0.5 + 0.3 * p.y, 0.4 + 0.2 * p.z])
            .collect();
        let truth = VertexTruth {
            mesh,
            albedo,
            roughness: 0.4,
            metallic: 0.0,
        };
        (
            truth,
            vec![Viewpoint::omnidirectional(DVec3::new(0.0, 0.0, 3.0))],
        )
    }

    #[test]
    fn the_truth_up_to_a_gain_scores_exactly_on_the_seen_side() {
        let (truth, views) = sphere_truth();
        let truth_at = |p: [f32; 3]| {
            let i = truth
                .mesh
                .positions
                .iter()
                .position(|q| q.to_array() == p)
                .expect("a vertex");
            truth.albedo[i]
        };
        let e = evaluate_vertex_materials(&truth, &views, |pts| {
            pts.iter()
                .map(|p| {
                    let a = truth_at(*p);
                    let mut t = [0.0f32; PARAM_COUNT];
                    for c in 0..3 {
                        t[BASE_COLOR + c] = 0.5 * a[c];
                    }
                    t[ROUGHNESS] = 0.5;
                    t[METALLIC] = 0.25;
                    t
                })
                .collect()
        })
        .unwrap();
        // one camera sees about half of the sphere
        assert!(
            e.vertices > e.vertices_total / 3 && e.vertices < e.vertices_total,
            "{e:?}"
        );
        for k in e.base_color_scale {
            assert!((k - 2.0).abs() < 1e-6, "{e:?}");
        }
        assert!(e.base_color_psnr_aligned > 0.9 * MAX_PSNR, "{e:?}");
        assert!(e.base_color_psnr < 20.0, "{e:?}");
        assert!((e.roughness_mae - 0.1).abs() < 1e-6 && (e.roughness_mean - 0.5).abs() < 1e-6);
        assert!((e.metallic_mae - 0.25).abs() < 1e-6);
    }

    #[test]
    fn a_folder_without_the_truth_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let err = VertexTruth::read(dir.path()).unwrap_err().to_string();
        assert!(err.contains(MESH_FILE), "{err}");
        wildlight_mesh::ply::write_ply(&crate::shapes::icosphere(1), &dir.path().join(MESH_FILE))
            .unwrap();
        let err = VertexTruth::read(dir.path()).unwrap_err().to_string();
        assert!(
            err.contains(ALBEDO_FILE) && err.contains("cannot open"),
            "{err}"
        );
    }
}
