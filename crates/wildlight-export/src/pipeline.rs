//! The whole export: marching cubes → clean-up → simplification → UV atlas
//! → bake → dilation → files, with a progress bar per stage (stderr).

use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Mat4;
use indicatif::{MultiProgress, ProgressBar, ProgressDrawTarget, ProgressStyle};
use wildlight_mesh::{SupportPlane, SupportSearch, TriMesh};

use crate::ExportError;
use crate::atlas::{AtlasOptions, unwrap};
use crate::bake::{BakeOptions, bake, dilate};
use crate::gltf::{Asset, AssetFrame, write_glb};
use crate::marching::{MarchingOptions, MarchingStats, extract_surface};
use crate::obj::write_obj_bundle;
use crate::simplify::simplify;
use crate::source::FieldSource;

/// Everything an export can be told.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportOptions {
    /// Marching-cubes settings (resolution default 512).
    pub marching: MarchingOptions,
    /// Largest face count of the exported mesh (default 131,072).
    pub max_faces: usize,
    /// Connected pieces with less area than this fraction of the largest
    /// piece are removed (default 0.02).
    pub min_component_fraction: f64,
    /// Keep the object alone ([`TriMesh::object_only`]): cut away what lies
    /// outside the unit sphere, the support plane the object stands on and
    /// everything below it, and every piece but the largest (default false;
    /// the CLI turns it on for runs trained without masks).
    pub object_only: bool,
    /// With `object_only`: the support plane known from elsewhere
    /// (normalized frame), cut by when the surface holds no plane that
    /// agrees with it ([`SupportSearch::known`]); default none.
    pub known_support: Option<SupportPlane>,
    /// Atlas settings (texture size default 2048).
    pub atlas: AtlasOptions,
    /// Texel projection settings.
    pub bake: BakeOptions,
    /// Normalized → world map: x_world = scale_mat · x_normalized (SPEC §5).
    pub scale_mat: Mat4,
    /// Write vertices in world units (apply `scale_mat`, default true) or
    /// in the normalized frame.
    pub world_units: bool,
    /// Draw progress bars on stderr (default true).
    pub progress: bool,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            marching: MarchingOptions::default(),
            max_faces: 131_072,
            min_component_fraction: 0.02,
            object_only: false,
            known_support: None,
            atlas: AtlasOptions::default(),
            bake: BakeOptions::default(),
            scale_mat: Mat4::IDENTITY,
            world_units: true,
            progress: true,
        }
    }
}

impl ExportOptions {
    /// The map from the normalized frame to the frame of the written files.
    pub fn export_transform(&self) -> Mat4 {
        if self.world_units {
            self.scale_mat
        } else {
            Mat4::IDENTITY
        }
    }
}

/// What an export produced and how long each stage took.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct ExportReport {
    /// Triangles of the marching-cubes mesh (after small-piece removal).
    pub raw_triangles: usize,
    /// Vertices of the marching-cubes mesh.
    pub raw_vertices: usize,
    /// Triangles of the exported mesh.
    pub faces: usize,
    /// Vertices of the exported mesh (split along UV seams).
    pub vertices: usize,
    /// Texture width × height.
    pub texture_size: [u32; 2],
    /// UV charts.
    pub charts: u32,
    /// Fraction of texels covered by charts.
    pub utilization: f32,
    /// SDF evaluations of marching cubes.
    pub sdf_evaluations: u64,
    /// Narrow-band blocks evaluated / all blocks.
    pub active_blocks: [u64; 2],
    /// With [`ExportOptions::object_only`]: the support plane cut by (the
    /// surface's own or the known one; normalized frame: unit normal
    /// towards the object, offset), if any.
    pub support_plane: Option<([f32; 3], f32)>,
    /// Where [`ExportReport::support_plane`] came from: `"surface"` (found
    /// on the extracted surface) or `"known"` ([`ExportOptions::known_support`]).
    pub support_source: Option<String>,
    /// With [`ExportOptions::object_only`]: the surface area removed as
    /// support, outside the sphere and as other pieces (normalized units²).
    pub removed_area: Option<[f64; 3]>,
    /// Seconds per stage, in order.
    pub seconds: Vec<(String, f64)>,
}

/// An export held in memory.
#[derive(Clone, Debug, PartialEq)]
pub struct Exported {
    /// The textured, simplified asset (export frame).
    pub asset: Asset,
    /// The marching-cubes mesh before simplification (export frame).
    pub raw_mesh: TriMesh,
    /// Statistics and timings.
    pub report: ExportReport,
}

/// The files [`write_export`] writes.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportFiles {
    /// `model.glb`.
    pub glb: PathBuf,
    /// `model.obj` (with `model.mtl` and the PNG maps next to it).
    pub obj: PathBuf,
    /// `mesh_raw.ply`.
    pub raw_ply: PathBuf,
}

fn stage_bar(multi: &MultiProgress, name: &str) -> ProgressBar {
    let bar = multi.add(ProgressBar::new(0));
    bar.set_style(
        ProgressStyle::with_template("{prefix:>14} [{elapsed_precise}] {wide_bar} {pos}/{len}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar.set_prefix(name.to_string());
    bar
}

/// Runs the export pipeline on `source` and returns the result in memory.
pub fn export_asset<S: FieldSource + ?Sized>(
    source: &S,
    options: &ExportOptions,
) -> Result<Exported, ExportError> {
    let multi = MultiProgress::with_draw_target(if options.progress {
        ProgressDrawTarget::stderr()
    } else {
        ProgressDrawTarget::hidden()
    });
    let mut report = ExportReport::default();
    let mut clock = Instant::now();
    let mut lap = |report: &mut ExportReport, name: &str| {
        report
            .seconds
            .push((name.to_string(), clock.elapsed().as_secs_f64()));
        clock = Instant::now();
    };
    let to_export = options.export_transform();
    let to_normalized = to_export.inverse();

    let bar = stage_bar(&multi, "marching cubes");
    let (fine, stats): (TriMesh, MarchingStats) = extract_surface(source, &options.marching, &bar)?;
    bar.finish();
    report.sdf_evaluations = stats.evaluations;
    report.active_blocks = [stats.active_blocks, stats.total_blocks];
    lap(&mut report, "marching cubes");

    let bar = stage_bar(&multi, "clean-up");
    bar.set_length(1);
    let fine = if options.object_only {
        let cut = fine.object_only(&SupportSearch {
            known: options.known_support,
            ..SupportSearch::new(glam::Vec3::ZERO, 1.0)
        });
        report.support_plane = cut.plane.map(|p| (p.normal.to_array(), p.offset));
        report.support_source = cut.plane.map(|_| {
            if cut.plane_from_surface {
                "surface"
            } else {
                "known"
            }
            .to_string()
        });
        report.removed_area = Some([cut.support_area, cut.outside_area, cut.fragment_area]);
        cut.mesh
    } else {
        fine.without_small_components(options.min_component_fraction)
    };
    if fine.triangles.is_empty() {
        return Err(ExportError::EmptySurface {
            resolution: options.marching.resolution,
        });
    }
    report.raw_triangles = fine.triangles.len();
    report.raw_vertices = fine.positions.len();
    bar.finish();
    lap(&mut report, "small pieces");

    let bar = stage_bar(&multi, "simplify");
    bar.set_length(1);
    let mut coarse = simplify(&fine, options.max_faces)?;
    bar.finish();
    lap(&mut report, "simplify");

    // Smooth vertex normals before the seams split vertices; then the
    // export frame (normals follow the inverse transpose).
    coarse.normals = Some(coarse.vertex_normals_from_faces());
    coarse.transform(&to_export);
    let raw_mesh = fine.transformed(&to_export);
    drop(fine);

    let bar = stage_bar(&multi, "UV atlas");
    bar.set_length(1);
    let (mesh, size) = unwrap(&coarse, &options.atlas)?;
    bar.finish();
    report.faces = mesh.triangles.len();
    report.vertices = mesh.positions.len();
    report.texture_size = [size.width, size.height];
    report.charts = size.charts;
    report.utilization = size.utilization;
    lap(&mut report, "uv atlas + tangents");

    let bar = stage_bar(&multi, "bake texels");
    let (mut textures, covered) = bake(
        source,
        &mesh,
        &to_normalized,
        size.width,
        size.height,
        &options.bake,
        &bar,
    );
    bar.finish();
    lap(&mut report, "bake");

    let bar = stage_bar(&multi, "dilate");
    bar.set_length(1);
    dilate(&mut textures, &covered);
    bar.finish();
    lap(&mut report, "dilate");

    Ok(Exported {
        asset: Asset {
            mesh,
            textures,
            frame: Some(if options.world_units {
                AssetFrame::World
            } else {
                AssetFrame::Normalized
            }),
        },
        raw_mesh,
        report,
    })
}

/// Writes `dir/model.glb`, `dir/model.obj` + `model.mtl` + PNG maps, and
/// `dir/mesh_raw.ply`, each atomically; creates `dir` if needed.
pub fn write_export(exported: &Exported, dir: &Path) -> Result<ExportFiles, ExportError> {
    std::fs::create_dir_all(dir).map_err(|e| ExportError::io(dir, e))?;
    let files = ExportFiles {
        glb: dir.join("model.glb"),
        obj: dir.join("model.obj"),
        raw_ply: dir.join("mesh_raw.ply"),
    };
    write_glb(&exported.asset, &files.glb)?;
    write_obj_bundle(&exported.asset, dir, "model")?;
    exported.raw_mesh.write(&files.raw_ply)?;
    Ok(files)
}

/// [`export_asset`] then [`write_export`]; the report includes the write time.
pub fn export_to_dir<S: FieldSource + ?Sized>(
    source: &S,
    options: &ExportOptions,
    dir: &Path,
) -> Result<(ExportFiles, ExportReport), ExportError> {
    let mut exported = export_asset(source, options)?;
    let start = Instant::now();
    let files = write_export(&exported, dir)?;
    exported
        .report
        .seconds
        .push(("write files".into(), start.elapsed().as_secs_f64()));
    Ok((files, exported.report))
}
