//! `wildlight demo`: the whole job on the built-in default scene, with no
//! data needed: synthesize a capture, train, render the held-out views,
//! export the asset, and measure everything against the ground truth.

use anyhow::{Context, bail};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};
use wildlight_eval::cameras::{Frame, viewpoints};
use wildlight_eval::{
    Split, SurfaceDistanceOptions, evaluate_images, evaluate_materials, evaluate_meshes,
};
use wildlight_export::{AtlasOptions, ExportOptions, MarchingOptions, export_to_dir};
use wildlight_synth::{RigOptions, SynthOptions, synthesize};
use wildlight_train::TrainConfig;
use wildlight_train::inference::{ExportSource, TrainedRun, render_views_to_dir};
use wildlight_train::run::{RunOptions, train};

/// Options of `wildlight demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// About two minutes instead of about fifteen: a smaller capture
    /// (24 views at 96×96), 90 s of training and a lighter export.
    #[arg(long)]
    pub quick: bool,
    /// Folder for everything the demo writes (replaced when it holds an earlier demo).
    #[arg(long, value_name = "DIR", default_value = "wildlight-demo")]
    pub out: PathBuf,
    /// Training time [default: 12m, or 90s with --quick].
    #[arg(long, value_name = "DURATION", value_parser = wildlight_train::config::parse_duration)]
    pub time_budget: Option<Duration>,
    /// Train exactly this many steps instead of for a time budget
    /// (reproducible: the same steps on any machine).
    #[arg(long, value_name = "N", conflicts_with = "time_budget")]
    pub iters: Option<u64>,
    /// End with one JSON line of the metrics.
    #[arg(long)]
    pub json: bool,
}

/// The metrics the demo reports.
#[derive(serde::Serialize, Debug)]
pub struct DemoMetrics {
    /// Mean eq. 16 distance of the visible surface, normalized frame.
    pub mesh_mean: f64,
    /// Median of the same pair values.
    pub mesh_median: f64,
    /// Base-colour PSNR after per-channel scale alignment (val views), dB.
    pub base_color_psnr: Option<f64>,
    /// Novel-view PSNR of the flash views, dB.
    pub novel_view_psnr_flash: Option<f64>,
    /// Novel-view PSNR of the no-flash views, dB.
    pub novel_view_psnr_noflash: Option<f64>,
    /// Wall time of the whole demo, seconds.
    pub seconds: f64,
}

fn prepare_out(out: &Path) -> anyhow::Result<()> {
    if out.exists() {
        let marker = out.join("demo.json");
        let empty = std::fs::read_dir(out)
            .with_context(|| format!("cannot read {}", out.display()))?
            .next()
            .is_none();
        if !empty && !marker.exists() {
            bail!(
                "{} exists and does not hold an earlier demo; choose another --out",
                out.display()
            );
        }
        for sub in ["capture", "run", "render-val", "export"] {
            let p = out.join(sub);
            if p.exists() {
                std::fs::remove_dir_all(&p)
                    .with_context(|| format!("cannot remove {}", p.display()))?;
            }
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("cannot create {}", out.display()))
}

/// Runs `wildlight demo`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let start = Instant::now();
    let out = args.out.clone();
    prepare_out(&out)?;
    let progress = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let capture = out.join("capture");
    let (views, size, spp) = if args.quick {
        (24, 96, 16)
    } else {
        (64, 256, 64)
    };
    eprintln!("1/5 synthesizing the default capture ({views} views, {size}×{size}) …");
    synthesize(&SynthOptions {
        rig: RigOptions {
            views,
            val_views: if args.quick { 4 } else { 8 },
            width: size,
            height: size,
            ..RigOptions::default()
        },
        spp,
        mesh_resolution: if args.quick { 96 } else { 160 },
        out: capture.clone(),
        overwrite: true,
        progress,
        ..SynthOptions::default()
    })
    .context("synthesizing the capture")?;

    let budget = args.time_budget.unwrap_or(if args.quick {
        Duration::from_secs(90)
    } else {
        Duration::from_secs(12 * 60)
    });
    let run_dir = out.join("run");
    let (config, time_budget) = match args.iters {
        Some(n) => {
            eprintln!("2/5 training {n} steps …");
            let config = TrainConfig {
                iters: n.max(1),
                ..TrainConfig::default()
            };
            // --iters 0: no step at all (the untrained model, for comparisons).
            (config, (n == 0).then_some(Duration::ZERO))
        }
        None => {
            eprintln!("2/5 training for {:.0} s …", budget.as_secs_f64());
            let config = TrainConfig {
                iters: 20_000,
                ..TrainConfig::default()
            };
            (config, Some(budget))
        }
    };
    train(&RunOptions {
        data: Some(capture.clone()),
        out: run_dir.clone(),
        config,
        time_budget,
        resume: false,
        progress,
    })?;

    eprintln!("3/5 rendering the held-out views …");
    let mut trained = TrainedRun::load(&run_dir)?;
    let val_cameras = wildlight_data::Dataset::load_cameras(&capture.join("val"))?;
    let refs: Vec<&wildlight_data::Camera> = val_cameras.iter().collect();
    let render_dir = out.join("render-val");
    render_views_to_dir(
        &mut trained,
        &refs,
        |c| c.light_energy.map(|e| e as f32),
        "val",
        1.0,
        &render_dir,
        || {},
    )?;

    eprintln!("4/5 exporting the asset …");
    let train_cameras = wildlight_data::Dataset::load_cameras(&capture)?;
    let scale_mat = train_cameras[0].scale_mat.as_mat4();
    let export_dir = out.join("export");
    let options = ExportOptions {
        marching: MarchingOptions {
            resolution: if args.quick { 256 } else { 512 },
            ..MarchingOptions::default()
        },
        max_faces: if args.quick { 30_000 } else { 131_072 },
        atlas: AtlasOptions {
            texture_size: if args.quick { 1024 } else { 2048 },
            ..AtlasOptions::default()
        },
        scale_mat,
        progress,
        ..ExportOptions::default()
    };
    let (files, _) = export_to_dir(&ExportSource::new(&trained), &options, &export_dir)?;

    eprintln!("5/5 measuring against the ground truth …");
    let pred = wildlight_mesh::TriMesh::read(&files.raw_ply)?;
    let gt = wildlight_mesh::TriMesh::read(capture.join("gt/mesh_world.ply"))?;
    let vps = viewpoints(&train_cameras, Frame::World);
    let mesh = evaluate_meshes(&pred, &gt, Some(&vps), &SurfaceDistanceOptions::default())?;
    let world_scale = train_cameras[0].world_scale();
    let images = evaluate_images(&render_dir, &capture)?;
    let materials = evaluate_materials(&render_dir, &capture, Split::Val)?;
    let metrics = DemoMetrics {
        mesh_mean: mesh.distance.mean / world_scale,
        mesh_median: mesh.distance.median / world_scale,
        base_color_psnr: materials.base_color_psnr_aligned,
        novel_view_psnr_flash: images.psnr_flash,
        novel_view_psnr_noflash: images.psnr_noflash,
        seconds: start.elapsed().as_secs_f64(),
    };
    let opt = |v: Option<f64>| v.map_or("n/a".to_string(), |v| format!("{v:.2} dB"));
    println!(
        "wildlight demo ({})",
        if args.quick { "quick" } else { "full" }
    );
    println!(
        "  surface distance (eq. 16, normalized)  mean {:.5}  median {:.5}",
        metrics.mesh_mean, metrics.mesh_median
    );
    println!(
        "  base colour PSNR (scale-aligned)       {}",
        opt(metrics.base_color_psnr)
    );
    println!(
        "  novel views PSNR, flash                {}",
        opt(metrics.novel_view_psnr_flash)
    );
    println!(
        "  novel views PSNR, no flash             {}",
        opt(metrics.novel_view_psnr_noflash)
    );
    println!(
        "  time                                   {:.0} s",
        metrics.seconds
    );
    println!("wrote:");
    println!("  capture       {}", capture.display());
    println!(
        "  run           {} (previews in previews/)",
        run_dir.display()
    );
    println!("  renderings    {}", render_dir.display());
    println!("  glTF          {}", files.glb.display());
    println!("  OBJ           {}", files.obj.display());
    let json = serde_json::to_string(&metrics)?;
    std::fs::write(out.join("demo.json"), &json)
        .with_context(|| format!("cannot write {}", out.join("demo.json").display()))?;
    if args.json {
        println!("{json}");
    }
    Ok(())
}
