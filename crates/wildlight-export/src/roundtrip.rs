//! Measuring an export's round trip: how closely the exported asset
//! reproduces the fields it was baked from.
//!
//! - **Flash term** ([`flash_round_trip`]): the asset's flash term
//!   (textures sampled at the hit's UV, normal map applied) against the
//!   fields' own (sphere tracing of the SDF, material at the hit), view by
//!   view, as a PSNR.
//! - **Geometry** ([`level_set_reference`]): a reference for "the fields'
//!   zero level set" that eq. 16 (SPEC §7) can score like any mesh: a
//!   marching-cubes extraction at a finer resolution whose every vertex is
//!   then moved onto the zero level set by Newton steps
//!   p ← p − φ(p) ∇φ/|∇φ|². The vertices carry no interpolation error and
//!   the faceting between them shrinks with the square of the finer cell,
//!   so the eq. 16 distance of this mesh stands for the level set's. The
//!   exported raw mesh's distance is compared with it.

use glam::Vec3;
use indicatif::ProgressBar;
use rayon::prelude::*;
use serde::Serialize;
use wildlight_data::Camera;
use wildlight_mesh::TriMesh;

use crate::ExportError;
use crate::marching::{MarchingOptions, extract_surface};
use crate::render::{AssetTracer, FlashSettings, flash_psnr, render_source_flash};
use crate::source::{FieldSource, MAX_BATCH};

/// Settings of [`level_set_reference`].
#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceOptions {
    /// Marching-cubes settings of the reference extraction (default
    /// resolution 1024, twice the export's default).
    pub marching: MarchingOptions,
    /// Newton steps per vertex (default 4).
    pub iterations: u32,
    /// Largest move of one Newton step, normalized units (default 0.01).
    pub max_step: f32,
    /// Connected pieces with less area than this fraction of the largest
    /// are removed, as the export does (default 0.02).
    pub min_component_fraction: f64,
}

impl Default for ReferenceOptions {
    fn default() -> Self {
        ReferenceOptions {
            marching: MarchingOptions {
                resolution: 1024,
                ..MarchingOptions::default()
            },
            iterations: 4,
            max_step: 0.01,
            min_component_fraction: 0.02,
        }
    }
}

/// How far the vertices were from the zero level set before and after
/// [`project_to_level_set`] (|φ| in normalized units).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ProjectionStats {
    /// Vertices projected.
    pub vertices: usize,
    /// Mean |φ| before.
    pub mean_abs_sdf_before: f64,
    /// Largest |φ| before.
    pub max_abs_sdf_before: f64,
    /// Mean |φ| after.
    pub mean_abs_sdf_after: f64,
    /// Largest |φ| after.
    pub max_abs_sdf_after: f64,
}

/// The SDF restricted to the unit sphere, max(φ, |p| − 1), and its
/// gradient, at `points` (the surface marching cubes extracts).
fn bounded_sdf_and_gradient<S: FieldSource + ?Sized>(
    source: &S,
    points: &[[f32; 3]],
    phi: &mut [f32],
    grad: &mut [[f32; 3]],
) {
    source.sdf(points, phi);
    source.gradient(points, grad);
    for ((p, f), g) in points.iter().zip(phi.iter_mut()).zip(grad.iter_mut()) {
        let p = Vec3::from_array(*p);
        let sphere = p.length() - 1.0;
        if sphere > *f {
            *f = sphere;
            *g = p.normalize_or_zero().to_array();
        }
    }
}

fn abs_stats(phi: &[f32]) -> (f64, f64) {
    let sum: f64 = phi.iter().map(|f| f.abs() as f64).sum();
    let max = phi.iter().fold(0.0f64, |m, f| m.max(f.abs() as f64));
    (sum / phi.len().max(1) as f64, max)
}

/// Moves every vertex of `mesh` (normalized frame) onto the zero level set
/// of `source`'s SDF restricted to the unit sphere with `iterations`
/// Newton steps p ← p − φ ∇φ/|∇φ|², each at most `max_step` long.
pub fn project_to_level_set<S: FieldSource + ?Sized>(
    source: &S,
    mesh: &mut TriMesh,
    iterations: u32,
    max_step: f32,
) -> ProjectionStats {
    let per_chunk: Vec<(Vec<f32>, Vec<f32>)> = mesh
        .positions
        .par_chunks_mut(MAX_BATCH)
        .map(|chunk| {
            let mut points: Vec<[f32; 3]> = chunk.iter().map(|p| p.to_array()).collect();
            let mut phi = vec![0.0f32; points.len()];
            let mut grad = vec![[0.0f32; 3]; points.len()];
            let mut before = Vec::new();
            for k in 0..iterations {
                bounded_sdf_and_gradient(source, &points, &mut phi, &mut grad);
                if k == 0 {
                    before = phi.clone();
                }
                for ((p, f), g) in points.iter_mut().zip(&phi).zip(&grad) {
                    let g = Vec3::from_array(*g);
                    let g2 = g.length_squared();
                    if g2 > 1e-12 && f.is_finite() {
                        let step = (g * (*f / g2)).clamp_length_max(max_step);
                        *p = (Vec3::from_array(*p) - step).to_array();
                    }
                }
            }
            bounded_sdf_and_gradient(source, &points, &mut phi, &mut grad);
            if iterations == 0 {
                before = phi.clone();
            }
            for (v, p) in chunk.iter_mut().zip(&points) {
                *v = Vec3::from_array(*p);
            }
            (before, phi)
        })
        .collect();
    let before: Vec<f32> = per_chunk.iter().flat_map(|c| c.0.iter().copied()).collect();
    let after: Vec<f32> = per_chunk.iter().flat_map(|c| c.1.iter().copied()).collect();
    let (mean_b, max_b) = abs_stats(&before);
    let (mean_a, max_a) = abs_stats(&after);
    mesh.normals = None;
    ProjectionStats {
        vertices: mesh.positions.len(),
        mean_abs_sdf_before: mean_b,
        max_abs_sdf_before: max_b,
        mean_abs_sdf_after: mean_a,
        max_abs_sdf_after: max_a,
    }
}

/// The reference surface of `source`'s zero level set (see the module
/// documentation), in the normalized frame: extraction at
/// `options.marching`, small pieces removed, vertices projected.
pub fn level_set_reference<S: FieldSource + ?Sized>(
    source: &S,
    options: &ReferenceOptions,
    progress: &ProgressBar,
) -> Result<(TriMesh, ProjectionStats), ExportError> {
    let (mesh, _) = extract_surface(source, &options.marching, progress)?;
    let mut mesh = mesh.without_small_components(options.min_component_fraction);
    let stats = project_to_level_set(source, &mut mesh, options.iterations, options.max_step);
    Ok((mesh, stats))
}

/// The flash round trip of one view.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ViewRoundTrip {
    /// Image index.
    pub index: usize,
    /// PSNR (dB) of the asset's flash term against the fields' over the
    /// pixels where either hits the surface ([`flash_psnr`]).
    pub psnr: f64,
    /// Pixels where the fields' surface is hit.
    pub surface_pixels: usize,
}

/// Renders the flash term of the asset (`tracer`) and of `source` at every
/// camera with the flash on and compares them (views with no surface pixel
/// are left out). `settings.gain` applies to both.
pub fn flash_round_trip<S: FieldSource + ?Sized>(
    tracer: &AssetTracer<'_>,
    source: &S,
    cameras: &[Camera],
    settings: &FlashSettings,
) -> Vec<ViewRoundTrip> {
    cameras
        .iter()
        .filter(|c| c.flash())
        .filter_map(|camera| {
            let asset = tracer.render_flash(camera, settings);
            let fields = render_source_flash(source, camera, settings);
            let psnr = flash_psnr(&asset, &fields)?;
            Some(ViewRoundTrip {
                index: camera.index,
                psnr,
                surface_pixels: fields.hit.iter().filter(|h| **h).count(),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::AnalyticSource;

    #[test]
    fn projection_lands_on_the_level_set_of_a_non_distance_field() {
        // φ = |p|² − 0.25 has |∇φ| ≠ 1: Newton steps, not distance steps.
        let source = AnalyticSource::new(|p: Vec3| p.length_squared() - 0.25, |_| [0.5; 9]);
        let mut mesh = TriMesh::new(
            vec![
                Vec3::new(0.52, 0.0, 0.0),
                Vec3::new(0.0, -0.47, 0.01),
                Vec3::new(0.3, 0.3, 0.3),
                // Just outside the surface.
                Vec3::new(0.0, 0.0, 0.505),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let stats = project_to_level_set(&source, &mut mesh, 6, 0.05);
        assert_eq!(stats.vertices, 4);
        for p in &mesh.positions {
            assert!((p.length() - 0.5).abs() < 1e-5, "{p}");
        }
        assert!(stats.max_abs_sdf_before > 0.02);
        assert!(stats.max_abs_sdf_after < 1e-5);
        // The direction of each point is kept (radial Newton steps).
        assert!((mesh.positions[2].normalize() - Vec3::splat(1.0).normalize()).length() < 1e-5);
    }

    #[test]
    fn projection_respects_the_unit_sphere_clip() {
        // A plane z = 0 clipped by the unit sphere: a point beyond the rim
        // goes onto the sphere |p| = 1, where max(φ, |p| − 1) vanishes.
        let source = AnalyticSource::new(|p: Vec3| p.z.abs() - 0.9, |_| [0.5; 9])
            .with_gradient(|p: Vec3| Vec3::new(0.0, 0.0, p.z.signum()));
        let mut mesh = TriMesh::new(
            vec![
                Vec3::new(0.0, 0.0, 0.95),
                Vec3::new(0.6, 0.0, 0.9),
                Vec3::new(0.0, 0.2, 0.89),
            ],
            vec![[0, 1, 2]],
        );
        project_to_level_set(&source, &mut mesh, 8, 0.1);
        // (0.6, 0, 0.9) has |p| = 1.08 > 1: the clip pulls it radially in.
        assert!(
            (mesh.positions[1].length() - 1.0).abs() < 1e-5,
            "{}",
            mesh.positions[1]
        );
        assert!((mesh.positions[0].z - 0.9).abs() < 1e-5);
        assert!((mesh.positions[2].z - 0.9).abs() < 1e-5);
    }
}
