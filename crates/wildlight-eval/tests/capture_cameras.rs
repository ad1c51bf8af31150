//! Visibility from a real capture's cameras (the Mitsuba torus, written by
//! another renderer) in the world and the normalized frame.

use glam::{DVec3, Mat4, Vec3};
use std::path::Path;
use wildlight_data::Dataset;
use wildlight_eval::cameras::{Frame, viewpoints};
use wildlight_eval::{SurfaceDistanceOptions, evaluate_meshes, visible_triangles};
use wildlight_mesh::TriMesh;

fn fixture(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures/mitsuba-torus")
        .join(name)
}

#[test]
fn frustum_projection_matches_the_camera_model() {
    let cameras = Dataset::load_cameras(&fixture("cameras_sphere.npz")).unwrap();
    assert_eq!(cameras.len(), 12);
    assert_eq!((cameras[0].width, cameras[0].height), (96, 96));
    let world = viewpoints(&cameras, Frame::World);
    let normalized = viewpoints(&cameras, Frame::Normalized);
    for (i, camera) in cameras.iter().enumerate() {
        assert!((world[i].center - camera.center_world()).length() < 1e-12);
        assert!((normalized[i].center - camera.center).length() < 1e-12);
        for p in [
            DVec3::ZERO,
            DVec3::new(0.3, -0.2, 0.5),
            DVec3::new(-0.6, 0.1, -0.4),
        ] {
            let expected = camera.project(p).unwrap();
            for (viewpoint, q) in [(&normalized[i], p), (&world[i], camera.to_world(p))] {
                let frustum = viewpoint.frustum.as_ref().unwrap();
                let h = frustum.projection * q.extend(1.0);
                assert!(h.z > 0.0, "camera {i}: point in front has positive depth");
                let pixel = glam::DVec2::new(h.x / h.z, h.y / h.z);
                assert!(
                    (pixel - expected).length() < 1e-6,
                    "camera {i}: {pixel} vs {expected}"
                );
            }
        }
        // The object's centre is in every view.
        let center_world = camera.to_world(DVec3::ZERO).as_vec3();
        assert!(world[i].frustum.as_ref().unwrap().contains(center_world));
    }
}

#[test]
fn world_and_normalized_frames_agree_up_to_the_scale() {
    let cameras = Dataset::load_cameras(&fixture("cameras_sphere.npz")).unwrap();
    let gt_world = TriMesh::read(fixture("gt_mesh.ply")).unwrap();
    let scale_mat = cameras[0].scale_mat.as_mat4();
    let scale = cameras[0].world_scale();
    let to_normalized = scale_mat.inverse();
    let gt_normalized = gt_world.transformed(&to_normalized);
    // The prediction: the ground truth grown by 3 % about the object centre.
    let grow = Mat4::from_scale(Vec3::splat(1.03));
    let pred_normalized = gt_normalized.transformed(&grow);
    let pred_world = pred_normalized.transformed(&scale_mat);

    let vis_world = visible_triangles(&gt_world, &viewpoints(&cameras, Frame::World)).unwrap();
    let vis_norm =
        visible_triangles(&gt_normalized, &viewpoints(&cameras, Frame::Normalized)).unwrap();
    let count = |v: &[bool]| v.iter().filter(|x| **x).count();
    let (cw, cn) = (count(&vis_world), count(&vis_norm));
    // 12 views at low elevation see most of the torus but not all of it.
    assert!(cw > 16384 / 2 && cw < 16384, "{cw} visible");
    let differing = vis_world
        .iter()
        .zip(&vis_norm)
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        differing <= 16,
        "{differing} triangles differ between frames"
    );
    assert!(cw.abs_diff(cn) <= 16);

    let options = SurfaceDistanceOptions {
        max_pairs: 100_000,
        ..SurfaceDistanceOptions::default()
    };
    let w = evaluate_meshes(
        &pred_world,
        &gt_world,
        Some(&viewpoints(&cameras, Frame::World)),
        &options,
    )
    .unwrap();
    let n = evaluate_meshes(
        &pred_normalized,
        &gt_normalized,
        Some(&viewpoints(&cameras, Frame::Normalized)),
        &options,
    )
    .unwrap();
    assert_eq!(w.cameras, 12);
    assert!(
        (w.distance.mean - scale * n.distance.mean).abs() < 0.01 * w.distance.mean,
        "world {} vs scale × normalized {}",
        w.distance.mean,
        scale * n.distance.mean
    );
}
