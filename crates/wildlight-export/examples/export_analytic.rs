//! Exports an analytic scene end to end and measures its flash round trip.
//!
//! ```text
//! cargo run --release -p wildlight-export --example export_analytic -- OUT_DIR [RESOLUTION] [FACES] [TEXTURE]
//! ```
//!
//! The scene is a bumpy torus (normalized frame) with a procedural
//! material, placed in the world by scale_mat = translate(0.3, −0.2, 1) ·
//! scale(2.5). It writes OUT_DIR/model.glb, model.obj (+ .mtl, PNG maps)
//! and mesh_raw.ply, reads the .glb back, and prints the PSNR of its
//! ray-traced flash term against the analytic scene's at four views.

use glam::{DVec3, Mat4, Vec2, Vec3};
use wildlight_data::Camera;
use wildlight_data::camera::intrinsics_from_fov_x;
use wildlight_export::{
    AnalyticSource, AssetTracer, AtlasOptions, ExportOptions, FlashSettings, MarchingOptions,
    export_to_dir, flash_psnr, read_glb, render_source_flash,
};

fn bumpy_torus(p: Vec3) -> f32 {
    let ring = Vec2::new(p.truncate().length() - 0.5, p.z).length() - 0.22;
    ring + 0.01 * (9.0 * p.x).sin() * (9.0 * p.y).sin() * (9.0 * p.z).sin()
}

fn material(p: Vec3) -> [f32; 9] {
    let s = |x: f32| 0.5 + 0.5 * x.sin();
    [
        0.15 + 0.6 * s(3.0 * p.x),
        0.2 + 0.5 * s(2.0 * p.y + 1.0),
        0.25 + 0.4 * s(2.5 * p.z - 0.5),
        0.35 + 0.4 * s(2.0 * p.x + 1.5 * p.y),
        0.3 + 0.5 * s(1.5 * p.y),
        0.2 * s(2.0 * p.z),
        0.25 * s(1.7 * p.x + 0.3),
        0.3 + 0.4 * s(2.2 * p.y - p.z),
        0.3 * s(1.3 * p.x - 2.0 * p.z),
    ]
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let out = std::path::PathBuf::from(args.get(1).map(String::as_str).unwrap_or("export-out"));
    let arg = |i: usize, default: u32| -> anyhow::Result<u32> {
        Ok(args
            .get(i)
            .map(|s| s.parse())
            .transpose()?
            .unwrap_or(default))
    };
    let scale_mat =
        Mat4::from_translation(Vec3::new(0.3, -0.2, 1.0)) * Mat4::from_scale(Vec3::splat(2.5));
    let options = ExportOptions {
        marching: MarchingOptions {
            resolution: arg(2, 256)?,
            ..Default::default()
        },
        max_faces: arg(3, 65_536)? as usize,
        atlas: AtlasOptions {
            texture_size: arg(4, 1024)?,
            ..Default::default()
        },
        scale_mat,
        ..Default::default()
    };
    let source = AnalyticSource::new(bumpy_torus, material);
    let (files, report) = export_to_dir(&source, &options, &out)?;
    println!("{}", serde_json::to_string_pretty(&report)?);
    println!("wrote {}", files.glb.display());

    let asset = read_glb(&files.glb)?;
    let tracer = AssetTracer::new(&asset, scale_mat.inverse())?;
    let sm = scale_mat.as_dmat4();
    let center = sm.transform_point3(DVec3::ZERO);
    let k = intrinsics_from_fov_x(160, 120, 40.0);
    let settings = FlashSettings::default();
    for (i, azimuth) in [0.3f64, 1.9, 3.4, 5.0].into_iter().enumerate() {
        let eye =
            center + DVec3::new(azimuth.cos() * 0.8, azimuth.sin() * 0.8, 0.6).normalize() * 7.5;
        let camera = Camera::look_at(i, 160, 120, k, eye, center, DVec3::Z, sm, [3.0, 3.0, 3.0])?;
        let exported = tracer.render_flash(&camera, &settings);
        let reference = render_source_flash(&source, &camera, &settings);
        let psnr = flash_psnr(&exported, &reference).unwrap_or(f64::NAN);
        println!("view {i}: flash PSNR exported vs analytic = {psnr:.2} dB");
    }
    Ok(())
}
