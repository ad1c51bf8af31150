//! How well the scene's exact shape can reproduce a synthetic capture's
//! held-out flash views when everything else is right: each flash view is
//! rendered as the true ambient term (the capture's `val/gt/ambient` map)
//! plus the flash term of SPEC §2 with the true material (`val/gt/params`),
//!
//! ```text
//!   f = E ⊙ ρ(n, h; Θ) · max(0, n·h) / |x − o|²
//! ```
//!
//! at the point x where the camera ray meets the built-in scene's distance
//! function (sphere tracing), clipped at the capture's saturation level and
//! compared with the photo over the mask. Two normals are used: the
//! capture's own normal map (a control: the photos were shaded with it, so
//! this must reproduce them up to the small difference in |x − o|), and
//! the distance function's gradient at x, the normal an SDF equal to the
//! true shape would render. The synthesizer shades a mesh of the distance
//! function (surface nets at `--mesh-resolution`) with interpolated vertex
//! normals, which no surface has exactly; the second PSNR is the ceiling
//! that an exact SDF with perfect materials and ambient light reaches on
//! these photos, and what it loses is lost to that shading. The flash
//! energy E is the median ratio of the flash map to the unit-energy flash
//! term with the capture's normals (printed; constant for a capture); the
//! BRDF settings are the capture's (`gt/material.json`).
//!
//! ```sh
//! cargo run --release -p wildlight-train --example flash_ceiling -- kettle CAPTURE
//! ```

use anyhow::{Context, Result, bail};
use glam::DVec3;
use std::path::Path;
use wildlight_data::exr_io::{read_exr_channels, read_exr_rgb};
use wildlight_material::PARAM_COUNT;
use wildlight_material::brdf::eval;
use wildlight_synth::ground_truth::GroundTruthMaterial;
use wildlight_synth::scenes::BuiltinScene;
use wildlight_train::run::load_capture;

/// Sphere tracing stops this close to the surface.
const HIT_DISTANCE: f64 = 1e-7;
/// Sphere tracing gives up after this many steps or beyond this distance.
const MAX_TRACE_STEPS: usize = 2000;
const MAX_TRACE_DISTANCE: f64 = 10.0;

fn main() -> Result<()> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    if a.len() != 2 {
        bail!("usage: flash_ceiling SCENE CAPTURE");
    }
    let scene = BuiltinScene::from_name(&a[0]).with_context(|| format!("no scene {}", a[0]))?;
    let capture = Path::new(&a[1]);
    let (dataset, _) = load_capture(capture)?;
    let val = dataset
        .val
        .as_ref()
        .with_context(|| format!("{}: no val/ split", capture.display()))?;
    let cap = val.saturation.unwrap_or(f32::INFINITY);
    // the BRDF settings the capture was rendered with
    let settings =
        GroundTruthMaterial::load(&capture.join("gt").join("material.json"))?.brdf_settings;
    let gt = capture.join("val").join("gt");
    let (mut pooled, mut count) = ([0.0f64; 2], 0usize);
    // per-view PSNRs, for their mean (the figure `eval images` reports)
    let mut views: Vec<[f64; 2]> = Vec::new();
    for view in val.views.iter().filter(|v| v.camera.flash()) {
        let name = format!("{:03}.exr", view.camera.index);
        let map = |term: &str| {
            let path = gt.join(term).join(&name);
            read_exr_rgb(&path).with_context(|| format!("reading {}", path.display()))
        };
        let (ambient, flash, normal) = (map("ambient")?, map("flash")?, map("normal")?);
        let params_path = gt.join("params").join(&name);
        let params = read_exr_channels(&params_path)?;
        let planes = (0..PARAM_COUNT)
            .map(|c| {
                params
                    .channel(&format!("p{c}"))
                    .with_context(|| format!("{}: no channel p{c}", params_path.display()))
            })
            .collect::<Result<Vec<_>>>()?;
        let mask = view
            .mask
            .as_ref()
            .with_context(|| format!("val view {}: no mask", view.camera.index))?;
        let width = view.image.width;
        // (pixel, unit-energy flash term with the capture's normal, with the exact shape's)
        let mut pixels = Vec::new();
        for y in 0..view.image.height {
            for x in (0..width).filter(|&x| mask.get(x, y)) {
                let i = (y * width + x) as usize;
                let ray = view.camera.ray(f64::from(x), f64::from(y));
                let dir = ray.dir.normalize();
                let theta: [f32; PARAM_COUNT] = std::array::from_fn(|c| planes[c][i]);
                let Some(t) = sphere_trace(scene, ray.origin, dir) else {
                    pixels.push((i, [0.0; 3], [0.0; 3]));
                    continue;
                };
                let rgb = |v: &[f32]| DVec3::new(v[0].into(), v[1].into(), v[2].into());
                let captured = rgb(&normal.data[3 * i..3 * i + 3]).normalize_or_zero();
                let exact = scene.normal(ray.origin + dir * t);
                let term = |n: DVec3| {
                    let c = n.dot(-dir).max(0.0) as f32;
                    eval(&theta, c, &settings).map(|r| r * c / (t * t) as f32)
                };
                pixels.push((i, term(captured), term(exact)));
            }
        }
        let mut ratios: Vec<f32> = pixels
            .iter()
            .flat_map(|(i, f, _)| (0..3).map(move |c| (*i, f[c], c)))
            .filter(|(_, f, _)| *f > 1e-4)
            .map(|(i, f, c)| flash.data[3 * i + c] / f)
            .collect();
        if ratios.is_empty() {
            bail!("val view {}: no lit pixels", view.camera.index);
        }
        ratios.sort_by(f32::total_cmp);
        let energy = ratios[ratios.len() / 2];
        let mut squared = [0.0f64; 2];
        for (i, captured, exact) in &pixels {
            for c in 0..3 {
                let photo = view.image.data[3 * i + c].min(cap);
                for (s, f) in squared.iter_mut().zip([captured[c], exact[c]]) {
                    let image = (ambient.data[3 * i + c] + energy * f).min(cap);
                    *s += f64::from(image - photo).powi(2);
                }
            }
        }
        let n = 3 * pixels.len();
        println!(
            "val view {}: E {energy:.4}; capture's normals {:.2} dB, exact shape's normals {:.2} dB",
            view.camera.index,
            psnr(squared[0], n),
            psnr(squared[1], n)
        );
        views.push(squared.map(|s| psnr(s, n)));
        for (p, s) in pooled.iter_mut().zip(squared) {
            *p += s;
        }
        count += n;
    }
    let mean = |k: usize| views.iter().map(|v| v[k]).sum::<f64>() / views.len().max(1) as f64;
    println!(
        "flash views, mean of the views (as `eval images`): capture's normals {:.2} dB, exact shape's normals {:.2} dB",
        mean(0),
        mean(1)
    );
    println!(
        "flash views, pooled: capture's normals {:.2} dB, exact shape's normals {:.2} dB",
        psnr(pooled[0], count),
        psnr(pooled[1], count)
    );
    Ok(())
}

/// PSNR (peak 1) of `n` values with summed squared error `squared`.
fn psnr(squared: f64, n: usize) -> f64 {
    10.0 * (n as f64 / squared).log10()
}

/// Distance along the unit direction `dir` to the scene's surface.
fn sphere_trace(scene: BuiltinScene, origin: DVec3, dir: DVec3) -> Option<f64> {
    let mut t = 0.0;
    for _ in 0..MAX_TRACE_STEPS {
        let d = scene.distance(origin + dir * t);
        if d < HIT_DISTANCE {
            return Some(t);
        }
        // the scene's distance is a bound near smooth unions: step a little short
        t += 0.9 * d;
        if t > MAX_TRACE_DISTANCE {
            break;
        }
    }
    None
}
