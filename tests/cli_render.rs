//! `wildlight render --asset`: an exported asset ray traced with a
//! capture's cameras writes every map in the run renderer's layout (which
//! `wildlight eval images` reads), and bad input is reported clearly.

mod common;

use std::path::{Path, PathBuf};

use common::{path_arg, run};
use glam::Vec3;
use wildlight_data::Dataset;
use wildlight_data::exr_io::read_exr_rgb;
use wildlight_export::{
    AnalyticSource, AtlasOptions, ExportOptions, MarchingOptions, export_to_dir,
};

const RADIUS: f32 = 0.6;
const BASE_COLOR: [f32; 3] = [0.7, 0.45, 0.2];

/// A tiny synthetic capture (4 training views, 32×32) and a sphere of
/// radius 0.6 with one material exported in its world units.
fn capture_and_asset(dir: &Path) -> (PathBuf, PathBuf) {
    let data = dir.join("capture");
    let out = common::tiny_synth("kettle", &data)
        .output()
        .expect("the wildlight binary runs");
    assert!(
        out.status.success(),
        "synth: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let cameras = Dataset::load_cameras(&data).unwrap();
    let mut params = [0.3f32; 9];
    params[..3].copy_from_slice(&BASE_COLOR);
    let source = AnalyticSource::new(|p: Vec3| p.length() - RADIUS, move |_| params)
        .with_gradient(|p: Vec3| p.normalize_or_zero());
    let options = ExportOptions {
        marching: MarchingOptions {
            resolution: 48,
            ..Default::default()
        },
        max_faces: 3000,
        atlas: AtlasOptions {
            texture_size: 128,
            ..Default::default()
        },
        scale_mat: cameras[0].scale_mat.as_mat4(),
        progress: false,
        ..Default::default()
    };
    let (files, _) = export_to_dir(&source, &options, &dir.join("asset")).unwrap();
    (data, files.glb)
}

#[test]
fn asset_renders_every_map_and_eval_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    let (data, glb) = capture_and_asset(dir.path());
    let render = dir.path().join("render");
    let out = run(&[
        "render",
        "--asset",
        path_arg(&glb),
        "--data",
        path_arg(&data),
        "--split",
        "train",
        "--env",
        "sky",
        "--spp",
        "4",
        "--out",
        path_arg(&render),
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "render: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let views: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(render.join("views.json")).unwrap()).unwrap();
    let cameras = Dataset::load_cameras(&data).unwrap();
    assert_eq!(views.as_array().unwrap().len(), cameras.len());
    let mut hits = 0;
    for (view, camera) in views.as_array().unwrap().iter().zip(&cameras) {
        assert_eq!(view["index"], camera.index);
        assert_eq!(view["split"], "train");
        assert_eq!(view["flash"], camera.flash());
        let name = format!("{:03}.exr", camera.index);
        for kind in [
            "image",
            "flash",
            "ambient",
            "normal",
            "depth",
            "base_color",
            "roughness",
            "metallic",
            "acc",
            "params",
        ] {
            assert!(render.join(kind).join(&name).is_file(), "{kind}/{name}");
        }
        let depth = read_exr_rgb(&render.join("depth").join(&name)).unwrap();
        let base = read_exr_rgb(&render.join("base_color").join(&name)).unwrap();
        let flash = read_exr_rgb(&render.join("flash").join(&name)).unwrap();
        for y in 0..32 {
            for x in 0..32 {
                let d = depth.get(x, y)[0] as f64;
                if d == 0.0 {
                    continue;
                }
                hits += 1;
                // Depth is in world units; the hit lies on the sphere (or
                // inside it by the faceting of 3000 faces).
                let p = camera.ray(x as f64, y as f64).at(d / camera.world_scale());
                let r = p.length() as f32;
                assert!(
                    r < RADIUS + 1e-4 && r > RADIUS - 6e-3,
                    "({x},{y}): |p| = {r}"
                );
                let b = base.get(x, y);
                for c in 0..3 {
                    // 8-bit sRGB quantization of the base colour texture.
                    assert!((b[c] - BASE_COLOR[c]).abs() < 0.01, "({x},{y}) {b:?}");
                }
                assert_eq!(flash.get(x, y)[0] > 0.0, camera.flash());
            }
        }
    }
    assert!(hits > 500, "{hits} surface pixels");
    let eval = run(&[
        "eval",
        "images",
        "--pred",
        path_arg(&render),
        "--gt",
        path_arg(&data),
        "--json",
    ]);
    assert!(
        eval.status.success(),
        "eval: {}",
        String::from_utf8_lossy(&eval.stderr)
    );
    let scores: serde_json::Value = serde_json::from_slice(&eval.stdout).unwrap();
    assert!(
        scores["psnr_all"].as_f64().is_some_and(f64::is_finite),
        "{scores}"
    );
}

/// Runs `wildlight render` with `args`, expects failure, returns stderr.
fn failure(args: &[&str]) -> String {
    let out = run(args);
    assert!(!out.status.success(), "{args:?} succeeded");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn bad_asset_input_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let d = path_arg(dir.path());
    let missing = dir.path().join("missing.glb");
    let not_glb = dir.path().join("notes.txt");
    std::fs::write(&not_glb, "hello").unwrap();
    let garbage = dir.path().join("broken.glb");
    std::fs::write(&garbage, "this is not a glb file at all").unwrap();
    let err = failure(&["render", "--run", d, "--asset", path_arg(&missing)]);
    assert!(err.contains("cannot be used with"), "{err}");
    let err = failure(&["render"]);
    assert!(err.contains("--run") && err.contains("--asset"), "{err}");
    let err = failure(&["render", "--asset", path_arg(&missing), "--data", d]);
    assert!(
        err.contains("does not exist") && err.contains("missing.glb"),
        "{err}"
    );
    let err = failure(&["render", "--asset", path_arg(&not_glb), "--data", d]);
    assert!(err.contains("not a .glb file"), "{err}");
    let err = failure(&["render", "--asset", path_arg(&garbage), "--data", d]);
    assert!(
        err.contains("broken.glb") && err.contains("not a binary glTF"),
        "{err}"
    );
    let err = failure(&["render", "--asset", path_arg(&garbage)]);
    assert!(err.contains("needs --data"), "{err}");
    let err = failure(&["render", "--run", d, "--env", "sky"]);
    assert!(err.contains("--asset"), "{err}");
}

#[test]
fn a_folder_that_is_not_a_run_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let d = path_arg(dir.path());
    let err = failure(&["render", "--run", d]);
    assert!(
        err.contains("is not a wildlight run folder") && err.contains("config.toml"),
        "{err}"
    );
    // a run folder whose configuration is broken: the file and the key
    std::fs::write(dir.path().join("config.toml"), "iters = 3\nbogus_key = 1\n").unwrap();
    let err = failure(&["render", "--run", d]);
    assert!(
        err.contains("config.toml") && err.contains("bogus_key"),
        "{err}"
    );
}
