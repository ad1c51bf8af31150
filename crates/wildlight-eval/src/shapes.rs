//! Simple analytic meshes for tests and benchmarks: icospheres, tori,
//! boxes and flat patches. All are closed and outward-oriented except the
//! patch.

use glam::Vec3;
use std::collections::HashMap;
use wildlight_mesh::TriMesh;

/// A unit-radius icosphere: an icosahedron subdivided `subdivisions` times
/// (each step splits every triangle into four) with all vertices projected
/// onto the unit sphere. It has 20·4^subdivisions triangles.
pub fn icosphere(subdivisions: u32) -> TriMesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vec3::from_array(*p).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoint: HashMap<(u32, u32), u32> = HashMap::new();
        let mut mid = |a: u32, b: u32, positions: &mut Vec<Vec3>| {
            *midpoint.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let p = (positions[a as usize] + positions[b as usize]).normalize();
                positions.push(p);
                (positions.len() - 1) as u32
            })
        };
        let mut next = Vec::with_capacity(triangles.len() * 4);
        for [a, b, c] in triangles {
            let ab = mid(a, b, &mut positions);
            let bc = mid(b, c, &mut positions);
            let ca = mid(c, a, &mut positions);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    TriMesh::new(positions, triangles)
}

/// A torus around the z axis with tube centre radius `major` and tube
/// radius `minor`, sampled on a `segments_major` × `segments_minor` grid
/// (2·segments_major·segments_minor triangles). `bump(u, v)` adds a radial
/// offset to the tube radius at angles u (around z) and v (around the tube),
/// both in [0, 2π); pass `|_, _| 0.0` for a plain torus.
pub fn torus(
    major: f32,
    minor: f32,
    segments_major: u32,
    segments_minor: u32,
    bump: impl Fn(f32, f32) -> f32,
) -> TriMesh {
    let tau = std::f32::consts::TAU;
    let mut positions = Vec::with_capacity((segments_major * segments_minor) as usize);
    for i in 0..segments_major {
        let u = tau * i as f32 / segments_major as f32;
        for j in 0..segments_minor {
            let v = tau * j as f32 / segments_minor as f32;
            let r = minor + bump(u, v);
            let ring = major + r * v.cos();
            positions.push(Vec3::new(ring * u.cos(), ring * u.sin(), r * v.sin()));
        }
    }
    let index = |i: u32, j: u32| (i % segments_major) * segments_minor + (j % segments_minor);
    TriMesh::new(
        positions,
        grid_triangles(segments_major, segments_minor, index),
    )
}

/// Two triangles (a, b, c) and (a, c, d) for each cell (i, j) of an
/// `nu` × `nv` grid of quads, where `index(i, j)` is the vertex at grid
/// point (i, j) (a = (i, j), b = (i + 1, j), c = (i + 1, j + 1),
/// d = (i, j + 1)); a closed grid wraps its indices in `index`.
fn grid_triangles(nu: u32, nv: u32, index: impl Fn(u32, u32) -> u32) -> Vec<[u32; 3]> {
    let mut triangles = Vec::with_capacity((2 * nu * nv) as usize);
    for i in 0..nu {
        for j in 0..nv {
            let (a, b, c, d) = (
                index(i, j),
                index(i + 1, j),
                index(i + 1, j + 1),
                index(i, j + 1),
            );
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    triangles
}

/// An axis-aligned box centred at `center` with half extents `half`
/// (12 triangles, 8 shared vertices, outward normals).
pub fn axis_box(center: Vec3, half: Vec3) -> TriMesh {
    let positions = (0..8)
        .map(|i| {
            let s = Vec3::new(
                if i & 1 == 0 { -1.0 } else { 1.0 },
                if i & 2 == 0 { -1.0 } else { 1.0 },
                if i & 4 == 0 { -1.0 } else { 1.0 },
            );
            center + s * half
        })
        .collect();
    let triangles = vec![
        // -x, +x
        [0, 4, 6],
        [0, 6, 2],
        [1, 3, 7],
        [1, 7, 5],
        // -y, +y
        [0, 1, 5],
        [0, 5, 4],
        [2, 6, 7],
        [2, 7, 3],
        // -z, +z
        [0, 2, 3],
        [0, 3, 1],
        [4, 5, 7],
        [4, 7, 6],
    ];
    TriMesh::new(positions, triangles)
}

/// A flat rectangle `[x0, x0 + width] × [y0, y0 + height]` in the plane
/// z = `z`, split into `nx` × `ny` cells of two triangles each, facing +z.
pub fn flat_patch(origin: Vec3, width: f32, height: f32, nx: u32, ny: u32) -> TriMesh {
    let mut positions = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            positions.push(
                origin
                    + Vec3::new(
                        width * i as f32 / nx as f32,
                        height * j as f32 / ny as f32,
                        0.0,
                    ),
            );
        }
    }
    TriMesh::new(positions, grid_triangles(nx, ny, |i, j| j * (nx + 1) + i))
}

/// `count` points spread evenly over a sphere of radius `radius` around
/// `center` (a Fibonacci lattice), e.g. camera centres around an object.
pub fn fibonacci_sphere(count: usize, radius: f32, center: Vec3) -> Vec<Vec3> {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    (0..count)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / count as f32;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f32;
            center + radius * Vec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_have_the_expected_size_and_area() {
        let s = icosphere(3);
        assert_eq!(s.triangles.len(), 20 * 64);
        // Inscribed polyhedron: area slightly below 4π, converging to it.
        let a = s.total_area();
        assert!(a < 4.0 * std::f64::consts::PI && a > 0.99 * 4.0 * std::f64::consts::PI);
        assert!(s.positions.iter().all(|p| (p.length() - 1.0).abs() < 1e-6));
        assert!(
            s.face_normals()
                .iter()
                .zip(&s.triangles)
                .all(|(n, t)| { n.dot(s.positions[t[0] as usize]) > 0.0 })
        );

        let b = axis_box(Vec3::ZERO, Vec3::new(0.5, 1.0, 1.5));
        assert!((b.total_area() - 2.0 * (1.0 * 2.0 + 1.0 * 3.0 + 2.0 * 3.0)).abs() < 1e-9);
        for (t, n) in b.face_normals().iter().enumerate() {
            let c = b.triangle_corners(t).iter().sum::<Vec3>() / 3.0;
            assert!(n.dot(c) > 0.0, "box triangle {t} faces inwards");
        }

        let t = torus(1.0, 0.25, 64, 32, |_, _| 0.0);
        assert_eq!(t.triangles.len(), 2 * 64 * 32);
        // Torus area 4π² R r; the polyhedron is within 1 %.
        let exact = 4.0 * std::f64::consts::PI.powi(2) * 0.25;
        assert!((t.total_area() - exact).abs() < 0.01 * exact);

        let p = flat_patch(Vec3::ZERO, 2.0, 3.0, 4, 5);
        assert!((p.total_area() - 6.0).abs() < 1e-9);
        assert!(p.face_normals().iter().all(|n| *n == Vec3::Z));

        let f = fibonacci_sphere(64, 3.0, Vec3::X);
        assert!(
            f.iter()
                .all(|c| ((*c - Vec3::X).length() - 3.0).abs() < 1e-5)
        );
        let mean = f.iter().sum::<Vec3>() / 64.0;
        assert!((mean - Vec3::X).length() < 0.05);
    }
}
