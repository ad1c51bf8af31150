//! `wildlight info` from the outside: the JSON interface of issue 2 on the
//! Mitsuba capture (an independent NeuS-format writer), the table, the
//! warnings, and clear failures on bad input.

mod common;

use std::path::Path;
use std::process::Output;

use common::mitsuba_torus as torus;

fn info(args: &[&str]) -> Output {
    common::wildlight().arg("info").args(args).output().unwrap()
}

fn json_of(dir: &Path) -> serde_json::Value {
    common::run_json(&["info", "--data", dir.to_str().unwrap(), "--json"])
}

fn vec3(v: &serde_json::Value) -> [f64; 3] {
    serde_json::from_value(v.clone()).unwrap()
}

#[test]
fn json_reports_the_mitsuba_cameras_exactly() {
    let j = json_of(&torus());
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(torus().join("meta.json")).unwrap()).unwrap();
    assert_eq!(j["images"], 12);
    assert_eq!(j["flash_images"], 6);
    assert_eq!(j["width"], 96);
    assert_eq!(j["height"], 96);
    assert_eq!(j["has_masks"], true);
    assert!(j["saturation"].is_null());
    assert_eq!(j["val_images"], 2);
    let le = vec3(&meta["light_energy"]);
    let f = 48.0 / 22.5f64.to_radians().tan();
    let cams = j["cameras"].as_array().unwrap();
    let views = meta["views"].as_array().unwrap();
    assert_eq!(cams.len(), views.len());
    for (c, m) in cams.iter().zip(views) {
        assert_eq!(c["index"], m["index"]);
        assert_eq!(c["flash"], m["flash"]);
        let flash = c["flash"].as_bool().unwrap();
        assert_eq!(flash, c["index"].as_u64().unwrap() % 2 == 0);
        for (key, meta_key) in [
            ("center_normalized", "C_normalized"),
            ("center_world", "C_world"),
        ] {
            let (a, b) = (vec3(&c[key]), vec3(&m[meta_key]));
            for k in 0..3 {
                assert!(
                    (a[k] - b[k]).abs() < 1e-5,
                    "camera {}: {key} {a:?} vs {b:?}",
                    c["index"]
                );
            }
        }
        let e = vec3(&c["light_energy"]);
        for k in 0..3 {
            let want = if flash { le[k] } else { 0.0 };
            assert!(
                (e[k] - want).abs() < 1e-5,
                "camera {}: light_energy {e:?}",
                c["index"]
            );
        }
        for key in ["fx", "fy"] {
            assert!((c[key].as_f64().unwrap() - f).abs() < 1e-3);
        }
        for key in ["cx", "cy"] {
            assert!((c[key].as_f64().unwrap() - 47.5).abs() < 1e-3);
        }
    }
    let d = &j["camera_distance"];
    assert!(d["min"].as_f64().unwrap() > 2.0 && d["max"].as_f64().unwrap() < 4.0);
    assert!(j["mask_coverage"]["mean"].as_f64().unwrap() > 0.1);
    assert_eq!(j["warnings"].as_array().unwrap().len(), 0);
}

#[test]
fn table_is_readable() {
    let out = info(&["--data", torus().to_str().unwrap()]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.contains("12 (6 with flash), 96x96"), "{text}");
    assert!(text.contains("saturation  none"), "{text}");
    assert!(text.contains("val         2 images"), "{text}");
    // One line per camera, training and val.
    assert!(
        text.lines()
            .filter(|l| l.trim_start().starts_with("val "))
            .count()
            >= 2,
        "{text}"
    );
}

#[test]
fn a_warning_without_flash_and_a_note_without_masks() {
    let dir = tempfile::tempdir().unwrap();
    // The Mitsuba cameras and images, with every light_energy removed and no masks.
    std::fs::create_dir(dir.path().join("image")).unwrap();
    for i in 0..12 {
        let name = format!("{i:03}.exr");
        std::fs::copy(
            torus().join("image").join(&name),
            dir.path().join("image").join(&name),
        )
        .unwrap();
    }
    let mut cams = wildlight_data::Dataset::load_cameras(&torus()).unwrap();
    for c in &mut cams {
        c.light_energy = [0.0; 3];
    }
    let arrays: Vec<_> = cams.iter().map(|c| c.to_arrays()).collect();
    wildlight_data::npz::write_cameras_npz(&dir.path().join("cameras_sphere.npz"), &arrays, None)
        .unwrap();
    let j = json_of(dir.path());
    assert_eq!(j["flash_images"], 0);
    assert_eq!(j["has_masks"], false);
    let warnings: Vec<String> = serde_json::from_value(j["warnings"].clone()).unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("reflectance cannot be separated")),
        "{warnings:?}"
    );
    let notes: Vec<String> = serde_json::from_value(j["notes"].clone()).unwrap();
    assert!(
        notes
            .iter()
            .any(|n| n.contains("no masks: training will model the background")),
        "{notes:?}"
    );
}

fn assert_fails(args: &[&str], needles: &[&str]) {
    let out = info(args);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    for n in needles {
        assert!(err.contains(n), "stderr lacks {n:?}: {err}");
    }
}

#[test]
fn missing_folder_fails_clearly() {
    assert_fails(
        &["--data", "/no/such/capture"],
        &["/no/such/capture", "dataset folder not found"],
    );
}

#[test]
fn bad_npz_fails_clearly() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("cameras_sphere.npz"), b"garbage").unwrap();
    assert_fails(
        &["--data", dir.path().to_str().unwrap()],
        &["cameras_sphere.npz", "cannot read npz"],
    );
}

#[test]
fn mismatched_images_fail_clearly() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(
        torus().join("cameras_sphere.npz"),
        dir.path().join("cameras_sphere.npz"),
    )
    .unwrap();
    std::fs::create_dir(dir.path().join("image")).unwrap();
    std::fs::copy(
        torus().join("image/000.exr"),
        dir.path().join("image/000.exr"),
    )
    .unwrap();
    assert_fails(
        &["--data", dir.path().to_str().unwrap()],
        &["image", "no file for camera indices [1, 2"],
    );
}
