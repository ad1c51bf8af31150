//! The object alone: finding the surface an object stands on and cutting it
//! away.
//!
//! A capture trained without masks reconstructs whatever lies inside the
//! region of interest, and a real object stands on a table that crosses it:
//! the extracted surface is the object plus a disc of table top. The table
//! is told apart from a flat face of the object by its reach. A plane that
//! crosses the region's sphere at distance `h` from its centre meets the
//! sphere in a circle of radius `√(r² − h²)`, and a support plane's flat
//! part spans that circle, while an object's face stays well inside it.
//!
//! [`TriMesh::object_only`] finds the plane by RANSAC over the triangles'
//! own planes (area-weighted draws, inliers by distance and normal),
//! refines it by a least-squares fit of its inliers, removes every triangle
//! on or below it and everything outside the sphere, and keeps the largest
//! connected piece.
//!
//! A support that the surface barely holds (a run without masks often
//! leaves the table to the background model, and the SDF keeps at most a
//! ragged patch of it) can be given instead: [`SupportSearch::known`], e.g.
//! a plane fitted by [`fit_plane`] to points seen on the table. The
//! surface's own plane is used when it agrees with the known one.

use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;

use crate::TriMesh;

/// A plane `normal · x = offset` with `normal` of unit length; the object
/// stands on the side `normal · x > offset`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SupportPlane {
    /// Unit normal, pointing from the support towards the object.
    pub normal: Vec3,
    /// Signed distance of the plane from the origin along `normal`.
    pub offset: f32,
}

impl SupportPlane {
    /// Whether `other` is the same plane within the tolerances of `search`:
    /// normals within its angle, offsets (at its centre) within twice its
    /// distance tolerance.
    pub fn agrees_with(&self, other: &SupportPlane, search: &SupportSearch) -> bool {
        let cos_tol = search.angle_tolerance_deg.to_radians().cos();
        self.normal.dot(other.normal) >= cos_tol
            && (self.height(search.center) - other.height(search.center)).abs()
                <= 2.0 * search.distance_tolerance * search.radius
    }

    /// Signed distance of `p` above the plane (positive on the object's side).
    pub fn height(&self, p: Vec3) -> f32 {
        self.normal.dot(p) - self.offset
    }
}

/// Settings of [`TriMesh::object_only`]. Lengths are fractions of the
/// sphere's radius, so one setting serves any frame.
#[derive(Clone, Copy, Debug)]
pub struct SupportSearch {
    /// Centre of the region of interest.
    pub center: Vec3,
    /// Radius of the region of interest.
    pub radius: f32,
    /// Largest distance of an inlier triangle's centroid from the plane
    /// (fraction of the radius).
    pub distance_tolerance: f32,
    /// Largest angle between an inlier triangle's normal and the plane's
    /// normal (degrees).
    pub angle_tolerance_deg: f32,
    /// Smallest share of the surface's area a support plane must hold.
    pub min_area_fraction: f32,
    /// How far, as a fraction of the radius of the circle in which the plane
    /// meets the sphere, the inliers must reach from the circle's centre.
    pub min_reach: f32,
    /// Triangles closer than this to the plane on the object's side are cut
    /// with the plane (fraction of the radius), so that the rim where the
    /// table meets the object goes too.
    pub cut_margin: f32,
    /// Plane hypotheses drawn.
    pub hypotheses: usize,
    /// Seed of the draws.
    pub seed: u64,
    /// A support plane known from elsewhere (e.g. fitted to what the
    /// background shows): cut by it when the surface holds no plane that
    /// agrees with it (within the angle tolerance and twice the distance
    /// tolerance).
    pub known: Option<SupportPlane>,
}

impl SupportSearch {
    /// The defaults for a region of interest of the given centre and radius.
    pub fn new(center: Vec3, radius: f32) -> Self {
        SupportSearch {
            center,
            radius,
            distance_tolerance: 0.01,
            angle_tolerance_deg: 15.0,
            min_area_fraction: 0.1,
            min_reach: 0.8,
            cut_margin: 0.01,
            hypotheses: 512,
            seed: 0,
            known: None,
        }
    }
}

/// What [`TriMesh::object_only`] did.
#[derive(Clone, Debug)]
pub struct ObjectOnly {
    /// The object: inside the sphere, above the support, one connected piece.
    pub mesh: TriMesh,
    /// The support plane cut by, when there was one.
    pub plane: Option<SupportPlane>,
    /// Whether [`ObjectOnly::plane`] is the surface's own (else the known one).
    pub plane_from_surface: bool,
    /// Area removed as support (on or below the plane).
    pub support_area: f64,
    /// Area removed as outside the sphere.
    pub outside_area: f64,
    /// Area removed as pieces other than the largest.
    pub fragment_area: f64,
}

impl TriMesh {
    /// The largest plane that the surface holds and that spans the region of
    /// interest like a table top (see the module docs), or `None`.
    pub fn find_support_plane(&self, search: &SupportSearch) -> Option<SupportPlane> {
        let n = self.triangles.len();
        if n == 0 {
            return None;
        }
        let areas = self.triangle_areas();
        let total: f64 = areas.iter().sum();
        if total <= 0.0 {
            return None;
        }
        let normals = self.face_normals();
        let centroids: Vec<Vec3> = (0..n)
            .map(|t| {
                let [a, b, c] = self.triangle_corners(t);
                (a + b + c) / 3.0
            })
            .collect();
        let cumulative: Vec<f64> = areas
            .iter()
            .scan(0.0, |acc, a| {
                *acc += a;
                Some(*acc)
            })
            .collect();
        let tolerance = search.distance_tolerance * search.radius;
        let cos_tol = search.angle_tolerance_deg.to_radians().cos();
        let score = |normal: Vec3, offset: f32| -> f64 {
            (0..n)
                .filter(|&t| {
                    (normal.dot(centroids[t]) - offset).abs() <= tolerance
                        && normal.dot(normals[t]).abs() >= cos_tol
                })
                .map(|t| areas[t])
                .sum()
        };
        let mut rng = Pcg64Mcg::seed_from_u64(search.seed);
        let mut best: Option<(f64, Vec3, f32)> = None;
        for _ in 0..search.hypotheses {
            let u = rng.random::<f64>() * total;
            let t = cumulative.partition_point(|&c| c < u).min(n - 1);
            let normal = normals[t];
            if normal.length_squared() < 0.5 {
                continue;
            }
            let offset = normal.dot(centroids[t]);
            let s = score(normal, offset);
            if best.is_none_or(|(b, _, _)| s > b) {
                best = Some((s, normal, offset));
            }
        }
        let (_, normal, offset) = best?;
        // Least-squares refinement over the inliers: the plane through their
        // area-weighted mean, normal to their direction of least spread.
        let inliers: Vec<usize> = (0..n)
            .filter(|&t| {
                (normal.dot(centroids[t]) - offset).abs() <= tolerance
                    && normal.dot(normals[t]).abs() >= cos_tol
            })
            .collect();
        let weight: f64 = inliers.iter().map(|&t| areas[t]).sum();
        if weight < search.min_area_fraction as f64 * total {
            return None;
        }
        let mean = inliers
            .iter()
            .map(|&t| centroids[t].as_dvec3() * areas[t])
            .sum::<DVec3>()
            / weight;
        let mut cov = [[0.0f64; 3]; 3];
        for &t in &inliers {
            let d = centroids[t].as_dvec3() - mean;
            for (i, row) in cov.iter_mut().enumerate() {
                for (j, c) in row.iter_mut().enumerate() {
                    *c += areas[t] * d[i] * d[j];
                }
            }
        }
        let refined = least_spread_direction(cov, normal.as_dvec3());
        let normal = refined.as_vec3();
        let offset = normal.dot(mean.as_vec3());
        // A support reaches the sphere: its inliers span the circle in which
        // the plane meets it.
        let h = normal.dot(search.center) - offset;
        let circle = (search.radius * search.radius - h * h).max(0.0).sqrt();
        let foot = search.center - normal * h;
        let reach = inliers
            .iter()
            .map(|&t| {
                let p = centroids[t] - foot;
                (p - normal * normal.dot(p)).length()
            })
            .fold(0.0f32, f32::max);
        if circle <= 0.0 || reach < search.min_reach * circle {
            return None;
        }
        // The object stands on the side that holds most of the rest of the
        // surface, not counting what lies near the sphere (an extraction
        // clipped to the sphere closes the solid below a table with a cap of
        // the sphere, which can outweigh the object).
        let mut above = 0.0;
        let mut below = 0.0;
        for t in 0..n {
            if (centroids[t] - search.center).length() > 0.9 * search.radius {
                continue;
            }
            let d = normal.dot(centroids[t]) - offset;
            if d > tolerance {
                above += areas[t];
            } else if d < -tolerance {
                below += areas[t];
            }
        }
        Some(if above >= below {
            SupportPlane { normal, offset }
        } else {
            SupportPlane {
                normal: -normal,
                offset: -offset,
            }
        })
    }

    /// The object alone: triangles outside the sphere of `search` removed,
    /// the support plane (when [`TriMesh::find_support_plane`] finds one)
    /// and everything below it removed, then every piece but the largest.
    pub fn object_only(&self, search: &SupportSearch) -> ObjectOnly {
        let areas = self.triangle_areas();
        let found = self.find_support_plane(search);
        let (plane, plane_from_surface) = match (found, search.known) {
            (Some(f), Some(k)) if f.agrees_with(&k, search) => (Some(f), true),
            (_, Some(k)) => (Some(k), false),
            (f, None) => (f, f.is_some()),
        };
        let margin = (search.cut_margin + search.distance_tolerance) * search.radius;
        let mut keep = vec![true; self.triangles.len()];
        let (mut support_area, mut outside_area) = (0.0, 0.0);
        for (t, k) in keep.iter_mut().enumerate() {
            let [a, b, c] = self.triangle_corners(t);
            let centroid = (a + b + c) / 3.0;
            if (centroid - search.center).length() > search.radius {
                *k = false;
                outside_area += areas[t];
            } else if let Some(p) = plane
                && [a, b, c].iter().any(|&v| p.height(v) <= margin)
            {
                *k = false;
                support_area += areas[t];
            }
        }
        let cut = self.select_triangles(&keep);
        let before: f64 = cut.total_area();
        let mesh = cut.without_small_components(1.0);
        let fragment_area = before - mesh.total_area();
        ObjectOnly {
            mesh,
            plane,
            plane_from_surface,
            support_area,
            outside_area,
            fragment_area,
        }
    }
}

/// A plane fitted to points by RANSAC: of `hypotheses` planes through three
/// of the points (a fixed pseudo-random sequence from `seed`), the one with
/// the most points within `tolerance`, refined by a least-squares fit of
/// those points. Returns the plane (its normal's sign arbitrary) and its
/// inliers' indices, or `None` for fewer than three points or no plane.
pub fn fit_plane(
    points: &[Vec3],
    tolerance: f32,
    hypotheses: usize,
    seed: u64,
) -> Option<(SupportPlane, Vec<usize>)> {
    let n = points.len();
    if n < 3 {
        return None;
    }
    let mut rng = Pcg64Mcg::seed_from_u64(seed);
    let inliers_of = |normal: Vec3, offset: f32| -> Vec<usize> {
        (0..n)
            .filter(|&i| (normal.dot(points[i]) - offset).abs() <= tolerance)
            .collect()
    };
    let mut best: Option<(usize, Vec3, f32)> = None;
    for _ in 0..hypotheses {
        let [a, b, c] = [0; 3].map(|_| points[rng.random_range(0..n)]);
        let Some(normal) = (b - a).cross(c - a).try_normalize() else {
            continue;
        };
        let offset = normal.dot(a);
        let count = (0..n)
            .filter(|&i| (normal.dot(points[i]) - offset).abs() <= tolerance)
            .count();
        if best.is_none_or(|(k, _, _)| count > k) {
            best = Some((count, normal, offset));
        }
    }
    let (_, normal, offset) = best?;
    let inliers = inliers_of(normal, offset);
    let mean = inliers.iter().map(|&i| points[i].as_dvec3()).sum::<DVec3>() / inliers.len() as f64;
    let mut cov = [[0.0f64; 3]; 3];
    for &i in &inliers {
        let d = points[i].as_dvec3() - mean;
        for (r, row) in cov.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v += d[r] * d[c];
            }
        }
    }
    let normal = least_spread_direction(cov, normal.as_dvec3()).as_vec3();
    let offset = normal.dot(mean.as_vec3());
    let inliers = inliers_of(normal, offset);
    Some((SupportPlane { normal, offset }, inliers))
}

/// The eigenvector of the symmetric 3×3 matrix `m` with the smallest
/// eigenvalue, by inverse power iteration from `start` (a shift keeps the
/// iteration well posed when the smallest eigenvalue is 0).
fn least_spread_direction(m: [[f64; 3]; 3], start: DVec3) -> DVec3 {
    let trace = m[0][0] + m[1][1] + m[2][2];
    let shift = 1e-9 * trace.max(1e-300);
    let a = glam::DMat3::from_cols_array_2d(&m) + glam::DMat3::from_diagonal(DVec3::splat(shift));
    if a.determinant().abs() < 1e-300 {
        return start.normalize();
    }
    let inv = a.inverse();
    let mut v = start.normalize();
    for _ in 0..50 {
        let next = (inv * v).normalize();
        if !next.is_finite() {
            break;
        }
        v = next;
    }
    if v.dot(start) < 0.0 { -v } else { v }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A UV sphere of `radius` around `center`.
    fn sphere(center: Vec3, radius: f32, rings: u32, segments: u32) -> TriMesh {
        let mut positions = Vec::new();
        for i in 0..=rings {
            let theta = std::f32::consts::PI * i as f32 / rings as f32;
            for j in 0..segments {
                let phi = std::f32::consts::TAU * j as f32 / segments as f32;
                positions.push(
                    center
                        + radius
                            * Vec3::new(
                                theta.sin() * phi.cos(),
                                theta.cos(),
                                theta.sin() * phi.sin(),
                            ),
                );
            }
        }
        let mut triangles = Vec::new();
        for i in 0..rings {
            for j in 0..segments {
                let a = i * segments + j;
                let b = i * segments + (j + 1) % segments;
                let c = a + segments;
                let d = b + segments;
                triangles.push([a, c, b]);
                triangles.push([b, c, d]);
            }
        }
        TriMesh::new(positions, triangles).without_degenerate()
    }

    /// A square grid in the plane y = `y`, of half-width `half`, `n` cells a side.
    fn plane_grid(y: f32, half: f32, n: u32) -> TriMesh {
        let mut positions = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                let x = -half + 2.0 * half * i as f32 / n as f32;
                let z = -half + 2.0 * half * j as f32 / n as f32;
                positions.push(Vec3::new(x, y, z));
            }
        }
        let mut triangles = Vec::new();
        for i in 0..n {
            for j in 0..n {
                let a = i * (n + 1) + j;
                let b = a + 1;
                let c = a + n + 1;
                let d = c + 1;
                triangles.push([a, b, c]);
                triangles.push([b, d, c]);
            }
        }
        TriMesh::new(positions, triangles)
    }

    fn merged(a: &TriMesh, b: &TriMesh) -> TriMesh {
        let offset = a.positions.len() as u32;
        let mut positions = a.positions.clone();
        positions.extend(&b.positions);
        let mut triangles = a.triangles.clone();
        triangles.extend(b.triangles.iter().map(|t| t.map(|v| v + offset)));
        TriMesh::new(positions, triangles)
    }

    impl TriMesh {
        /// Drops the zero-area triangles a UV sphere has at its poles.
        fn without_degenerate(&self) -> TriMesh {
            let keep: Vec<bool> = self.triangle_areas().iter().map(|&a| a > 1e-12).collect();
            self.select_triangles(&keep)
        }
    }

    #[test]
    fn a_ball_on_a_table_loses_the_table_and_keeps_the_ball() {
        let ball = sphere(Vec3::new(0.1, -0.1, 0.0), 0.4, 24, 48);
        // The table top at y = −0.5 crosses the unit sphere and beyond it,
        // as marching cubes over the cube [−1, 1]³ would extract it.
        let table = plane_grid(-0.5, 1.0, 40);
        let scene = merged(&ball, &table);
        let result = scene.object_only(&SupportSearch::new(Vec3::ZERO, 1.0));
        let plane = result.plane.expect("the table is found");
        assert!(plane.normal.dot(Vec3::Y) > 0.999, "{plane:?}");
        assert!((plane.offset + 0.5).abs() < 1e-4, "{plane:?}");
        // Nothing on or below the table remains.
        for p in &result.mesh.positions {
            assert!(p.y > -0.5 + 0.01, "vertex {p} on the table");
        }
        // The ball is kept whole but for its cap within the cut margin (a cap
        // of height 0.02 is 2.5 % of it; the rings make it a little more).
        let ball_area = ball.total_area();
        let kept = result.mesh.total_area();
        assert!(
            kept > 0.95 * ball_area && kept <= ball_area * 1.0001,
            "{kept} of {ball_area}"
        );
        // The table inside the sphere went as support, the rest as outside.
        assert!(
            result.support_area > 0.9 * std::f64::consts::PI * 0.75,
            "{result:?}"
        );
        assert!(result.outside_area > 0.5, "{}", result.outside_area);
    }

    #[test]
    fn an_object_without_a_table_keeps_its_flat_face() {
        // A box whose bottom face is flat and large, but far from reaching the
        // sphere: no support plane.
        let ball = sphere(Vec3::ZERO, 0.5, 16, 32);
        let bottom = plane_grid(-0.45, 0.3, 10);
        let scene = merged(&ball, &bottom);
        let search = SupportSearch::new(Vec3::ZERO, 1.0);
        assert_eq!(scene.find_support_plane(&search), None);
        let result = scene.object_only(&search);
        assert_eq!(result.support_area, 0.0);
        // The largest piece (the ball) stays; the face is a separate piece.
        assert!((result.mesh.total_area() - ball.total_area()).abs() < 1e-6);
    }

    #[test]
    fn a_tilted_table_in_another_frame_is_found() {
        // The same scene in a world frame: scaled by 3, rotated, moved.
        let ball = sphere(Vec3::new(0.0, 0.0, 0.0), 0.4, 24, 48);
        let table = plane_grid(-0.4, 1.0, 40);
        let scene = merged(&ball, &table);
        let m = glam::Mat4::from_translation(Vec3::new(2.0, -1.0, 5.0))
            * glam::Mat4::from_axis_angle(Vec3::new(1.0, 0.0, 1.0).normalize(), 0.6)
            * glam::Mat4::from_scale(Vec3::splat(3.0));
        let world = scene.transformed(&m);
        let center = m.transform_point3(Vec3::ZERO);
        let result = world.object_only(&SupportSearch::new(center, 3.0));
        let plane = result.plane.expect("the table is found");
        let up = m.transform_vector3(Vec3::Y).normalize();
        assert!(plane.normal.dot(up) > 0.999, "{plane:?}");
        let table_point = m.transform_point3(Vec3::new(0.0, -0.4, 0.0));
        assert!(plane.height(table_point).abs() < 1e-3, "{plane:?}");
        let kept = result.mesh.total_area();
        let ball_area = 9.0 * ball.total_area();
        assert!(
            kept > 0.95 * ball_area && kept < 1.0001 * ball_area,
            "{kept} of {ball_area}"
        );
    }

    /// An open cylinder of `radius` around the y axis from `y0` up to `y1`.
    fn tube(radius: f32, y0: f32, y1: f32, rings: u32, segments: u32) -> TriMesh {
        let mut positions = Vec::new();
        for i in 0..=rings {
            let y = y0 + (y1 - y0) * i as f32 / rings as f32;
            for j in 0..segments {
                let phi = std::f32::consts::TAU * j as f32 / segments as f32;
                positions.push(Vec3::new(radius * phi.cos(), y, radius * phi.sin()));
            }
        }
        let mut triangles = Vec::new();
        for i in 0..rings {
            for j in 0..segments {
                let a = i * segments + j;
                let b = i * segments + (j + 1) % segments;
                triangles.push([a, a + segments, b]);
                triangles.push([b, a + segments, b + segments]);
            }
        }
        TriMesh::new(positions, triangles)
    }

    #[test]
    fn a_known_plane_cuts_what_the_surface_holds_below_it() {
        // A vase's wall that runs on below the table top (y = −0.5), with no
        // table in the surface: nothing to find, the known plane cuts.
        let wall = tube(0.3, -0.9, 0.5, 56, 48);
        let known = SupportPlane {
            normal: Vec3::Y,
            offset: -0.5,
        };
        let search = SupportSearch {
            known: Some(known),
            ..SupportSearch::new(Vec3::ZERO, 1.0)
        };
        assert_eq!(wall.find_support_plane(&search), None);
        let result = wall.object_only(&search);
        assert_eq!(result.plane, Some(known));
        assert!(!result.plane_from_surface);
        let lowest = result
            .mesh
            .positions
            .iter()
            .map(|p| p.y)
            .fold(f32::MAX, f32::min);
        assert!(lowest > -0.5 + 0.02 && lowest < -0.5 + 0.05, "{lowest}");
        // The wall above the cut is kept: 1.0 − 0.02 of its 1.4 height.
        let expected = std::f64::consts::TAU * 0.3 * 0.98;
        let kept = result.mesh.total_area();
        assert!((kept / expected - 1.0).abs() < 0.03, "{kept} vs {expected}");
        // Without the known plane, nothing is cut.
        let alone = wall.object_only(&SupportSearch::new(Vec3::ZERO, 1.0));
        assert_eq!(alone.plane, None);
    }

    #[test]
    fn the_surfaces_plane_is_kept_when_it_agrees_with_the_known_one() {
        let scene = merged(&sphere(Vec3::ZERO, 0.4, 24, 48), &plane_grid(-0.5, 1.0, 40));
        // Known a little off (0.01 lower, 2° tilted): the surface's own wins.
        let tilt = Vec3::new(0.0, 2f32.to_radians().cos(), 2f32.to_radians().sin());
        let near = SupportPlane {
            normal: tilt,
            offset: -0.51,
        };
        let search = |known| SupportSearch {
            known: Some(known),
            ..SupportSearch::new(Vec3::ZERO, 1.0)
        };
        let result = scene.object_only(&search(near));
        assert!(result.plane_from_surface);
        assert!((result.plane.unwrap().offset + 0.5).abs() < 1e-4);
        // Known far off (0.1 lower): the known one is cut by.
        let far = SupportPlane {
            normal: Vec3::Y,
            offset: -0.6,
        };
        let result = scene.object_only(&search(far));
        assert!(!result.plane_from_surface);
        assert_eq!(result.plane, Some(far));
    }

    #[test]
    fn a_plane_is_fitted_through_outliers() {
        // 300 points on y = 0.2x − 0.3 (noise ±0.005) among 200 scattered.
        let mut rng = Pcg64Mcg::seed_from_u64(7);
        let mut points = Vec::new();
        for _ in 0..300 {
            let (x, z) = (rng.random_range(-2.0..2.0), rng.random_range(-2.0..2.0));
            let noise = rng.random_range(-0.005..0.005);
            points.push(Vec3::new(x, 0.2 * x - 0.3 + noise, z));
        }
        for _ in 0..200 {
            points.push(Vec3::new(
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
                rng.random_range(-2.0..2.0),
            ));
        }
        let (plane, inliers) = fit_plane(&points, 0.02, 200, 0).expect("a plane");
        let truth = Vec3::new(-0.2, 1.0, 0.0).normalize();
        let sign = plane.normal.dot(truth).signum();
        assert!(sign * plane.normal.dot(truth) > 0.9999, "{plane:?}");
        // y = 0.2x − 0.3 ⇔ (−0.2, 1, 0)·p = −0.3
        assert!(
            (sign * plane.offset - (-0.3 / 1.04f32.sqrt())).abs() < 2e-3,
            "{plane:?}"
        );
        assert!(
            inliers.len() >= 300 && inliers.len() < 320,
            "{}",
            inliers.len()
        );
        assert!(inliers.iter().filter(|&&i| i < 300).count() == 300);
        assert_eq!(fit_plane(&points[..2], 0.02, 10, 0), None);
    }

    #[test]
    fn an_empty_mesh_has_no_support() {
        let empty = TriMesh::new(Vec::new(), Vec::new());
        let search = SupportSearch::new(Vec3::ZERO, 1.0);
        assert_eq!(empty.find_support_plane(&search), None);
        assert!(empty.object_only(&search).mesh.triangles.is_empty());
    }
}
