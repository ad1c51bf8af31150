//! Scores a trained run's materials against truth given per vertex of the
//! ground-truth mesh, for captures without per-pixel material maps — such
//! as the Mitsuba 3 torus of `crates/wildlight-data/tests/fixtures`, whose
//! full copy (`shared/testdata/mitsuba-torus`) has `gt_mesh_normalized.ply`,
//! `gt_albedo_vertex.npy` (linear RGB per vertex) and, in `meta.json`, one
//! roughness and one metallic value for the whole object.
//!
//! The material field is read at every vertex that a capture camera sees
//! (a vertex of a visible triangle, by `wildlight_eval::visible_triangles`,
//! normalized frame); the true surface is within the mesh distance of the
//! model's, and the field varies slowly across that gap. Prints one JSON
//! object: the vertices used, base colour PSNR plain and aligned (per
//! channel, up to the flash gain, as `wildlight eval materials`), the
//! alignment's factors, and roughness and metallic as mean, and mean
//! absolute error.
//!
//! ```sh
//! cargo run --release -p wildlight-train --example vertex_materials -- RUN CAPTURE
//! ```

use anyhow::{Context, Result, bail, ensure};
use ndarray::Array2;
use ndarray_npy::ReadNpyExt;
use std::path::Path;
use wildlight_data::Dataset;
use wildlight_eval::ColourFit;
use wildlight_eval::cameras::{Frame, viewpoints};
use wildlight_material::{BASE_COLOR, METALLIC, PARAM_COUNT, ROUGHNESS};
use wildlight_train::inference::TrainedRun;
use wildlight_train::material_field::MaterialContext;

fn main() -> Result<()> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    if a.len() != 2 {
        bail!("usage: vertex_materials RUN CAPTURE");
    }
    let (run, capture) = (Path::new(&a[0]), Path::new(&a[1]));
    let trained = TrainedRun::load(run)?;

    let mesh_path = capture.join("gt_mesh_normalized.ply");
    let mesh = wildlight_mesh::ply::read_ply(&mesh_path)?;
    let albedo_path = capture.join("gt_albedo_vertex.npy");
    let file = std::fs::File::open(&albedo_path)
        .with_context(|| format!("cannot open {}", albedo_path.display()))?;
    let albedo = Array2::<f32>::read_npy(file)
        .with_context(|| format!("{}: not an n × 3 float32 array", albedo_path.display()))?;
    ensure!(
        albedo.dim() == (mesh.positions.len(), 3),
        "{}: {:?} values for the {} vertices of {}",
        albedo_path.display(),
        albedo.dim(),
        mesh.positions.len(),
        mesh_path.display()
    );
    let meta_path = capture.join("meta.json");
    let meta: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(&meta_path)
            .with_context(|| format!("cannot read {}", meta_path.display()))?,
    )
    .with_context(|| format!("{}: not JSON", meta_path.display()))?;
    let truth = |key: &str| {
        meta["material"][key]
            .as_f64()
            .with_context(|| format!("{}: no material.{key}", meta_path.display()))
    };
    let (roughness_true, metallic_true) = (truth("roughness")?, truth("metallic")?);

    // The vertices of the triangles a camera sees.
    let cameras = Dataset::load_cameras(capture)
        .with_context(|| format!("cannot read the cameras of {}", capture.display()))?;
    let visible =
        wildlight_eval::visible_triangles(&mesh, &viewpoints(&cameras, Frame::Normalized))?;
    let mut seen = vec![false; mesh.positions.len()];
    for (tri, v) in mesh.triangles.iter().zip(&visible) {
        if *v {
            for &i in tri {
                seen[i as usize] = true;
            }
        }
    }
    let used: Vec<usize> = (0..seen.len()).filter(|&i| seen[i]).collect();
    ensure!(
        !used.is_empty(),
        "no vertex of {} is seen by a camera",
        mesh_path.display()
    );
    let points: Vec<[f32; 3]> = used.iter().map(|&i| mesh.positions[i].to_array()).collect();
    let mut ctx = MaterialContext::new();
    trained.model.material.forward(&points, &mut ctx);

    let mut base = ColourFit::default();
    let (mut rough, mut rough_err, mut metal, mut metal_err) = (0.0, 0.0, 0.0, 0.0);
    for (theta, &i) in ctx.output().chunks_exact(PARAM_COUNT).zip(&used) {
        let p = [0, 1, 2].map(|c| theta[BASE_COLOR + c] as f64);
        let g = [0, 1, 2].map(|c| albedo[[i, c]] as f64);
        base.add(p, g);
        let (r, m) = (theta[ROUGHNESS] as f64, theta[METALLIC] as f64);
        rough += r;
        rough_err += (r - roughness_true).abs();
        metal += m;
        metal_err += (m - metallic_true).abs();
    }
    let n = used.len() as f64;
    println!(
        "{}",
        serde_json::json!({
            "vertices": used.len(),
            "vertices_total": mesh.positions.len(),
            "base_color_psnr": base.psnr(),
            "base_color_psnr_aligned": base.psnr_aligned(),
            "base_color_scale": base.scale(),
            "roughness_mean": rough / n,
            "roughness_true": roughness_true,
            "roughness_mae": rough_err / n,
            "metallic_mean": metal / n,
            "metallic_true": metallic_true,
            "metallic_mae": metal_err / n,
        })
    );
    Ok(())
}
