//! Signed distance primitives and combinators used to model the built-in
//! scenes (negative inside, positive outside, in normalized-frame units).
//!
//! The boolean combinators return bounds rather than exact distances near
//! their seams; the mesher only needs the sign and a Lipschitz-1 bound.

use glam::{DVec2, DVec3};

/// Sphere of radius `r` centred at the origin.
#[inline]
pub fn sphere(p: DVec3, r: f64) -> f64 {
    p.length() - r
}

/// Box with half extents `b` and edges rounded by `round`, centred at the origin.
#[inline]
pub fn round_box(p: DVec3, b: DVec3, round: f64) -> f64 {
    let q = p.abs() - (b - DVec3::splat(round));
    q.max(DVec3::ZERO).length() + q.max_element().min(0.0) - round
}

/// Torus around the y axis: major radius `major`, tube radius `minor`.
#[inline]
pub fn torus_y(p: DVec3, major: f64, minor: f64) -> f64 {
    let q = DVec2::new(DVec2::new(p.x, p.z).length() - major, p.y);
    q.length() - minor
}

/// Torus around the z axis (lying in the xy plane).
#[inline]
pub fn torus_z(p: DVec3, major: f64, minor: f64) -> f64 {
    torus_y(DVec3::new(p.x, p.z, p.y), major, minor)
}

/// Capsule: segment `a`–`b` thickened by `r`.
#[inline]
pub fn capsule(p: DVec3, a: DVec3, b: DVec3, r: f64) -> f64 {
    let pa = p - a;
    let ba = b - a;
    let h = (pa.dot(ba) / ba.length_squared()).clamp(0.0, 1.0);
    (pa - ba * h).length() - r
}

/// Infinite cylinder of radius `r` along the x axis.
#[inline]
pub fn cylinder_x(p: DVec3, r: f64) -> f64 {
    DVec2::new(p.y, p.z).length() - r
}

/// Infinite cylinder of radius `r` along the z axis.
#[inline]
pub fn cylinder_z(p: DVec3, r: f64) -> f64 {
    DVec2::new(p.x, p.y).length() - r
}

/// Union with a polynomial blend of width `k` (k = 0: plain minimum).
#[inline]
pub fn smooth_union(a: f64, b: f64, k: f64) -> f64 {
    if k <= 0.0 {
        return a.min(b);
    }
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b + (a - b) * h - k * h * (1.0 - h)
}

/// `a` minus `b`, blended over width `k`.
#[inline]
pub fn smooth_subtract(a: f64, b: f64, k: f64) -> f64 {
    -smooth_union(-a, b, k)
}

/// Intersection of `a` and `b`, blended over width `k`.
#[inline]
pub fn smooth_intersect(a: f64, b: f64, k: f64) -> f64 {
    -smooth_union(-a, -b, k)
}

/// Central-difference gradient of `f` at `p` with step `eps`.
#[inline]
pub fn gradient(f: &impl Fn(DVec3) -> f64, p: DVec3, eps: f64) -> DVec3 {
    let dx = DVec3::new(eps, 0.0, 0.0);
    let dy = DVec3::new(0.0, eps, 0.0);
    let dz = DVec3::new(0.0, 0.0, eps);
    DVec3::new(
        f(p + dx) - f(p - dx),
        f(p + dy) - f(p - dy),
        f(p + dz) - f(p - dz),
    ) / (2.0 * eps)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn primitives_have_the_right_zero_sets() {
        assert!((sphere(DVec3::new(0.0, 0.6, 0.0), 0.5) - 0.1).abs() < 1e-15);
        assert!(round_box(DVec3::new(0.3, 0.0, 0.0), DVec3::splat(0.3), 0.05).abs() < 1e-15);
        assert!(round_box(DVec3::ZERO, DVec3::splat(0.3), 0.05) < 0.0);
        assert!(torus_y(DVec3::new(0.5, 0.1, 0.0), 0.5, 0.1).abs() < 1e-15);
        assert!(torus_z(DVec3::new(0.0, 0.6, 0.0), 0.5, 0.1).abs() < 1e-15);
        let a = DVec3::ZERO;
        let b = DVec3::new(0.0, 1.0, 0.0);
        assert!((capsule(DVec3::new(0.2, 0.5, 0.0), a, b, 0.1) - 0.1).abs() < 1e-15);
        assert!((cylinder_x(DVec3::new(9.0, 0.3, 0.4), 0.5)).abs() < 1e-15);
        assert!((cylinder_z(DVec3::new(0.3, 0.4, 9.0), 0.4) - 0.1).abs() < 1e-15);
    }

    #[test]
    fn combinators_reduce_to_min_max_far_from_the_seam() {
        assert_eq!(smooth_union(0.3, -0.2, 0.0), -0.2);
        assert!((smooth_union(0.3, -0.2, 0.1) + 0.2).abs() < 1e-15);
        assert!((smooth_subtract(0.3, -0.2, 0.1) - 0.3).abs() < 1e-15);
        assert!((smooth_intersect(0.3, -0.2, 0.1) - 0.3).abs() < 1e-15);
        // The blend only deepens the union.
        assert!(smooth_union(0.05, 0.05, 0.1) < 0.05);
    }

    #[test]
    fn gradient_of_sphere_is_radial() {
        let p = DVec3::new(0.3, -0.4, 0.5);
        let g = gradient(&|q| sphere(q, 0.5), p, 1e-5);
        assert!(g.abs_diff_eq(p.normalize(), 1e-8));
    }
}
