//! Appendix eq. 16 on meshes with exactly known answers.

mod common;

use common::merge;
use glam::{DVec3, Mat4, Vec3};
use wildlight_eval::shapes::{axis_box, flat_patch, icosphere};
use wildlight_eval::{
    SurfaceDistanceOptions, Viewpoint, restrict_to_visible, surface_distance, visible_triangles,
};
use wildlight_mesh::TriMesh;

fn options(seed: u64) -> SurfaceDistanceOptions {
    SurfaceDistanceOptions {
        seed,
        ..SurfaceDistanceOptions::default()
    }
}

#[test]
fn mesh_against_itself_is_zero() {
    let s = icosphere(3);
    let r = surface_distance(&s, &s, &options(1)).unwrap();
    assert!(r.mean < 1e-6 && r.median < 1e-6, "{r:?}");
    // All pair values are (nearly) equal: the σ criterion stops after one batch.
    assert_eq!(r.pairs, 10_000);
    assert!(r.std_of_mean <= 1e-5);
}

#[test]
fn concentric_spheres_differ_by_delta_up_to_tessellation() {
    let (radius, delta) = (1.0f32, 0.01f32);
    let unit = icosphere(4);
    let s1 = unit.transformed(&Mat4::from_scale(Vec3::splat(radius)));
    let s2 = unit.transformed(&Mat4::from_scale(Vec3::splat(radius + delta)));
    // Tessellation error e: how far the flat faces sink below the sphere of
    // radius R (largest gap between the sphere and a face plane).
    let min_plane = unit
        .face_normals()
        .iter()
        .zip(&unit.triangles)
        .map(|(n, t)| n.dot(unit.positions[t[0] as usize]) as f64)
        .fold(f64::INFINITY, f64::min);
    let e = (1.0 - min_plane) * radius as f64;
    // Every pair value lies in [δ − e(1 + δ/R), δ]: S₂ is S₁ scaled by
    // (R+δ)/R about the centre, S₁ lies inside the ball of radius R and S₂
    // outside the ball of radius (R+δ)(1 − e/R).
    let (delta, r) = (delta as f64, radius as f64);
    let lower = delta - e * (1.0 + delta / r) - 1e-6;
    let upper = delta + 1e-6;
    let res = surface_distance(&s1, &s2, &options(2)).unwrap();
    assert!(e > 0.0 && e < 2e-3, "tessellation error {e}");
    for value in [
        res.mean,
        res.median,
        res.mean_pred_to_gt,
        res.mean_gt_to_pred,
    ] {
        assert!(
            value >= lower && value <= upper,
            "{value} outside [{lower}, {upper}]"
        );
    }
    // The spread is tiny, so the σ rule ends it after the first batch.
    assert_eq!(res.pairs, 10_000);
}

/// ∫₀ᵃ √(c² + u²) du.
fn integral_hypot(a: f64, c: f64) -> f64 {
    let h = (a * a + c * c).sqrt();
    0.5 * (a * h + c * c * ((a + h) / c).ln())
}

#[test]
fn translated_plane_patch_matches_the_closed_form() {
    let (tx, tz) = (0.1f32, 0.05f32);
    let s1 = flat_patch(Vec3::ZERO, 1.0, 1.0, 1, 1);
    let s2 = s1.transformed(&Mat4::from_translation(Vec3::new(tx, 0.0, tz)));
    // A point of the unit square at x < tx projects outside the shifted
    // square; its nearest point is on the shifted square's edge x = tx:
    // E[d] = (1 − tx)·tz + ∫₀^tx √(tz² + u²) du, the same in both directions.
    let (tx, tz) = (tx as f64, tz as f64);
    let expected = (1.0 - tx) * tz + integral_hypot(tx, tz);
    let r = surface_distance(&s1, &s2, &options(3)).unwrap();
    // σ of one pair value is about 0.0066, so the σ-of-the-mean rule (1e-5)
    // stops the sampling after about 440 000 pairs, before the cap.
    assert!(r.pairs > 400_000 && r.pairs < 480_000, "{r:?}");
    assert_eq!(r.pairs % 10_000, 0);
    assert!(r.std_of_mean <= 1e-5);
    assert!(
        (r.mean - expected).abs() < 5.0 * r.std_of_mean + 1e-7,
        "{} vs {expected} (σ {})",
        r.mean,
        r.std_of_mean
    );
    // Without the in-plane shift every distance is tz exactly.
    let s3 = s1.transformed(&Mat4::from_translation(Vec3::new(0.0, 0.0, tz as f32)));
    let r = surface_distance(&s1, &s3, &options(3)).unwrap();
    assert!((r.mean - tz).abs() < 1e-7 && (r.median - tz).abs() < 1e-7);
}

#[test]
fn median_of_a_three_valued_distribution() {
    // S₁: patch A (area 0.6) and patch B (area 0.4), far apart in the plane
    // z = 0. S₂: A lifted by 0.01, B lifted by 0.05. Each one-sided distance
    // is 0.01 with probability 0.6 and 0.05 with probability 0.4, so a pair
    // value is 0.01 (p = 0.36), 0.03 (p = 0.48) or 0.05 (p = 0.16): the
    // median is 0.03 and the mean 0.6·0.01 + 0.4·0.05 = 0.026.
    let a = flat_patch(Vec3::ZERO, 1.0, 0.6, 2, 2);
    let b = flat_patch(Vec3::new(3.0, 0.0, 0.0), 1.0, 0.4, 2, 2);
    let s1 = merge(&a, &b);
    let s2 = merge(
        &a.transformed(&Mat4::from_translation(Vec3::new(0.0, 0.0, 0.01))),
        &b.transformed(&Mat4::from_translation(Vec3::new(0.0, 0.0, 0.05))),
    );
    let r = surface_distance(&s1, &s2, &options(4)).unwrap();
    // σ of one pair value is 0.013856: reaching σ_mean ≤ 1e-5 would take
    // 1.9 million pairs, so the one-million cap ends the sampling.
    assert_eq!(r.pairs, 1_000_000);
    assert!((r.median - 0.03).abs() < 1e-7, "median {}", r.median);
    assert!((r.mean - 0.026).abs() < 4.0 * r.std_of_mean, "{r:?}");
    assert!((r.std_of_mean - 0.013856 / 1000.0).abs() < 2e-7, "{r:?}");
}

#[test]
fn cube_seen_from_one_side_counts_only_that_face() {
    let cube = axis_box(Vec3::ZERO, Vec3::splat(0.5));
    let above = [Viewpoint::omnidirectional(DVec3::new(0.0, 0.0, 10.0))];
    let visible = visible_triangles(&cube, &above).unwrap();
    let expected: Vec<bool> = (0..12).map(|t| t >= 10).collect(); // the +z pair
    assert_eq!(visible, expected);

    // Two cameras (+z and −x) see two faces.
    let two = [
        above[0].clone(),
        Viewpoint::omnidirectional(DVec3::new(-10.0, 0.2, 0.1)),
    ];
    let seen = visible_triangles(&cube, &two).unwrap();
    let expected: Vec<bool> = (0..12).map(|t| !(2..10).contains(&t)).collect();
    assert_eq!(seen, expected);

    // Restricted eq. 16: the top faces of the cube and of a copy lifted by
    // 0.1 are exactly 0.1 apart, although the whole cubes are not.
    let lifted = cube.transformed(&Mat4::from_translation(Vec3::new(0.0, 0.0, 0.1)));
    let lifted_cameras = [Viewpoint::omnidirectional(DVec3::new(0.0, 0.0, 10.1))];
    let top1 = restrict_to_visible(&cube, &above, "cube").unwrap();
    let top2 = restrict_to_visible(&lifted, &lifted_cameras, "lifted").unwrap();
    assert_eq!(top1.triangles.len(), 2);
    assert!((top1.total_area() - 1.0).abs() < 1e-9);
    let restricted = surface_distance(&top1, &top2, &options(5)).unwrap();
    assert!((restricted.mean - 0.1).abs() < 1e-6, "{restricted:?}");
    let whole = surface_distance(&cube, &lifted, &options(5)).unwrap();
    assert!(
        whole.mean < 0.05,
        "whole cubes are closer on average: {whole:?}"
    );
}

#[test]
fn nothing_visible_is_an_error() {
    let cube = axis_box(Vec3::ZERO, Vec3::splat(0.5));
    let inside_other = [Viewpoint {
        center: DVec3::new(0.0, 0.0, 10.0),
        // A camera that looks away from the cube (+z forward, K = identity
        // with a 10×10 image, so only points in front of it are in view).
        frustum: Some(wildlight_eval::Frustum {
            projection: glam::DMat4::from_translation(DVec3::new(0.0, 0.0, -10.0)),
            width: 10,
            height: 10,
        }),
    }];
    let err = restrict_to_visible(&cube, &inside_other, "pred.ply").unwrap_err();
    assert!(err.to_string().contains("pred.ply"), "{err}");
}

#[test]
fn result_does_not_depend_on_thread_count() {
    let s1 = icosphere(2);
    let s2 = s1.transformed(&Mat4::from_scale(Vec3::new(1.05, 1.0, 0.97)));
    let opts = SurfaceDistanceOptions {
        max_pairs: 20_000,
        ..options(6)
    };
    let run = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| surface_distance(&s1, &s2, &opts).unwrap())
    };
    assert_eq!(run(1), run(2));
    let other_seed = surface_distance(&s1, &s2, &options(7)).unwrap();
    assert_ne!(run(1).mean, other_seed.mean);
}

#[test]
fn degenerate_mesh_is_rejected() {
    let flat = TriMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0], vec![[0, 1, 2]]);
    let good = icosphere(0);
    let err = surface_distance(&flat, &good, &options(0)).unwrap_err();
    assert!(err.to_string().contains("predicted mesh"), "{err}");
    assert!(err.to_string().contains("positive area"), "{err}");
}
