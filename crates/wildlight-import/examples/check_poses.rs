//! Checks an imported capture against ground-truth cameras (for example
//! `testdata/mitsuba-phone/gt/cameras.json`), which the import itself never
//! reads: flash labels, and camera centres and rotations after a similarity
//! alignment (Umeyama on the centres; the rotation part also from the
//! orientations, quaternion mean), plus the region of interest against
//! `meta.json`'s object sphere when given.
//!
//! With `--align-mesh IN.ply OUT.ply`, also moves a mesh in the capture's
//! world frame (`wildlight export`'s `mesh_raw.ply`) into the truth's frame
//! by the same similarity, for `wildlight eval mesh` against the true mesh.
//!
//! ```text
//! cargo run --release -p wildlight-import --example check_poses -- \
//!     CAPTURE path/to/gt/cameras.json [path/to/gt/meta.json] [--align-mesh IN.ply OUT.ply]
//! ```

use std::path::PathBuf;

use glam::{DMat3, DVec3};
use serde_json::Value;
use wildlight_data::camera::decompose_projection;
use wildlight_data::npz::read_cameras_npz;
use wildlight_import::align::{rotation_alignment, rotation_angle_deg, umeyama};

fn vec3(v: &Value) -> DVec3 {
    DVec3::new(
        v[0].as_f64().unwrap(),
        v[1].as_f64().unwrap(),
        v[2].as_f64().unwrap(),
    )
}

fn mat3_rows(v: &Value) -> DMat3 {
    DMat3::from_cols(vec3(&v[0]), vec3(&v[1]), vec3(&v[2])).transpose()
}

fn stats(mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    (v[(v.len() - 1) / 2], *v.last().unwrap())
}

fn main() {
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let align_mesh = args.iter().position(|a| a == "--align-mesh").map(|k| {
        let files: Vec<String> = args.drain(k..).skip(1).collect();
        assert_eq!(files.len(), 2, "--align-mesh IN.ply OUT.ply");
        (PathBuf::from(&files[0]), PathBuf::from(&files[1]))
    });
    if args.len() < 2 {
        eprintln!(
            "usage: check_poses CAPTURE GT_CAMERAS_JSON [GT_META_JSON] [--align-mesh IN.ply OUT.ply]"
        );
        std::process::exit(2);
    }
    let capture = PathBuf::from(&args[0]);
    let read_json = |p: &str| -> Value {
        serde_json::from_str(&std::fs::read_to_string(p).expect("readable JSON")).expect("JSON")
    };
    let report = read_json(capture.join("import.json").to_str().unwrap());
    let gt = read_json(&args[1]);
    let npz = read_cameras_npz(&capture.join("cameras_sphere.npz")).expect("cameras");
    let base = |s: &str| s.rsplit('/').next().unwrap_or(s).to_string();

    let mut flash_ok = 0;
    let mut flash_total = 0;
    let mut est_c = Vec::new();
    let mut gt_c = Vec::new();
    let mut est_r = Vec::new();
    let mut gt_r = Vec::new();
    let mut names = Vec::new();
    for photo in report["photos"].as_array().unwrap() {
        let file = photo["file"].as_str().unwrap();
        let Some(g) = gt
            .as_array()
            .unwrap()
            .iter()
            .find(|g| base(g["file"].as_str().unwrap()) == file)
        else {
            eprintln!("{file}: not in the ground truth");
            continue;
        };
        flash_total += 1;
        if photo["flash"].as_bool() == g["flash"].as_bool() {
            flash_ok += 1;
        } else {
            println!("flash label differs: {file}");
        }
        let Some(index) = photo["index"].as_u64() else {
            continue;
        };
        let cam = npz
            .cameras
            .iter()
            .find(|c| c.index == index as usize)
            .expect("camera of the index");
        let d = decompose_projection(&cam.world_mat).expect("a camera");
        est_c.push(d.center);
        est_r.push(d.w2c);
        gt_c.push(vec3(&g["C_world"]));
        gt_r.push(mat3_rows(&g["R"]));
        names.push(file.to_string());
    }
    println!(
        "flash labels: {flash_ok} of {flash_total} agree with the ground truth; {} cameras registered",
        est_c.len()
    );
    let sim = umeyama(&est_c, &gt_c).expect("an alignment");
    if let Some((from, to)) = &align_mesh {
        let mut mesh = wildlight_mesh::ply::read_ply(from).expect("a readable mesh");
        for p in &mut mesh.positions {
            *p = sim.apply(p.as_dvec3()).as_vec3();
        }
        wildlight_mesh::ply::write_ply(&mesh, to).expect("the aligned mesh written");
        println!("aligned mesh:   {} (scale {:.5})", to.display(), sim.scale);
    }
    let meta = args.get(2).map(|p| read_json(p));
    let object = meta
        .as_ref()
        .map(|m| vec3(&m["object_center_world"]))
        .unwrap_or_else(|| gt_c.iter().copied().sum::<DVec3>() / gt_c.len() as f64);
    let align = rotation_alignment(&est_r, &gt_r).expect("rotations");
    let mut centre_err = Vec::new();
    let mut rot_err = Vec::new();
    let mut rot_err_centres = Vec::new();
    for k in 0..est_c.len() {
        let c = sim.apply(est_c[k]);
        let dist = (gt_c[k] - object).length();
        centre_err.push(100.0 * (c - gt_c[k]).length() / dist);
        // camera rotation in the ground-truth frame: R_est · R_alignᵀ
        let r = est_r[k] * align.transpose();
        rot_err.push(rotation_angle_deg(r * gt_r[k].transpose()));
        let r = est_r[k] * sim.rotation.transpose();
        rot_err_centres.push(rotation_angle_deg(r * gt_r[k].transpose()));
    }
    if std::env::var_os("CHECK_VERBOSE").is_some() {
        for k in 0..names.len() {
            println!(
                "  {}: {:.3} %, {:.3} deg",
                names[k], centre_err[k], rot_err[k]
            );
        }
    }
    let (cm, cx) = stats(centre_err.clone());
    let (rm, rx) = stats(rot_err.clone());
    println!("camera centres: median {cm:.3} %, max {cx:.3} % of the object distance");
    println!(
        "rotations:      median {rm:.3} deg, max {rx:.3} deg (world rotation from the orientations)"
    );
    let (rm2, rx2) = stats(rot_err_centres);
    println!(
        "                median {rm2:.3} deg, max {rx2:.3} deg (world rotation from the centres)"
    );
    let worst = (0..names.len())
        .max_by(|a, b| centre_err[*a].total_cmp(&centre_err[*b]))
        .unwrap();
    println!(
        "worst camera:   {} ({:.3} %, {:.3} deg)",
        names[worst], centre_err[worst], rot_err[worst]
    );
    if let Some(m) = meta {
        let c = vec3(&report["roi"]["center"]);
        let r = report["roi"]["radius"].as_f64().unwrap();
        let c_gt = sim.apply(c);
        let radius = m["object_radius_world"].as_f64().unwrap();
        println!(
            "region:         centre {:.4} from the object's centre ({:.1} % of the object radius), radius {:.4} for an object of radius {:.4} ({:.2}x)",
            (c_gt - object).length(),
            100.0 * (c_gt - object).length() / radius,
            r * sim.scale,
            radius,
            r * sim.scale / radius
        );
        if let Some(a) = report["roi"]["axes_point"].as_array() {
            let a = sim.apply(vec3(&Value::Array(a.clone())));
            println!(
                "                the optical axes meet {:.4} from the object's centre",
                (a - object).length()
            );
        }
        println!(
            "                the object's sphere inside the region: {}",
            (c_gt - object).length() + radius <= r * sim.scale
        );
    }
}
