//! COLMAP models read back: a hand-written text model and a hand-built
//! binary one whose cameras project known points to known pixels, a
//! round trip through both writers, and errors naming the file.

mod common;

use glam::{DVec2, DVec3};
use wildlight_import::colmap::{CameraModel, ColmapModel};

const CAMERAS_TXT: &str = "\
# Camera list with one line of data per camera:
#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]
# Number of cameras: 2
1 PINHOLE 200 100 100 110 100.5 50.5
2 SIMPLE_RADIAL 200 100 100 100 50 0.1
";

// Image 1: identity rotation, t = (0, 0, 5). Image 2: 90° about y
// (q = (cos 45°, 0, sin 45°, 0)), t = (0, 0, 5), SIMPLE_RADIAL camera,
// and no keypoints (an empty second line).
const IMAGES_TXT: &str = "\
# Image list with two lines of data per image:
#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME
#   POINTS2D[] as (X, Y, POINT3D_ID)
# Number of images: 2, mean observations per image: 1
1 1 0 0 0 0 0 5 1 IMG_0001.jpg
120.5 94.5 7 10.0 20.0 -1
3 0.7071067811865476 0 0.7071067811865476 0 0 0 5 2 sub dir/IMG_0002.jpg

";

const POINTS_TXT: &str = "\
# 3D point list with one line of data per point:
#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, POINT2D_IDX)
7 1 2 0 255 128 0 0.25 1 0 3 0
8 -1 0.5 2 10 20 30 0.75 1 1
";

fn project(model: &ColmapModel, image: u32, p: DVec3) -> DVec2 {
    let im = &model.images[&image];
    model.cameras[&im.camera_id]
        .project(im.to_camera(p))
        .expect("in front")
}

fn check_known_model(m: &ColmapModel) {
    assert_eq!(m.cameras.len(), 2);
    assert_eq!(m.cameras[&1].model, CameraModel::Pinhole);
    assert_eq!(m.cameras[&2].params, [100.0, 100.0, 50.0, 0.1]);
    assert_eq!(m.images.len(), 2);
    assert_eq!(m.images[&3].name, "sub dir/IMG_0002.jpg");
    assert!(m.images[&3].points2d.is_empty());
    assert_eq!(m.images[&1].points2d, [(120.5, 94.5, 7), (10.0, 20.0, -1)]);
    assert_eq!(m.points.len(), 2);
    assert_eq!(m.points[0].rgb, [255, 128, 0]);
    assert_eq!(m.points[0].track, [(1, 0), (3, 0)]);
    assert!((m.mean_reprojection_error() - 0.5).abs() < 1e-12);

    // Point 7 = (1, 2, 0). Image 1: camera coordinates (1, 2, 5) →
    // (100 · 0.2 + 100.5, 110 · 0.4 + 50.5) = (120.5, 94.5), its keypoint.
    let q = project(m, 1, DVec3::new(1.0, 2.0, 0.0));
    assert!((q - DVec2::new(120.5, 94.5)).length() < 1e-9, "{q}");
    // Image 2: R = rotation of 90° about y: (x, y, z) → (z, y, −x), so
    // (1, 2, 0) → (0, 2, −1) + t = (0, 2, 4) → normalized (0, 0.5);
    // SIMPLE_RADIAL k = 0.1: r² = 0.25 → × 1.025 → (0, 0.5125) →
    // pixel (100 · 0 + 100, 100 · 0.5125 + 50) = (100, 101.25).
    let q = project(m, 3, DVec3::new(1.0, 2.0, 0.0));
    assert!((q - DVec2::new(100.0, 101.25)).length() < 1e-9, "{q}");
    // Centres −Rᵀt: image 1 at (0, 0, −5); image 2 at −Rᵀ(0, 0, 5) = (5, 0, 0).
    assert!((m.images[&1].center() - DVec3::new(0.0, 0.0, -5.0)).length() < 1e-12);
    let c2 = m.images[&3].center();
    assert!((c2 - DVec3::new(5.0, 0.0, 0.0)).length() < 1e-9, "{c2}");
    // the optical axis of image 2 points from its centre to the origin
    assert!((m.images[&3].axis() - DVec3::new(-1.0, 0.0, 0.0)).length() < 1e-9);
    // and unproject inverts project through the distortion
    let uv = m.cameras[&2].unproject(DVec2::new(100.0, 101.25)).unwrap();
    assert!((uv - DVec2::new(0.0, 0.5)).length() < 1e-9, "{uv}");
}

fn write_text(dir: &std::path::Path) {
    std::fs::write(dir.join("cameras.txt"), CAMERAS_TXT).unwrap();
    std::fs::write(dir.join("images.txt"), IMAGES_TXT).unwrap();
    std::fs::write(dir.join("points3D.txt"), POINTS_TXT).unwrap();
}

#[test]
fn text_model_projects_known_points_to_known_pixels() {
    let dir = tempfile::tempdir().unwrap();
    write_text(dir.path());
    let m = ColmapModel::read(dir.path()).unwrap();
    check_known_model(&m);
}

/// The same model as COLMAP's binary files, built byte by byte.
fn binary_files(dir: &std::path::Path) {
    let mut cams = Vec::new();
    cams.extend(2u64.to_le_bytes());
    for (id, model, params) in [
        (1i32, 1i32, vec![100.0f64, 110.0, 100.5, 50.5]),
        (2, 2, vec![100.0, 100.0, 50.0, 0.1]),
    ] {
        cams.extend(id.to_le_bytes());
        cams.extend(model.to_le_bytes());
        cams.extend(200u64.to_le_bytes());
        cams.extend(100u64.to_le_bytes());
        params.iter().for_each(|p| cams.extend(p.to_le_bytes()));
    }
    std::fs::write(dir.join("cameras.bin"), cams).unwrap();
    let h = std::f64::consts::FRAC_1_SQRT_2;
    let mut ims = Vec::new();
    ims.extend(2u64.to_le_bytes());
    for (id, q, cam, name, kps) in [
        (
            1i32,
            [1.0, 0.0, 0.0, 0.0],
            1i32,
            "IMG_0001.jpg",
            vec![(120.5f64, 94.5f64, 7i64), (10.0, 20.0, -1)],
        ),
        (3, [h, 0.0, h, 0.0], 2, "sub dir/IMG_0002.jpg", vec![]),
    ] {
        ims.extend(id.to_le_bytes());
        q.iter().for_each(|v: &f64| ims.extend(v.to_le_bytes()));
        [0.0f64, 0.0, 5.0]
            .iter()
            .for_each(|v| ims.extend(v.to_le_bytes()));
        ims.extend(cam.to_le_bytes());
        ims.extend(name.as_bytes());
        ims.push(0);
        ims.extend((kps.len() as u64).to_le_bytes());
        for (x, y, p) in kps {
            ims.extend(x.to_le_bytes());
            ims.extend(y.to_le_bytes());
            ims.extend(p.to_le_bytes());
        }
    }
    std::fs::write(dir.join("images.bin"), ims).unwrap();
    let mut pts = Vec::new();
    pts.extend(2u64.to_le_bytes());
    for (id, xyz, rgb, err, track) in [
        (
            7u64,
            [1.0f64, 2.0, 0.0],
            [255u8, 128, 0],
            0.25f64,
            vec![(1i32, 0i32), (3, 0)],
        ),
        (8, [-1.0, 0.5, 2.0], [10, 20, 30], 0.75, vec![(1, 1)]),
    ] {
        pts.extend(id.to_le_bytes());
        xyz.iter().for_each(|v| pts.extend(v.to_le_bytes()));
        pts.extend(rgb);
        pts.extend(err.to_le_bytes());
        pts.extend((track.len() as u64).to_le_bytes());
        for (i, k) in track {
            pts.extend(i.to_le_bytes());
            pts.extend(k.to_le_bytes());
        }
    }
    std::fs::write(dir.join("points3D.bin"), pts).unwrap();
}

#[test]
fn binary_model_projects_known_points_to_known_pixels() {
    let dir = tempfile::tempdir().unwrap();
    binary_files(dir.path());
    let m = ColmapModel::read(dir.path()).unwrap();
    check_known_model(&m);
    // the same model as the text files, field for field
    let text = tempfile::tempdir().unwrap();
    write_text(text.path());
    assert_eq!(m, ColmapModel::read(text.path()).unwrap());
}

#[test]
fn both_writers_round_trip() {
    let model = common::ring_model(
        6,
        3.0,
        DVec3::new(0.2, -0.1, 1.0),
        common::simple_radial(64, 48, 60.0, -0.02),
    );
    for binary in [false, true] {
        let dir = tempfile::tempdir().unwrap();
        if binary {
            model.write_binary(dir.path()).unwrap();
        } else {
            model.write_text(dir.path()).unwrap();
        }
        let back = ColmapModel::read(dir.path()).unwrap();
        assert_eq!(back, model, "binary: {binary}");
    }
}

#[test]
fn broken_models_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    // no model at all
    let err = ColmapModel::read(dir.path()).unwrap_err().to_string();
    assert!(err.contains("not a COLMAP sparse model"), "{err}");
    // a truncated images.bin
    binary_files(dir.path());
    let path = dir.path().join("images.bin");
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 5]).unwrap();
    let err = ColmapModel::read(dir.path()).unwrap_err().to_string();
    assert!(
        err.contains("images.bin") && err.contains("truncated"),
        "{err}"
    );
    // an unknown camera model in text, with its line number
    let dir = tempfile::tempdir().unwrap();
    write_text(dir.path());
    std::fs::write(
        dir.path().join("cameras.txt"),
        "# comment\n1 PINHOLE 200 100 100 110 100.5 50.5\n2 FISHEYE_X 1 1 1\n",
    )
    .unwrap();
    let err = ColmapModel::read(dir.path()).unwrap_err().to_string();
    assert!(
        err.contains("cameras.txt") && err.contains("line 3") && err.contains("FISHEYE_X"),
        "{err}"
    );
    // an image whose camera is missing
    std::fs::write(
        dir.path().join("cameras.txt"),
        "1 PINHOLE 200 100 100 110 100.5 50.5\n",
    )
    .unwrap();
    let err = ColmapModel::read(dir.path()).unwrap_err().to_string();
    assert!(err.contains("uses camera 2"), "{err}");
}
