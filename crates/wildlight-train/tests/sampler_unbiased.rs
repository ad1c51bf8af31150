//! The fast sampler (occupancy grid, coarse steps only where the surface can
//! be, hierarchical refinement, early termination) against dense uniform
//! sampling, through the real fields of the model: the same colour, flash
//! and ambient parts and Σw to within a small tolerance. Both passes set the
//! ε of the NeuS alpha to 0: with SPEC §2's ε = 1e-5 every section adds about
//! ε of opacity, so 4096 dense sections alone would leak 4 % of Σw into rays
//! that miss the object, an artefact of the formula rather than of sampling.

use wildlight_render::{OccupancyGrid, RaySamples, Rays, RefreshMode, Sampler, dense_samples};
use wildlight_train::config::TrainConfig;
use wildlight_train::model::Model;
use wildlight_train::pipeline::{PassSettings, Pipeline, RayInputs, eval_sdf};

/// Sharpness parameter v with s = exp(10 v) ≈ 400: a crisp surface, about
/// five dense samples across the logistic's width.
const SHARP_V: f32 = 0.6;
const DENSE_SAMPLES: usize = 4096;

fn normalize(v: [f32; 3]) -> [f32; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|x| x / l)
}

/// A 16×16 fan of rays from a camera 2.6 away, wide enough to graze the
/// sphere and miss it; every other ray has the flash on.
type Points = Vec<[f32; 3]>;

fn rays() -> (Points, Points, Points) {
    let origin = [0.3, 0.9, 2.4];
    let (mut o, mut d, mut e) = (Vec::new(), Vec::new(), Vec::new());
    for i in 0..16 {
        for j in 0..16 {
            let (u, v) = (i as f32 / 15.0 - 0.5, j as f32 / 15.0 - 0.5);
            let target = [u * 1.4, v * 1.4, 0.1 * u * v];
            o.push(origin);
            d.push(normalize([
                target[0] - origin[0],
                target[1] - origin[1],
                target[2] - origin[2],
            ]));
            e.push(if (i + j) % 2 == 0 { [8.0; 3] } else { [0.0; 3] });
        }
    }
    (o, d, e)
}

#[test]
fn fast_sampler_matches_dense_sampling_through_the_fields() {
    let config = TrainConfig::default();
    let mut model: Model = Model::new(&config.model, 7).expect("model");
    model.sharpness = SHARP_V;
    let s = model.s();
    assert!(s > 300.0, "s = {s}");

    let mut grid = OccupancyGrid::new(config.sampling.occupancy()).expect("grid");
    let mut sdf_ctx = Default::default();
    grid.refresh(
        |pts: &[[f32; 3]], out: &mut [f32]| eval_sdf(&model, pts, out, &mut sdf_ctx),
        s,
        RefreshMode::Full,
    );
    let (origins, dirs, energy) = rays();
    let inputs = RayInputs {
        origins: &origins,
        dirs: &dirs,
        energy: &energy,
    };
    let settings = PassSettings {
        normals: model.normal_method(),
        cos_anneal_ratio: 1.0,
        jitter_seed: None,
        for_backward: false,
        alpha_eps: 0.0,
        ambient_flash_gradient: 1.0,
    };

    let mut fast = Pipeline::new(Sampler::new(config.sampling.sampler()).expect("sampler"));
    fast.forward(&model, &grid, &inputs, &[], &settings);
    let fast_samples = fast.n_samples();

    let mut dense_raw = RaySamples::default();
    let render_rays = Rays {
        origins: &origins,
        dirs: &dirs,
    };
    dense_samples(&render_rays, DENSE_SAMPLES, 1.0, &mut dense_raw);
    let mut dense: Pipeline = Pipeline::default();
    dense.samples.set_from(&dense_raw);
    dense.forward_samples(&model, &inputs, &[], &settings);

    // The fast sampler must be far cheaper…
    assert!(
        fast_samples * 20 < dense.n_samples(),
        "fast {fast_samples} vs dense {} samples",
        dense.n_samples()
    );
    // …and see the same object: about a third of the rays hit the r = 0.5 sphere.
    let acc_fast = fast.acc_weight();
    let acc_dense = dense.acc_weight();
    let hits = acc_dense.iter().filter(|a| **a > 0.5).count();
    assert!((40..200).contains(&hits), "{hits} rays hit the sphere");

    let (mut max_colour, mut max_acc, mut sum_colour) = (0.0f32, 0.0f32, 0.0f64);
    let mut peak = 0.0f32;
    for r in 0..origins.len() {
        max_acc = max_acc.max((acc_fast[r] - acc_dense[r]).abs());
        for c in 0..3 {
            let d = (fast.colour[r][c] - dense.colour[r][c]).abs();
            max_colour = max_colour.max(d);
            sum_colour += d as f64;
            peak = peak.max(dense.colour[r][c]);
        }
    }
    let mean_colour = sum_colour / (3 * origins.len()) as f64;
    eprintln!(
        "fast {fast_samples} / dense {} samples; max |Δcolour| {max_colour:.2e} (peak {peak:.3}), mean {mean_colour:.2e}, max |ΔΣw| {max_acc:.2e}",
        dense.n_samples()
    );
    assert!(peak > 0.05, "the image is not blank: peak {peak}");
    assert!(max_acc < 0.01, "Σw differs by {max_acc}");
    assert!(
        max_colour < 0.01 * peak.max(1.0),
        "colour differs by {max_colour}"
    );
    assert!(mean_colour < 2e-4, "mean colour difference {mean_colour}");
}
