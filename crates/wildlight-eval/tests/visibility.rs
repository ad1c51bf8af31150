//! Visibility restriction: occlusion, open and inward-oriented meshes, frustum.

mod common;

use common::merge;
use glam::{DMat4, DVec3, Mat4, Vec3};
use wildlight_eval::shapes::{axis_box, flat_patch, icosphere};
use wildlight_eval::{Frustum, Viewpoint, visible_triangles};

#[test]
fn open_patch_is_seen_from_behind() {
    let patch = flat_patch(Vec3::ZERO, 1.0, 1.0, 2, 2);
    let below = [Viewpoint::omnidirectional(DVec3::new(0.5, 0.5, -3.0))];
    assert!(
        visible_triangles(&patch, &below)
            .unwrap()
            .iter()
            .all(|v| *v)
    );
}

#[test]
fn inward_oriented_cube_sees_the_same_face() {
    let mut cube = axis_box(Vec3::ZERO, Vec3::splat(0.5));
    for t in &mut cube.triangles {
        t.swap(1, 2);
    }
    let above = [Viewpoint::omnidirectional(DVec3::new(0.1, -0.2, 10.0))];
    let visible = visible_triangles(&cube, &above).unwrap();
    assert_eq!(visible, (0..12).map(|t| t >= 10).collect::<Vec<_>>());
}

#[test]
fn a_sphere_inside_a_box_is_hidden() {
    let shell = axis_box(Vec3::ZERO, Vec3::splat(1.0));
    let inner = icosphere(1).transformed(&Mat4::from_scale(Vec3::splat(0.5)));
    let both = merge(&shell, &inner);
    let cameras: Vec<Viewpoint> = wildlight_eval::shapes::fibonacci_sphere(16, 5.0, Vec3::ZERO)
        .into_iter()
        .map(|c| Viewpoint::omnidirectional(c.as_dvec3()))
        .collect();
    let visible = visible_triangles(&both, &cameras).unwrap();
    assert!(visible[..12].iter().all(|v| *v), "every box face is seen");
    assert!(
        visible[12..].iter().all(|v| !*v),
        "the inner sphere is hidden"
    );
    // Alone, the sphere is seen by every camera side.
    assert!(
        visible_triangles(&inner, &cameras)
            .unwrap()
            .iter()
            .all(|v| *v)
    );
}

#[test]
fn partially_occluded_patch_behind_a_small_blocker() {
    // A 2×2 patch at z = 0 (8×8 cells) and a blocker square over its left
    // half at z = 1; a camera high above sees only the right half. A
    // triangle counts when any of its test points is seen, so exactly the
    // cells with x ≥ 1 are visible (the blocker edge is on a cell boundary
    // and the camera is above that boundary).
    let floor = flat_patch(Vec3::new(-1.0, -1.0, 0.0), 2.0, 2.0, 8, 8);
    let blocker = flat_patch(Vec3::new(-1.5, -1.5, 1.0), 1.5, 3.0, 1, 1);
    let scene = merge(&floor, &blocker);
    let camera = [Viewpoint::omnidirectional(DVec3::new(0.0, 0.0, 1000.0))];
    let visible = visible_triangles(&scene, &camera).unwrap();
    for (t, seen) in visible.iter().enumerate().take(floor.triangles.len()) {
        let corners = floor.triangle_corners(t);
        let centroid_x = (corners[0].x + corners[1].x + corners[2].x) / 3.0;
        assert_eq!(*seen, centroid_x > 0.0, "triangle {t} at x {centroid_x}");
    }
    assert!(visible[floor.triangles.len()..].iter().all(|v| *v));
}

#[test]
fn frustum_limits_what_a_camera_sees() {
    // Camera at z = 5 looking down −z (OpenCV: x right, y down, z forward):
    // rotation diag(1, −1, −1), focal 10 px, 20×20 image centred at (10, 10).
    // It sees |x|, |y| ≤ 4.75 at z = 0 (pixel edge 19.5 = 10 + 10·x/5) – the whole small patch but none
    // of a patch shifted to x = 8.
    let w2c = DMat4::from_cols(
        glam::DVec4::new(1.0, 0.0, 0.0, 0.0),
        glam::DVec4::new(0.0, -1.0, 0.0, 0.0),
        glam::DVec4::new(0.0, 0.0, -1.0, 0.0),
        glam::DVec4::new(0.0, 0.0, 5.0, 1.0),
    );
    let k = DMat4::from_cols(
        glam::DVec4::new(10.0, 0.0, 0.0, 0.0),
        glam::DVec4::new(0.0, 10.0, 0.0, 0.0),
        glam::DVec4::new(10.0, 10.0, 1.0, 0.0),
        glam::DVec4::new(0.0, 0.0, 0.0, 1.0),
    );
    let camera = [Viewpoint {
        center: DVec3::new(0.0, 0.0, 5.0),
        frustum: Some(Frustum {
            projection: k * w2c,
            width: 20,
            height: 20,
        }),
    }];
    let near = flat_patch(Vec3::new(-1.0, -1.0, 0.0), 2.0, 2.0, 2, 2);
    let far = flat_patch(Vec3::new(8.0, -1.0, 0.0), 2.0, 2.0, 2, 2);
    assert!(
        visible_triangles(&near, &camera)
            .unwrap()
            .iter()
            .all(|v| *v)
    );
    assert!(
        visible_triangles(&far, &camera)
            .unwrap()
            .iter()
            .all(|v| !*v)
    );
    let frustum = camera[0].frustum.as_ref().unwrap();
    assert!(frustum.contains(Vec3::new(4.7, -4.7, 0.0)));
    assert!(!frustum.contains(Vec3::new(4.8, 0.0, 0.0)));
    assert!(!frustum.contains(Vec3::new(0.0, -4.8, 0.0)));
    // Behind the camera nothing is in view.
    assert!(!frustum.contains(Vec3::new(0.0, 0.0, 6.0)));
}
