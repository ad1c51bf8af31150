//! `wildlight eval` from the outside: the JSON interface of issue 4 for
//! meshes, images and materials, the tables, and clear failures.

mod common;

use glam::{DMat4, DVec3};
use std::path::{Path, PathBuf};
use std::process::Output;
use wildlight_data::camera::intrinsics_from_fov_x;
use wildlight_data::exr_io::write_exr_rgb;
use wildlight_data::writer::{DatasetWriter, ViewToWrite};
use wildlight_data::{Camera, Mask, RgbImage};

fn torus(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("crates/wildlight-eval/tests/fixtures/mitsuba-torus")
        .join(name)
}

fn eval(args: &[&str]) -> Output {
    common::wildlight().arg("eval").args(args).output().unwrap()
}

/// `wildlight eval` with `args`, which must succeed; its JSON output.
fn json(args: &[&str]) -> serde_json::Value {
    let mut all = vec!["eval"];
    all.extend_from_slice(args);
    common::run_json(&all)
}

#[test]
fn mesh_against_itself_with_capture_cameras() {
    let gt = torus("gt_mesh.ply");
    let npz = torus("cameras_sphere.npz");
    let (gt, npz) = (gt.to_str().unwrap(), npz.to_str().unwrap());
    let j = json(&["mesh", "--pred", gt, "--gt", gt, "--cameras", npz, "--json"]);
    assert!(j["mean"].as_f64().unwrap() < 1e-7, "{j}");
    assert!(j["median"].as_f64().unwrap() < 1e-7, "{j}");
    assert!(j["std_of_mean"].as_f64().unwrap() <= 1e-5);
    assert_eq!(j["pairs"], 10_000);
    assert_eq!(j["cameras"], 12);
    let used = j["triangles_gt_used"].as_u64().unwrap();
    assert!(used > 8192 && used < 16384, "{j}");
    assert_eq!(j["triangles_pred_used"], j["triangles_gt_used"]);

    // The table names the statistics.
    let out = eval(&["mesh", "--pred", gt, "--gt", gt]);
    assert!(out.status.success());
    let table = String::from_utf8(out.stdout).unwrap();
    for word in ["mean", "median", "pairs", "std of mean"] {
        assert!(table.contains(word), "{table}");
    }
}

#[test]
fn mesh_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.obj");
    std::fs::write(&bad, "v 0 0 0\nv 1 0 0\nf 1 2 3\n").unwrap();
    let gt = torus("gt_mesh.ply");
    let out = eval(&[
        "mesh",
        "--pred",
        bad.to_str().unwrap(),
        "--gt",
        gt.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("bad.obj") && err.contains("line 3"), "{err}");
    let out = eval(&[
        "mesh",
        "--pred",
        gt.to_str().unwrap(),
        "--gt",
        gt.to_str().unwrap(),
        "--cameras",
        "/no/such/capture",
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("/no/such/capture"));
}

/// `eval vertex-materials` needs a run folder; given another, it says so.
/// (Its success on a trained run is `tests/cli_train_foreign.rs`; missing
/// truth files are the library's tests.)
#[test]
fn vertex_materials_errors_name_the_folder() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().to_str().unwrap();
    let out = eval(&["vertex-materials", "--run", d, "--gt", d]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains(d) && err.contains("is not a wildlight run folder"),
        "{err}"
    );
}

fn constant(w: u32, h: u32, value: [f32; 3]) -> RgbImage {
    RgbImage {
        width: w,
        height: h,
        data: (0..w * h).flat_map(|_| value).collect(),
    }
}

#[test]
fn images_and_materials_json() {
    let root = tempfile::tempdir().unwrap();
    let (gt_dir, pred_dir) = (root.path().join("capture"), root.path().join("render"));
    let (w, h) = (8, 8);
    let k = intrinsics_from_fov_x(w, h, 40.0);
    let cams: Vec<Camera> = (0..2)
        .map(|i| {
            let eye = DVec3::new(3.0 * (i as f64).cos(), 3.0 * (i as f64).sin(), 1.0);
            let energy = [if i == 0 { 1.0 } else { 0.0 }; 3];
            Camera::look_at(
                i,
                w,
                h,
                k,
                eye,
                DVec3::ZERO,
                DVec3::Z,
                DMat4::IDENTITY,
                energy,
            )
            .unwrap()
        })
        .collect();
    let gt_image = constant(w, h, [0.5; 3]);
    let mask = Mask {
        width: w,
        height: h,
        data: vec![true; 64],
    };
    let writer = DatasetWriter::create(&gt_dir).unwrap();
    let views: Vec<ViewToWrite> = cams
        .iter()
        .map(|c| ViewToWrite {
            camera: c,
            image: &gt_image,
            mask: Some(&mask),
        })
        .collect();
    writer.write_views(&views, None).unwrap();
    std::fs::create_dir_all(pred_dir.join("image")).unwrap();
    // Flash view exact, no-flash view off by 0.1 (PSNR 20 dB, peak 1 without a cap).
    write_exr_rgb(&pred_dir.join("image/000.exr"), &gt_image).unwrap();
    write_exr_rgb(&pred_dir.join("image/001.exr"), &constant(w, h, [0.6; 3])).unwrap();
    std::fs::write(
        pred_dir.join("views.json"),
        r#"[{"index":0,"split":"train","flash":true},{"index":1,"split":"train","flash":false}]"#,
    )
    .unwrap();
    let (p, g) = (pred_dir.to_str().unwrap(), gt_dir.to_str().unwrap());
    let j = json(&["images", "--pred", p, "--gt", g, "--json"]);
    assert!(
        (j["psnr_noflash"].as_f64().unwrap() - 20.0).abs() < 1e-4,
        "{j}"
    );
    assert!(
        (j["psnr_flash"].as_f64().unwrap() - 100.0).abs() < 1e-9,
        "{j}"
    );
    assert!((j["psnr_all"].as_f64().unwrap() - 60.0).abs() < 1e-4, "{j}");
    assert!((j["ssim_flash"].as_f64().unwrap() - 1.0).abs() < 1e-9);
    let expected_ssim = (2.0 * 0.3 + 1e-4) / (0.25 + 0.36 + 1e-4);
    assert!(
        (j["ssim_noflash"].as_f64().unwrap() - expected_ssim).abs() < 1e-5,
        "{j}"
    );
    let table = String::from_utf8(eval(&["images", "--pred", p, "--gt", g]).stdout).unwrap();
    assert!(
        table.contains("no-flash") && table.contains("20.00"),
        "{table}"
    );

    // Materials on the training split: base colour half the truth.
    for (i, _) in cams.iter().enumerate() {
        writer
            .write_map("base_color", i, &constant(w, h, [0.4, 0.4, 0.4]))
            .unwrap();
        writer
            .write_map("normal", i, &constant(w, h, [0.0, 1.0, 0.0]))
            .unwrap();
        std::fs::create_dir_all(pred_dir.join("base_color")).unwrap();
        std::fs::create_dir_all(pred_dir.join("normal")).unwrap();
        let name = format!("{i:03}.exr");
        write_exr_rgb(
            &pred_dir.join("base_color").join(&name),
            &constant(w, h, [0.2; 3]),
        )
        .unwrap();
        write_exr_rgb(
            &pred_dir.join("normal").join(&name),
            &constant(w, h, [0.0, 1.0, 0.0]),
        )
        .unwrap();
    }
    let j = json(&["materials", "--pred", p, "--gt", g, "--json"]);
    assert_eq!(j["split"], "train");
    assert!(
        (j["base_color_psnr"].as_f64().unwrap() - 20.0 * 5f64.log10()).abs() < 1e-4,
        "{j}"
    );
    assert!(j["base_color_psnr_aligned"].as_f64().unwrap() > 90.0, "{j}");
    assert!(j["normal_error_deg"].as_f64().unwrap() < 1e-3, "{j}");
    assert!(j["roughness_mae"].is_null());
}

/// `eval mesh --object-only` measures the object alone: a table top added
/// under the torus (crossing the region of interest) is cut away again, so
/// the distance is the torus's against itself; without the flag the table
/// counts.
#[test]
fn mesh_object_only_cuts_the_table() {
    use wildlight_mesh::TriMesh;
    let gt_path = torus("gt_mesh.ply");
    let npz = torus("cameras_sphere.npz");
    let gt = TriMesh::read(&gt_path).unwrap();
    let cameras = wildlight_data::Dataset::load_cameras(&npz).unwrap();
    let m = cameras[0].scale_mat.as_mat4();
    let (center, radius) = (m.transform_point3(glam::Vec3::ZERO), m.x_axis.length());
    // A square table of 3 radii half-width just below the torus's lowest point.
    let low = gt
        .positions
        .iter()
        .map(|p| p.y)
        .fold(f32::INFINITY, f32::min);
    let y = low - 0.005 * radius;
    let mut with_table = gt.clone();
    let base = with_table.positions.len() as u32;
    let n = 8;
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (
                i as f32 / n as f32 * 2.0 - 1.0,
                j as f32 / n as f32 * 2.0 - 1.0,
            );
            with_table.positions.push(glam::Vec3::new(
                center.x + 3.0 * radius * u,
                y,
                center.z + 3.0 * radius * v,
            ));
        }
    }
    for j in 0..n {
        for i in 0..n {
            let k = base + (j * (n + 1) + i) as u32;
            let row = (n + 1) as u32;
            with_table.triangles.push([k, k + row, k + 1]);
            with_table.triangles.push([k + 1, k + row, k + row + 1]);
        }
    }
    with_table.normals = None;
    with_table.colors = None;
    with_table.uvs = None;
    let dir = tempfile::tempdir().unwrap();
    let pred = dir.path().join("with_table.ply");
    wildlight_mesh::ply::write_ply(&with_table, &pred).unwrap();
    let (pred, gt_s, npz_s) = (
        pred.to_str().unwrap(),
        gt_path.to_str().unwrap(),
        npz.to_str().unwrap(),
    );
    let all = json(&[
        "mesh",
        "--pred",
        pred,
        "--gt",
        gt_s,
        "--cameras",
        npz_s,
        "--json",
    ]);
    let object = json(&[
        "mesh",
        "--pred",
        pred,
        "--gt",
        gt_s,
        "--cameras",
        npz_s,
        "--object-only",
        "--json",
    ]);
    let (all, object) = (
        all["mean"].as_f64().unwrap(),
        object["mean"].as_f64().unwrap(),
    );
    // The cut also takes the torus's few triangles within its margin of
    // the table, hence a small distance rather than none.
    assert!(object < 0.002 * radius as f64, "object only: {object}");
    assert!(
        all > 10.0 * object.max(1e-7),
        "with the table: {all} (object {object})"
    );
    // In the world frame the flag needs the cameras.
    let out = eval(&["mesh", "--pred", pred, "--gt", gt_s, "--object-only"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--cameras"));
}
