//! Clean-up and simplification of the marching-cubes mesh: removal of
//! small disconnected pieces and quadric edge collapse with `meshopt`.

use wildlight_mesh::TriMesh;

use crate::ExportError;

/// Simplifies `mesh` to at most `max_faces` triangles with meshopt's
/// quadric simplifier (vertices keep positions of the input, so they stay
/// on the fine surface). When topology stops the simplifier above the
/// target, the sloppy (clustering) simplifier finishes the job. Unused
/// vertices are removed. A mesh already small enough is returned as is.
pub fn simplify(mesh: &TriMesh, max_faces: usize) -> Result<TriMesh, ExportError> {
    if max_faces == 0 {
        return Err(ExportError::InvalidOption {
            name: "faces",
            problem: "must be at least 1".into(),
        });
    }
    if mesh.triangles.len() <= max_faces {
        return Ok(mesh.without_unused_vertices());
    }
    let positions: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let adapter = meshopt::VertexDataAdapter::new(
        meshopt::typed_to_bytes(&positions),
        std::mem::size_of::<[f32; 3]>(),
        0,
    )
    .map_err(|e| ExportError::stage("simplification", e.to_string()))?;
    // Target error 1.0 is relative to the mesh extent: no error limit, the
    // face count decides.
    let mut result = meshopt::simplify(
        &indices,
        &adapter,
        max_faces * 3,
        1.0,
        meshopt::SimplifyOptions::None,
        None,
    );
    if result.len() > max_faces * 3 {
        result = meshopt::simplify_sloppy(&result, &adapter, max_faces * 3, 1.0, None);
    }
    let triangles: Vec<[u32; 3]> = result
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
        .collect();
    Ok(TriMesh::new(mesh.positions.clone(), triangles).without_unused_vertices())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::marching::{MarchingOptions, extract_surface};
    use crate::source::AnalyticSource;
    use glam::Vec3;

    #[test]
    fn sphere_simplifies_to_the_target_and_stays_on_the_surface() {
        let source = AnalyticSource::new(|p: Vec3| p.length() - 0.7, |_| [0.5; 9]);
        let options = MarchingOptions {
            resolution: 64,
            ..Default::default()
        };
        let (fine, _) =
            extract_surface(&source, &options, &indicatif::ProgressBar::hidden()).unwrap();
        assert!(fine.triangles.len() > 10_000);
        let coarse = simplify(&fine, 2000).unwrap();
        assert!(coarse.triangles.len() <= 2000 && coarse.triangles.len() > 1500);
        // Vertices are a subset of the fine ones: still on the sphere.
        for p in &coarse.positions {
            assert!((p.length() - 0.7).abs() < 2e-3);
        }
        // Still closed: area close to the fine mesh's.
        let rel = (coarse.total_area() - fine.total_area()).abs() / fine.total_area();
        assert!(rel < 0.01, "area changed by {rel}");
        assert!(simplify(&fine, 0).is_err());
    }
}
