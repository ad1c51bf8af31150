//! Mesh helpers shared by the integration tests.

// Every test binary compiles this module but uses only some of its helpers.
#![allow(dead_code)]

use wildlight_mesh::TriMesh;

/// One mesh holding the triangles of `a` followed by those of `b` (the
/// vertices of `b` renumbered after those of `a`).
pub fn merge(a: &TriMesh, b: &TriMesh) -> TriMesh {
    let offset = a.positions.len() as u32;
    let mut m = a.clone();
    m.positions.extend(&b.positions);
    m.triangles
        .extend(b.triangles.iter().map(|t| t.map(|v| v + offset)));
    m
}
