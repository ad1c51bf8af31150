//! The optional per-image saturation cap `max_intensity_i` (written by
//! `wildlight import`): read back per view, falling back to the global
//! `max_intensity` (or the format's default) for images without one.

use glam::{DMat4, DVec3};
use wildlight_data::camera::intrinsics_from_fov_x;
use wildlight_data::npz::{read_cameras_npz, write_cameras_npz};
use wildlight_data::{Camera, Dataset, DatasetWriter, LoadOptions, RgbImage};

fn write(root: &std::path::Path, caps: &[Option<f64>], global: Option<f64>) {
    let writer = DatasetWriter::create(root).unwrap();
    let k = intrinsics_from_fov_x(4, 3, 50.0);
    let arrays: Vec<_> = caps
        .iter()
        .enumerate()
        .map(|(i, cap)| {
            let eye = DVec3::new(3.0 * (i as f64).cos(), 0.2, 3.0 * (i as f64).sin());
            let cam = Camera::look_at(
                i,
                4,
                3,
                k,
                eye,
                DVec3::ZERO,
                DVec3::Y,
                DMat4::IDENTITY,
                [0.0; 3],
            )
            .unwrap();
            writer.write_image(i, &RgbImage::new(4, 3)).unwrap();
            let mut a = cam.to_arrays();
            a.max_intensity = *cap;
            a
        })
        .collect();
    write_cameras_npz(&root.join("cameras_sphere.npz"), &arrays, global).unwrap();
}

#[test]
fn per_image_caps_round_trip_and_fall_back_to_the_global_cap() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), &[Some(0.5), None, Some(2.0)], Some(0.4));
    let npz = read_cameras_npz(&dir.path().join("cameras_sphere.npz")).unwrap();
    let caps: Vec<_> = npz.cameras.iter().map(|c| c.max_intensity).collect();
    assert_eq!(caps, [Some(0.5), None, Some(2.0)]);
    assert_eq!(npz.max_intensity, Some(0.4));

    let data = Dataset::load(dir.path(), &LoadOptions::default()).unwrap();
    assert_eq!(data.saturation, Some(0.4));
    let views: Vec<_> = data.views.iter().map(|v| v.saturation).collect();
    assert_eq!(views, [Some(0.5), Some(0.4), Some(2.0)]);
    assert_eq!(data.saturation_of(2), Some(2.0));

    // An override applies to every view.
    let opts = LoadOptions {
        saturation_override: Some(None),
        ..LoadOptions::default()
    };
    let data = Dataset::load(dir.path(), &opts).unwrap();
    assert!(data.views.iter().all(|v| v.saturation.is_none()));
}

#[test]
fn without_per_image_caps_every_view_has_the_global_cap() {
    let dir = tempfile::tempdir().unwrap();
    // EXR without any cap: none anywhere (published captures read as before).
    write(dir.path(), &[None, None], None);
    let data = Dataset::load(dir.path(), &LoadOptions::default()).unwrap();
    assert_eq!(data.saturation, None);
    assert!(data.views.iter().all(|v| v.saturation.is_none()));
    write(dir.path(), &[None, None], Some(0.7));
    let data = Dataset::load(dir.path(), &LoadOptions::default()).unwrap();
    assert!(data.views.iter().all(|v| v.saturation == Some(0.7)));
}

#[test]
fn a_non_positive_per_image_cap_is_an_error_naming_the_key() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), &[Some(1.0), Some(0.0)], None);
    let err = read_cameras_npz(&dir.path().join("cameras_sphere.npz"))
        .unwrap_err()
        .to_string();
    assert!(err.contains("max_intensity_1"), "{err}");
    assert!(err.contains("positive"), "{err}");
}
