//! `wildlight import` from the outside: clear failures with a non-zero
//! exit and nothing written on bad input, COLMAP missing from PATH, and
//! (when COLMAP is installed) `--json` on eight phone-like photos.

mod common;

use std::path::Path;

fn import(args: &[&str]) -> std::process::Output {
    common::wildlight()
        .arg("import")
        .args(args)
        .output()
        .unwrap()
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn an_empty_folder_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let photos = dir.path().join("photos");
    std::fs::create_dir(&photos).unwrap();
    let out = dir.path().join("capture");
    let o = import(&[common::path_arg(&photos), "--out", common::path_arg(&out)]);
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(err.contains("no photos found"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists());
}

#[test]
fn colmap_missing_says_how_to_install_it() {
    let dir = tempfile::tempdir().unwrap();
    let photos = dir.path().join("photos");
    std::fs::create_dir(&photos).unwrap();
    for k in 0..3 {
        image::RgbImage::from_pixel(40, 30, image::Rgb([k * 50, 100, 150]))
            .save(photos.join(format!("p{k}.png")))
            .unwrap();
    }
    let out = dir.path().join("capture");
    let o = common::wildlight()
        .env("PATH", dir.path().join("empty-bin"))
        .args([
            "import",
            common::path_arg(&photos),
            "--out",
            common::path_arg(&out),
        ])
        .args(["--flash", "p0.png", "--no-flash", "p1.png,p2.png"])
        .output()
        .unwrap();
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(
        err.contains("COLMAP is not installed") && err.contains("apt-get install colmap"),
        "{err}"
    );
    assert!(!out.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "left files beside --out"
    );
}

#[test]
fn center_needs_radius() {
    let o = import(&["photos", "--out", "x", "--center", "0,0,0"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("--radius"), "{}", stderr(&o));
}

#[test]
fn json_report_on_eight_photos() {
    let has_colmap = std::env::split_paths(&std::env::var_os("PATH").unwrap_or_default())
        .any(|d| d.join("colmap").is_file());
    if !has_colmap {
        println!(
            "json_report_on_eight_photos: skipped: COLMAP is not installed (apt-get install colmap)"
        );
        return;
    }
    let photos = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("crates/wildlight-import/tests/fixtures/phone-arc/photos");
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("capture");
    let o = import(&[
        common::path_arg(&photos),
        "--out",
        common::path_arg(&out),
        "--json",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("import:"), "--json prints no progress");
    let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert!(j["registered"].as_u64().unwrap() >= 6);
    assert_eq!(j["photos"].as_array().unwrap().len(), 8);
    assert_eq!(
        j["flash_count"].as_u64().unwrap() + j["no_flash_count"].as_u64().unwrap(),
        j["registered"].as_u64().unwrap()
    );
    // `info` reads the capture
    let info = common::run_json(&["info", "--data", common::path_arg(&out), "--json"]);
    assert_eq!(info["images"], j["registered"]);
}
