//! `wildlight demo`: the whole job on the built-in default scene, with no
//! data needed: synthesize a capture, train, render the held-out views,
//! export the asset, measure everything against the ground truth, and draw
//! a side-by-side preview (`preview.png`) of ground truth and reconstruction.

use crate::field_source::ExportSource;
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
use wildlight_train::inference::{RenderedView, TrainedRun, render_views_to_dir};
use wildlight_train::run::{RunOptions, planned_iters, train};

use crate::display::{exposure_for, rgb, tile, tone_map};

/// Options of `wildlight demo`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// About two minutes instead of about fifteen: a smaller capture
    /// (24 + 4 views at 96×96 instead of 64 + 8 at 256×256), 90 s of training
    /// instead of 12 min, and a lighter export (256³ marching cubes, 30k faces,
    /// 1024² textures instead of 512³, 131k, 2048²).
    #[arg(long)]
    pub quick: bool,
    /// Folder for everything the demo writes (replaced when it holds an earlier demo).
    #[arg(long, value_name = "DIR", default_value = "wildlight-demo")]
    pub out: PathBuf,
    /// Training wall time, e.g. 90s, 12m, 1h30m (a bare number is seconds)
    /// [default: 12m, or 90s with --quick].
    #[arg(long, value_name = "DURATION", value_parser = wildlight_train::config::parse_duration)]
    pub time_budget: Option<Duration>,
    /// Train exactly this many steps instead of for a time budget
    /// (reproducible: the same steps on any machine; 0 = the untrained model)
    /// [default: none: train for --time-budget].
    #[arg(long, value_name = "N", conflicts_with = "time_budget")]
    pub iters: Option<u64>,
    /// End with one JSON line of the metrics (mesh_mean, mesh_median,
    /// base_color_psnr, novel_view_psnr_flash, novel_view_psnr_noflash, seconds).
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
        let preview = out.join("preview.png");
        if preview.exists() {
            std::fs::remove_file(&preview)
                .with_context(|| format!("cannot remove {}", preview.display()))?;
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
    let (views, size, spp, val_spp) = if args.quick {
        (24, 96, 16, 256)
    } else {
        (64, 256, 256, 1024)
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
        val_spp,
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
    let time_budget = match args.iters {
        Some(n) => {
            eprintln!("2/5 training {n} steps …");
            // --iters 0: no step at all (the untrained model, for comparisons).
            (n == 0).then_some(Duration::ZERO)
        }
        None => {
            eprintln!("2/5 training for {:.0} s …", budget.as_secs_f64());
            Some(budget)
        }
    };
    let config = TrainConfig {
        iters: planned_iters(args.iters, time_budget, 0).max(1),
        ..TrainConfig::default()
    };
    train(&RunOptions {
        data: Some(capture.clone()),
        out: run_dir.clone(),
        config,
        time_budget,
        snapshot_every: None,
        resume: false,
        resume_iters: None,
        progress,
        masks: Default::default(),
    })?;

    eprintln!("3/5 rendering the held-out views …");
    let mut trained = TrainedRun::load(&run_dir)?;
    let val_cameras = wildlight_data::Dataset::load_cameras(&capture.join("val"))?;
    let refs: Vec<&wildlight_data::Camera> = val_cameras.iter().collect();
    let render_dir = out.join("render-val");
    let rendered = render_views_to_dir(
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
    let images = evaluate_images(&render_dir, &capture, wildlight_eval::Pixels::Mask)?;
    let materials = evaluate_materials(&render_dir, &capture, Split::Val)?;
    let metrics = DemoMetrics {
        mesh_mean: mesh.distance.mean / world_scale,
        mesh_median: mesh.distance.median / world_scale,
        base_color_psnr: materials.base_color_psnr_aligned,
        novel_view_psnr_flash: images.psnr_flash,
        novel_view_psnr_noflash: images.psnr_noflash,
        seconds: start.elapsed().as_secs_f64(),
    };
    let preview_path = out.join("preview.png");
    // The metrics are the demo's result: a preview that cannot be drawn is a
    // warning, not a failure.
    let preview = write_preview(&capture.join("val"), &render_dir, &rendered, &preview_path);
    if let Err(e) = &preview {
        eprintln!("warning: no preview: {e:#}");
    }
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
    if preview.is_ok() {
        println!("  preview       {}", preview_path.display());
    }
    println!("  metrics       {}", out.join("demo.json").display());
    let json = serde_json::to_string(&metrics)?;
    wildlight_data::atomic::write_bytes_atomically(&out.join("demo.json"), json.as_bytes())
        .with_context(|| format!("cannot write {}", out.join("demo.json").display()))?;
    if args.json {
        println!("{json}");
    }
    Ok(())
}

/// The row labels of the preview, top to bottom.
pub const PREVIEW_ROWS: [&str; 4] = ["FLASH", "NO FLASH", "BASE COLOUR", "NORMALS"];

/// The most held-out views the preview shows (two columns each).
pub const PREVIEW_VIEWS: usize = 2;

/// The maps of one held-out view that the preview shows.
struct PreviewView {
    index: usize,
    flash: bool,
    mask: wildlight_data::Mask,
    gt_photo: wildlight_data::RgbImage,
    gt_ambient: wildlight_data::RgbImage,
    gt_base: wildlight_data::RgbImage,
    gt_normal: wildlight_data::RgbImage,
    photo: wildlight_data::RgbImage,
    ambient: wildlight_data::RgbImage,
    base: wildlight_data::RgbImage,
    normal: wildlight_data::RgbImage,
    acc: wildlight_data::RgbImage,
}

impl PreviewView {
    fn load(val: &Path, render_dir: &Path, index: usize, flash: bool) -> anyhow::Result<Self> {
        use wildlight_data::exr_io::read_exr_rgb;
        let name = wildlight_data::writer::indexed_file_name(index, "exr");
        let gt = |kind: &str| read_exr_rgb(&val.join("gt").join(kind).join(&name));
        let ours = |kind: &str| read_exr_rgb(&render_dir.join(kind).join(&name));
        let mask_name = wildlight_data::writer::indexed_file_name(index, "png");
        Ok(PreviewView {
            index,
            flash,
            mask: wildlight_data::png_io::read_mask_png(&val.join("mask").join(mask_name))?,
            gt_photo: read_exr_rgb(&val.join("image").join(&name))?,
            gt_ambient: gt("ambient")?,
            gt_base: gt("base_color")?,
            gt_normal: gt("normal")?,
            photo: ours("image")?,
            ambient: ours("ambient")?,
            base: ours("base_color")?,
            normal: ours("normal")?,
            acc: ours("acc")?,
        })
    }

    fn size_matches(&self, w: u32, h: u32) -> bool {
        [
            &self.gt_photo,
            &self.gt_ambient,
            &self.gt_base,
            &self.gt_normal,
            &self.photo,
            &self.ambient,
            &self.base,
            &self.normal,
            &self.acc,
        ]
        .iter()
        .all(|m| (m.width, m.height) == (w, h))
            && (self.mask.width, self.mask.height) == (w, h)
    }
}

/// Draws the preview grid of ground truth against reconstruction for up to
/// [`PREVIEW_VIEWS`] held-out views (flash views first) and writes it to
/// `path` atomically. Columns: GT and OURS of each view; rows:
/// [`PREVIEW_ROWS`]. Radiance rows share one exposure per row (the GT's
/// 99th-percentile object value maps to 1), then clip and sRGB; base colour
/// is clipped and sRGB-encoded as is (no scale alignment); normals show
/// 0.5 + 0.5·n. Pixels outside the GT mask (GT) or weighted by 1 − the
/// accumulated weight (OURS) show a grey backdrop. A no-flash view has no
/// flash photo: its FLASH tiles are left empty.
pub fn write_preview(
    val: &Path,
    render_dir: &Path,
    rendered: &[RenderedView],
    path: &Path,
) -> anyhow::Result<()> {
    let mut order: Vec<&RenderedView> = rendered.iter().collect();
    order.sort_by_key(|v| (!v.flash, v.index));
    let mut views = Vec::new();
    for v in order.into_iter().take(PREVIEW_VIEWS) {
        views.push(
            PreviewView::load(val, render_dir, v.index, v.flash)
                .with_context(|| format!("loading the maps of val view {}", v.index))?,
        );
    }
    let Some(first) = views.first() else {
        bail!("no held-out view to preview");
    };
    let (w, h) = (first.gt_photo.width, first.gt_photo.height);
    views.retain(|v| v.size_matches(w, h));
    if views.is_empty() {
        bail!("the rendered maps and the ground truth of the held-out views differ in size");
    }
    let n = (w * h) as usize;
    let object = |v: &PreviewView, img: &wildlight_data::RgbImage| -> Vec<f32> {
        (0..n)
            .filter(|&i| v.mask.data[i])
            .flat_map(|i| rgb(img, i))
            .collect()
    };
    let flash_exposure = exposure_for(
        views
            .iter()
            .filter(|v| v.flash)
            .flat_map(|v| object(v, &v.gt_photo))
            .collect(),
    );
    let ambient_exposure = exposure_for(
        views
            .iter()
            .flat_map(|v| object(v, &v.gt_ambient))
            .collect(),
    );
    let gt_cov = |v: &PreviewView| {
        let mask = v.mask.data.clone();
        move |i: usize| if mask[i] { 1.0 } else { 0.0 }
    };
    let our_cov = |v: &PreviewView| {
        let acc = v.acc.data.clone();
        move |i: usize| acc[3 * i]
    };
    // Rendered radiance is premultiplied by the accumulated weight: divide
    // it out before tone mapping, then blend with the backdrop by coverage.
    let radiance = |img: &wildlight_data::RgbImage, acc: Option<&wildlight_data::RgbImage>, e| {
        let img = img.clone();
        let acc = acc.cloned();
        move |i: usize| {
            let a = acc.as_ref().map_or(1.0, |a| a.data[3 * i].max(1e-3));
            rgb(&img, i).map(|c| tone_map(c / a, e))
        }
    };
    let base = |img: &wildlight_data::RgbImage| {
        let img = img.clone();
        move |i: usize| rgb(&img, i).map(|c| tone_map(c, 1.0))
    };
    let normal = |img: &wildlight_data::RgbImage| {
        let img = img.clone();
        move |i: usize| rgb(&img, i).map(|c| (0.5 + 0.5 * c).clamp(0.0, 1.0))
    };
    let mut rows: Vec<Vec<Option<image::RgbImage>>> = vec![Vec::new(); PREVIEW_ROWS.len()];
    let mut column_labels = Vec::new();
    for v in &views {
        column_labels.push(format!("GT {:03}", v.index));
        column_labels.push(format!("OURS {:03}", v.index));
        if v.flash {
            rows[0].push(Some(tile(
                w,
                h,
                radiance(&v.gt_photo, None, flash_exposure),
                gt_cov(v),
            )));
            rows[0].push(Some(tile(
                w,
                h,
                radiance(&v.photo, Some(&v.acc), flash_exposure),
                our_cov(v),
            )));
        } else {
            rows[0].extend([None, None]);
        }
        rows[1].push(Some(tile(
            w,
            h,
            radiance(&v.gt_ambient, None, ambient_exposure),
            gt_cov(v),
        )));
        rows[1].push(Some(tile(
            w,
            h,
            radiance(&v.ambient, Some(&v.acc), ambient_exposure),
            our_cov(v),
        )));
        rows[2].push(Some(tile(w, h, base(&v.gt_base), gt_cov(v))));
        rows[2].push(Some(tile(w, h, base(&v.base), our_cov(v))));
        rows[3].push(Some(tile(w, h, normal(&v.gt_normal), gt_cov(v))));
        rows[3].push(Some(tile(w, h, normal(&v.normal), our_cov(v))));
    }
    crate::plot::ImageGrid {
        tile_width: w,
        tile_height: h,
        column_labels,
        row_labels: PREVIEW_ROWS.iter().map(|s| s.to_string()).collect(),
        tiles: rows,
    }
    .write_png(path)
}
