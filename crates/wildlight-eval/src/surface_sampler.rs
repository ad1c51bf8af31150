//! Uniform sampling of points on a triangle mesh by area, and
//! point-to-surface distances through a bounding-volume hierarchy.

use crate::EvalError;
use glam::{DVec3, Vec3};
use parry3d::query::PointQuery;
use rand::Rng;
use wildlight_mesh::TriMesh;

/// A mesh prepared for eq. 16: an area-weighted triangle table for uniform
/// sampling and a parry3d BVH for nearest-point queries.
pub struct SampledSurface {
    corners: Vec<[DVec3; 3]>,
    /// Cumulative triangle areas; the last entry is the total area.
    cumulative_area: Vec<f64>,
    shape: parry3d::shape::TriMesh,
}

impl SampledSurface {
    /// Prepares `mesh`; `what` names it in errors. Fails when the mesh has
    /// no triangle of positive area.
    pub fn new(mesh: &TriMesh, what: &str) -> Result<SampledSurface, EvalError> {
        let unusable = |problem: &str| EvalError::UnusableMesh {
            what: what.to_string(),
            problem: problem.to_string(),
        };
        mesh.validate(std::path::Path::new(what))?;
        let mut corners = Vec::with_capacity(mesh.triangles.len());
        let mut cumulative_area = Vec::with_capacity(mesh.triangles.len());
        let mut total = 0.0;
        for (t, area) in mesh.triangle_areas().into_iter().enumerate() {
            if area > 0.0 && area.is_finite() {
                corners.push(mesh.triangle_corners(t).map(|p| p.as_dvec3()));
                total += area;
                cumulative_area.push(total);
            }
        }
        if corners.is_empty() {
            return Err(unusable("no triangle with positive area"));
        }
        let positions: Vec<parry3d::math::Vector> = mesh
            .positions
            .iter()
            .map(|p| parry3d::math::Vector::new(p.x, p.y, p.z))
            .collect();
        let shape = parry3d::shape::TriMesh::new(positions, mesh.triangles.clone())
            .map_err(|e| unusable(&format!("cannot build the BVH: {e}")))?;
        Ok(SampledSurface {
            corners,
            cumulative_area,
            shape,
        })
    }

    /// The total area of the triangles with positive area.
    pub fn area(&self) -> f64 {
        *self.cumulative_area.last().unwrap_or(&0.0)
    }

    /// A point drawn uniformly by area: a triangle with probability
    /// proportional to its area, then a uniform point in it
    /// (barycentrics (1 − √r₁, √r₁(1 − r₂), √r₁ r₂)).
    pub fn sample(&self, rng: &mut impl Rng) -> Vec3 {
        let target = rng.random::<f64>() * self.area();
        let t = self
            .cumulative_area
            .partition_point(|&c| c <= target)
            .min(self.corners.len() - 1);
        let (r1, r2): (f64, f64) = (rng.random(), rng.random());
        let s = r1.sqrt();
        let [a, b, c] = self.corners[t];
        ((1.0 - s) * a + s * (1.0 - r2) * b + s * r2 * c).as_vec3()
    }

    /// The Euclidean distance from `point` to the nearest point of the
    /// surface (not of the enclosed solid).
    pub fn distance(&self, point: Vec3) -> f64 {
        let p = parry3d::math::Vector::new(point.x, point.y, point.z);
        self.shape.distance_to_local_point(p, false) as f64
    }
}
