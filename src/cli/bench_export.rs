//! `wildlight bench export`: wall time and peak memory of `wildlight
//! export` on a trained run (medians of several exports), and with
//! `--roundtrip` the two round-trip checks of issue 8:
//!
//! - the exported asset's flash term (read back from `model.glb`) against
//!   the trained fields' (sphere-traced SDF, material at the hit) at the
//!   capture's training flash views, with the run's flash gain γ: PSNR per
//!   view; and, as a second measure, against the run renderer's
//!   volume-rendered flash map over the capture's mask;
//! - the eq. 16 distance (SPEC §7, visible surface, world units) of the raw
//!   marching-cubes mesh to the capture's ground-truth mesh, against that
//!   of the fields' zero level set, represented by a finer extraction
//!   whose vertices are projected onto it (`wildlight_export::roundtrip`);
//!   and, as a second reference, the raw mesh itself with its vertices
//!   projected.
//!
//! Thread count: the rayon pool (`RAYON_NUM_THREADS`).

use crate::field_source::ExportSource;
use anyhow::Context;
use indicatif::ProgressBar;
use serde::Serialize;
use std::path::PathBuf;
use std::time::Instant;
use wildlight_data::{Dataset, RgbImage};
use wildlight_eval::{SurfaceDistanceOptions, evaluate_meshes};
use wildlight_export::{
    AssetTracer, FlashImage, FlashSettings, ReferenceOptions, export_to_dir, flash_psnr,
    flash_round_trip, level_set_reference, project_to_level_set, read_glb,
};
use wildlight_mesh::TriMesh;
use wildlight_train::inference::TrainedRun;

use crate::cli::export::{export_options, run_cameras, run_scale_mat};

/// Options of `wildlight bench export`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The run folder written by `wildlight train`.
    #[arg(long, value_name = "RUN")]
    run: PathBuf,
    /// Where the exports are written [default: RUN/bench-export].
    #[arg(long, value_name = "DIR")]
    out: Option<PathBuf>,
    /// Timed exports (medians are reported); 0 reuses the export in --out.
    #[arg(long, default_value_t = 3)]
    repeat: usize,
    /// Marching-cubes cells per axis.
    #[arg(long, default_value_t = 512)]
    resolution: u32,
    /// Largest face count of the simplified mesh.
    #[arg(long, default_value_t = 131_072)]
    faces: usize,
    /// Texture width and height in texels.
    #[arg(long, default_value_t = 2048)]
    texture: u32,
    /// Also measure the round trip (flash PSNR and eq. 16 against the level set).
    #[arg(long)]
    roundtrip: bool,
    /// Marching-cubes resolution of the level-set reference [default: 2 × --resolution].
    #[arg(long)]
    reference_resolution: Option<u32>,
    /// The capture (cameras, gt/mesh_world.ply) [default: the run's own].
    #[arg(long, value_name = "DIR")]
    data: Option<PathBuf>,
    /// eq. 16 estimates per mesh, with sampler seeds 0..N (averaged).
    #[arg(long, default_value_t = 1)]
    eq16_seeds: u64,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// One timed export.
#[derive(Serialize)]
struct Timing {
    seconds: f64,
    stages: Vec<(String, f64)>,
}

/// The eq. 16 comparison.
#[derive(Serialize)]
struct GeometryRoundTrip {
    /// eq. 16 mean of the raw marching-cubes mesh (world units, averaged
    /// over the sampler seeds).
    raw_mean: f64,
    /// Its median.
    raw_median: f64,
    /// eq. 16 mean of the finer, projected level-set reference.
    reference_mean: f64,
    /// Its median.
    reference_median: f64,
    /// |raw − reference| / reference (means).
    relative_difference: f64,
    /// eq. 16 mean of the raw mesh with its own vertices projected.
    raw_projected_mean: f64,
    /// |raw − raw projected| / raw projected (means).
    relative_difference_projected: f64,
    /// eq. 16 means per sampler seed: raw, reference, raw projected.
    per_seed_means: [Vec<f64>; 3],
    /// Resolution of the reference extraction.
    reference_resolution: u32,
    /// Triangles of the raw mesh and of the reference.
    triangles: [usize; 2],
    /// Pairs drawn by the eq. 16 estimates of each mesh (all seeds).
    pairs: [usize; 3],
    /// |φ| at the reference's vertices before/after projection.
    reference_projection: wildlight_export::ProjectionStats,
    /// |φ| at the raw mesh's vertices before/after projection.
    raw_projection: wildlight_export::ProjectionStats,
    /// Seconds spent on the reference and the three estimates.
    seconds: f64,
}

/// The flash comparison.
#[derive(Serialize)]
struct FlashRoundTrip {
    /// Flash gain γ of the run (applied to both).
    gain: f32,
    /// Views compared.
    views: usize,
    /// Smallest, median and mean PSNR over the views (dB).
    min_psnr: f64,
    median_psnr: f64,
    mean_psnr: f64,
    /// Per view: index, PSNR, surface pixels.
    per_view: Vec<wildlight_export::ViewRoundTrip>,
    /// Against the run renderer's volume-rendered flash map instead, over
    /// the capture's mask: smallest, median and mean PSNR (dB).
    volume_min_psnr: Option<f64>,
    volume_median_psnr: Option<f64>,
    volume_mean_psnr: Option<f64>,
    /// Seconds spent.
    seconds: f64,
}

#[derive(Serialize)]
struct Report {
    run: PathBuf,
    threads: usize,
    resolution: u32,
    faces: usize,
    texture: u32,
    exports: Vec<Timing>,
    median_seconds: Option<f64>,
    /// Peak resident memory of this process after the exports (MiB, VmHWM).
    peak_rss_mib: Option<f64>,
    flash: Option<FlashRoundTrip>,
    geometry: Option<GeometryRoundTrip>,
}

/// Peak resident set size of this process in MiB (Linux /proc; None elsewhere).
fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}

fn median(values: &mut [f64]) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    Some(if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    })
}

/// Runs the export benchmark.
pub fn run(args: Args) -> anyhow::Result<()> {
    let trained = TrainedRun::load(&args.run)?;
    let scale_mat = run_scale_mat(&run_cameras(&trained)?)?;
    let options = export_options(
        args.resolution,
        args.faces,
        args.texture,
        scale_mat,
        true,
        false,
    )?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| args.run.join("bench-export"));
    let source = ExportSource::new(&trained);
    let mut exports = Vec::new();
    for k in 0..args.repeat {
        let start = Instant::now();
        let (_, report) = export_to_dir(&source, &options, &out)
            .with_context(|| format!("export of {} failed", args.run.display()))?;
        let seconds = start.elapsed().as_secs_f64();
        if !args.json {
            eprintln!("export {}: {seconds:.2} s", k + 1);
        }
        exports.push(Timing {
            seconds,
            stages: report.seconds,
        });
    }
    let peak = peak_rss_mib();
    let mut seconds: Vec<f64> = exports.iter().map(|t| t.seconds).collect();
    let mut report = Report {
        run: args.run.clone(),
        threads: rayon::current_num_threads(),
        resolution: args.resolution,
        faces: args.faces,
        texture: args.texture,
        median_seconds: median(&mut seconds),
        exports,
        peak_rss_mib: peak,
        flash: None,
        geometry: None,
    };
    if args.roundtrip {
        let data = args
            .data
            .clone()
            .unwrap_or_else(|| trained.info.data.clone());
        let gain = trained.model.gamma();
        // A second copy of the model for the run renderer (it needs `&mut`).
        let mut volume = TrainedRun::load(&args.run)?;
        report.flash = Some(flash_check(
            &source,
            &mut volume,
            &out,
            &data,
            gain,
            &scale_mat,
        )?);
        drop(volume);
        if !args.json {
            eprintln!("flash round trip done");
        }
        let reference_resolution = args
            .reference_resolution
            .unwrap_or(2 * args.resolution)
            .min(4096);
        report.geometry = Some(geometry_check(
            &source,
            &out,
            &data,
            &scale_mat,
            reference_resolution,
            args.eq16_seeds,
        )?);
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_table(&report);
    }
    Ok(())
}

fn flash_check(
    source: &ExportSource<'_>,
    volume: &mut TrainedRun,
    out: &std::path::Path,
    data: &std::path::Path,
    gain: f32,
    scale_mat: &glam::Mat4,
) -> anyhow::Result<FlashRoundTrip> {
    let start = Instant::now();
    let glb = out.join("model.glb");
    let asset = read_glb(&glb).with_context(|| {
        format!(
            "cannot read {} (run with --repeat ≥ 1 first)",
            glb.display()
        )
    })?;
    let tracer = AssetTracer::new(&asset, scale_mat.inverse())?;
    let cameras = Dataset::load_cameras(data)
        .with_context(|| format!("cannot read the cameras of {}", data.display()))?;
    let settings = FlashSettings {
        gain,
        ..FlashSettings::default()
    };
    let per_view = flash_round_trip(&tracer, source, &cameras, &settings);
    anyhow::ensure!(
        !per_view.is_empty(),
        "{} has no training view with the flash on",
        data.display()
    );
    // The run renderer's flash map (NeuS compositing) over the mask, where
    // its soft silhouette does not count.
    let dataset = Dataset::load(data, &wildlight_data::LoadOptions::default())
        .with_context(|| format!("cannot read {}", data.display()))?;
    let mut volume_psnr = Vec::new();
    for view in dataset.views.iter().filter(|v| v.camera.flash()) {
        let Some(mask) = &view.mask else { continue };
        let camera = &view.camera;
        let hit: Vec<bool> = (0..camera.width * camera.height)
            .map(|i| mask.get(i % camera.width, i / camera.width))
            .collect();
        let maps = volume.render(camera, camera.light_energy.map(|e| e as f32), 1.0);
        let reference = FlashImage {
            image: RgbImage {
                width: camera.width,
                height: camera.height,
                data: maps.flash.iter().flatten().copied().collect(),
            },
            hit: hit.clone(),
        };
        let asset = FlashImage {
            hit,
            ..tracer.render_flash(camera, &settings)
        };
        if let Some(p) = flash_psnr(&asset, &reference) {
            volume_psnr.push(p);
        }
    }
    let volume_mean = (!volume_psnr.is_empty())
        .then(|| volume_psnr.iter().sum::<f64>() / volume_psnr.len() as f64);
    let volume_min = volume_psnr.iter().copied().reduce(f64::min);
    let volume_median = median(&mut volume_psnr);
    let mut psnr: Vec<f64> = per_view.iter().map(|v| v.psnr).collect();
    let mean = psnr.iter().sum::<f64>() / psnr.len() as f64;
    let min = psnr.iter().copied().fold(f64::INFINITY, f64::min);
    Ok(FlashRoundTrip {
        gain,
        views: per_view.len(),
        min_psnr: min,
        median_psnr: median(&mut psnr).unwrap_or(f64::NAN),
        mean_psnr: mean,
        per_view,
        volume_min_psnr: volume_min,
        volume_median_psnr: volume_median,
        volume_mean_psnr: volume_mean,
        seconds: start.elapsed().as_secs_f64(),
    })
}

fn geometry_check(
    source: &ExportSource<'_>,
    out: &std::path::Path,
    data: &std::path::Path,
    scale_mat: &glam::Mat4,
    reference_resolution: u32,
    seeds: u64,
) -> anyhow::Result<GeometryRoundTrip> {
    let start = Instant::now();
    let gt_path = data.join("gt").join("mesh_world.ply");
    let gt = TriMesh::read(&gt_path)
        .with_context(|| format!("cannot read the ground-truth mesh {}", gt_path.display()))?;
    let raw_path = out.join("mesh_raw.ply");
    let raw =
        TriMesh::read(&raw_path).with_context(|| format!("cannot read {}", raw_path.display()))?;
    let cameras = Dataset::load_cameras(data)
        .with_context(|| format!("cannot read the cameras of {}", data.display()))?;
    let views =
        wildlight_eval::cameras::viewpoints(&cameras, wildlight_eval::cameras::Frame::World);
    let options = ReferenceOptions {
        marching: wildlight_export::MarchingOptions {
            resolution: reference_resolution,
            ..Default::default()
        },
        ..ReferenceOptions::default()
    };
    let (reference, reference_projection) =
        level_set_reference(source, &options, &ProgressBar::hidden())?;
    let reference = reference.transformed(scale_mat);
    let mut raw_projected = raw.transformed(&scale_mat.inverse());
    let raw_projection = project_to_level_set(
        source,
        &mut raw_projected,
        options.iterations,
        options.max_step,
    );
    let raw_projected = raw_projected.transformed(scale_mat);
    // eq. 16 of one mesh, averaged over the sampler seeds 0..seeds (the
    // same seeds for every mesh): (mean, median, per-seed means, pairs).
    let eq16 = |mesh: &TriMesh| -> anyhow::Result<(f64, f64, Vec<f64>, usize)> {
        let mut means = Vec::new();
        let (mut median_sum, mut pairs) = (0.0, 0);
        for seed in 0..seeds.max(1) {
            let options = SurfaceDistanceOptions {
                seed,
                ..SurfaceDistanceOptions::default()
            };
            let d = evaluate_meshes(mesh, &gt, Some(&views), &options)?.distance;
            means.push(d.mean);
            median_sum += d.median;
            pairs += d.pairs;
        }
        let n = means.len() as f64;
        Ok((means.iter().sum::<f64>() / n, median_sum / n, means, pairs))
    };
    let d_raw = eq16(&raw)?;
    let d_ref = eq16(&reference)?;
    let d_proj = eq16(&raw_projected)?;
    Ok(GeometryRoundTrip {
        raw_mean: d_raw.0,
        raw_median: d_raw.1,
        reference_mean: d_ref.0,
        reference_median: d_ref.1,
        relative_difference: (d_raw.0 - d_ref.0).abs() / d_ref.0,
        raw_projected_mean: d_proj.0,
        relative_difference_projected: (d_raw.0 - d_proj.0).abs() / d_proj.0,
        per_seed_means: [d_raw.2, d_ref.2, d_proj.2],
        reference_resolution,
        triangles: [raw.triangles.len(), reference.triangles.len()],
        pairs: [d_raw.3, d_ref.3, d_proj.3],
        reference_projection,
        raw_projection,
        seconds: start.elapsed().as_secs_f64(),
    })
}

fn print_table(r: &Report) {
    println!(
        "export of {} at {}³, {} faces, {}² textures, {} threads",
        r.run.display(),
        r.resolution,
        r.faces,
        r.texture,
        r.threads
    );
    for (k, t) in r.exports.iter().enumerate() {
        let stages: Vec<String> = t
            .stages
            .iter()
            .map(|(name, s)| format!("{name} {s:.2}"))
            .collect();
        println!(
            "  run {}: {:.2} s  ({})",
            k + 1,
            t.seconds,
            stages.join(", ")
        );
    }
    if let Some(m) = r.median_seconds {
        println!("  median {m:.2} s");
    }
    if let Some(p) = r.peak_rss_mib {
        println!("  peak RSS {p:.0} MiB");
    }
    if let Some(f) = &r.flash {
        println!(
            "flash round trip over {} flash views (gain {:.4}): PSNR min {:.2} dB, median {:.2} dB, mean {:.2} dB",
            f.views, f.gain, f.min_psnr, f.median_psnr, f.mean_psnr
        );
        if let (Some(a), Some(b), Some(c)) =
            (f.volume_min_psnr, f.volume_median_psnr, f.volume_mean_psnr)
        {
            println!(
                "  against the run renderer's flash map over the mask: PSNR min {a:.2} dB, median {b:.2} dB, mean {c:.2} dB"
            );
        }
    }
    if let Some(g) = &r.geometry {
        println!("eq. 16 against the ground truth (visible surface, world units):");
        println!(
            "  raw marching cubes      mean {:.6e}  median {:.6e}",
            g.raw_mean, g.raw_median
        );
        println!(
            "  level set ({}³, projected) mean {:.6e}  median {:.6e}",
            g.reference_resolution, g.reference_mean, g.reference_median
        );
        println!(
            "  relative difference     {:.3} %",
            100.0 * g.relative_difference
        );
        println!(
            "  raw vertices projected  mean {:.6e}  ({:.3} % from raw)",
            g.raw_projected_mean,
            100.0 * g.relative_difference_projected
        );
    }
}
