//! Rendering whole views of a trained model: the image and its maps
//! (flash-only, ambient-only, normal, depth, accumulated weight and the
//! material parameters), in ray chunks.
//!
//! A model with a background (a run without masks, SPEC §6) shows it in
//! the image and splits it between the flash-only and ambient-only maps
//! like the object (its flash term γ E ρ / t² to the flash map), so that
//! image = flash + ambient still holds; the object's own maps (normal,
//! depth, Σw, material) leave it out.

use crate::model::Model;
use crate::pipeline::{PassSettings, Pipeline, RayInputs};
use wildlight_data::{Camera, ViewMaps};
use wildlight_fields::NormalMethod;
use wildlight_material::PARAM_COUNT;
use wildlight_render::{OccupancyGrid, composite};

/// Rays rendered per chunk (bounds memory).
pub const RENDER_CHUNK: usize = 8192;

/// Renders `camera` at `scale` times its resolution with the given flash
/// energy (use the camera's own `light_energy` for "as captured").
pub fn render_view(
    model: &Model,
    grid: &OccupancyGrid,
    pipeline: &mut Pipeline,
    camera: &Camera,
    energy: [f32; 3],
    scale: f64,
    normals: NormalMethod,
) -> ViewMaps {
    let width = ((camera.width as f64 * scale).round() as u32).max(1);
    let height = ((camera.height as f64 * scale).round() as u32).max(1);
    let (sx, sy) = (
        camera.width as f64 / width as f64,
        camera.height as f64 / height as f64,
    );
    let n = (width * height) as usize;
    let mut maps = ViewMaps::with_capacity(width, height);
    let settings = PassSettings::rendering(normals);
    let (mut origins, mut dirs) = (Vec::new(), Vec::new());
    for start in (0..n).step_by(RENDER_CHUNK) {
        let end = (start + RENDER_CHUNK).min(n);
        origins.clear();
        dirs.clear();
        for p in start..end {
            let (x, y) = ((p as u32 % width) as f64, (p as u32 / width) as f64);
            // pixel centre of the scaled image in the original pixel grid
            let ray = camera.ray((x + 0.5) * sx - 0.5, (y + 0.5) * sy - 0.5);
            origins.push(ray.origin.as_vec3().to_array());
            dirs.push(ray.dir.as_vec3().normalize().to_array());
        }
        let energies = vec![energy; end - start];
        let rays = RayInputs {
            origins: &origins,
            dirs: &dirs,
            energy: &energies,
        };
        pipeline.forward(model, grid, &rays, &[], &settings);
        append_maps(pipeline, end - start, &mut maps);
    }
    maps
}

fn append_maps(p: &Pipeline, n_rays: usize, maps: &mut ViewMaps) {
    let offsets = &p.samples.offsets;
    let w = &p.weights.weight;
    let mut buf3 = vec![[0.0f32; 3]; n_rays];
    maps.rgb.extend_from_slice(&p.colour);
    let acc = p.acc_weight();
    let bg = &p.background;
    let has_bg = bg.colour.len() == n_rays;
    composite(offsets, w, &p.flash, &mut buf3);
    if has_bg {
        // (1 − Σw) × the background's flash part, B − Σ_j w_j a_j
        for (r, f) in buf3.iter_mut().enumerate() {
            let (b, a) = (bg.colour[r], bg.ambient_colour[r]);
            for (c, v) in f.iter_mut().enumerate() {
                *v += (1.0 - acc[r]) * (b[c] - a[c]);
            }
        }
    }
    maps.flash.extend_from_slice(&buf3);
    composite(offsets, w, &p.ambient, &mut buf3);
    if has_bg {
        for (r, a) in buf3.iter_mut().enumerate() {
            for (v, b) in a.iter_mut().zip(bg.ambient_colour[r]) {
                *v += (1.0 - acc[r]) * b;
            }
        }
    }
    maps.ambient.extend_from_slice(&buf3);
    composite(offsets, w, &p.normals, &mut buf3);
    for (nrm, a) in buf3.iter().zip(acc) {
        let len = (nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]).sqrt();
        maps.normal.push(if *a > 1e-3 && len > 1e-6 {
            [nrm[0] / len, nrm[1] / len, nrm[2] / len]
        } else {
            [0.0; 3]
        });
    }
    let t1: Vec<[f32; 1]> = p.samples.t.iter().map(|t| [*t]).collect();
    let mut depth = vec![[0.0f32; 1]; n_rays];
    composite(offsets, w, &t1, &mut depth);
    let mut params = vec![[0.0f32; PARAM_COUNT]; n_rays];
    composite(offsets, w, &p.theta, &mut params);
    for ((d, th), a) in depth.iter().zip(&mut params).zip(acc) {
        let inv = if *a > 1e-3 { 1.0 / a } else { 0.0 };
        maps.depth.push(d[0] * inv);
        th.iter_mut().for_each(|v| *v *= inv);
    }
    maps.params.extend_from_slice(&params);
    maps.acc.extend_from_slice(acc);
}
