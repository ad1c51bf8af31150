//! Meshing of a signed distance function by surface nets on a regular grid.
//!
//! Each grid cell whose corners change sign gets one vertex: the mean of
//! the edge crossings, then moved onto the zero level set by a few Newton
//! steps along the gradient (kept inside its cell). Each grid edge with a
//! sign change becomes a quad between the four cells around it, split into
//! two triangles along the shorter diagonal. Vertices are shared by
//! construction (no welding needed), triangles are oriented with their
//! normals pointing to positive distance (outside), and the vertex normals
//! are the normalized gradient of the distance function.

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use wildlight_mesh::TriMesh;

use crate::sdf::gradient;

/// Meshes the zero level set of `f` inside the cube [−half, half]³ with
/// `resolution` grid points per axis. The surface must stay inside the cube.
pub fn mesh_sdf<F>(f: &F, half: f64, resolution: usize) -> TriMesh
where
    F: Fn(DVec3) -> f64 + Sync,
{
    let n = resolution.max(4);
    let h = 2.0 * half / (n - 1) as f64;
    let origin = DVec3::splat(-half);
    let point =
        |i: usize, j: usize, k: usize| origin + DVec3::new(i as f64, j as f64, k as f64) * h;
    let idx = |i: usize, j: usize, k: usize| i + n * (j + n * k);

    // Distance at every grid point, slab by slab in parallel.
    let mut values = vec![0.0f64; n * n * n];
    values
        .par_chunks_mut(n * n)
        .enumerate()
        .for_each(|(k, slab)| {
            for j in 0..n {
                for i in 0..n {
                    slab[i + n * j] = f(point(i, j, k));
                }
            }
        });

    // Active cells (corner signs differ).
    let m = n - 1;
    let cell_idx = |i: usize, j: usize, k: usize| i + m * (j + m * k);
    let active: Vec<Vec<usize>> = (0..m)
        .into_par_iter()
        .map(|k| {
            let mut list = Vec::new();
            for j in 0..m {
                for i in 0..m {
                    let mut inside = 0;
                    for c in 0..8 {
                        let v = values[idx(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2))];
                        inside += (v < 0.0) as u32;
                    }
                    if inside != 0 && inside != 8 {
                        list.push(cell_idx(i, j, k));
                    }
                }
            }
            list
        })
        .collect();
    let active: Vec<usize> = active.into_iter().flatten().collect();
    let mut cell_vertex = vec![u32::MAX; m * m * m];
    for (v, &c) in active.iter().enumerate() {
        cell_vertex[c] = v as u32;
    }

    // Vertex positions and normals.
    const EDGES: [(usize, usize); 12] = [
        (0, 1),
        (2, 3),
        (4, 5),
        (6, 7),
        (0, 2),
        (1, 3),
        (4, 6),
        (5, 7),
        (0, 4),
        (1, 5),
        (2, 6),
        (3, 7),
    ];
    let verts: Vec<(Vec3, Vec3)> = active
        .par_iter()
        .map(|&c| {
            let i = c % m;
            let j = (c / m) % m;
            let k = c / (m * m);
            let corner = |q: usize| (i + (q & 1), j + ((q >> 1) & 1), k + (q >> 2));
            let mut sum = DVec3::ZERO;
            let mut count = 0.0;
            for (a, b) in EDGES {
                let (ai, aj, ak) = corner(a);
                let (bi, bj, bk) = corner(b);
                let va = values[idx(ai, aj, ak)];
                let vb = values[idx(bi, bj, bk)];
                if (va < 0.0) != (vb < 0.0) {
                    let t = va / (va - vb);
                    sum += point(ai, aj, ak).lerp(point(bi, bj, bk), t);
                    count += 1.0;
                }
            }
            let lo = point(i, j, k) - DVec3::splat(0.05 * h);
            let hi = point(i + 1, j + 1, k + 1) + DVec3::splat(0.05 * h);
            let mut p = sum / count;
            let eps = 1e-3 * h;
            for _ in 0..4 {
                let d = f(p);
                let g = gradient(f, p, eps);
                let g2 = g.length_squared();
                if !(g2 > 1e-12) {
                    break;
                }
                p = (p - d * g / g2).clamp(lo, hi);
            }
            let normal = gradient(f, p, eps).try_normalize().unwrap_or(DVec3::Z);
            (p.as_vec3(), normal.as_vec3())
        })
        .collect();

    // Quads around sign-changing edges whose four cells exist.
    let mut triangles: Vec<[u32; 3]> = Vec::with_capacity(2 * verts.len());
    let positions: Vec<Vec3> = verts.iter().map(|v| v.0).collect();
    let mut emit = |q: [u32; 4]| {
        let [a, b, c, d] = q.map(|v| positions[v as usize]);
        if (a - c).length_squared() <= (b - d).length_squared() {
            triangles.push([q[0], q[1], q[2]]);
            triangles.push([q[0], q[2], q[3]]);
        } else {
            triangles.push([q[0], q[1], q[3]]);
            triangles.push([q[1], q[2], q[3]]);
        }
    };
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let v0 = values[idx(i, j, k)];
                // Edge along axis a from (i,j,k); its cells are offset by −1 in the
                // two other axes (u, w) with (a, u, w) a cyclic permutation.
                for axis in 0..3 {
                    let (ni, nj, nk) = match axis {
                        0 => (i + 1, j, k),
                        1 => (i, j + 1, k),
                        _ => (i, j, k + 1),
                    };
                    if ni >= n || nj >= n || nk >= n {
                        continue;
                    }
                    let v1 = values[idx(ni, nj, nk)];
                    if (v0 < 0.0) == (v1 < 0.0) {
                        continue;
                    }
                    let (u0, w0) = match axis {
                        0 => (j, k),
                        1 => (k, i),
                        _ => (i, j),
                    };
                    if u0 == 0 || w0 == 0 || u0 >= m || w0 >= m {
                        continue;
                    }
                    let cell = |du: usize, dw: usize| {
                        let (u, w) = (u0 - 1 + du, w0 - 1 + dw);
                        let (ci, cj, ck) = match axis {
                            0 => (i, u, w),
                            1 => (w, j, u),
                            _ => (u, w, k),
                        };
                        cell_vertex[cell_idx(ci, cj, ck)]
                    };
                    let q = [cell(0, 0), cell(1, 0), cell(1, 1), cell(0, 1)];
                    if q.contains(&u32::MAX) {
                        continue;
                    }
                    if v0 < 0.0 {
                        emit(q);
                    } else {
                        emit([q[3], q[2], q[1], q[0]]);
                    }
                }
            }
        }
    }
    let mut mesh = TriMesh::new(positions, triangles);
    mesh.normals = Some(verts.iter().map(|v| v.1).collect());
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sdf::{sphere, torus_y};

    fn signed_volume(mesh: &TriMesh) -> f64 {
        mesh.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| mesh.positions[v as usize].as_dvec3());
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    #[test]
    fn sphere_mesh_is_closed_outward_and_on_the_surface() {
        let r = 0.5;
        let mesh = mesh_sdf(&|p| sphere(p, r), 0.8, 48);
        let vol = signed_volume(&mesh);
        let exact = 4.0 / 3.0 * std::f64::consts::PI * r * r * r;
        assert!(
            (vol - exact).abs() < 0.01 * exact,
            "volume {vol} vs {exact}"
        );
        for p in &mesh.positions {
            assert!((p.length() as f64 - r).abs() < 1e-5, "{p:?}");
        }
        // Closed: every edge is shared by exactly two triangles, in opposite directions.
        let mut edges = std::collections::HashMap::new();
        for t in &mesh.triangles {
            for e in 0..3 {
                *edges.entry((t[e], t[(e + 1) % 3])).or_insert(0) += 1;
            }
        }
        for (&(a, b), &count) in &edges {
            assert_eq!(count, 1);
            assert_eq!(edges.get(&(b, a)), Some(&1), "edge {a}-{b} is open");
        }
        // Face normals agree with the vertex normals (outward).
        for (t, fnrm) in mesh.triangles.iter().zip(mesh.face_normals()) {
            let vn = mesh.normals.as_ref().unwrap()[t[0] as usize];
            assert!(vn.dot(fnrm) > 0.5);
        }
    }

    #[test]
    fn torus_has_genus_one() {
        let mesh = mesh_sdf(&|p| torus_y(p, 0.5, 0.15), 0.8, 64);
        let v = mesh.positions.len() as i64;
        let f = mesh.triangles.len() as i64;
        let e = f * 3 / 2;
        assert_eq!(v - e + f, 0, "Euler characteristic");
        let exact = 2.0 * std::f64::consts::PI.powi(2) * 0.5 * 0.15 * 0.15;
        assert!((signed_volume(&mesh) - exact).abs() < 0.02 * exact);
    }
}
