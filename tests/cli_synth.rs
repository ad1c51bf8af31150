//! `wildlight synth` from the command line: `--list`, and for every
//! built-in scene a tiny capture that `wildlight info` then reads.

mod common;

use common::wildlight;

fn scene_names() -> Vec<String> {
    let out = wildlight().args(["synth", "--list"]).output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .collect()
}

#[test]
fn list_names_the_scenes_default_first() {
    let names = scene_names();
    assert_eq!(names.first().map(String::as_str), Some("kettle"));
    assert!(names.iter().any(|n| n == "sampler"), "{names:?}");
}

#[test]
fn every_scene_synthesizes_and_info_reads_it() {
    let dir = tempfile::tempdir().unwrap();
    for (i, name) in scene_names().into_iter().enumerate() {
        let out = dir.path().join(&name);
        // the default scene with the default cap, the others in full HDR
        let cap = if i == 0 { "1" } else { "none" };
        let status = common::tiny_synth(&name, &out)
            .args(["--saturation", cap])
            .output()
            .unwrap();
        assert!(
            status.status.success(),
            "synth {name}: {}",
            String::from_utf8_lossy(&status.stderr)
        );
        for file in [
            "cameras_sphere.npz",
            "image/003.exr",
            "mask/003.png",
            "val/image/000.exr",
            "gt/mesh_world.ply",
            "gt/mesh_normalized.ply",
            "gt/material.json",
            "gt/params/000.exr",
            "val/gt/normal/000.exr",
        ] {
            assert!(out.join(file).is_file(), "{name}: {file} missing");
        }
        let info = wildlight()
            .args(["info", "--data"])
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            info.status.success(),
            "info {name}: {}",
            String::from_utf8_lossy(&info.stderr)
        );
        let text = String::from_utf8_lossy(&info.stdout);
        assert!(text.contains('4'), "info output: {text}");
        let data = wildlight_data::Dataset::load(&out, &wildlight_data::LoadOptions::default())
            .expect("the capture loads");
        let expected = (i == 0).then_some(wildlight_synth::DEFAULT_SATURATION as f32);
        assert_eq!(data.saturation, expected, "{name}: max_intensity");
        let peak = data
            .views
            .iter()
            .map(|v| v.image.max_value())
            .fold(0.0, f32::max);
        if i == 0 {
            assert!(peak <= 1.0, "{name}: pixels above the cap: {peak}");
        }
    }
}

#[test]
fn bad_input_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let out = wildlight()
        .args(["synth", "--scene", "teapot", "--out"])
        .arg(dir.path().join("x"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("kettle"));
    let out = wildlight()
        .args(["synth", "--mesh"])
        .arg(dir.path().join("missing.ply"))
        .arg("--out")
        .arg(dir.path().join("y"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("missing.ply"));
    let out = wildlight()
        .args(["synth", "--scene", "kettle", "--saturation", "0", "--out"])
        .arg(dir.path().join("z"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("'0' is not a positive number"));
}

#[test]
fn mesh_file_with_constant_material() {
    let dir = tempfile::tempdir().unwrap();
    // a tetrahedron far from the origin and large: it must be rescaled into the unit sphere
    let mesh = dir.path().join("tet.obj");
    std::fs::write(
        &mesh,
        "v 10 10 10\nv 14 10 10\nv 10 14 10\nv 10 10 14\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    let out = dir.path().join("cap");
    let run = wildlight()
        .args(["synth", "--mesh"])
        .arg(&mesh)
        .arg("--out")
        .arg(&out)
        .args([
            "--views",
            "2",
            "--val-views",
            "0",
            "--width",
            "24",
            "--height",
            "24",
            "--spp",
            "2",
            "--val-spp",
            "2",
            "--quiet",
        ])
        .args([
            "--material",
            r#"{"base_color":[0.9,0.1,0.1],"roughness":0.4}"#,
        ])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let json = std::fs::read_to_string(out.join("gt/material.json")).unwrap();
    assert!(json.contains("constant") && json.contains("0.9"), "{json}");
    let mesh = std::fs::read(out.join("gt/mesh_normalized.ply")).unwrap();
    assert!(!mesh.is_empty());
}

#[test]
fn background_table_records_its_plane_and_keeps_cameras_above_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("table");
    let run = common::tiny_synth("kettle", &out)
        .args(["--background", "table"])
        .output()
        .unwrap();
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("gt/background.json")).unwrap())
            .unwrap();
    assert_eq!(json["kind"], "table", "{json}");
    let table = &json["table"];
    // the plane touches the world mesh's lowest point
    let world = wildlight_mesh::TriMesh::read(out.join("gt/mesh_world.ply")).unwrap();
    let low = world
        .positions
        .iter()
        .map(|p| p.y as f64)
        .fold(f64::MAX, f64::min);
    let offset_world = table["offset_world"].as_f64().unwrap();
    assert!((offset_world - low).abs() < 1e-5, "{offset_world} vs {low}");
    // every camera (normalized frame) lies above the plane
    let offset = table["offset_normalized"].as_f64().unwrap();
    let data = wildlight_data::Dataset::load(&out, &wildlight_data::LoadOptions::default())
        .expect("the capture loads");
    for v in &data.views {
        assert!(v.camera.center.y > offset + 0.05, "{:?}", v.camera.center);
    }
    // the default background writes no record
    let room = dir.path().join("room");
    let run = common::tiny_synth("kettle", &room).output().unwrap();
    assert!(run.status.success());
    assert!(!room.join("gt/background.json").exists());
}

#[test]
fn bad_backgrounds_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let help = common::run_ok(&["synth", "--help"]);
    assert!(
        help.contains("--background") && help.contains("table") && help.contains("none"),
        "{help}"
    );
    let out = common::tiny_synth("kettle", &dir.path().join("wall"))
        .args(["--background", "wall"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("room") && err.contains("table"), "{err}");
    // every camera below the table: refused, nothing written
    let below = dir.path().join("below");
    let out = common::tiny_synth("kettle", &below)
        .args(["--background", "table"])
        .args(["--elevation-min", "-60", "--elevation-max", "-20"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--elevation-max"), "{err}");
    assert!(!below.exists());
}
