//! The region of interest: the sphere that becomes the unit sphere of the
//! normalized frame (SPEC §5), found from the cameras and the sparse points.
//!
//! 1. The centre starts at the point nearest to all optical axes (least
//!    squares: Σ (I − aaᵀ)(c − Cᵢ) = 0), where a photographer aims.
//! 2. The radius is bounded by what the photos frame: an object that fits
//!    in the photos has a radius of at most D · sin(φ), with D the median
//!    camera distance and φ the half field of view across the image's
//!    short side.
//! 3. The sparse points within that bound (seen by ≥ 3 photos, the far
//!    background left out) refine it: the centre moves to their trimmed
//!    middle (5th–95th percentile box, the move capped at a quarter of the
//!    bound), and the radius covers 95 % of them with 10 % to spare,
//!    never more than the bound.
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
    let mut center = axes_point;
    let mut used = near(center, framing_radius);
    if used.len() >= 10 {
        let mid = |f: fn(&DVec3) -> f64| {
            let mut v: Vec<f64> = used.iter().map(f).collect();
            0.5 * (percentile(&mut v, 0.05) + percentile(&mut v, 0.95))
        };
        let box_mid = DVec3::new(mid(|p| p.x), mid(|p| p.y), mid(|p| p.z));
        let shift = box_mid - axes_point;
        let cap = 0.25 * framing_radius;
        center = axes_point + shift.clamp_length_max(cap);
        used = near(center, framing_radius);
    }
    let mut radius = framing_radius;
    if used.len() >= 10 {
        let mut d: Vec<f64> = used.iter().map(|p| (*p - center).length()).collect();
        radius = (1.1 * percentile(&mut d, 0.95)).min(framing_radius);
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
        points_used: used.len(),
        nearest_camera: nearest / radius,
    })
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
