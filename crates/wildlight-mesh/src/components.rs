//! Connected components of a mesh and removal of small ones.

use crate::TriMesh;

/// Union-find over vertex indices.
struct DisjointSets {
    parent: Vec<u32>,
}

impl DisjointSets {
    fn new(n: usize) -> Self {
        DisjointSets {
            parent: (0..n as u32).collect(),
        }
    }

    fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let grand = self.parent[self.parent[x as usize] as usize];
            self.parent[x as usize] = grand;
            x = grand;
        }
        x
    }

    fn union(&mut self, a: u32, b: u32) {
        let (ra, rb) = (self.find(a), self.find(b));
        if ra != rb {
            self.parent[ra.max(rb) as usize] = ra.min(rb);
        }
    }
}

impl TriMesh {
    /// Labels every triangle with its connected component (triangles that
    /// share a vertex are connected). Labels are 0..count, numbered in the
    /// order components first appear in `triangles`. Returns
    /// `(labels, count)`.
    pub fn triangle_components(&self) -> (Vec<u32>, usize) {
        let mut sets = DisjointSets::new(self.positions.len());
        for &[a, b, c] in &self.triangles {
            sets.union(a, b);
            sets.union(b, c);
        }
        let mut label_of_root = vec![u32::MAX; self.positions.len()];
        let mut count = 0usize;
        let labels = self
            .triangles
            .iter()
            .map(|t| {
                let root = sets.find(t[0]) as usize;
                if label_of_root[root] == u32::MAX {
                    label_of_root[root] = count as u32;
                    count += 1;
                }
                label_of_root[root]
            })
            .collect();
        (labels, count)
    }

    /// The surface area of every connected component, indexed by the labels
    /// of [`TriMesh::triangle_components`].
    pub fn component_areas(&self) -> Vec<f64> {
        let (labels, count) = self.triangle_components();
        let mut areas = vec![0.0; count];
        for (label, area) in labels.iter().zip(self.triangle_areas()) {
            areas[*label as usize] += area;
        }
        areas
    }

    /// Removes connected components whose area is below
    /// `min_fraction` × the area of the largest component (so `1.0` keeps
    /// only the largest piece, `0.0` keeps everything). Unused vertices are
    /// removed.
    pub fn without_small_components(&self, min_fraction: f64) -> TriMesh {
        let (labels, _) = self.triangle_components();
        let areas = self.component_areas();
        let largest = areas.iter().cloned().fold(0.0, f64::max);
        let keep: Vec<bool> = labels
            .iter()
            .map(|&l| areas[l as usize] >= min_fraction * largest)
            .collect();
        self.select_triangles(&keep)
    }
}

#[cfg(test)]
mod tests {
    use crate::TriMesh;
    use glam::Vec3;

    fn two_pieces() -> TriMesh {
        // A unit quad (area 1) and a far small triangle (area 0.005).
        TriMesh::new(
            vec![
                Vec3::ZERO,
                Vec3::X,
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::Y,
                Vec3::new(5.0, 0.0, 0.0),
                Vec3::new(5.1, 0.0, 0.0),
                Vec3::new(5.0, 0.1, 0.0),
            ],
            vec![[0, 1, 2], [4, 5, 6], [0, 2, 3]],
        )
    }

    #[test]
    fn components_are_labelled_and_measured() {
        let m = two_pieces();
        assert_eq!(m.triangle_components(), (vec![0, 1, 0], 2));
        let areas = m.component_areas();
        assert!((areas[0] - 1.0).abs() < 1e-9);
        assert!((areas[1] - 0.005).abs() < 1e-7);
    }

    #[test]
    fn small_component_is_removed() {
        let m = two_pieces();
        let big = m.without_small_components(0.01);
        assert_eq!(big.triangles.len(), 2);
        assert_eq!(big.positions.len(), 4);
        assert!((big.total_area() - 1.0).abs() < 1e-9);
        // A threshold below the small piece's relative area (0.5 %) keeps it.
        assert_eq!(m.without_small_components(0.004).triangles.len(), 3);
    }
}
