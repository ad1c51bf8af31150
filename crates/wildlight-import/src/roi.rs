//! The region of interest: the sphere that becomes the unit sphere of the
//! normalized frame (SPEC §5), found from the cameras and the sparse points.
//!
//! 1. The centre starts at the point nearest to all optical axes (least
//!    squares: Σ (I − aaᵀ)(c − Cᵢ) = 0), where a photographer aims.
//! 2. The radius is bounded by what the photos frame: an object that fits
//!    in the photos has a radius of at most D · sin(φ), with D the median
//!    camera distance and φ the half field of view across the image's
//!    short side.
//! 3. The sparse points within that bound refine it. When most of them
//!    lie on one plane (the table or floor the object stands on: RANSAC),
//!    the plane's points and those beyond it are left out, so that what
//!    remains is the object. The centre moves towards the median of the
//!    remaining points (by at most a tenth of the bound: the axes are
//!    usually the better guess, the points correct a photographer who aimed
//!    off), and the radius covers 95 % of them with 15 % to spare, between
//!    half the bound and the bound.
//! 4. The radius stays well inside the nearest camera: at most
//!    [`MAX_RADIUS_OF_NEAREST`] of its distance, so every camera is at
//!    least 1.25 radii from the centre (SPEC §6's background model needs
//!    the cameras outside the unit sphere).

use glam::{DMat3, DMat4, DVec3};

/// The largest radius, as a share of the nearest camera's distance.
pub const MAX_RADIUS_OF_NEAREST: f64 = 0.8;

/// A sphere in world units.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Roi {
    /// Centre.
    pub center: DVec3,
    /// Radius.
    pub radius: f64,
}

impl Roi {
    /// `scale_mat`: x_world = scale_mat · x_normalized.
    pub fn scale_mat(&self) -> DMat4 {
        DMat4::from_cols(
            glam::DVec4::new(self.radius, 0.0, 0.0, 0.0),
            glam::DVec4::new(0.0, self.radius, 0.0, 0.0),
            glam::DVec4::new(0.0, 0.0, self.radius, 0.0),
            self.center.extend(1.0),
        )
    }
}

/// A camera as the ROI estimator sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RoiCamera {
    /// Centre in the world.
    pub center: DVec3,
    /// Optical axis (unit) in the world.
    pub axis: DVec3,
    /// Half field of view across the image's short side, in radians.
    pub half_fov: f64,
}

/// The estimate and how it was reached.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RoiEstimate {
    /// The sphere.
    pub roi: Roi,
    /// The point nearest to the optical axes.
    pub axes_point: DVec3,
    /// The radius bound from the framing.
    pub framing_radius: f64,
    /// How many sparse points refined it.
    pub points_used: usize,
    /// The nearest camera's distance from the centre, in radii.
    pub nearest_camera: f64,
}

/// The point nearest to all lines (centre, unit axis) in the least-squares
/// sense; `None` when the lines are (nearly) parallel.
pub fn nearest_point_to_axes(cameras: &[RoiCamera]) -> Option<DVec3> {
    let mut a = DMat3::ZERO;
    let mut b = DVec3::ZERO;
    for cam in cameras {
        let d = cam.axis.normalize();
        let m = DMat3::IDENTITY - DMat3::from_cols(d * d.x, d * d.y, d * d.z);
        a += m;
        b += m * cam.center;
    }
    let det = a.determinant();
    let scale = a
        .x_axis
        .length()
        .max(a.y_axis.length())
        .max(a.z_axis.length());
    if det.abs().is_nan() || det.abs() <= 1e-9 * scale.powi(3) {
        return None;
    }
    let c = a.inverse() * b;
    c.is_finite().then_some(c)
}

fn percentile(values: &mut [f64], q: f64) -> f64 {
    values.sort_by(f64::total_cmp);
    let i = ((values.len() - 1) as f64 * q).round() as usize;
    values[i]
}

fn median(mut values: Vec<f64>) -> f64 {
    percentile(&mut values, 0.5)
}

/// Estimates the region of interest from the cameras and the sparse
/// points (world units); `None` with fewer than two cameras or axes that
/// do not converge in front of the cameras.
pub fn estimate_roi(cameras: &[RoiCamera], points: &[DVec3]) -> Option<RoiEstimate> {
    if cameras.len() < 2 {
        return None;
    }
    let axes_point = nearest_point_to_axes(cameras)?;
    // The cameras must look towards it.
    let in_front = cameras
        .iter()
        .filter(|c| (axes_point - c.center).dot(c.axis) > 0.0)
        .count();
    if in_front * 2 < cameras.len() {
        return None;
    }
    let dist = |c: DVec3| cameras.iter().map(move |cam| (cam.center - c).length());
    let framing = |c: DVec3| {
        let d = median(dist(c).collect());
        let fov = median(cameras.iter().map(|c| c.half_fov).collect());
        d * fov.sin()
    };
    let framing_radius = framing(axes_point);
    let near = |c: DVec3, r: f64| -> Vec<DVec3> {
        points
            .iter()
            .copied()
            .filter(|p| (*p - c).length() <= r)
            .collect()
    };
    let near_axes = near(axes_point, framing_radius);
    let object = off_plane(&near_axes, cameras, 0.02 * framing_radius);
    let mut center = axes_point;
    let mut radius = framing_radius;
    let mut used = 0;
    if object.len() >= 10 {
        let med = DVec3::new(
            median(object.iter().map(|p| p.x).collect()),
            median(object.iter().map(|p| p.y).collect()),
            median(object.iter().map(|p| p.z).collect()),
        );
        center = axes_point + (med - axes_point).clamp_length_max(0.1 * framing_radius);
        let mut d: Vec<f64> = object.iter().map(|p| (*p - center).length()).collect();
        radius = (1.15 * percentile(&mut d, 0.95)).clamp(0.5 * framing_radius, framing_radius);
        used = object.len();
    }
    let nearest = dist(center).fold(f64::INFINITY, f64::min);
    radius = radius.min(MAX_RADIUS_OF_NEAREST * nearest);
    if !(radius > 0.0 && radius.is_finite()) {
        return None;
    }
    Some(RoiEstimate {
        roi: Roi { center, radius },
        axes_point,
        framing_radius,
        points_used: used,
        nearest_camera: nearest / radius,
    })
}

/// The points of `points` that are not on a dominant plane: when a plane
/// (RANSAC, inlier distance `tolerance`) holds at least 40 % of them, its
/// inliers and the points beyond it (on the side away from most cameras)
/// are left out. Deterministic (a fixed pseudo-random sequence).
pub fn off_plane(points: &[DVec3], cameras: &[RoiCamera], tolerance: f64) -> Vec<DVec3> {
    let n = points.len();
    if n < 20 {
        return points.to_vec();
    }
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = |m: usize| {
        state = state
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        ((state >> 33) % m as u64) as usize
    };
    let mut best: Option<(usize, DVec3, f64)> = None;
    for _ in 0..300 {
        let (a, b, c) = (points[next(n)], points[next(n)], points[next(n)]);
        let Some(normal) = (b - a).cross(c - a).try_normalize() else {
            continue;
        };
        let offset = normal.dot(a);
        let count = points
            .iter()
            .filter(|p| (normal.dot(**p) - offset).abs() <= tolerance)
            .count();
        if best.is_none_or(|(k, _, _)| count > k) {
            best = Some((count, normal, offset));
        }
    }
    let Some((count, mut normal, mut offset)) = best else {
        return points.to_vec();
    };
    if count * 10 < n * 4 {
        return points.to_vec();
    }
    // orient the normal towards the cameras
    let above = cameras
        .iter()
        .filter(|c| normal.dot(c.center) > offset)
        .count();
    if above * 2 < cameras.len() {
        normal = -normal;
        offset = -offset;
    }
    points
        .iter()
        .copied()
        .filter(|p| normal.dot(*p) - offset > tolerance)
        .collect()
}

/// The cameras (by position in `centers`) at or inside the sphere, with
/// their distance from the centre in radii.
pub fn cameras_inside(roi: &Roi, centers: &[DVec3]) -> Vec<(usize, f64)> {
    centers
        .iter()
        .enumerate()
        .map(|(i, c)| (i, (*c - roi.center).length() / roi.radius))
        .filter(|(_, d)| *d <= 1.0)
        .collect()
}
