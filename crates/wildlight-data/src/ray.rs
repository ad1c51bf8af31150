//! Camera rays and their chord through the unit sphere (SPEC §5).

use glam::DVec3;

/// A ray `r(t) = origin + t · dir` in the normalized frame, `|dir| = 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point (the camera centre for camera rays).
    pub origin: DVec3,
    /// Unit direction.
    pub dir: DVec3,
}

impl Ray {
    /// The point at parameter `t`.
    pub fn at(&self, t: f64) -> DVec3 {
        self.origin + t * self.dir
    }

    /// Near and far parameters of the chord of the unit sphere along this
    /// ray, with near clipped at 0 (SPEC §5). `None` when the ray misses the
    /// sphere or the sphere lies entirely behind the origin.
    ///
    /// Solves |o + t d|² = 1 with |d| = 1: t = −o·d ± sqrt((o·d)² − |o|² + 1).
    pub fn near_far_unit_sphere(&self) -> Option<(f64, f64)> {
        let b = self.origin.dot(self.dir);
        let disc = b * b - (self.origin.length_squared() - 1.0);
        if disc.is_nan() || disc <= 0.0 {
            return None;
        }
        let root = disc.sqrt();
        let far = -b + root;
        if far <= 0.0 {
            return None;
        }
        Some(((-b - root).max(0.0), far))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chord_from_outside_through_centre() {
        let ray = Ray {
            origin: DVec3::new(0.0, 0.0, -3.0),
            dir: DVec3::Z,
        };
        let (near, far) = ray.near_far_unit_sphere().unwrap();
        assert!((near - 2.0).abs() < 1e-12 && (far - 4.0).abs() < 1e-12);
    }

    #[test]
    fn chord_endpoints_lie_on_sphere() {
        let dir = DVec3::new(1.0, 0.2, 0.1).normalize();
        let ray = Ray {
            origin: DVec3::new(-2.0, 0.1, 0.3),
            dir,
        };
        let (near, far) = ray.near_far_unit_sphere().unwrap();
        assert!((ray.at(near).length() - 1.0).abs() < 1e-12);
        assert!((ray.at(far).length() - 1.0).abs() < 1e-12);
        assert!(near < far);
    }

    #[test]
    fn near_is_clipped_inside_sphere() {
        let ray = Ray {
            origin: DVec3::new(0.5, 0.0, 0.0),
            dir: DVec3::X,
        };
        let (near, far) = ray.near_far_unit_sphere().unwrap();
        assert_eq!(near, 0.0);
        assert!((far - 0.5).abs() < 1e-12);
    }

    #[test]
    fn misses_and_behind() {
        let miss = Ray {
            origin: DVec3::new(0.0, 2.0, -3.0),
            dir: DVec3::Z,
        };
        assert!(miss.near_far_unit_sphere().is_none());
        let behind = Ray {
            origin: DVec3::new(0.0, 0.0, 3.0),
            dir: DVec3::Z,
        };
        assert!(behind.near_far_unit_sphere().is_none());
    }
}
