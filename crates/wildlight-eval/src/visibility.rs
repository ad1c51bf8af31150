//! Restriction of a mesh to the surface that at least one camera sees
//! (SPEC §7: "restricted to their visible surface").
//!
//! Visibility is decided **per triangle**. A triangle counts as visible when
//! at least one of its seven test points is seen by at least one camera:
//! the centroid, the three points at barycentrics (0.8, 0.1, 0.1) near the
//! corners and the three points at (0.45, 0.45, 0.1) near the edge
//! midpoints.
//!
//! What "seen" means depends on whether the camera's image is known:
//!
//! - **A capture camera** (a [`Frustum`] is given) sees what its pixels
//!   see. Its depth image is rendered first: one ray through every pixel
//!   centre, the depth of the first triangle hit (infinite where the ray
//!   misses). A point is seen when it projects into the image and is no
//!   deeper than the deepest of the four pixel centres around its
//!   projection, up to a relative tolerance of [`DEPTH_TOLERANCE`] (a
//!   shadow-map test). For a plane the depth of a point lies between the
//!   depths at the surrounding pixel centres (its inverse is affine in the
//!   image), so a visible surface passes without bias; taking the deepest
//!   of the four counts the one-pixel band along an occluding edge as seen.
//!   A gap narrower than a pixel that no pixel centre looks through hides
//!   what is behind it, as it does in the photographs. (A test against the
//!   exact ray from the camera centre would count a surface seen through
//!   any hairline crack; two extractions of one level set at different
//!   resolutions then differ in whole grazing strips behind thin parts.)
//! - **A camera without an image** ([`Viewpoint::omnidirectional`]) sees a
//!   point when the segment from its centre to the point crosses no
//!   triangle of the same mesh before it (closer than the point minus a
//!   tolerance of 1e-5 × the mesh's bounding-box diagonal plus 1e-6 × the
//!   segment length).
//!
//! Why per triangle rather than rejecting individual samples: the restricted
//! surface must serve both as the set x₁ is drawn from and as the target S₁
//! that x₂ is measured against; a set of whole triangles is itself a mesh,
//! so both roles use the same BVH machinery. The price is that a triangle
//! straddling the boundary of the visible region counts whole (or not at
//! all when none of its test points is seen); the discrepancy is confined
//! to a band one triangle wide along that boundary, which is negligible for
//! meshes whose triangles are small compared with the object (marching
//! cubes output, scanned meshes).
//!
//! Each mesh occludes only itself: the predicted and the ground-truth mesh
//! are restricted independently.
//!
//! Shortcut for closed pieces: when a connected component is closed (every
//! edge shared by exactly two of its triangles with opposite directions),
//! a camera behind the plane of one of its triangles cannot see that
//! triangle (the ray would have to leave the solid at the point, so it
//! crossed the surface before), and such cameras are skipped. "Behind" is
//! taken with respect to the component's outward side, found from the sign
//! of its enclosed volume, so inward-oriented meshes are handled too. This
//! assumes the cameras are outside the object, as they are in a capture.
//! Open components are always tested with every camera.

use crate::EvalError;
use glam::{DMat3, DMat4, DVec3, Vec3};
use parry3d::query::{Ray, RayCast};
use rayon::prelude::*;
use std::collections::HashMap;
use wildlight_mesh::TriMesh;

/// The image rectangle of a camera, to tell whether a point is in view.
#[derive(Clone, Debug)]
pub struct Frustum {
    /// Projection from the mesh frame to homogeneous pixel coordinates
    /// (rows 0..3 used: (u, v, w) = P·(x, 1); pixel = (u/w, v/w), w > 0 in
    /// front of the camera). For world-frame meshes this is `world_mat`; for
    /// normalized-frame meshes `world_mat · scale_mat` (SPEC §5).
    pub projection: DMat4,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

impl Frustum {
    /// Whether `p` projects in front of the camera into the image rectangle
    /// `[-0.5, width - 0.5] × [-0.5, height - 0.5]` (pixel centres are at
    /// integer coordinates, SPEC §5).
    pub fn contains(&self, p: Vec3) -> bool {
        self.project(p).is_some()
    }

    /// The pixel position (x, y) and depth w of `p` when it is in view (see
    /// [`Frustum::contains`]).
    fn project(&self, p: Vec3) -> Option<(f64, f64, f64)> {
        let h = self.projection * p.as_dvec3().extend(1.0);
        if h.z <= 0.0 {
            return None;
        }
        let (x, y) = (h.x / h.z, h.y / h.z);
        let inside =
            x >= -0.5 && y >= -0.5 && x <= self.width as f64 - 0.5 && y <= self.height as f64 - 0.5;
        inside.then_some((x, y, h.z))
    }
}

/// A camera for visibility: its centre in the mesh frame and, when known,
/// its image rectangle.
#[derive(Clone, Debug)]
pub struct Viewpoint {
    /// Camera centre in the same frame as the mesh.
    pub center: DVec3,
    /// The image rectangle; `None` means every direction is in view.
    pub frustum: Option<Frustum>,
}

impl Viewpoint {
    /// A viewpoint that sees in every direction from `center`.
    pub fn omnidirectional(center: DVec3) -> Viewpoint {
        Viewpoint {
            center,
            frustum: None,
        }
    }
}

/// Relative depth tolerance of the depth-image test: a point up to this
/// fraction of its depth behind the surface a pixel sees still counts as
/// seen (at 6 units from the camera: 3e-3 units).
pub const DEPTH_TOLERANCE: f64 = 5e-4;

/// A capture camera's depth image: for every pixel centre the depth `w` of
/// the first triangle its ray meets (`f32::INFINITY` where it meets none),
/// in the units of the frustum's homogeneous coordinate, so that a point
/// `p` is compared through `w = (P·(p, 1)).z`.
struct DepthImage<'a> {
    frustum: &'a Frustum,
    depth: Vec<f32>,
}

impl<'a> DepthImage<'a> {
    /// Casts one ray per pixel centre of `frustum` (not empty) from
    /// `center` at `shape`.
    fn render(
        shape: &parry3d::shape::TriMesh,
        center: DVec3,
        frustum: &'a Frustum,
    ) -> DepthImage<'a> {
        let p = frustum.projection;
        // (u, v, w) = M·x + p₄ with M the left 3×3 block; the ray through
        // pixel (x, y) is C + t·M⁻¹(x, y, 1), and at parameter t its point
        // projects with w = t (M·C + p₄ = 0), so the hit time is the depth.
        let m = DMat3::from_cols(
            p.x_axis.truncate(),
            p.y_axis.truncate(),
            p.z_axis.truncate(),
        );
        let m_inv = m.inverse();
        let (width, height) = (frustum.width as usize, frustum.height as usize);
        let origin = parry3d::math::Vector::new(center.x as f32, center.y as f32, center.z as f32);
        let depth = (0..width * height)
            .into_par_iter()
            .map(|i| {
                let d = m_inv * DVec3::new((i % width) as f64, (i / width) as f64, 1.0);
                let ray = Ray::new(
                    origin,
                    parry3d::math::Vector::new(d.x as f32, d.y as f32, d.z as f32),
                );
                shape
                    .cast_local_ray(&ray, f32::MAX, false)
                    .unwrap_or(f32::INFINITY)
            })
            .collect();
        DepthImage { frustum, depth }
    }

    /// Whether `p` projects into the image no deeper than the deepest of
    /// the four pixel centres around it, within [`DEPTH_TOLERANCE`].
    fn sees(&self, p: Vec3) -> bool {
        let Some((x, y, w)) = self.frustum.project(p) else {
            return false;
        };
        let (width, height) = (self.frustum.width as usize, self.frustum.height as usize);
        let x0 = (x.floor().max(0.0) as usize).min(width - 1);
        let y0 = (y.floor().max(0.0) as usize).min(height - 1);
        let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
        let deepest = [(x0, y0), (x1, y0), (x0, y1), (x1, y1)]
            .iter()
            .map(|&(x, y)| self.depth[y * width + x])
            .fold(0.0f32, f32::max) as f64;
        w <= deepest * (1.0 + DEPTH_TOLERANCE)
    }
}

/// Barycentric coordinates of the seven test points of a triangle.
const TEST_POINTS: [[f32; 3]; 7] = [
    [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
    [0.8, 0.1, 0.1],
    [0.1, 0.8, 0.1],
    [0.1, 0.1, 0.8],
    [0.45, 0.45, 0.1],
    [0.1, 0.45, 0.45],
    [0.45, 0.1, 0.45],
];

/// For every triangle of `mesh`, whether at least one viewpoint sees it
/// (see the module documentation for the exact rule).
pub fn visible_triangles(mesh: &TriMesh, viewpoints: &[Viewpoint]) -> Result<Vec<bool>, EvalError> {
    mesh.validate(std::path::Path::new("mesh"))?;
    if mesh.triangles.is_empty() || viewpoints.is_empty() {
        return Ok(vec![false; mesh.triangles.len()]);
    }
    let positions: Vec<parry3d::math::Vector> = mesh
        .positions
        .iter()
        .map(|p| parry3d::math::Vector::new(p.x, p.y, p.z))
        .collect();
    let shape = parry3d::shape::TriMesh::new(positions, mesh.triangles.clone()).map_err(|e| {
        EvalError::UnusableMesh {
            what: "mesh".into(),
            problem: format!("cannot build the BVH for visibility: {e}"),
        }
    })?;
    let diagonal = mesh.bounding_box().map_or(1.0, |b| b.diagonal() as f64);
    let tolerance = 1e-5 * diagonal;
    let normals = mesh.face_normals();
    let orientation = closed_component_orientation(mesh);
    let centers: Vec<Vec3> = viewpoints.iter().map(|v| v.center.as_vec3()).collect();
    // Cameras with an image are tested against their depth image, the
    // others against exact rays (see the module documentation).
    let depth_images: Vec<Option<DepthImage>> = viewpoints
        .iter()
        .map(|v| {
            v.frustum
                .as_ref()
                .filter(|f| f.width > 0 && f.height > 0)
                .map(|f| DepthImage::render(&shape, v.center, f))
        })
        .collect();

    let visible = (0..mesh.triangles.len())
        .into_par_iter()
        .map(|t| {
            let corners = mesh.triangle_corners(t);
            let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
            let facing = |c: usize| normals[t].dot(centers[c] - centroid);
            // Cameras in front of the triangle first; cameras behind it only
            // for open components (see the module documentation).
            let (front, back): (Vec<usize>, Vec<usize>) =
                (0..viewpoints.len()).partition(|&c| match orientation[t] {
                    Some(sign) => sign * facing(c) > 0.0,
                    None => facing(c) > 0.0,
                });
            let candidates = match orientation[t] {
                Some(_) => front,
                None => front.into_iter().chain(back).collect(),
            };
            candidates.into_iter().any(|c| {
                TEST_POINTS.iter().any(|w| {
                    let p = w[0] * corners[0] + w[1] * corners[1] + w[2] * corners[2];
                    match &depth_images[c] {
                        Some(image) => image.sees(p),
                        None => sees(&shape, &viewpoints[c], centers[c], p, tolerance),
                    }
                })
            })
        })
        .collect();
    Ok(visible)
}

/// For every triangle: `Some(+1.0)` if its component is closed and
/// outward-oriented, `Some(-1.0)` if closed and inward-oriented, `None` if
/// the component is open.
fn closed_component_orientation(mesh: &TriMesh) -> Vec<Option<f32>> {
    let (labels, count) = mesh.triangle_components();
    let mut directed: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * mesh.triangles.len());
    for &[a, b, c] in &mesh.triangles {
        for edge in [(a, b), (b, c), (c, a)] {
            *directed.entry(edge).or_default() += 1;
        }
    }
    let mut closed = vec![true; count];
    // Six times the signed volume enclosed by each component (divergence theorem).
    let mut volume = vec![0.0f64; count];
    for (t, &[a, b, c]) in mesh.triangles.iter().enumerate() {
        let label = labels[t] as usize;
        for (u, v) in [(a, b), (b, c), (c, a)] {
            if directed.get(&(u, v)) != Some(&1) || directed.get(&(v, u)) != Some(&1) {
                closed[label] = false;
            }
        }
        let [p, q, r] = mesh.triangle_corners(t).map(|x| x.as_dvec3());
        volume[label] += p.dot(q.cross(r));
    }
    labels
        .iter()
        .map(|&l| {
            let l = l as usize;
            (closed[l] && volume[l] != 0.0).then(|| volume[l].signum() as f32)
        })
        .collect()
}

/// Whether `viewpoint` (centre `center`) sees the point `p` of `shape`.
fn sees(
    shape: &parry3d::shape::TriMesh,
    viewpoint: &Viewpoint,
    center: Vec3,
    p: Vec3,
    tolerance: f64,
) -> bool {
    if let Some(frustum) = &viewpoint.frustum
        && !frustum.contains(p)
    {
        return false;
    }
    let offset = p - center;
    let length = offset.length();
    if length <= 0.0 {
        return true;
    }
    let dir = offset / length;
    let reach = length as f64 - tolerance - 1e-6 * length as f64;
    if reach <= 0.0 {
        return true;
    }
    let reach = reach as f32;
    let ray = Ray::new(
        parry3d::math::Vector::new(center.x, center.y, center.z),
        parry3d::math::Vector::new(dir.x, dir.y, dir.z),
    );
    // Any-hit traversal: stop at the first triangle crossed before `reach`.
    let occluded = shape
        .bvh()
        .leaves(|node| node.aabb().intersects_local_ray(&ray, reach))
        .any(|leaf| {
            let tri = shape.triangle(leaf);
            let corners = [tri.a, tri.b, tri.c].map(|v| Vec3::new(v.x, v.y, v.z));
            segment_crosses_triangle(center, dir, reach, corners)
        });
    !occluded
}

/// Whether the ray `origin + t·dir` meets the triangle (either side) at
/// some 0 < t < `reach` (Möller–Trumbore).
fn segment_crosses_triangle(origin: Vec3, dir: Vec3, reach: f32, [a, b, c]: [Vec3; 3]) -> bool {
    let (e1, e2) = (b - a, c - a);
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det.abs() <= f32::EPSILON * e1.length() * e2.length() {
        return false; // ray parallel to the triangle's plane, or degenerate triangle
    }
    let inv = 1.0 / det;
    let s = origin - a;
    let u = s.dot(p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let t = e2.dot(q) * inv;
    t > 0.0 && t < reach
}

/// The part of `mesh` that at least one viewpoint sees; `what` names the
/// mesh in the error returned when nothing is visible.
pub fn restrict_to_visible(
    mesh: &TriMesh,
    viewpoints: &[Viewpoint],
    what: &str,
) -> Result<TriMesh, EvalError> {
    let visible = visible_triangles(mesh, viewpoints)?;
    if !visible.iter().any(|v| *v) {
        return Err(EvalError::UnusableMesh {
            what: what.to_string(),
            problem: format!(
                "no triangle is visible from the {} cameras",
                viewpoints.len()
            ),
        });
    }
    Ok(mesh.select_triangles(&visible))
}
