//! Visibility restriction: occlusion, open and inward-oriented meshes, frustum.

mod common;

use common::merge;
use glam::{DMat4, DVec3, Mat4, Vec3};
use wildlight_eval::shapes::{axis_box, flat_patch, icosphere};
use wildlight_eval::{Frustum, Viewpoint, visible_triangles};
use wildlight_mesh::TriMesh;

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

/// A capture camera at (0, 0, `height`) looking down −z (OpenCV: x right,
/// y down, z forward): rotation diag(1, −1, −1), focal `focal` px, a
/// `size`×`size` image with its principal point at the centre pixel.
fn camera_looking_down(height: f64, focal: f64, size: u32) -> Viewpoint {
    let w2c = DMat4::from_cols(
        glam::DVec4::new(1.0, 0.0, 0.0, 0.0),
        glam::DVec4::new(0.0, -1.0, 0.0, 0.0),
        glam::DVec4::new(0.0, 0.0, -1.0, 0.0),
        glam::DVec4::new(0.0, 0.0, height, 1.0),
    );
    let c = (size / 2) as f64;
    let k = DMat4::from_cols(
        glam::DVec4::new(focal, 0.0, 0.0, 0.0),
        glam::DVec4::new(0.0, focal, 0.0, 0.0),
        glam::DVec4::new(c, c, 1.0, 0.0),
        glam::DVec4::new(0.0, 0.0, 0.0, 1.0),
    );
    Viewpoint {
        center: DVec3::new(0.0, 0.0, height),
        frustum: Some(Frustum {
            projection: k * w2c,
            width: size,
            height: size,
        }),
    }
}

/// A floor (z = 0, fine cells) under a roof at z = 1 with a slit along y
/// spanning `slit` in x; the floor's triangles come first.
fn floor_under_a_slit_roof(slit: (f32, f32)) -> (TriMesh, usize) {
    let floor = flat_patch(Vec3::new(-1.0, -1.0, 0.0), 2.0, 2.0, 80, 80);
    let left = flat_patch(Vec3::new(-3.0, -3.0, 1.0), slit.0 + 3.0, 6.0, 1, 1);
    let right = flat_patch(Vec3::new(slit.1, -3.0, 1.0), 3.0 - slit.1, 6.0, 1, 1);
    let n = floor.triangles.len();
    (merge(&merge(&floor, &left), &right), n)
}

#[test]
fn a_capture_camera_does_not_see_through_a_slit_narrower_than_a_pixel() {
    // Camera 5 above the floor, focal 10 px: at the roof (4 away) a pixel
    // spans 0.4 and the pixel centres are at x = 0.4·k. A slit from 0.05 to
    // 0.35 lets exact rays reach the floor strip 0.0625 < x < 0.4375, but no
    // pixel centre looks through it.
    let camera = camera_looking_down(5.0, 10.0, 20);
    let exact = [Viewpoint::omnidirectional(camera.center)];
    let (scene, floor_triangles) = floor_under_a_slit_roof((0.05, 0.35));
    let by_ray = visible_triangles(&scene, &exact).unwrap();
    let by_pixels = visible_triangles(&scene, std::slice::from_ref(&camera)).unwrap();
    let seen = |v: &[bool]| v[..floor_triangles].iter().filter(|x| **x).count();
    assert!(
        seen(&by_ray) >= 100,
        "exact rays see {} floor triangles",
        seen(&by_ray)
    );
    assert_eq!(seen(&by_pixels), 0, "the photographs show no floor");
    assert!(
        by_pixels[floor_triangles..].iter().all(|v| *v),
        "the roof is seen"
    );

    // A slit that contains the pixel centre x = 0.4 shows the floor strip
    // under it (x = 0.5 at the floor) to the camera too, and nothing far from it.
    let (scene, floor_triangles) = floor_under_a_slit_roof((0.25, 0.55));
    let by_pixels = visible_triangles(&scene, std::slice::from_ref(&camera)).unwrap();
    let mut seen_x = Vec::new();
    for (t, seen) in by_pixels.iter().enumerate().take(floor_triangles) {
        let corners = scene.triangle_corners(t);
        if *seen {
            seen_x.push((corners[0].x + corners[1].x + corners[2].x) / 3.0);
        }
    }
    assert!(seen_x.len() >= 20, "{} floor triangles seen", seen_x.len());
    // One pixel around the centre that looks through: 0.5 ± 0.5 at the floor.
    assert!(seen_x.iter().all(|x| (x - 0.5).abs() < 0.55), "{seen_x:?}");
}

#[test]
fn a_capture_camera_sees_a_plane_at_a_grazing_angle_without_self_occlusion() {
    // A finely tessellated, strongly tilted plane (normal 80° from the view
    // axis) must be seen whole: the depth-image test has no acne.
    let patch = flat_patch(Vec3::new(-1.0, -1.0, 0.0), 2.0, 2.0, 60, 60)
        .transformed(&Mat4::from_rotation_y(80f32.to_radians()));
    let camera = camera_looking_down(6.0, 40.0, 64);
    let visible = visible_triangles(&patch, &[camera]).unwrap();
    let seen = visible.iter().filter(|v| **v).count();
    assert_eq!(
        seen,
        visible.len(),
        "{seen} of {} triangles seen",
        visible.len()
    );
}

#[test]
fn capture_cameras_and_exact_rays_agree_on_a_sphere_in_a_box() {
    // Away from occluding edges the two rules agree: the box hides the
    // sphere from both, and a sphere alone is seen from the same side.
    let shell = axis_box(Vec3::ZERO, Vec3::splat(1.0));
    let inner = icosphere(3).transformed(&Mat4::from_scale(Vec3::splat(0.5)));
    let camera = camera_looking_down(5.0, 30.0, 48);
    let both = merge(&shell, &inner);
    let visible = visible_triangles(&both, std::slice::from_ref(&camera)).unwrap();
    assert!(
        visible[12..].iter().all(|v| !*v),
        "the inner sphere is hidden"
    );
    let by_pixels = visible_triangles(&inner, std::slice::from_ref(&camera)).unwrap();
    let by_ray = visible_triangles(&inner, &[Viewpoint::omnidirectional(camera.center)]).unwrap();
    let differing = by_pixels
        .iter()
        .zip(&by_ray)
        .filter(|(a, b)| a != b)
        .count();
    let seen = by_ray.iter().filter(|v| **v).count();
    assert!(seen > by_ray.len() / 3, "{seen} of {} seen", by_ray.len());
    assert!(
        differing * 50 < seen,
        "{differing} of {seen} triangles differ between the two rules"
    );
}

#[test]
fn frustum_limits_what_a_camera_sees() {
    // The camera at z = 5 with focal 10 px and a 20×20 image sees
    // |x|, |y| ≤ 4.75 at z = 0 (pixel edge 19.5 = 10 + 10·x/5): the whole
    // small patch but none of a patch shifted to x = 8.
    let camera = [camera_looking_down(5.0, 10.0, 20)];
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
