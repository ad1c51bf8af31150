//! PNG and images.npy datasets (SPEC §5): value/256 or sRGB decoding, the
//! default saturation caps, the images.npy rescaling, and file names that
//! are not numbers.

use std::path::Path;

use glam::{DMat4, DVec3};
use ndarray::Array4;
use wildlight_data::camera::intrinsics_from_fov_x;
use wildlight_data::dataset::{ImageSource, NPY_SATURATION};
use wildlight_data::exr_io::write_exr_rgb;
use wildlight_data::png_io::{PNG_SATURATION, PngDecoding, srgb_to_linear};
use wildlight_data::{Camera, Dataset, DatasetWriter, LoadOptions, RgbImage};

const W: u32 = 5;
const H: u32 = 3;

fn cameras(n: usize) -> Vec<Camera> {
    let k = intrinsics_from_fov_x(W, H, 50.0);
    (0..n)
        .map(|i| {
            let eye = DVec3::new(3.0 * (i as f64).cos(), 0.3, 3.0 * (i as f64).sin());
            Camera::look_at(
                i,
                W,
                H,
                k,
                eye,
                DVec3::ZERO,
                DVec3::Y,
                DMat4::IDENTITY,
                [0.5; 3],
            )
            .unwrap()
        })
        .collect()
}

fn write_cameras(root: &Path, n: usize, max_intensity: Option<f64>) {
    DatasetWriter::create(root)
        .unwrap()
        .write_cameras(&cameras(n), max_intensity)
        .unwrap();
}

fn png_bytes(i: usize) -> Vec<u8> {
    (0..(W * H * 3) as usize)
        .map(|k| ((k * 17 + i * 5) % 256) as u8)
        .collect()
}

fn write_png_dataset(root: &Path) {
    write_cameras(root, 2, None);
    for i in 0..2 {
        let img = image::RgbImage::from_raw(W, H, png_bytes(i)).unwrap();
        img.save(root.join(format!("image/{i:03}.png"))).unwrap();
    }
}

#[test]
fn png_values_are_value_over_256_with_default_cap() {
    let dir = tempfile::tempdir().unwrap();
    write_png_dataset(dir.path());
    let data = Dataset::load(dir.path(), &LoadOptions::default()).unwrap();
    assert_eq!(data.source, ImageSource::Png);
    assert_eq!(data.saturation, Some(255.0 / 256.0 - 0.001));
    assert_eq!(data.saturation, Some(PNG_SATURATION));
    for i in 0..2 {
        let expected: Vec<f32> = png_bytes(i).iter().map(|v| *v as f32 / 256.0).collect();
        assert_eq!(data.views[i].image.data, expected);
    }
    // Exactly the values stored as 255 reach the cap.
    let cap = data.saturation.unwrap();
    let at_cap = data.views[0]
        .image
        .data
        .iter()
        .filter(|v| **v >= cap)
        .count();
    let raw_255 = png_bytes(0).iter().filter(|v| **v == 255).count();
    assert!(raw_255 > 0);
    assert_eq!(at_cap, raw_255);
}

#[test]
fn png_srgb_option_decodes_the_curve() {
    let dir = tempfile::tempdir().unwrap();
    write_png_dataset(dir.path());
    let opts = LoadOptions {
        png_decoding: PngDecoding::Srgb,
        ..LoadOptions::default()
    };
    let data = Dataset::load(dir.path(), &opts).unwrap();
    let expected: Vec<f32> = png_bytes(1)
        .iter()
        .map(|v| srgb_to_linear(*v as f32 / 255.0))
        .collect();
    assert_eq!(data.views[1].image.data, expected);
    assert_eq!(data.saturation, Some(0.999));
}

#[test]
fn max_intensity_overrides_the_png_cap() {
    let dir = tempfile::tempdir().unwrap();
    write_png_dataset(dir.path());
    write_cameras(dir.path(), 2, Some(0.9));
    let data = Dataset::load(dir.path(), &LoadOptions::default()).unwrap();
    assert_eq!(data.saturation, Some(0.9));
    let opts = LoadOptions {
        saturation_override: Some(None),
        ..LoadOptions::default()
    };
    assert_eq!(Dataset::load(dir.path(), &opts).unwrap().saturation, None);
}

fn npy_images(n: usize) -> Array4<f32> {
    Array4::from_shape_fn((n, H as usize, W as usize, 3), |(i, y, x, c)| {
        (i * 100 + y * 10 + x) as f32 + 0.25 * c as f32
    })
}

#[test]
fn images_npy_is_divided_by_max_intensity_times_5() {
    let dir = tempfile::tempdir().unwrap();
    write_cameras(dir.path(), 3, Some(40.0));
    ndarray_npy::write_npy(dir.path().join("images.npy"), &npy_images(3)).unwrap();
    let data = Dataset::load(dir.path(), &LoadOptions::default()).unwrap();
    assert_eq!(data.source, ImageSource::Npy);
    assert_eq!(data.saturation, Some(NPY_SATURATION));
    assert_eq!((data.width(), data.height()), (W, H));
    let raw = npy_images(3);
    for (i, view) in data.views.iter().enumerate() {
        assert_eq!(view.camera.index, i);
        for y in 0..H {
            for x in 0..W {
                let got = view.image.get(x, y);
                for (c, g) in got.iter().enumerate() {
                    let want = raw[[i, y as usize, x as usize, c]] / 40.0 * 5.0;
                    assert!((g - want).abs() < 1e-5, "{g} vs {want}");
                }
            }
        }
    }
    // Cameras alone: the size comes from the npy header.
    let cams = Dataset::load_cameras(dir.path()).unwrap();
    assert_eq!((cams[0].width, cams[0].height), (W, H));
}

#[test]
fn images_npy_without_max_intensity_uses_the_data_maximum() {
    let dir = tempfile::tempdir().unwrap();
    write_cameras(dir.path(), 2, None);
    ndarray_npy::write_npy(dir.path().join("images.npy"), &npy_images(2)).unwrap();
    let data = Dataset::load(dir.path(), &LoadOptions::default()).unwrap();
    let max = data
        .views
        .iter()
        .map(|v| v.image.max_value())
        .fold(0.0, f32::max);
    assert!((max - 5.0).abs() < 1e-6);
}

#[test]
fn images_npy_errors() {
    let dir = tempfile::tempdir().unwrap();
    write_cameras(dir.path(), 2, None);
    ndarray_npy::write_npy(dir.path().join("images.npy"), &npy_images(3)).unwrap();
    let err = Dataset::load(dir.path(), &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("images.npy") && err.contains("3 images for 2 cameras"),
        "{err}"
    );
    ndarray_npy::write_npy(
        dir.path().join("images.npy"),
        &ndarray::Array3::<f32>::zeros((2, 3, 5)),
    )
    .unwrap();
    let err = Dataset::load(dir.path(), &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("images.npy") && err.contains("expected (N, H, W, 3)"),
        "{err}"
    );
    let mut bad = npy_images(2);
    bad[[1, 2, 4, 0]] = f32::NAN;
    ndarray_npy::write_npy(dir.path().join("images.npy"), &bad).unwrap();
    let err = Dataset::load(dir.path(), &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("images.npy") && err.contains("x=4, y=2") && err.contains("NaN"),
        "{err}"
    );
}

#[test]
fn names_that_are_not_numbers_match_in_sorted_order() {
    let dir = tempfile::tempdir().unwrap();
    write_cameras(dir.path(), 2, None);
    let mut a = RgbImage::new(W, H);
    a.set(0, 0, [1.0, 0.0, 0.0]);
    let mut b = RgbImage::new(W, H);
    b.set(0, 0, [2.0, 0.0, 0.0]);
    write_exr_rgb(&dir.path().join("image/IMG_a.exr"), &a).unwrap();
    write_exr_rgb(&dir.path().join("image/IMG_b.exr"), &b).unwrap();
    let data = Dataset::load(dir.path(), &LoadOptions::default()).unwrap();
    assert_eq!(data.views[0].image, a);
    assert_eq!(data.views[1].image, b);
    write_exr_rgb(&dir.path().join("image/IMG_c.exr"), &b).unwrap();
    let err = Dataset::load(dir.path(), &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("not numbers") && err.contains("3 files for 2 cameras"),
        "{err}"
    );
}
