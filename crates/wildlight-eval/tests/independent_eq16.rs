//! Agreement with an independent implementation of appendix eq. 16:
//! brute-force point-to-triangle distances in f64 (no BVH, no parry3d), a
//! different random generator (SplitMix64) and a different way of drawing
//! uniform points in a triangle (parallelogram folding).

use glam::{DVec3, Mat4, Quat, Vec3};
use rayon::prelude::*;
use wildlight_eval::shapes::{icosphere, torus};
use wildlight_eval::{SurfaceDistanceOptions, surface_distance};
use wildlight_mesh::TriMesh;

struct SplitMix64(u64);

impl SplitMix64 {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn triangles_f64(mesh: &TriMesh) -> Vec<[DVec3; 3]> {
    mesh.triangles
        .iter()
        .map(|t| t.map(|v| mesh.positions[v as usize].as_dvec3()))
        .collect()
}

/// Nearest distance from p to the segment [a, b].
fn segment_distance(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let s = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    (a + s * ab - p).length()
}

/// Nearest distance from p to the triangle: the plane distance if the
/// projection falls inside, otherwise the nearest of the three edges.
fn triangle_distance(p: DVec3, [a, b, c]: [DVec3; 3]) -> f64 {
    let n = (b - a).cross(c - a);
    let q = p - n * (p - a).dot(n) / n.length_squared();
    let inside = [(a, b), (b, c), (c, a)]
        .iter()
        .all(|&(u, v)| (v - u).cross(q - u).dot(n) >= 0.0);
    if inside {
        (p - q).length()
    } else {
        segment_distance(p, a, b)
            .min(segment_distance(p, b, c))
            .min(segment_distance(p, c, a))
    }
}

fn surface_distance_brute(p: DVec3, tris: &[[DVec3; 3]]) -> f64 {
    tris.iter()
        .map(|t| triangle_distance(p, *t))
        .fold(f64::INFINITY, f64::min)
}

fn uniform_point(tris: &[[DVec3; 3]], areas: &[f64], total: f64, rng: &mut SplitMix64) -> DVec3 {
    let mut target = rng.next_f64() * total;
    let mut pick = tris.len() - 1;
    for (i, a) in areas.iter().enumerate() {
        if target < *a {
            pick = i;
            break;
        }
        target -= a;
    }
    let (mut u, mut v) = (rng.next_f64(), rng.next_f64());
    if u + v > 1.0 {
        (u, v) = (1.0 - u, 1.0 - v);
    }
    let [a, b, c] = tris[pick];
    a + u * (b - a) + v * (c - a)
}

/// Eq. 16 by brute force: (mean, median) of ½(d(x₁,S₂) + d(x₂,S₁)).
fn brute_force_eq16(s1: &TriMesh, s2: &TriMesh, pairs: usize, seed: u64) -> (f64, f64) {
    let (t1, t2) = (triangles_f64(s1), triangles_f64(s2));
    let area = |t: &[DVec3; 3]| 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length();
    let a1: Vec<f64> = t1.iter().map(area).collect();
    let a2: Vec<f64> = t2.iter().map(area).collect();
    let (total1, total2) = (a1.iter().sum(), a2.iter().sum());
    let mut rng = SplitMix64(seed);
    let points: Vec<(DVec3, DVec3)> = (0..pairs)
        .map(|_| {
            let x1 = uniform_point(&t1, &a1, total1, &mut rng);
            let x2 = uniform_point(&t2, &a2, total2, &mut rng);
            (x1, x2)
        })
        .collect();
    let mut values: Vec<f64> = points
        .par_iter()
        .map(|&(x1, x2)| 0.5 * (surface_distance_brute(x1, &t2) + surface_distance_brute(x2, &t1)))
        .collect();
    values.sort_by(f64::total_cmp);
    let mean = values.iter().sum::<f64>() / pairs as f64;
    (mean, values[pairs / 2])
}

/// Our eq. 16 and the brute-force one (10 000 pairs, `seed`) on `s1`, `s2`:
/// mean and median agree within 2 %. Returns the brute-force mean.
fn assert_agrees_with_brute_force(s1: &TriMesh, s2: &TriMesh, seed: u64) -> f64 {
    let (mean, median) = brute_force_eq16(s1, s2, 10_000, seed);
    let ours = surface_distance(s1, s2, &SurfaceDistanceOptions::default()).unwrap();
    eprintln!(
        "ours {} / {}, brute force {mean} / {median}",
        ours.mean, ours.median
    );
    assert!(
        (ours.mean - mean).abs() < 0.02 * mean,
        "{} vs {mean}",
        ours.mean
    );
    assert!(
        (ours.median - median).abs() < 0.02 * median,
        "{} vs {median}",
        ours.median
    );
    mean
}

#[test]
fn deformed_sphere_agrees_with_brute_force_within_two_percent() {
    let s1 = icosphere(2);
    let s2 = s1.transformed(
        &(Mat4::from_translation(Vec3::new(0.05, -0.02, 0.0))
            * Mat4::from_quat(Quat::from_rotation_y(0.3))
            * Mat4::from_scale(Vec3::new(1.1, 0.9, 1.0))),
    );
    let mean = assert_agrees_with_brute_force(&s1, &s2, 11);
    // The distance is of the order of the deformation, not a trivial value.
    assert!(mean > 0.02 && mean < 0.1, "{mean}");
}

#[test]
fn torus_against_a_bumpy_torus_agrees_with_brute_force() {
    let s1 = torus(1.0, 0.3, 24, 12, |_, _| 0.0);
    let s2 = torus(1.0, 0.3, 20, 10, |u, v| {
        0.05 * (3.0 * u).sin() * (2.0 * v).cos()
    });
    assert_agrees_with_brute_force(&s1, &s2, 12);
}
