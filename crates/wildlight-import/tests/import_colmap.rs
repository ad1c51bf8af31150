//! The import end to end with COLMAP (skipped, saying why, when `colmap`
//! is not on PATH): eight 400×300 phone-like photos (tests/fixtures/
//! phone-arc) become a capture whose cameras match the truth after a
//! similarity alignment; and photos COLMAP cannot reconstruct fail with
//! an error naming them, leaving nothing behind.

mod common;

use std::path::Path;
use std::time::Instant;

use glam::{DMat3, DVec3};
use wildlight_data::camera::decompose_projection;
use wildlight_data::npz::read_cameras_npz;
use wildlight_data::{Dataset, LoadOptions};
use wildlight_import::align::{rotation_alignment, rotation_angle_deg, umeyama};
use wildlight_import::colmap::find_colmap;
use wildlight_import::{ImportError, ImportOptions, import};

fn colmap_or_skip(test: &str) -> bool {
    match find_colmap() {
        Ok(_) => true,
        Err(e) => {
            println!("{test}: skipped: {e}");
            eprintln!("{test}: skipped: {e}");
            false
        }
    }
}

fn vec3(v: &serde_json::Value) -> DVec3 {
    DVec3::new(
        v[0].as_f64().unwrap(),
        v[1].as_f64().unwrap(),
        v[2].as_f64().unwrap(),
    )
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

#[test]
fn eight_phone_photos_become_a_capture_with_the_true_cameras() {
    if !colmap_or_skip("eight_phone_photos_become_a_capture_with_the_true_cameras") {
        return;
    }
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/phone-arc");
    let dir = tempfile::tempdir().unwrap();
    // The photos, one of them stored turned 90° with EXIF Orientation 6
    // (display = turn 90° clockwise): COLMAP must get the displayed pixels.
    let photos = dir.path().join("photos");
    std::fs::create_dir(&photos).unwrap();
    for entry in std::fs::read_dir(fixture.join("photos")).unwrap() {
        let path = entry.unwrap().path();
        std::fs::copy(&path, photos.join(path.file_name().unwrap())).unwrap();
    }
    let shown = image::open(photos.join("IMG_0014.jpg"))
        .unwrap()
        .into_rgb8();
    let stored = image::imageops::rotate270(&shown);
    let tags = common::Tags {
        orientation: Some(6),
        focal_35mm: None,
        ..common::Tags::phone(false, 60, 200)
    };
    common::write_jpeg(&photos.join("IMG_0014.jpg"), &stored, Some(&tags));
    let opts = ImportOptions::new(&photos, dir.path().join("capture"));
    let start = Instant::now();
    let report = import(&opts, &|line| eprintln!("import: {line}")).expect("the import works");
    eprintln!("import of 8 photos: {:.1} s", start.elapsed().as_secs_f64());
    assert!(report.registered >= 6, "{} registered", report.registered);
    assert!(report.mean_reprojection_error_px < 2.0);
    assert_eq!(common::entries(dir.path()), ["capture", "photos"]);
    let turned = report
        .photos
        .iter()
        .find(|p| p.file == "IMG_0014.jpg")
        .unwrap();
    assert_eq!(turned.orientation, 6);
    assert!(turned.index.is_some(), "the turned photo is registered");

    let data = Dataset::load(&opts.out, &LoadOptions::default()).expect("the capture loads");
    assert_eq!(data.views.len(), report.registered);
    assert_eq!(
        (data.width(), data.height()),
        (report.image_size[0], report.image_size[1])
    );
    for view in &data.views {
        assert!(
            view.camera.center.length() > 1.0,
            "a camera inside the unit sphere"
        );
        assert!(view.saturation.is_some());
    }

    // flash labels and cameras against the truth
    let truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fixture.join("truth.json")).unwrap())
            .unwrap();
    let object = vec3(&truth["object_center_world"]);
    let npz = read_cameras_npz(&opts.out.join("cameras_sphere.npz")).unwrap();
    let (mut est_c, mut est_r, mut gt_c, mut gt_r) = (vec![], vec![], vec![], vec![]);
    for photo in &report.photos {
        let t = truth["cameras"]
            .as_array()
            .unwrap()
            .iter()
            .find(|c| c["file"] == photo.file.as_str())
            .unwrap();
        assert_eq!(t["flash"].as_bool(), Some(photo.flash), "{}", photo.file);
        let Some(index) = photo.index else { continue };
        let cam = npz.cameras.iter().find(|c| c.index == index).unwrap();
        let d = decompose_projection(&cam.world_mat).unwrap();
        est_c.push(d.center);
        est_r.push(d.w2c);
        gt_c.push(vec3(&t["C_world"]));
        let r = &t["R"];
        gt_r.push(DMat3::from_cols(vec3(&r[0]), vec3(&r[1]), vec3(&r[2])).transpose());
    }
    let sim = umeyama(&est_c, &gt_c).expect("an alignment");
    let centre_err: Vec<f64> = (0..est_c.len())
        .map(|k| 100.0 * (sim.apply(est_c[k]) - gt_c[k]).length() / (gt_c[k] - object).length())
        .collect();
    // rotations aligned by the orientations (a short arc of centres leaves
    // the rotation about its chord weakly determined)
    let align = rotation_alignment(&est_r, &gt_r).unwrap();
    let rot_err: Vec<f64> = (0..est_r.len())
        .map(|k| rotation_angle_deg(est_r[k] * align.transpose() * gt_r[k].transpose()))
        .collect();
    eprintln!("centres {centre_err:.2?} %, rotations {rot_err:.2?} deg");
    // every camera, the turned one included
    assert!(median(centre_err.clone()) < 3.0);
    assert!(median(rot_err.clone()) < 5.0);
    assert!(centre_err.iter().all(|e| *e < 6.0) && rot_err.iter().all(|e| *e < 6.0));
    // the region of interest holds the object's centre
    let c = sim.apply(DVec3::from_array(report.roi.center));
    assert!((c - object).length() < 0.5 * report.roi.radius * sim.scale);
}

#[test]
fn photos_colmap_cannot_reconstruct_are_named() {
    if !colmap_or_skip("photos_colmap_cannot_reconstruct_are_named") {
        return;
    }
    // four unrelated noise pictures: nothing matches
    let dir = tempfile::tempdir().unwrap();
    let photos = dir.path().join("photos");
    std::fs::create_dir(&photos).unwrap();
    let mut state = 12345u32;
    for k in 0..4 {
        let img = image::RgbImage::from_fn(160, 120, |_, _| {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let v = (state >> 24) as u8;
            image::Rgb([v, v.wrapping_mul(3), v.wrapping_add(90)])
        });
        common::write_jpeg(
            &photos.join(format!("noise_{k}.jpg")),
            &img,
            Some(&common::Tags::phone(k % 2 == 0, 60, 100)),
        );
    }
    let opts = ImportOptions::new(&photos, dir.path().join("capture"));
    let err = import(&opts, &|_| {}).expect_err("nothing to reconstruct");
    let msg = err.to_string();
    match err {
        ImportError::NoModel { .. } => assert!(msg.contains("more photos"), "{msg}"),
        ImportError::TooFewRegistered { .. } => assert!(msg.contains("noise_"), "{msg}"),
        other => panic!("unexpected error: {other}"),
    }
    assert_eq!(common::entries(dir.path()), ["photos"]);
}
