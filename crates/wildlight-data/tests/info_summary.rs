//! The `wildlight info` summary: values on the Mitsuba capture, and the
//! warnings on datasets that lack flash images or masks or have cameras
//! inside the unit sphere.

use std::path::Path;

use glam::{DMat4, DVec3};
use wildlight_data::camera::intrinsics_from_fov_x;
use wildlight_data::writer::ViewToWrite;
use wildlight_data::{Camera, Dataset, DatasetInfo, DatasetWriter, LoadOptions, Mask, RgbImage};

#[test]
fn mitsuba_torus_summary() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/mitsuba-torus");
    let data = Dataset::load(&root, &LoadOptions::default()).unwrap();
    let info = DatasetInfo::from_dataset(&data);
    assert_eq!(
        (info.images, info.flash_images, info.width, info.height),
        (12, 6, 96, 96)
    );
    assert_eq!((info.val_images, info.val_flash_images), (2, 1));
    assert!(info.has_masks && info.masked_images == 12);
    assert_eq!(info.saturation, None);
    assert!(info.warnings.is_empty(), "{:?}", info.warnings);
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(root.join("meta.json")).unwrap()).unwrap();
    let dists: Vec<f64> = meta["views"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["distance_normalized"].as_f64().unwrap())
        .collect();
    let range = info.camera_distance.unwrap();
    let (lo, hi) = dists
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), d| (a.min(*d), b.max(*d)));
    assert!(
        (range.min - lo).abs() < 1e-5 && (range.max - hi).abs() < 1e-5,
        "{range:?} vs {lo}..{hi}"
    );
    let scale = meta["scale"].as_f64().unwrap();
    let world = info.camera_distance_world.unwrap();
    assert!((world.min - lo * scale).abs() < 1e-5);
    let pixels: Vec<f64> = meta["views"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v["mask_pixels"].as_f64().unwrap() / 9216.0)
        .collect();
    let cov = info.mask_coverage.unwrap();
    assert!((cov.mean - pixels.iter().sum::<f64>() / 12.0).abs() < 1e-12);
    let json = serde_json::to_value(&info).unwrap();
    assert!(json["saturation"].is_null());
    assert_eq!(
        json["cameras"][3]["center_normalized"]
            .as_array()
            .unwrap()
            .len(),
        3
    );
    let table = info.to_table();
    assert!(table.contains("12 (6 with flash), 96x96"), "{table}");
}

fn write_dataset(root: &Path, flash: bool, masks: bool, distance: f64) {
    let (w, h) = (6, 4);
    let k = intrinsics_from_fov_x(w, h, 60.0);
    let writer = DatasetWriter::create(root).unwrap();
    let cams: Vec<Camera> = (0..2)
        .map(|i| {
            let eye = DVec3::new(
                distance * (i as f64).cos(),
                0.2,
                distance * (i as f64).sin(),
            );
            let target = if distance < 1.0 {
                eye + DVec3::X
            } else {
                DVec3::ZERO
            };
            let e = if flash { [1.0; 3] } else { [0.0; 3] };
            Camera::look_at(i, w, h, k, eye, target, DVec3::Y, DMat4::IDENTITY, e).unwrap()
        })
        .collect();
    let img = RgbImage::new(w, h);
    let mask = Mask::new(w, h);
    let views: Vec<ViewToWrite> = cams
        .iter()
        .map(|c| ViewToWrite {
            camera: c,
            image: &img,
            mask: masks.then_some(&mask),
        })
        .collect();
    writer.write_views(&views, None).unwrap();
}

fn warnings(flash: bool, masks: bool, distance: f64) -> Vec<String> {
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), flash, masks, distance);
    let data = Dataset::load(dir.path(), &LoadOptions::default()).unwrap();
    DatasetInfo::from_dataset(&data).warnings
}

#[test]
fn warns_about_missing_flash() {
    let w = warnings(false, true, 3.0);
    assert!(w.iter().any(|s| s.contains("no flash images") && s.contains("reflectance cannot be separated")), "{w:?}");
    assert!(
        !warnings(true, true, 3.0)
            .iter()
            .any(|s| s.contains("flash"))
    );
}

#[test]
fn notes_that_without_masks_the_background_is_modelled() {
    let dir = tempfile::tempdir().unwrap();
    write_dataset(dir.path(), true, false, 3.0);
    let data = Dataset::load(dir.path(), &LoadOptions::default()).unwrap();
    let info = DatasetInfo::from_dataset(&data);
    assert!(
        info.warnings.is_empty(),
        "no masks is no warning: {:?}",
        info.warnings
    );
    assert_eq!(
        info.notes,
        ["no masks: training will model the background (SPEC §6)"]
    );
}

#[test]
fn warns_about_cameras_inside_the_sphere() {
    let w = warnings(true, true, 0.5);
    assert!(
        w.iter()
            .any(|s| s.contains("cameras inside the unit sphere") && s.contains("0, 1")),
        "{w:?}"
    );
    assert!(
        !warnings(true, true, 3.0)
            .iter()
            .any(|s| s.contains("inside"))
    );
}
