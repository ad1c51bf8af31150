//! Writing a dataset with `DatasetWriter` and loading it back gives the same
//! cameras, images and masks.

use glam::{DMat4, DVec3, DVec4};
use wildlight_data::camera::intrinsics_from_fov_x;
use wildlight_data::writer::ViewToWrite;
use wildlight_data::{Camera, Dataset, DatasetWriter, LoadOptions, Mask, RgbImage};

fn scale_mat() -> DMat4 {
    DMat4::from_cols(
        DVec4::new(0.25, 0.0, 0.0, 0.0),
        DVec4::new(0.0, 0.25, 0.0, 0.0),
        DVec4::new(0.0, 0.0, 0.25, 0.0),
        DVec4::new(0.12, -0.04, 0.07, 1.0),
    )
}

fn cameras(first_index: usize, count: usize) -> Vec<Camera> {
    let (w, h) = (20, 12);
    let k = intrinsics_from_fov_x(w, h, 40.0);
    let s = scale_mat();
    (0..count)
        .map(|i| {
            let a = 0.9 * i as f64 + 0.3;
            let eye_n = DVec3::new(2.5 * a.cos(), 0.4 + 0.1 * i as f64, 2.5 * a.sin());
            let eye = s.transform_point3(eye_n);
            let target = s.transform_point3(DVec3::ZERO);
            let energy = if i.is_multiple_of(2) {
                [3.0, 2.5, 2.0]
            } else {
                [0.0; 3]
            };
            Camera::look_at(first_index + i, w, h, k, eye, target, DVec3::Y, s, energy).unwrap()
        })
        .collect()
}

fn image_for(cam: &Camera) -> RgbImage {
    let mut img = RgbImage::new(cam.width, cam.height);
    for y in 0..cam.height {
        for x in 0..cam.width {
            let v = (x as f32 * 0.37 + y as f32 * 1.3 + cam.index as f32).sin();
            img.set(x, y, [v, 2.0 * v + 1.5, 1e-3 * x as f32]);
        }
    }
    img
}

fn mask_for(cam: &Camera) -> Mask {
    let mut m = Mask::new(cam.width, cam.height);
    for y in 0..cam.height {
        for x in 0..cam.width {
            m.set(x, y, (x + y + cam.index as u32).is_multiple_of(3));
        }
    }
    m
}

#[test]
fn written_dataset_loads_back_identically() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("capture");
    let writer = DatasetWriter::create(&root).unwrap();
    let cams = cameras(0, 4);
    let images: Vec<RgbImage> = cams.iter().map(image_for).collect();
    let masks: Vec<Mask> = cams.iter().map(mask_for).collect();
    // View 3 has no mask.
    let views: Vec<ViewToWrite> = (0..4)
        .map(|i| ViewToWrite {
            camera: &cams[i],
            image: &images[i],
            mask: (i != 3).then_some(&masks[i]),
        })
        .collect();
    writer.write_views(&views, None).unwrap();
    let val_cams = cameras(0, 2);
    let val_images: Vec<RgbImage> = val_cams.iter().map(image_for).collect();
    let val_masks: Vec<Mask> = val_cams.iter().map(mask_for).collect();
    let val_views: Vec<ViewToWrite> = (0..2)
        .map(|i| ViewToWrite {
            camera: &val_cams[i],
            image: &val_images[i],
            mask: Some(&val_masks[i]),
        })
        .collect();
    writer.val().unwrap().write_views(&val_views, None).unwrap();

    let data = Dataset::load(&root, &LoadOptions::default()).unwrap();
    assert_eq!(data.views.len(), 4);
    assert_eq!(
        data.saturation, None,
        "EXR without max_intensity has no cap"
    );
    assert_eq!(data.flash_count(), 2);
    for (i, view) in data.views.iter().enumerate() {
        let c = &view.camera;
        assert_eq!(c.index, i);
        assert_eq!(
            c.world_mat, cams[i].world_mat,
            "world_mat stored as float64 exactly"
        );
        assert_eq!(c.scale_mat, cams[i].scale_mat);
        assert_eq!(c.light_energy, cams[i].light_energy);
        assert!(c.center.abs_diff_eq(cams[i].center, 1e-12));
        assert!((c.k - cams[i].k).abs_diff_eq(glam::DMat3::ZERO, 1e-9));
        assert_eq!(view.image, images[i]);
        assert_eq!(view.mask.as_ref(), (i != 3).then_some(&masks[i]));
        assert_eq!(
            view.image_path,
            root.join("image").join(format!("00{i}.exr"))
        );
    }
    let val = data.val.as_ref().expect("val split loaded");
    assert_eq!(val.views.len(), 2);
    assert_eq!(val.views[1].image, val_images[1]);
    assert_eq!(val.views[0].mask.as_ref(), Some(&val_masks[0]));
    // No temporary files are left behind.
    for sub in ["", "image", "mask"] {
        for e in std::fs::read_dir(root.join(sub)).unwrap() {
            let name = e.unwrap().file_name().to_string_lossy().to_string();
            assert!(!name.ends_with(".tmp"), "{name}");
        }
    }
}

#[test]
fn max_intensity_is_written_and_read() {
    let dir = tempfile::tempdir().unwrap();
    let writer = DatasetWriter::create(dir.path()).unwrap();
    let cams = cameras(7, 2);
    let images: Vec<RgbImage> = cams.iter().map(image_for).collect();
    let views: Vec<ViewToWrite> = (0..2)
        .map(|i| ViewToWrite {
            camera: &cams[i],
            image: &images[i],
            mask: None,
        })
        .collect();
    writer.write_views(&views, Some(3.25)).unwrap();
    let data = Dataset::load(dir.path(), &LoadOptions::default()).unwrap();
    assert_eq!(data.saturation, Some(3.25));
    assert_eq!(data.views[0].camera.index, 7);
    assert_eq!(data.views[1].camera.index, 8);
    assert!(!data.has_masks());
    assert!(data.val.is_none());
    let only_cameras = Dataset::load_cameras(dir.path()).unwrap();
    assert_eq!(only_cameras.len(), 2);
    assert_eq!((only_cameras[0].width, only_cameras[0].height), (20, 12));
    // From the npz alone the size is estimated from the principal point.
    let from_npz = Dataset::load_cameras(&dir.path().join("cameras_sphere.npz")).unwrap();
    assert_eq!((from_npz[1].width, from_npz[1].height), (20, 12));
}

#[test]
fn ground_truth_maps_go_under_gt() {
    let dir = tempfile::tempdir().unwrap();
    let writer = DatasetWriter::create(dir.path()).unwrap();
    let img = image_for(&cameras(0, 1)[0]);
    let p = writer.write_map("normal", 4, &img).unwrap();
    assert_eq!(p, dir.path().join("gt/normal/004.exr"));
    assert_eq!(wildlight_data::exr_io::read_exr_rgb(&p).unwrap(), img);
    let plane: Vec<f32> = (0..img.pixel_count()).map(|i| i as f32).collect();
    let names = ["p0", "p1"];
    let chans: Vec<(&str, &[f32])> = names.iter().map(|n| (*n, plane.as_slice())).collect();
    let p = writer
        .write_map_channels("params", 4, img.width, img.height, &chans)
        .unwrap();
    let back = wildlight_data::exr_io::read_exr_channels(&p).unwrap();
    assert_eq!(back.channel("p1").unwrap(), plane.as_slice());
}

#[test]
fn writer_refuses_mismatched_sizes() {
    let dir = tempfile::tempdir().unwrap();
    let writer = DatasetWriter::create(dir.path()).unwrap();
    let cams = cameras(0, 1);
    let small = RgbImage::new(3, 3);
    let err = writer
        .write_views(
            &[ViewToWrite {
                camera: &cams[0],
                image: &small,
                mask: None,
            }],
            None,
        )
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("000.exr") && err.contains("3x3") && err.contains("20x12"),
        "{err}"
    );
    let img = image_for(&cams[0]);
    let bad_mask = Mask::new(5, 5);
    let err = writer
        .write_views(
            &[ViewToWrite {
                camera: &cams[0],
                image: &img,
                mask: Some(&bad_mask),
            }],
            None,
        )
        .unwrap_err()
        .to_string();
    assert!(err.contains("000.png") && err.contains("5x5"), "{err}");
}
