//! Pinhole cameras of a capture: decomposition of the projection matrix
//! into intrinsics and pose, pixel rays, projection, and the transforms
//! between the world and the normalized frame (SPEC §5).
//!
//! Conventions (SPEC §5, shared conventions): OpenCV camera axes (x right,
//! y down, z forward); the pixel in column x, row y has its centre at the
//! integer coordinates (x, y); x_world = scale_mat · x_normalized.

use glam::{DMat3, DMat4, DVec2, DVec3, DVec4};

use crate::error::DataError;
use crate::npz::CameraArrays;
use crate::ray::Ray;

/// One calibrated view: intrinsics, pose in the normalized frame, the
/// original matrices, and the flash energy.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Image index (the `i` of `world_mat_i`).
    pub index: usize,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Intrinsics K, upper triangular with `K[2][2]` = 1 (rows: fx s cx / 0 fy cy / 0 0 1).
    pub k: DMat3,
    /// Camera-to-frame rotation: its columns are the camera x, y, z axes in the normalized frame.
    pub c2w: DMat3,
    /// Camera centre in the normalized frame.
    pub center: DVec3,
    /// `world_mat_i` as stored (3×4 ones padded with `0 0 0 1`).
    pub world_mat: DMat4,
    /// `scale_mat_i`: x_world = scale_mat · x_normalized.
    pub scale_mat: DMat4,
    /// Flash RGB energy in normalized-frame units; zeros = flash off (SPEC §2).
    pub light_energy: [f64; 3],
}

/// Intrinsics and pose recovered from a 3×4 projection matrix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Decomposition {
    /// Intrinsics with `K[2][2]` = 1 and positive focal lengths.
    pub k: DMat3,
    /// Frame-to-camera rotation R (proper, det = +1).
    pub w2c: DMat3,
    /// Camera centre C with P · (C, 1) = 0.
    pub center: DVec3,
}

/// Decomposes the projection P (the first three rows of `p` are used) into
/// P ∝ K [R | −R C] (SPEC §5).
///
/// P and −P describe the same camera, so the sign is chosen to make
/// det(M) > 0 for the left 3×3 block M; then the RQ decomposition M = K R
/// (Gram–Schmidt on the rows of M, bottom row first) gives an upper
/// triangular K with positive diagonal and a proper rotation R. K is
/// divided by `K[2][2]`. The centre solves M C = −p₄.
///
/// Fails with a description when M is singular or P is not finite.
pub fn decompose_projection(p: &DMat4) -> Result<Decomposition, String> {
    let rows = [p.row(0), p.row(1), p.row(2)];
    if rows.iter().any(|r| !r.is_finite()) {
        return Err("the matrix has NaN or infinite entries".into());
    }
    let mut m = [rows[0].truncate(), rows[1].truncate(), rows[2].truncate()];
    let mut p4 = DVec3::new(rows[0].w, rows[1].w, rows[2].w);
    let mat = DMat3::from_cols(m[0], m[1], m[2]).transpose();
    let det = mat.determinant();
    let norms = m[0].length() * m[1].length() * m[2].length();
    if det.is_nan() || det.abs() <= 1e-12 * norms {
        return Err(format!(
            "its left 3x3 block has determinant {det:e} (rank < 3), so it has no camera centre and no intrinsics"
        ));
    }
    if det < 0.0 {
        for row in &mut m {
            *row = -*row;
        }
        p4 = -p4;
    }
    // RQ by Gram–Schmidt: m3 = k33 r3; m2 = k22 r2 + k23 r3; m1 = k11 r1 + k12 r2 + k13 r3.
    let k33 = m[2].length();
    let r3 = m[2] / k33;
    let k23 = m[1].dot(r3);
    let v2 = m[1] - k23 * r3;
    let k22 = v2.length();
    let r2 = v2 / k22;
    let k13 = m[0].dot(r3);
    let k12 = m[0].dot(r2);
    let v1 = m[0] - k12 * r2 - k13 * r3;
    let k11 = v1.length();
    let r1 = v1 / k11;
    if !(k11 > 0.0 && k22 > 0.0 && k33 > 0.0) {
        return Err("degenerate intrinsics (zero focal length)".into());
    }
    let k = DMat3::from_cols(
        DVec3::new(k11, 0.0, 0.0) / k33,
        DVec3::new(k12, k22, 0.0) / k33,
        DVec3::new(k13, k23, k33) / k33,
    );
    let w2c = DMat3::from_cols(r1, r2, r3).transpose();
    let mat = DMat3::from_cols(m[0], m[1], m[2]).transpose();
    let center = -(mat.inverse() * p4);
    if !center.is_finite() {
        return Err("the camera centre is not finite".into());
    }
    Ok(Decomposition { k, w2c, center })
}

/// Intrinsics for a pinhole camera with horizontal field of view
/// `fov_x_deg` across the full image width (square pixels, no skew),
/// principal point at the image centre: with pixel centres at integer
/// coordinates the centre is ((W − 1)/2, (H − 1)/2).
pub fn intrinsics_from_fov_x(width: u32, height: u32, fov_x_deg: f64) -> DMat3 {
    let f = 0.5 * width as f64 / (0.5 * fov_x_deg.to_radians()).tan();
    let cx = 0.5 * (width as f64 - 1.0);
    let cy = 0.5 * (height as f64 - 1.0);
    DMat3::from_cols(
        DVec3::new(f, 0.0, 0.0),
        DVec3::new(0.0, f, 0.0),
        DVec3::new(cx, cy, 1.0),
    )
}

/// World-to-camera rotation (OpenCV axes) of a camera at `eye` looking at
/// `target`, with `up` pointing up in the image (camera y points down).
/// `None` when `eye == target` or `up` is parallel to the viewing direction.
pub fn look_at_w2c(eye: DVec3, target: DVec3, up: DVec3) -> Option<DMat3> {
    let z = (target - eye).try_normalize()?;
    let x = z.cross(up).try_normalize()?;
    let y = z.cross(x);
    Some(DMat3::from_cols(x, y, z).transpose())
}

impl Camera {
    /// Builds a camera from `world_mat` and `scale_mat` by decomposing
    /// P = world_mat · scale_mat (SPEC §5). The error is the reason the
    /// projection is unusable (see [`decompose_projection`]).
    pub fn from_matrices(
        index: usize,
        width: u32,
        height: u32,
        world_mat: DMat4,
        scale_mat: DMat4,
        light_energy: [f64; 3],
    ) -> Result<Camera, String> {
        let d = decompose_projection(&(world_mat * scale_mat))?;
        Ok(Camera {
            index,
            width,
            height,
            k: d.k,
            c2w: d.w2c.transpose(),
            center: d.center,
            world_mat,
            scale_mat,
            light_energy,
        })
    }

    /// Builds a camera from the arrays read from `npz`; errors name the file and the index.
    pub fn from_arrays(
        arrays: &CameraArrays,
        width: u32,
        height: u32,
        npz: &std::path::Path,
    ) -> Result<Camera, DataError> {
        Camera::from_matrices(
            arrays.index,
            width,
            height,
            arrays.world_mat,
            arrays.scale_mat,
            arrays.light_energy,
        )
        .map_err(|problem| DataError::SingularProjection {
            path: npz.to_path_buf(),
            index: arrays.index,
            problem,
        })
    }

    /// Builds a camera from intrinsics `k` and the WORLD pose x_cam = R x_world + t
    /// (what a writer knows), with `world_mat = [[K,0],[0,1]] · [[R,t],[0,1]]`.
    #[allow(clippy::too_many_arguments)]
    pub fn from_krt(
        index: usize,
        width: u32,
        height: u32,
        k: DMat3,
        r: DMat3,
        t: DVec3,
        scale_mat: DMat4,
        light_energy: [f64; 3],
    ) -> Result<Camera, DataError> {
        let k4 = DMat4::from_cols(
            k.x_axis.extend(0.0),
            k.y_axis.extend(0.0),
            k.z_axis.extend(0.0),
            DVec4::W,
        );
        let rt = DMat4::from_cols(
            r.x_axis.extend(0.0),
            r.y_axis.extend(0.0),
            r.z_axis.extend(0.0),
            t.extend(1.0),
        );
        Camera::from_matrices(index, width, height, k4 * rt, scale_mat, light_energy).map_err(
            |problem| DataError::InvalidArgument {
                what: format!("camera {index}"),
                problem,
            },
        )
    }

    /// Builds a camera at `eye_world` looking at `target_world` (WORLD
    /// coordinates), `up_world` up in the image, with intrinsics `k`.
    #[allow(clippy::too_many_arguments)]
    pub fn look_at(
        index: usize,
        width: u32,
        height: u32,
        k: DMat3,
        eye_world: DVec3,
        target_world: DVec3,
        up_world: DVec3,
        scale_mat: DMat4,
        light_energy: [f64; 3],
    ) -> Result<Camera, DataError> {
        let r = look_at_w2c(eye_world, target_world, up_world).ok_or_else(|| {
            DataError::InvalidArgument {
                what: format!("camera {index}"),
                problem: "look-at direction is zero or parallel to the up vector".into(),
            }
        })?;
        Camera::from_krt(
            index,
            width,
            height,
            k,
            r,
            -(r * eye_world),
            scale_mat,
            light_energy,
        )
    }

    /// The arrays a writer stores for this camera.
    pub fn to_arrays(&self) -> CameraArrays {
        CameraArrays {
            index: self.index,
            world_mat: self.world_mat,
            scale_mat: self.scale_mat,
            light_energy: self.light_energy,
            max_intensity: None,
        }
    }

    /// Focal length in x (pixels).
    pub fn fx(&self) -> f64 {
        self.k.x_axis.x
    }
    /// Focal length in y (pixels).
    pub fn fy(&self) -> f64 {
        self.k.y_axis.y
    }
    /// Skew `K[0][1]` (0 for ordinary cameras).
    pub fn skew(&self) -> f64 {
        self.k.y_axis.x
    }
    /// Principal point x (pixels, pixel centres at integers).
    pub fn cx(&self) -> f64 {
        self.k.z_axis.x
    }
    /// Principal point y (pixels, pixel centres at integers).
    pub fn cy(&self) -> f64 {
        self.k.z_axis.y
    }

    /// Whether the flash is on for this view (any light_energy channel > 0).
    pub fn flash(&self) -> bool {
        self.light_energy.iter().any(|e| *e > 0.0)
    }

    /// Frame-to-camera rotation R (the transpose of [`Camera::c2w`]).
    pub fn w2c(&self) -> DMat3 {
        self.c2w.transpose()
    }

    /// Direction, in camera coordinates, of K⁻¹ (x, y, 1)ᵀ (not normalized).
    /// K is upper triangular with `K[2][2]` = 1, so this is a back substitution.
    pub fn camera_direction(&self, x: f64, y: f64) -> DVec3 {
        let yc = (y - self.cy()) / self.fy();
        let xc = (x - self.cx() - self.skew() * yc) / self.fx();
        DVec3::new(xc, yc, 1.0)
    }

    /// The ray from the camera centre through pixel position (x, y) (column,
    /// row; integers are pixel centres), in the normalized frame:
    /// direction R_c2w · normalize(K⁻¹ (x, y, 1)ᵀ) (SPEC §5).
    pub fn ray(&self, x: f64, y: f64) -> Ray {
        Ray {
            origin: self.center,
            dir: self.c2w * self.camera_direction(x, y).normalize(),
        }
    }

    /// Projects a point of the normalized frame to pixel coordinates (x, y);
    /// `None` when the point is not in front of the camera.
    pub fn project(&self, p_normalized: DVec3) -> Option<DVec2> {
        let pc = self.w2c() * (p_normalized - self.center);
        if pc.z <= 1e-12 * (1.0 + pc.length()) {
            return None;
        }
        let uv = self.k * (pc / pc.z);
        Some(DVec2::new(uv.x, uv.y))
    }

    /// Depth (camera z) of a normalized-frame point.
    pub fn depth(&self, p_normalized: DVec3) -> f64 {
        (self.w2c() * (p_normalized - self.center)).z
    }

    /// Whether pixel position (x, y) lies inside the image (pixel centres at
    /// integers, so the image spans [−0.5, W − 0.5) × [−0.5, H − 0.5)).
    pub fn contains_pixel(&self, p: DVec2) -> bool {
        p.x >= -0.5
            && p.y >= -0.5
            && p.x < self.width as f64 - 0.5
            && p.y < self.height as f64 - 0.5
    }

    /// Camera centre in world coordinates.
    pub fn center_world(&self) -> DVec3 {
        self.to_world(self.center)
    }

    /// Maps a normalized-frame point to the world: scale_mat · p.
    pub fn to_world(&self, p: DVec3) -> DVec3 {
        self.scale_mat.transform_point3(p)
    }

    /// Maps a world point to the normalized frame: scale_mat⁻¹ · p.
    pub fn to_normalized(&self, p: DVec3) -> DVec3 {
        self.scale_mat.inverse().transform_point3(p)
    }

    /// Maps a normalized-frame direction to world (not re-normalized).
    pub fn dir_to_world(&self, d: DVec3) -> DVec3 {
        self.scale_mat.transform_vector3(d)
    }

    /// The factor from normalized-frame to world lengths: cube root of
    /// |det| of scale_mat's linear part (the scale for a similarity).
    pub fn world_scale(&self) -> f64 {
        self.scale_mat.determinant().abs().cbrt()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scale_mat() -> DMat4 {
        let s = 0.3;
        DMat4::from_cols(
            DVec4::new(s, 0.0, 0.0, 0.0),
            DVec4::new(0.0, s, 0.0, 0.0),
            DVec4::new(0.0, 0.0, s, 0.0),
            DVec4::new(0.1, -0.2, 0.05, 1.0),
        )
    }

    fn test_camera() -> Camera {
        let mut k = intrinsics_from_fov_x(64, 48, 50.0);
        k.y_axis.x = 0.7; // skew
        k.y_axis.y *= 1.1; // non-square pixels
        let eye = DVec3::new(0.9, 0.4, -0.6);
        Camera::look_at(
            3,
            64,
            48,
            k,
            eye,
            DVec3::new(0.1, -0.2, 0.05),
            DVec3::Y,
            scale_mat(),
            [1.0, 2.0, 3.0],
        )
        .unwrap()
    }

    #[test]
    fn decomposition_recovers_k_and_pose() {
        let cam = test_camera();
        let k0 = {
            let mut k = intrinsics_from_fov_x(64, 48, 50.0);
            k.y_axis.x = 0.7;
            k.y_axis.y *= 1.1;
            k
        };
        assert!(
            (cam.k - k0).abs_diff_eq(DMat3::ZERO, 1e-9),
            "{:?} vs {k0:?}",
            cam.k
        );
        let eye_world = DVec3::new(0.9, 0.4, -0.6);
        assert!(cam.center_world().abs_diff_eq(eye_world, 1e-12));
        // The camera looks at the origin of the normalized frame (the target).
        let forward = cam.c2w.z_axis;
        assert!(forward.abs_diff_eq((-cam.center).normalize(), 1e-12));
        assert!((cam.c2w.determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn negative_scaled_projection_is_the_same_camera() {
        let cam = test_camera();
        let neg = Camera::from_matrices(3, 64, 48, cam.world_mat * -2.5, cam.scale_mat, [0.0; 3])
            .unwrap();
        assert!(neg.center.abs_diff_eq(cam.center, 1e-12));
        assert!((neg.k - cam.k).abs_diff_eq(DMat3::ZERO, 1e-9));
        assert!((neg.c2w - cam.c2w).abs_diff_eq(DMat3::ZERO, 1e-12));
    }

    #[test]
    fn project_then_ray_hits_point() {
        let cam = test_camera();
        for p in [
            DVec3::new(0.1, 0.2, -0.3),
            DVec3::new(-0.5, 0.1, 0.4),
            DVec3::ZERO,
        ] {
            let uv = cam.project(p).unwrap();
            let ray = cam.ray(uv.x, uv.y);
            let t = (p - ray.origin).dot(ray.dir);
            assert!(ray.at(t).abs_diff_eq(p, 1e-10), "{:?} vs {p:?}", ray.at(t));
            assert!((ray.dir.length() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn principal_point_ray_is_optical_axis_and_pixel_centres_are_integers() {
        let k = intrinsics_from_fov_x(4, 2, 90.0);
        let cam = Camera::from_krt(
            0,
            4,
            2,
            k,
            DMat3::IDENTITY,
            DVec3::ZERO,
            DMat4::IDENTITY,
            [0.0; 3],
        )
        .unwrap();
        // fov 90° across 4 pixels: f = 2; the image edge x = -0.5 is 45° off axis.
        assert!((cam.fx() - 2.0).abs() < 1e-14);
        let r = cam.ray(cam.cx(), cam.cy());
        assert!(r.dir.abs_diff_eq(DVec3::Z, 1e-15));
        let edge = cam.ray(-0.5, cam.cy());
        assert!((edge.dir.x / edge.dir.z + 1.0).abs() < 1e-14);
        // x right, y down.
        let right = cam.ray(3.0, cam.cy());
        assert!(right.dir.x > 0.0);
        let below = cam.ray(cam.cx(), 1.0);
        assert!(below.dir.y > 0.0);
    }

    #[test]
    fn world_normalized_round_trip() {
        let cam = test_camera();
        let p = DVec3::new(0.3, -0.7, 0.2);
        let w = cam.to_world(p);
        assert!(w.abs_diff_eq(
            DVec3::new(0.3 * 0.3 + 0.1, -0.7 * 0.3 - 0.2, 0.2 * 0.3 + 0.05),
            1e-15
        ));
        assert!(cam.to_normalized(w).abs_diff_eq(p, 1e-14));
        assert!((cam.world_scale() - 0.3).abs() < 1e-14);
    }

    #[test]
    fn singular_projection_is_reported() {
        let mut w = DMat4::IDENTITY;
        w.z_axis = DVec4::ZERO; // third column zero: rank 2
        let err = Camera::from_matrices(0, 8, 8, w, DMat4::IDENTITY, [0.0; 3]).unwrap_err();
        assert!(err.contains("determinant"), "{err}");
    }

    #[test]
    fn points_behind_do_not_project() {
        let cam = test_camera();
        let behind = cam.center - 0.5 * cam.c2w.z_axis;
        assert!(cam.project(behind).is_none());
    }
}
