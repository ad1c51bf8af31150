//! The fast sampler (occupancy grid + hierarchical refinement) renders the
//! same image as dense uniform sampling, and its sections are well formed.
#![allow(clippy::needless_range_loop)] // index-heavy test arithmetic over parallel arrays

mod common;

use common::{Torus, camera_rays};
use wildlight_material::BrdfSettings;
use wildlight_render::composite::composite;
use wildlight_render::flash::{FlashInputs, flash_forward};
use wildlight_render::neus::{NeusInputs, NeusSettings, NeusWeights};
use wildlight_render::occupancy::{OccupancyGrid, OccupancySettings, RefreshMode};
use wildlight_render::sampler::{
    CoarseSamples, RaySamples, Rays, Sampler, SamplerSettings, dense_samples, sphere_chord,
};

/// Renders colour (ambient = the smooth colour function, plus flash with a
/// fixed material) and Σw per ray, in f64, from the given samples.
fn render(
    torus: Torus,
    rays: &Rays<'_>,
    samples: &RaySamples,
    v: f64,
    settings: &NeusSettings,
) -> (Vec<[f64; 3]>, Vec<f64>) {
    let n = samples.len();
    let (sdf, grad, colours) = torus.fields_at(&samples.positions);
    let ambient: Vec<[f64; 3]> = colours.iter().map(|c| c.map(|c| 0.5 * c)).collect();
    let dirs: Vec<[f64; 3]> = rays.dirs.iter().map(|d| d.map(f64::from)).collect();
    let t: Vec<f64> = samples.t.iter().map(|&x| f64::from(x)).collect();
    let delta: Vec<f64> = samples.delta.iter().map(|&x| f64::from(x)).collect();
    let inputs = NeusInputs {
        offsets: &samples.offsets,
        ray_dirs: &dirs,
        sdf: &sdf,
        sdf_grad: &grad,
        delta: &delta,
    };
    let mut w = NeusWeights::new();
    w.forward(&inputs, v, settings);
    let energy = vec![[3.0, 3.0, 3.0]; rays.len()];
    let params = vec![[0.7, 0.4, 0.2, 0.4, 0.5, 0.0, 0.1, 0.5, 0.3]; n];
    let flash_in = FlashInputs {
        offsets: &samples.offsets,
        ray_dirs: &dirs,
        light_energy: &energy,
        t: &t,
        sdf_grad: &grad,
        params: &params,
    };
    let mut flash = vec![[0.0; 3]; n];
    flash_forward(&flash_in, 0.0, &BrdfSettings::default(), &mut flash, None);
    let c: Vec<[f64; 3]> = ambient
        .iter()
        .zip(&flash)
        .map(|(a, f)| [a[0] + f[0], a[1] + f[1], a[2] + f[2]])
        .collect();
    let mut out = vec![[0.0; 3]; rays.len()];
    composite(&samples.offsets, &w.weight, &c, &mut out);
    (out, w.acc_weight)
}

#[test]
fn fast_sampler_matches_dense_sampling() {
    let torus = Torus::standard();
    let (origins, dirs) = camera_rays([0.4, 1.2, 2.3], 24, 24, 0.3);
    let rays = Rays {
        origins: &origins,
        dirs: &dirs,
    };
    let mut worst = (0.0f64, 0.0f64);
    for &s in &[60.0f64, 500.0, 2000.0] {
        let v = s.ln() / 10.0;
        let mut grid = OccupancyGrid::new(OccupancySettings::default()).unwrap();
        grid.refresh(torus.batch_sdf(), s as f32, RefreshMode::Full);
        let fast = common::fast_samples(&grid, &rays, torus.batch_sdf(), s as f32, None);
        let mut dense = RaySamples::default();
        dense_samples(&rays, 4000, 1.0, &mut dense);
        // ε = 0: the SPEC's ε adds ≈ ε of opacity per sample (see
        // NeusSettings::alpha_eps), which would measure the sample count, not the sampler.
        let exact = NeusSettings {
            alpha_eps: 0.0,
            ..Default::default()
        };
        let (c_fast, w_fast) = render(torus, &rays, &fast, v, &exact);
        let (c_dense, w_dense) = render(torus, &rays, &dense, v, &exact);
        // With the SPEC's ε the fast sampler's image moves by at most ≈ n·ε.
        let (c_eps, _) = render(torus, &rays, &fast, v, &NeusSettings::default());
        for r in 0..rays.len() {
            let n = (fast.offsets[r + 1] - fast.offsets[r]) as f64;
            for i in 0..3 {
                assert!((c_eps[r][i] - c_fast[r][i]).abs() <= 2.0 * n * 1e-5 + 1e-9);
            }
        }
        let (mut max_c, mut sum_c, mut max_w) = (0.0f64, 0.0f64, 0.0f64);
        let mut hits = 0;
        for r in 0..rays.len() {
            for i in 0..3 {
                let e = (c_fast[r][i] - c_dense[r][i]).abs();
                max_c = max_c.max(e);
                sum_c += e;
            }
            max_w = max_w.max((w_fast[r] - w_dense[r]).abs());
            assert_eq!(w_fast[r] > 0.5, w_dense[r] > 0.5, "mask differs at ray {r}");
            if w_dense[r] > 0.5 {
                hits += 1;
            }
        }
        let mean_c = sum_c / (3 * rays.len()) as f64;
        let per_ray = fast.len() as f64 / rays.len() as f64;
        eprintln!(
            "s = {s}: max |ΔC| = {max_c:.2e}, mean |ΔC| = {mean_c:.2e}, max |ΔΣw| = {max_w:.2e}, \
             {per_ray:.1} samples/ray, {hits} hits"
        );
        assert!(
            hits > 80 && hits < 450,
            "the torus should cover part of the image: {hits}"
        );
        // Stated tolerance (measured for s = 60, 500, 2000 with the default
        // settings: max |ΔC| ≤ 8.2e-4, mean |ΔC| ≤ 2.5e-5, max |ΔΣw| ≤ 1.5e-3):
        // colour within 3e-3 everywhere and 1e-4 on average, Σw within 5e-3,
        // silhouette rays included.
        assert!(max_c < 3e-3 && mean_c < 1e-4 && max_w < 5e-3);
        assert!(per_ray < 100.0);
        worst = (worst.0.max(max_c), worst.1.max(max_w));
    }
    eprintln!("worst: {worst:?}");
}

#[test]
fn sections_are_contiguous_inside_the_sphere_and_respect_the_cap() {
    let torus = Torus::standard();
    let (origins, dirs) = camera_rays([0.0, 2.0, 2.0], 24, 24, 0.6);
    let rays = Rays {
        origins: &origins,
        dirs: &dirs,
    };
    for &s in &[20.0f32, 300.0, 3000.0] {
        let mut grid = common::occupancy_grid(64);
        grid.refresh(torus.batch_sdf(), s, RefreshMode::Full);
        let settings = SamplerSettings::default();
        let mut sampler = Sampler::new(settings).unwrap();
        let mut coarse = CoarseSamples::default();
        let mut fast = RaySamples::default();
        sampler.sample(
            &grid,
            &rays,
            torus.batch_sdf(),
            s,
            Some(42),
            &mut coarse,
            &mut fast,
        );
        let mut empty = 0;
        let (mut sampled_len, mut chord_len) = (0.0f32, 0.0f32);
        for r in 0..rays.len() {
            let range = fast.offsets[r] as usize..fast.offsets[r + 1] as usize;
            let chord = sphere_chord(origins[r], dirs[r], 1.0);
            if range.is_empty() {
                empty += 1;
                continue;
            }
            let [near, far] = chord.expect("samples on a ray that misses the sphere");
            chord_len += far - near;
            let intervals = coarse.opens_section
                [coarse.offsets[r] as usize..coarse.offsets[r + 1] as usize]
                .iter()
                .filter(|&&b| !b)
                .count();
            assert!(range.len() <= settings.max_coarse + settings.n_fine + intervals);
            for k in range.clone() {
                assert!(fast.delta[k] > 0.0);
                sampled_len += fast.delta[k];
                assert!(fast.t[k] - 0.5 * fast.delta[k] >= near - 1e-5);
                assert!(fast.t[k] + 0.5 * fast.delta[k] <= far + 1e-5);
                if k + 1 < range.end {
                    let end = fast.t[k] + 0.5 * fast.delta[k];
                    let next_start = fast.t[k + 1] - 0.5 * fast.delta[k + 1];
                    assert!(next_start >= end - 1e-5, "overlapping sections");
                    if next_start > end + 1e-5 {
                        // A skipped stretch: NeuS weights there are negligible,
                        // i.e. s·|φ| exceeds the tail of 10 (grid and sampler).
                        let mid = 0.5 * (end + next_start);
                        let p = [0, 1, 2].map(|i| f64::from(origins[r][i] + mid * dirs[r][i]));
                        let phi = torus.eval(p).0;
                        assert!(phi.abs() * s as f64 > 10.0, "skipped φ = {phi} at s = {s}");
                    }
                }
            }
        }
        // Rays that miss the torus region (corners of the image) get no
        // samples, and most of every chord is skipped, when s is large.
        let fraction = sampled_len / chord_len;
        if s >= 300.0 {
            assert!(empty > 50, "s = {s}: {empty} empty rays");
            assert!(fraction < 0.2, "s = {s}: sampled fraction {fraction}");
        } else {
            assert!(fraction > 0.3, "s = {s}: sampled fraction {fraction}");
        }
    }
}

#[test]
fn invalid_sampler_settings_are_rejected() {
    let bad = [
        SamplerSettings {
            bound_radius: 1.5,
            ..Default::default()
        },
        SamplerSettings {
            max_coarse: 0,
            ..Default::default()
        },
        SamplerSettings {
            min_transmittance: 1.0,
            ..Default::default()
        },
        SamplerSettings {
            coarse_steps_per_cell: f32::NAN,
            ..Default::default()
        },
    ];
    for b in bad {
        assert!(Sampler::new(b).is_err(), "{b:?}");
    }
    assert!(Sampler::new(SamplerSettings::default()).is_ok());
}

#[test]
fn sphere_chord_is_the_unit_sphere_chord() {
    let [near, far] = sphere_chord([0.0, 0.0, 3.0], [0.0, 0.0, -1.0], 1.0).unwrap();
    assert!((near - 2.0).abs() < 1e-6 && (far - 4.0).abs() < 1e-6);
    let [near, far] = sphere_chord([0.0, 0.5, 0.0], [1.0, 0.0, 0.0], 1.0).unwrap();
    assert_eq!(near, 0.0);
    assert!((far - 0.75f32.sqrt()).abs() < 1e-6);
    assert!(sphere_chord([0.0, 1.5, 3.0], [0.0, 0.0, -1.0], 1.0).is_none());
}

#[test]
fn sampling_is_deterministic_across_thread_counts() {
    let torus = Torus::standard();
    let (origins, dirs) = camera_rays([1.5, 1.0, 1.8], 30, 30, 0.5);
    let rays = Rays {
        origins: &origins,
        dirs: &dirs,
    };
    let mut grid = common::occupancy_grid(64);
    grid.refresh(torus.batch_sdf(), 400.0, RefreshMode::Full);
    let run = |threads: usize| {
        common::on_threads(threads, || {
            common::fast_samples(&grid, &rays, torus.batch_sdf(), 400.0, Some(7))
        })
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.offsets, b.offsets);
    assert!(
        a.t.iter()
            .zip(&b.t)
            .all(|(x, y)| x.to_bits() == y.to_bits())
    );
    assert!(a.len() > 1000);
}
