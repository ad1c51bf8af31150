//! `wildlight eval`: geometry (appendix eq. 16), image (PSNR/SSIM) and
//! material accuracy. Each prints a short table, or one JSON object with
//! `--json`. All the work happens in `wildlight-eval`.

use std::path::PathBuf;

use anyhow::{Context, bail};
use wildlight_data::Dataset;
use wildlight_eval::cameras::{Frame, viewpoints};
use wildlight_eval::{
    ImageEvaluation, MaterialEvaluation, MeshEvaluation, Pixels, Split, SurfaceDistanceOptions,
    VertexTruth, evaluate_images, evaluate_materials, evaluate_meshes, evaluate_vertex_materials,
};
use wildlight_mesh::TriMesh;

/// Options of `wildlight eval`.
#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    which: Which,
}

#[derive(clap::Subcommand, Debug)]
enum Which {
    /// Surface-to-surface distance of two meshes (SPEC §7, appendix eq. 16).
    Mesh(MeshArgs),
    /// PSNR and SSIM of rendered views over the masks (or the whole image), by flash /
    /// no-flash / all.
    Images(ImagesArgs),
    /// Material-map errors against a synthetic capture's ground truth.
    Materials(MaterialsArgs),
    /// A trained run's materials at the vertices of a capture's true mesh,
    /// against truth given per vertex (gt_albedo_vertex.npy, meta.json).
    VertexMaterials(VertexMaterialsArgs),
}

/// The frame of the meshes given to `eval mesh`.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum FrameArg {
    /// World units (x_world = scale_mat · x_normalized).
    World,
    /// The normalized frame (object inside the unit sphere).
    Normalized,
}

/// Options of `wildlight eval mesh`.
#[derive(clap::Args, Debug)]
struct MeshArgs {
    /// Predicted mesh (.ply or .obj).
    #[arg(long, value_name = "FILE")]
    pred: PathBuf,
    /// Ground-truth mesh (.ply or .obj).
    #[arg(long, value_name = "FILE")]
    gt: PathBuf,
    /// Restrict both meshes to the surface these cameras see: a dataset
    /// folder or a cameras_sphere.npz file [default: none: the whole of both meshes].
    #[arg(long, value_name = "DATASET_DIR_OR_NPZ")]
    cameras: Option<PathBuf>,
    /// The frame both meshes are in; the camera centres are taken in it.
    #[arg(long, value_enum, default_value = "world")]
    frame: FrameArg,
    /// Measure the predicted mesh's object alone, cut as `export
    /// --object-only` cuts it: the support plane and what lies below it,
    /// what lies outside the region of interest (the unit sphere; in the
    /// world frame, mapped by the cameras' scale_mat, so --cameras is
    /// needed there), and every piece but the largest.
    #[arg(long)]
    object_only: bool,
    /// Seed of the point sampler.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// Options of `wildlight eval images`.
#[derive(clap::Args, Debug)]
struct ImagesArgs {
    /// Folder written by `wildlight render` (image/NNN.exr and views.json).
    #[arg(long, value_name = "DIR")]
    pred: PathBuf,
    /// The capture's dataset folder (photos, masks, val/).
    #[arg(long, value_name = "DATASET_DIR")]
    gt: PathBuf,
    /// Score every pixel (the object and what the photo shows around it)
    /// instead of the masks' pixels.
    #[arg(long)]
    whole_image: bool,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// The split of `eval materials`.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
enum SplitArg {
    /// The dataset folder's own (training) views.
    Train,
    /// The dataset's val/ views.
    Val,
}

/// Options of `wildlight eval materials`.
#[derive(clap::Args, Debug)]
struct MaterialsArgs {
    /// Folder of predicted maps (base_color/, roughness/, metallic/, normal/).
    #[arg(long, value_name = "DIR")]
    pred: PathBuf,
    /// The synthetic dataset folder (ground truth in <split>/gt/<kind>/).
    #[arg(long, value_name = "DATASET_DIR")]
    gt: PathBuf,
    /// Which views' ground truth to use
    /// [default: val when the dataset has val/gt, otherwise train].
    #[arg(long, value_enum)]
    split: Option<SplitArg>,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// Options of `wildlight eval vertex-materials`.
#[derive(clap::Args, Debug)]
struct VertexMaterialsArgs {
    /// The run folder written by `wildlight train`.
    #[arg(long, value_name = "DIR")]
    run: PathBuf,
    /// The capture folder: cameras, gt_mesh_normalized.ply,
    /// gt_albedo_vertex.npy (linear RGB per vertex) and meta.json
    /// (material.roughness, material.metallic).
    #[arg(long, value_name = "DATASET_DIR")]
    gt: PathBuf,
    /// Print one JSON object instead of a table.
    #[arg(long)]
    json: bool,
}

/// Runs `wildlight eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.which {
        Which::Mesh(a) => run_mesh(a),
        Which::Images(a) => run_images(a),
        Which::Materials(a) => run_materials(a),
        Which::VertexMaterials(a) => run_vertex_materials(a),
    }
}

fn run_mesh(args: MeshArgs) -> anyhow::Result<()> {
    let mut pred = TriMesh::read(&args.pred)?;
    let gt = TriMesh::read(&args.gt)?;
    let frame = match args.frame {
        FrameArg::World => Frame::World,
        FrameArg::Normalized => Frame::Normalized,
    };
    let cameras = match &args.cameras {
        Some(path) => Some(
            Dataset::load_cameras(path)
                .with_context(|| format!("cannot read the cameras of {}", path.display()))?,
        ),
        None => None,
    };
    if args.object_only {
        // The region of interest in the meshes' frame.
        let (center, radius) = match (frame, &cameras) {
            (Frame::Normalized, _) => (glam::Vec3::ZERO, 1.0),
            (Frame::World, Some(cams)) => {
                let m = cams
                    .first()
                    .context("--object-only: the cameras are empty")?
                    .scale_mat
                    .as_mat4();
                (m.transform_point3(glam::Vec3::ZERO), m.x_axis.length())
            }
            (Frame::World, None) => bail!(
                "--object-only in the world frame needs --cameras (their scale_mat places the region of interest)"
            ),
        };
        let cut = pred.object_only(&wildlight_mesh::SupportSearch::new(center, radius));
        eprintln!(
            "object only: support plane {}; removed {:.4} (support), {:.4} (outside), {:.4} (other pieces) of {:.4} (area, mesh units²)",
            if cut.plane.is_some() {
                "found"
            } else {
                "not found"
            },
            cut.support_area,
            cut.outside_area,
            cut.fragment_area,
            pred.triangle_areas().iter().sum::<f64>()
        );
        pred = cut.mesh;
    }
    let views = cameras.as_ref().map(|c| viewpoints(c, frame));
    let options = SurfaceDistanceOptions {
        seed: args.seed,
        ..SurfaceDistanceOptions::default()
    };
    let result = evaluate_meshes(&pred, &gt, views.as_deref(), &options)?;
    print_report(args.json, &result, mesh_table)
}

/// Prints `result` as one JSON object or as its table.
fn print_report<R: serde::Serialize>(
    json: bool,
    result: &R,
    table: fn(&R) -> String,
) -> anyhow::Result<()> {
    if json {
        println!("{}", serde_json::to_string_pretty(result)?);
    } else {
        print!("{}", table(result));
    }
    Ok(())
}

fn mesh_table(r: &MeshEvaluation) -> String {
    let d = &r.distance;
    let mut s = String::from("surface distance (eq. 16), mesh units\n");
    s += &format!("  mean          {:.6e}\n", d.mean);
    s += &format!("  median        {:.6e}\n", d.median);
    s += &format!("  std of mean   {:.2e}\n", d.std_of_mean);
    s += &format!("  pairs         {}\n", d.pairs);
    s += &format!("  pred → gt     {:.6e}  (accuracy)\n", d.mean_pred_to_gt);
    s += &format!(
        "  gt → pred     {:.6e}  (completeness)\n",
        d.mean_gt_to_pred
    );
    if r.cameras > 0 {
        s += &format!(
            "  visible       pred {}/{} triangles, gt {}/{} triangles, {} cameras\n",
            r.triangles_pred_used, r.triangles_pred, r.triangles_gt_used, r.triangles_gt, r.cameras
        );
    }
    s
}

fn run_images(args: ImagesArgs) -> anyhow::Result<()> {
    let pixels = if args.whole_image {
        Pixels::WholeImage
    } else {
        Pixels::Mask
    };
    let result = evaluate_images(&args.pred, &args.gt, pixels)?;
    print_report(args.json, &result, images_table)
}

fn number(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".into(), |v| format!("{v:.digits$}"))
}

fn images_table(r: &ImageEvaluation) -> String {
    let mut s = String::from("views      count   PSNR (dB)   SSIM\n");
    for (name, count, psnr, ssim) in [
        ("no-flash", r.views_noflash, r.psnr_noflash, r.ssim_noflash),
        ("flash", r.views_flash, r.psnr_flash, r.ssim_flash),
        (
            "all",
            r.views_noflash + r.views_flash,
            r.psnr_all,
            r.ssim_all,
        ),
    ] {
        s += &format!(
            "{name:<10} {count:>5}   {:>9}   {:>6}\n",
            number(psnr, 2),
            number(ssim, 4)
        );
    }
    s
}

fn run_materials(args: MaterialsArgs) -> anyhow::Result<()> {
    let split = match args.split {
        Some(SplitArg::Train) => Split::Train,
        Some(SplitArg::Val) => Split::Val,
        None if args.gt.join("val").join("gt").is_dir() => Split::Val,
        None => Split::Train,
    };
    let result = evaluate_materials(&args.pred, &args.gt, split)?;
    print_report(args.json, &result, materials_table)
}

fn materials_table(r: &MaterialEvaluation) -> String {
    let mut s = format!(
        "materials ({} split, {} views, {} surface pixels)\n",
        r.split.name(),
        r.views,
        r.pixels
    );
    s += &format!(
        "  base colour PSNR          {} dB\n",
        number(r.base_color_psnr, 2)
    );
    s += &format!(
        "  base colour PSNR aligned  {} dB  (scale {})\n",
        number(r.base_color_psnr_aligned, 2),
        r.base_color_scale.map_or("-".into(), |k| format!(
            "{:.3} {:.3} {:.3}",
            k[0], k[1], k[2]
        ))
    );
    s += &format!(
        "  roughness MAE             {}\n",
        number(r.roughness_mae, 4)
    );
    s += &format!(
        "  metallic MAE              {}\n",
        number(r.metallic_mae, 4)
    );
    s += &format!(
        "  normal error              {}°  (median {}°, coverage {})\n",
        number(r.normal_error_deg, 2),
        number(r.normal_error_median_deg, 2),
        number(r.normal_coverage, 3)
    );
    if let Some(within) = &r.normal_within {
        let shares: Vec<String> = within
            .iter()
            .map(|w| format!("{}° {:.1} %", w.deg, 100.0 * w.fraction))
            .collect();
        s += &format!("  normals within            {}\n", shares.join(", "));
    }
    s
}

fn run_vertex_materials(args: VertexMaterialsArgs) -> anyhow::Result<()> {
    let trained = wildlight_train::inference::TrainedRun::load(&args.run)?;
    let truth = VertexTruth::read(&args.gt)?;
    let cameras = Dataset::load_cameras(&args.gt)
        .with_context(|| format!("cannot read the cameras of {}", args.gt.display()))?;
    let e =
        evaluate_vertex_materials(&truth, &viewpoints(&cameras, Frame::Normalized), |points| {
            trained.model.material_at(points)
        })?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&e)?);
        return Ok(());
    }
    let k = e.base_color_scale;
    print!(
        "vertices      {} of {} (those the cameras see)\n\
         base colour   {:.2} dB, aligned {:.2} dB (scale {:.3} {:.3} {:.3})\n\
         roughness     mean {:.3} for {:.3}, mean error {:.3}\n\
         metallic      mean {:.3} for {:.3}, mean error {:.3}\n",
        e.vertices,
        e.vertices_total,
        e.base_color_psnr,
        e.base_color_psnr_aligned,
        k[0],
        k[1],
        k[2],
        e.roughness_mean,
        e.roughness_true,
        e.roughness_mae,
        e.metallic_mean,
        e.metallic_true,
        e.metallic_mae,
    );
    Ok(())
}
