//! Every bad dataset gives one clear error naming the file and the problem
//! (issue 2, "Bad input"), and never panics.

use std::path::Path;

use glam::{DMat4, DVec3};
use wildlight_data::camera::intrinsics_from_fov_x;
use wildlight_data::exr_io::write_exr_rgb;
use wildlight_data::png_io::write_mask_png;
use wildlight_data::writer::ViewToWrite;
use wildlight_data::{Camera, Dataset, DatasetWriter, LoadOptions, Mask, RgbImage};

const W: u32 = 8;
const H: u32 = 6;

/// Writes a valid 3-view EXR dataset with masks into `root`.
fn write_valid(root: &Path) -> DatasetWriter {
    let writer = DatasetWriter::create(root).unwrap();
    let k = intrinsics_from_fov_x(W, H, 60.0);
    let cams: Vec<Camera> = (0..3)
        .map(|i| {
            let eye = DVec3::new(3.0 * (i as f64).cos(), 0.5, 3.0 * (i as f64).sin());
            Camera::look_at(
                i,
                W,
                H,
                k,
                eye,
                DVec3::ZERO,
                DVec3::Y,
                DMat4::IDENTITY,
                [1.0; 3],
            )
            .unwrap()
        })
        .collect();
    let mut image = RgbImage::new(W, H);
    image
        .data
        .iter_mut()
        .enumerate()
        .for_each(|(i, v)| *v = i as f32 / 100.0);
    let mut mask = Mask::new(W, H);
    mask.set(3, 3, true);
    let views: Vec<ViewToWrite> = cams
        .iter()
        .map(|c| ViewToWrite {
            camera: c,
            image: &image,
            mask: Some(&mask),
        })
        .collect();
    writer.write_views(&views, None).unwrap();
    writer
}

fn load_err(root: &Path) -> String {
    Dataset::load(root, &LoadOptions::default())
        .unwrap_err()
        .to_string()
}

fn assert_mentions(err: &str, needles: &[&str]) {
    for n in needles {
        assert!(err.contains(n), "error lacks {n:?}: {err}");
    }
}

#[test]
fn valid_dataset_loads() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    let data = Dataset::load(dir.path(), &LoadOptions::default()).unwrap();
    assert_eq!(data.views.len(), 3);
    assert_eq!(data.views[2].mask.as_ref().unwrap().count(), 1);
}

#[test]
fn missing_folder() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-capture");
    assert_mentions(
        &load_err(&missing),
        &["no-such-capture", "dataset folder not found"],
    );
}

#[test]
fn missing_npz() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    std::fs::remove_file(dir.path().join("cameras_sphere.npz")).unwrap();
    assert_mentions(
        &load_err(dir.path()),
        &["cameras_sphere.npz", "file not found"],
    );
}

#[test]
fn no_images() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    for i in 0..3 {
        std::fs::remove_file(dir.path().join(format!("image/00{i}.exr"))).unwrap();
    }
    assert_mentions(&load_err(dir.path()), &["no images found"]);
}

#[test]
fn image_without_camera() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    write_exr_rgb(&dir.path().join("image/007.exr"), &RgbImage::new(W, H)).unwrap();
    assert_mentions(
        &load_err(dir.path()),
        &["image", "cameras_sphere.npz", "no world_mat_<i>", "[7]"],
    );
}

#[test]
fn camera_without_image() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    std::fs::remove_file(dir.path().join("image/001.exr")).unwrap();
    assert_mentions(
        &load_err(dir.path()),
        &["image", "no file for camera indices [1]"],
    );
}

#[test]
fn two_files_for_one_index() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    std::fs::copy(
        dir.path().join("image/001.exr"),
        dir.path().join("image/1.exr"),
    )
    .unwrap();
    assert_mentions(
        &load_err(dir.path()),
        &["001.exr", "1.exr", "both claim index 1"],
    );
}

#[test]
fn images_of_different_sizes() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    write_exr_rgb(&dir.path().join("image/002.exr"), &RgbImage::new(W + 1, H)).unwrap();
    assert_mentions(&load_err(dir.path()), &["002.exr", "9x6", "000.exr", "8x6"]);
}

#[test]
fn mask_of_another_size() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    write_mask_png(&dir.path().join("mask/001.png"), &Mask::new(W, H + 2)).unwrap();
    assert_mentions(
        &load_err(dir.path()),
        &["001.png", "mask is 8x8", "image is 8x6"],
    );
}

#[test]
fn mask_without_camera() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    write_mask_png(&dir.path().join("mask/004.png"), &Mask::new(W, H)).unwrap();
    assert_mentions(&load_err(dir.path()), &["mask", "[4]"]);
}

#[test]
fn nan_pixel() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    let mut img = RgbImage::new(W, H);
    img.set(5, 2, [0.0, f32::NAN, 0.0]);
    write_exr_rgb(&dir.path().join("image/001.exr"), &img).unwrap();
    assert_mentions(
        &load_err(dir.path()),
        &["001.exr", "x=5, y=2", "channel 1", "NaN"],
    );
}

#[test]
fn infinite_pixel() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    let mut img = RgbImage::new(W, H);
    img.set(0, 5, [f32::INFINITY, 0.0, 0.0]);
    write_exr_rgb(&dir.path().join("image/002.exr"), &img).unwrap();
    assert_mentions(&load_err(dir.path()), &["002.exr", "x=0, y=5", "inf"]);
}

#[test]
fn unreadable_exr() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    std::fs::write(dir.path().join("image/001.exr"), b"not an exr").unwrap();
    assert_mentions(&load_err(dir.path()), &["001.exr", "unreadable EXR image"]);
}

#[test]
fn truncated_exr() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    let path = dir.path().join("image/000.exr");
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() / 2]).unwrap();
    assert_mentions(&load_err(dir.path()), &["000.exr", "unreadable EXR image"]);
}

#[test]
fn unreadable_png_image() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    for i in 0..3 {
        std::fs::remove_file(dir.path().join(format!("image/00{i}.exr"))).unwrap();
        write_mask_png(
            &dir.path().join(format!("image/00{i}.png")),
            &Mask::new(W, H),
        )
        .unwrap();
    }
    std::fs::write(dir.path().join("image/002.png"), b"\x89PNG garbage").unwrap();
    assert_mentions(&load_err(dir.path()), &["002.png", "unreadable PNG image"]);
}

#[test]
fn unreadable_mask() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    std::fs::write(dir.path().join("mask/000.png"), b"").unwrap();
    assert_mentions(&load_err(dir.path()), &["000.png", "unreadable PNG image"]);
}

#[test]
fn singular_projection_in_folder() {
    let dir = tempfile::tempdir().unwrap();
    write_valid(dir.path());
    let mut cams = Dataset::load_cameras(dir.path()).unwrap();
    cams[1].world_mat.z_axis = cams[1].world_mat.x_axis; // two equal columns: rank 2
    let arrays: Vec<_> = cams.iter().map(Camera::to_arrays).collect();
    wildlight_data::npz::write_cameras_npz(&dir.path().join("cameras_sphere.npz"), &arrays, None)
        .unwrap();
    assert_mentions(
        &load_err(dir.path()),
        &["cameras_sphere.npz", "camera 1", "singular projection"],
    );
}

#[test]
fn bad_val_split_is_reported_with_its_path() {
    let dir = tempfile::tempdir().unwrap();
    let writer = write_valid(dir.path());
    let val = writer.val().unwrap();
    // val/ exists with images but no cameras.
    write_exr_rgb(&val.image_path(0), &RgbImage::new(W, H)).unwrap();
    assert_mentions(
        &load_err(dir.path()),
        &["val", "cameras_sphere.npz", "file not found"],
    );
}
