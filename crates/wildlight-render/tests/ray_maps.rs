//! Depth, normal and mask maps from the fast sampler match the analytic
//! ray–sphere intersection.
#![allow(clippy::needless_range_loop)] // index-heavy test arithmetic over parallel arrays

mod common;

use wildlight_render::composite::ray_maps;
use wildlight_render::neus::{NeusInputs, NeusSettings, NeusWeights};
use wildlight_render::occupancy::{OccupancyGrid, OccupancySettings, RefreshMode};
use wildlight_render::sampler::Rays;

const CENTRE: [f32; 3] = [0.1, -0.05, 0.0];
const RADIUS: f32 = 0.6;

fn sdf_grad(p: [f32; 3]) -> (f32, [f32; 3]) {
    let rel = [p[0] - CENTRE[0], p[1] - CENTRE[1], p[2] - CENTRE[2]];
    let l = (rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2]).sqrt();
    (l - RADIUS, rel.map(|x| x / l))
}

#[test]
fn depth_normal_and_mask_match_the_analytic_sphere() {
    let s = 2000.0f32;
    let n = 48;
    let eye = [0.0f32, 0.0, 2.5];
    let mut origins = Vec::new();
    let mut dirs = Vec::new();
    for y in 0..n {
        for x in 0..n {
            let u = (x as f32 + 0.5) / n as f32 * 0.7 - 0.35;
            let v = (y as f32 + 0.5) / n as f32 * 0.7 - 0.35;
            let l = (u * u + v * v + 1.0).sqrt();
            origins.push(eye);
            dirs.push([u / l, v / l, -1.0 / l]);
        }
    }
    let rays = Rays {
        origins: &origins,
        dirs: &dirs,
    };
    let batch = |p: &[[f32; 3]], out: &mut [f32]| {
        for (o, &x) in out.iter_mut().zip(p) {
            *o = sdf_grad(x).0;
        }
    };
    let mut grid = OccupancyGrid::new(OccupancySettings::default()).unwrap();
    grid.refresh(batch, s, RefreshMode::Full);
    let samples = common::fast_samples(&grid, &rays, batch, s, None);
    let (sdf, grad): (Vec<f32>, Vec<[f32; 3]>) =
        samples.positions.iter().map(|&p| sdf_grad(p)).unzip();
    let inputs = NeusInputs {
        offsets: &samples.offsets,
        ray_dirs: &dirs,
        sdf: &sdf,
        sdf_grad: &grad,
        delta: &samples.delta,
    };
    let mut w = NeusWeights::new();
    w.forward(&inputs, s.ln() / 10.0, &NeusSettings::default());
    let maps = ray_maps(&samples.offsets, &w.weight, &samples.t, &grad);
    let (mut hits, mut misses) = (0, 0);
    for r in 0..rays.len() {
        // Analytic intersection with the sphere.
        let d = dirs[r];
        let oc = [eye[0] - CENTRE[0], eye[1] - CENTRE[1], eye[2] - CENTRE[2]];
        let b = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
        let c = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - RADIUS * RADIUS;
        let disc = b * b - c;
        // Skip the silhouette band, where the mask is fractional.
        if disc.abs() < 0.02 {
            continue;
        }
        if disc < 0.0 {
            misses += 1;
            assert!(
                maps.acc_weight[r] < 1e-3,
                "miss ray {r}: Σw = {}",
                maps.acc_weight[r]
            );
            continue;
        }
        hits += 1;
        let t_hit = -b - disc.sqrt();
        let p: [f32; 3] = std::array::from_fn(|i| eye[i] + t_hit * d[i]);
        let normal = sdf_grad(p).1;
        assert!(
            maps.acc_weight[r] > 0.999,
            "hit ray {r}: Σw = {}",
            maps.acc_weight[r]
        );
        assert!(
            (maps.depth[r] - t_hit).abs() < 2e-3,
            "ray {r}: depth {} vs {t_hit}",
            maps.depth[r]
        );
        let cos: f32 = (0..3).map(|i| maps.normal[r][i] * normal[i]).sum();
        assert!(
            cos > 0.9995,
            "ray {r}: normal {:?} vs {normal:?}",
            maps.normal[r]
        );
    }
    assert!(hits > 500 && misses > 200, "hits {hits}, misses {misses}");
}
