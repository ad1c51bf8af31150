//! Viewpoints for the visibility restriction from a capture's cameras.

use crate::visibility::{Frustum, Viewpoint};
use glam::{DMat4, DVec4};
use wildlight_data::Camera;

/// The frame the meshes are in, so the cameras are expressed in it too.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Frame {
    /// World units: x_world = scale_mat · x_normalized (SPEC §5).
    World,
    /// The normalized frame (object inside the unit sphere).
    Normalized,
}

/// The projection from the normalized frame to homogeneous pixels,
/// K [R | −R C], with the sign that puts points in front of the camera at
/// positive depth.
fn normalized_projection(camera: &Camera) -> DMat4 {
    let r = camera.w2c();
    let t = -(r * camera.center);
    let rt = DMat4::from_cols(
        r.x_axis.extend(0.0),
        r.y_axis.extend(0.0),
        r.z_axis.extend(0.0),
        DVec4::new(t.x, t.y, t.z, 1.0),
    );
    DMat4::from_mat3(camera.k) * rt
}

/// One viewpoint per camera, in `frame`: the camera centre and its image
/// rectangle (when the image size is known, i.e. non-zero).
pub fn viewpoints(cameras: &[Camera], frame: Frame) -> Vec<Viewpoint> {
    cameras
        .iter()
        .map(|camera| {
            let projection = normalized_projection(camera);
            let (center, projection) = match frame {
                Frame::Normalized => (camera.center, projection),
                Frame::World => (
                    camera.center_world(),
                    // SPEC §5: x_normalized = scale_mat⁻¹ · x_world.
                    projection * camera.scale_mat.inverse(),
                ),
            };
            let frustum = (camera.width > 0 && camera.height > 0).then_some(Frustum {
                projection,
                width: camera.width,
                height: camera.height,
            });
            Viewpoint { center, frustum }
        })
        .collect()
}
