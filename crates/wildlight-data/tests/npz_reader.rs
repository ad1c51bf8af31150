//! The npz reader on files written by numpy (`fixtures/make_fixtures.py`):
//! float32 and float64, 3×4 and 4×4, C and Fortran order, compared with
//! the camera parameters numpy computed (`fixtures/npz_expected.json`);
//! and every malformed npz gives an error naming the file and the problem.

use std::path::{Path, PathBuf};

use glam::{DMat3, DVec3};
use wildlight_data::npz::read_cameras_npz;
use wildlight_data::{Camera, Dataset};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/fixtures")
        .join(name)
}

fn expected() -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(fixture("npz_expected.json")).unwrap()).unwrap()
}

fn vec3(v: &serde_json::Value) -> DVec3 {
    let a: Vec<f64> = serde_json::from_value(v.clone()).unwrap();
    DVec3::new(a[0], a[1], a[2])
}

/// A 3×3 matrix from the JSON rows.
fn mat3(v: &serde_json::Value) -> DMat3 {
    let rows: Vec<Vec<f64>> = serde_json::from_value(v.clone()).unwrap();
    DMat3::from_cols_array_2d(&[
        [rows[0][0], rows[0][1], rows[0][2]],
        [rows[1][0], rows[1][1], rows[1][2]],
        [rows[2][0], rows[2][1], rows[2][2]],
    ])
    .transpose()
}

fn check_file(name: &str, tol_k: f64, tol_pose: f64, max_intensity: Option<f64>) {
    let path = fixture(name);
    let npz = read_cameras_npz(&path).unwrap();
    assert_eq!(npz.max_intensity, max_intensity, "{name}");
    let indices: Vec<usize> = npz.cameras.iter().map(|c| c.index).collect();
    assert_eq!(
        indices,
        vec![0, 1, 5],
        "{name}: world_mat_inv_* must be ignored"
    );
    let exp = expected();
    for arrays in &npz.cameras {
        let e = &exp["cameras"][arrays.index.to_string()];
        let cam = Camera::from_arrays(arrays, 64, 48, &path).unwrap();
        let k = mat3(&e["K"]);
        assert!(
            (cam.k - k).abs_diff_eq(DMat3::ZERO, tol_k),
            "{name} camera {}: K {:?} vs {k:?}",
            arrays.index,
            cam.k
        );
        assert_eq!(cam.k.z_axis.z, 1.0);
        let c2w = mat3(&e["c2w"]);
        assert!(
            (cam.c2w - c2w).abs_diff_eq(DMat3::ZERO, tol_pose),
            "{name} camera {}: c2w",
            arrays.index
        );
        let c = vec3(&e["center_normalized"]);
        assert!(
            cam.center.abs_diff_eq(c, tol_pose),
            "{name} camera {}: {:?} vs {c:?}",
            arrays.index,
            cam.center
        );
        let cw = vec3(&e["center_world"]);
        assert!(
            cam.center_world().abs_diff_eq(cw, tol_pose),
            "{name} camera {}",
            arrays.index
        );
        let le: Vec<f64> = serde_json::from_value(e["light_energy"].clone()).unwrap();
        assert_eq!(cam.light_energy.to_vec(), le);
        assert_eq!(cam.flash(), arrays.index != 1);
    }
}

#[test]
fn float64_4x4() {
    check_file("cams_f64_4x4.npz", 1e-9, 1e-11, Some(4.5));
}

#[test]
fn float32_3x4() {
    // float32 storage: about 7 significant digits.
    check_file("cams_f32_3x4.npz", 2e-3, 2e-5, None);
}

#[test]
fn float32_4x4_fortran_order() {
    check_file("cams_f32_4x4_fortran.npz", 2e-3, 2e-5, None);
}

#[test]
fn float64_3x4_fortran_order() {
    check_file("cams_f64_3x4_fortran.npz", 1e-9, 1e-11, None);
}

#[test]
fn float64_compressed_savez() {
    check_file("cams_f64_4x4_compressed.npz", 1e-9, 1e-11, Some(4.5));
}

/// Asserts that `err` names `file` and contains every `needle`.
fn assert_mentions(err: &str, file: &str, needles: &[&str]) {
    assert!(err.contains(file), "error does not name {file}: {err}");
    for n in needles {
        assert!(err.contains(n), "error lacks {n:?}: {err}");
    }
}

fn npz_error(name: &str) -> String {
    read_cameras_npz(&fixture(name)).unwrap_err().to_string()
}

#[test]
fn missing_npz() {
    assert_mentions(&npz_error("nope.npz"), "nope.npz", &["file not found"]);
}

#[test]
fn not_an_npz() {
    assert_mentions(
        &npz_error("bad_not_a_zip.npz"),
        "bad_not_a_zip.npz",
        &["cannot read npz"],
    );
}

#[test]
fn npz_without_world_mat() {
    assert_mentions(
        &npz_error("bad_no_world_mat.npz"),
        "bad_no_world_mat.npz",
        &["no world_mat_<i>", "scale_mat_0", "light_energy_0"],
    );
}

#[test]
fn world_mat_of_wrong_shape() {
    assert_mentions(
        &npz_error("bad_shape.npz"),
        "bad_shape.npz",
        &["world_mat_0", "[3, 3]", "4x4 or 3x4"],
    );
}

#[test]
fn scale_mat_of_wrong_shape() {
    assert_mentions(
        &npz_error("bad_scale_shape.npz"),
        "bad_scale_shape.npz",
        &["scale_mat_0", "[2, 2]"],
    );
}

#[test]
fn missing_scale_mat() {
    assert_mentions(
        &npz_error("bad_missing_scale.npz"),
        "bad_missing_scale.npz",
        &["scale_mat_0", "missing"],
    );
}

#[test]
fn nan_in_world_mat() {
    assert_mentions(
        &npz_error("bad_nan.npz"),
        "bad_nan.npz",
        &["world_mat_0", "NaN"],
    );
}

#[test]
fn light_energy_of_wrong_length() {
    assert_mentions(
        &npz_error("bad_light_energy.npz"),
        "bad_light_energy.npz",
        &["light_energy_0", "[4]"],
    );
}

#[test]
fn singular_projection() {
    // The arrays are well formed; the projection they describe is not.
    let err = Dataset::load_cameras(&fixture("bad_singular.npz"))
        .unwrap_err()
        .to_string();
    assert_mentions(
        &err,
        "bad_singular.npz",
        &["camera 0", "singular projection", "rank < 3"],
    );
}

#[test]
fn scale_mat_must_be_affine() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("cameras_sphere.npz");
    let mut arrays = read_cameras_npz(&fixture("cams_f64_4x4.npz"))
        .unwrap()
        .cameras;
    // Rounding noise in the last row is accepted (and dropped).
    arrays[0].scale_mat.x_axis.w = 1e-12;
    wildlight_data::npz::write_cameras_npz(&path, &arrays, None).unwrap();
    let back = read_cameras_npz(&path).unwrap();
    assert_eq!(back.cameras[0].scale_mat.x_axis.w, 0.0);
    // A projective last row is not.
    arrays[1].scale_mat.z_axis.w = 0.5;
    wildlight_data::npz::write_cameras_npz(&path, &arrays, None).unwrap();
    let err = read_cameras_npz(&path).unwrap_err().to_string();
    assert_mentions(
        &err,
        "cameras_sphere.npz",
        &["scale_mat_1", "last row", "affine"],
    );
}
