//! Welding of coincident vertices (marching-cubes triangle soups).

use crate::TriMesh;
use std::collections::HashMap;

impl TriMesh {
    /// Merges vertices closer than `tolerance` (Euclidean distance) and
    /// drops the triangles that become degenerate (two equal corners).
    ///
    /// Vertices are visited in order; each one joins the first earlier
    /// representative within `tolerance` (found through a hash grid of cell
    /// size `tolerance`), or becomes a representative itself. A merged vertex
    /// keeps its representative's position and attributes. With
    /// `tolerance = 0` only exactly equal positions merge.
    pub fn welded(&self, tolerance: f32) -> TriMesh {
        let tolerance = tolerance.max(0.0);
        let cell_size = if tolerance > 0.0 { tolerance } else { 1.0 };
        let cell = |p: glam::Vec3| -> [i64; 3] { (p / cell_size).floor().as_i64vec3().to_array() };
        let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        let mut representative_of = vec![0u32; self.positions.len()];
        let mut order = Vec::new();
        for (i, &p) in self.positions.iter().enumerate() {
            let [cx, cy, cz] = cell(p);
            let mut found = None;
            'search: for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        let Some(members) = grid.get(&[cx + dx, cy + dy, cz + dz]) else {
                            continue;
                        };
                        for &m in members {
                            let q = self.positions[order[m as usize]];
                            if p.distance(q) <= tolerance {
                                found = Some(m);
                                break 'search;
                            }
                        }
                    }
                }
            }
            representative_of[i] = found.unwrap_or_else(|| {
                let m = order.len() as u32;
                order.push(i);
                grid.entry([cx, cy, cz]).or_default().push(m);
                m
            });
        }
        let mut welded = self.remapped(&order, &representative_of);
        welded
            .triangles
            .retain(|[a, b, c]| a != b && b != c && a != c);
        welded.without_unused_vertices()
    }
}

#[cfg(test)]
mod tests {
    use crate::TriMesh;
    use glam::Vec3;

    #[test]
    fn soup_of_two_triangles_welds_into_a_quad() {
        // Two triangles sharing an edge, stored as a soup with a tiny jitter.
        let e = 1e-6;
        let soup = TriMesh::new(
            vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::Y,
                Vec3::new(1.0 + e, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0 - e, 0.0),
            ],
            vec![[0, 1, 2], [3, 4, 5]],
        );
        let welded = soup.welded(1e-5);
        assert_eq!(welded.positions.len(), 4);
        assert_eq!(welded.triangles, vec![[0, 1, 2], [1, 3, 2]]);
        // Without tolerance the jittered copies stay apart.
        assert_eq!(soup.welded(0.0).positions.len(), 6);
    }

    #[test]
    fn collapsed_triangles_are_dropped() {
        let m = TriMesh::new(
            vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 0.001, 0.0), Vec3::Y],
            vec![[0, 1, 2], [0, 1, 3]],
        );
        let w = m.welded(0.01);
        assert_eq!(w.triangles.len(), 1);
        assert_eq!(w.positions.len(), 3);
        assert!((w.total_area() - 0.5).abs() < 1e-9);
    }
}
