//! The [`TriMesh`] type and its basic geometry.

use crate::MeshError;
use glam::{Mat3, Mat4, Vec2, Vec3};
use std::path::Path;

/// An indexed triangle mesh with optional per-vertex attributes.
///
/// `triangles` index into `positions`; each optional attribute, when
/// present, has exactly one entry per position. Triangles are
/// counter-clockwise seen from the side their face normal points to.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Triangles as three vertex indices.
    pub triangles: Vec<[u32; 3]>,
    /// Per-vertex normals (not necessarily unit length as read from a file).
    pub normals: Option<Vec<Vec3>>,
    /// Per-vertex linear RGB colours in [0, 1].
    pub colors: Option<Vec<Vec3>>,
    /// Per-vertex texture coordinates.
    pub uvs: Option<Vec<Vec2>>,
}

/// An axis-aligned bounding box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Component-wise minimum corner.
    pub min: Vec3,
    /// Component-wise maximum corner.
    pub max: Vec3,
}

impl Aabb {
    /// The box centre.
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }

    /// The box extent along each axis (`max - min`).
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }

    /// The length of the box diagonal.
    pub fn diagonal(&self) -> f32 {
        self.size().length()
    }
}

impl TriMesh {
    /// A mesh of positions and triangles without attributes.
    pub fn new(positions: Vec<Vec3>, triangles: Vec<[u32; 3]>) -> Self {
        TriMesh {
            positions,
            triangles,
            normals: None,
            colors: None,
            uvs: None,
        }
    }

    /// Reads a `.ply` or `.obj` file (chosen by extension, case-insensitive).
    pub fn read(path: impl AsRef<Path>) -> Result<TriMesh, MeshError> {
        let path = path.as_ref();
        match extension(path).as_deref() {
            Some("ply") => crate::ply::read_ply(path),
            Some("obj") => crate::obj::read_obj(path),
            _ => Err(MeshError::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }

    /// Writes a `.ply` (binary little endian) or `.obj` file, chosen by
    /// extension, atomically (temporary file in the same folder + rename).
    pub fn write(&self, path: impl AsRef<Path>) -> Result<(), MeshError> {
        let path = path.as_ref();
        match extension(path).as_deref() {
            Some("ply") => crate::ply::write_ply(self, path),
            Some("obj") => crate::obj::write_obj(self, path),
            _ => Err(MeshError::UnknownFormat {
                path: path.to_path_buf(),
            }),
        }
    }

    /// The three corner positions of triangle `t`.
    #[inline]
    pub fn triangle_corners(&self, t: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[t];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// The area of every triangle (½ |(b − a) × (c − a)|), computed in f64.
    pub fn triangle_areas(&self) -> Vec<f64> {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.triangle_corners(t);
                let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
                0.5 * (b - a).cross(c - a).length()
            })
            .collect()
    }

    /// The total surface area (sum of the triangle areas).
    pub fn total_area(&self) -> f64 {
        self.triangle_areas().iter().sum()
    }

    /// The unit normal of every triangle (right-hand rule on the corner
    /// order); zero for degenerate triangles.
    pub fn face_normals(&self) -> Vec<Vec3> {
        (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.triangle_corners(t);
                (b - a).cross(c - a).normalize_or_zero()
            })
            .collect()
    }

    /// Area-weighted unit vertex normals computed from the faces (zero for
    /// vertices that no non-degenerate triangle uses).
    pub fn vertex_normals_from_faces(&self) -> Vec<Vec3> {
        let mut normals = vec![Vec3::ZERO; self.positions.len()];
        for (t, tri) in self.triangles.iter().enumerate() {
            let [a, b, c] = self.triangle_corners(t);
            // The un-normalized cross product has length 2·area: area weighting.
            let n = (b - a).cross(c - a);
            for &v in tri {
                normals[v as usize] += n;
            }
        }
        normals.iter().map(|n| n.normalize_or_zero()).collect()
    }

    /// The bounding box of all positions, or `None` for a mesh without vertices.
    pub fn bounding_box(&self) -> Option<Aabb> {
        let first = *self.positions.first()?;
        let (min, max) = self
            .positions
            .iter()
            .fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        Some(Aabb { min, max })
    }

    /// Applies an affine 4×4 matrix to the positions (as points) and to the
    /// normals (by the inverse transpose of the linear part, re-normalized).
    /// A transform with negative determinant also reverses the triangle
    /// winding so that face normals keep pointing outwards.
    pub fn transformed(&self, matrix: &Mat4) -> TriMesh {
        let mut out = self.clone();
        out.transform(matrix);
        out
    }

    /// In-place version of [`TriMesh::transformed`].
    pub fn transform(&mut self, matrix: &Mat4) {
        for p in &mut self.positions {
            *p = matrix.transform_point3(*p);
        }
        let linear = Mat3::from_mat4(*matrix);
        if let Some(normals) = &mut self.normals {
            let normal_matrix = linear.inverse().transpose();
            for n in normals.iter_mut() {
                *n = (normal_matrix * *n).normalize_or_zero();
            }
        }
        if linear.determinant() < 0.0 {
            for tri in &mut self.triangles {
                tri.swap(1, 2);
            }
        }
    }

    /// Checks that every triangle index is in range and every attribute has
    /// one entry per position. `source` names the mesh in the error.
    pub fn validate(&self, source: &Path) -> Result<(), MeshError> {
        let n = self.positions.len();
        for (name, len) in [
            ("normals", self.normals.as_ref().map(Vec::len)),
            ("colors", self.colors.as_ref().map(Vec::len)),
            ("uvs", self.uvs.as_ref().map(Vec::len)),
        ] {
            if let Some(len) = len
                && len != n
            {
                return Err(MeshError::invalid(
                    source,
                    format!("{len} {name} for {n} vertices"),
                ));
            }
        }
        for (t, tri) in self.triangles.iter().enumerate() {
            if let Some(&bad) = tri.iter().find(|&&v| v as usize >= n) {
                return Err(MeshError::invalid(
                    source,
                    format!("triangle {t} uses vertex {bad}, but there are only {n} vertices"),
                ));
            }
        }
        Ok(())
    }

    /// The sub-mesh made of the triangles for which `keep[t]` is true, with
    /// unused vertices removed (attributes carried along).
    pub fn select_triangles(&self, keep: &[bool]) -> TriMesh {
        let triangles = self
            .triangles
            .iter()
            .zip(keep)
            .filter(|(_, k)| **k)
            .map(|(t, _)| *t)
            .collect();
        TriMesh {
            triangles,
            ..self.clone()
        }
        .without_unused_vertices()
    }

    /// Removes vertices no triangle uses and renumbers the triangles.
    pub fn without_unused_vertices(&self) -> TriMesh {
        let mut new_index = vec![u32::MAX; self.positions.len()];
        let mut order = Vec::new();
        for tri in &self.triangles {
            for &v in tri {
                if new_index[v as usize] == u32::MAX {
                    new_index[v as usize] = order.len() as u32;
                    order.push(v as usize);
                }
            }
        }
        // Keep the original vertex order among the used vertices.
        order.sort_unstable();
        for (i, &v) in order.iter().enumerate() {
            new_index[v] = i as u32;
        }
        self.remapped(&order, &new_index)
    }

    /// Builds a mesh whose vertex `i` is old vertex `order[i]`, with the
    /// triangles renumbered through `new_index` (old → new).
    pub(crate) fn remapped(&self, order: &[usize], new_index: &[u32]) -> TriMesh {
        fn pick<T: Copy>(values: &Option<Vec<T>>, order: &[usize]) -> Option<Vec<T>> {
            values
                .as_ref()
                .map(|v| order.iter().map(|&i| v[i]).collect())
        }
        TriMesh {
            positions: order.iter().map(|&i| self.positions[i]).collect(),
            triangles: self
                .triangles
                .iter()
                .map(|t| t.map(|v| new_index[v as usize]))
                .collect(),
            normals: pick(&self.normals, order),
            colors: pick(&self.colors, order),
            uvs: pick(&self.uvs, order),
        }
    }
}

/// The lower-cased file extension.
fn extension(path: &Path) -> Option<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn right_triangle() -> TriMesh {
        TriMesh::new(
            vec![
                Vec3::ZERO,
                Vec3::new(2.0, 0.0, 0.0),
                Vec3::new(0.0, 3.0, 0.0),
            ],
            vec![[0, 1, 2]],
        )
    }

    #[test]
    fn area_normal_and_box_of_a_right_triangle() {
        let m = right_triangle();
        assert_eq!(m.triangle_areas(), vec![3.0]);
        assert_eq!(m.total_area(), 3.0);
        assert_eq!(m.face_normals(), vec![Vec3::Z]);
        let b = m.bounding_box().unwrap();
        assert_eq!(b.min, Vec3::ZERO);
        assert_eq!(b.max, Vec3::new(2.0, 3.0, 0.0));
        assert_eq!(b.center(), Vec3::new(1.0, 1.5, 0.0));
        assert!(TriMesh::default().bounding_box().is_none());
    }

    #[test]
    fn transform_scales_area_and_mirror_keeps_normals_outward() {
        let mut m = right_triangle();
        m.normals = Some(vec![Vec3::Z; 3]);
        let scaled = m.transformed(&Mat4::from_scale(Vec3::new(2.0, 1.0, 1.0)));
        assert_eq!(scaled.total_area(), 6.0);
        // Mirror in z: the surface normal flips, and winding must follow it.
        let mirrored = m.transformed(&Mat4::from_scale(Vec3::new(1.0, 1.0, -1.0)));
        assert_eq!(mirrored.face_normals(), vec![-Vec3::Z]);
        assert_eq!(mirrored.normals.unwrap()[0], -Vec3::Z);
        let moved = m.transformed(&Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0)));
        assert_eq!(moved.positions[1], Vec3::new(3.0, 2.0, 3.0));
        assert_eq!(moved.normals.unwrap()[0], Vec3::Z);
    }

    #[test]
    fn select_triangles_drops_unused_vertices() {
        let m = TriMesh::new(
            vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::Y,
                Vec3::new(5.0, 5.0, 5.0),
                Vec3::new(6.0, 5.0, 5.0),
                Vec3::new(5.0, 6.0, 5.0),
            ],
            vec![[0, 1, 2], [3, 4, 5]],
        );
        let s = m.select_triangles(&[false, true]);
        assert_eq!(s.positions.len(), 3);
        assert_eq!(s.triangles, vec![[0, 1, 2]]);
        assert_eq!(s.positions[0], Vec3::new(5.0, 5.0, 5.0));
    }

    #[test]
    fn validate_reports_out_of_range_index() {
        let m = TriMesh::new(vec![Vec3::ZERO; 3], vec![[0, 1, 7]]);
        let err = m.validate(Path::new("x.ply")).unwrap_err().to_string();
        assert!(err.contains("x.ply") && err.contains("vertex 7"), "{err}");
    }
}
