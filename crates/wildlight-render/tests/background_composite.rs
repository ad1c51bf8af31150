//! The object and the background compose as SPEC §6 has it: a ray that
//! misses the unit sphere sees the background alone, and an opaque object
//! hides it.

use wildlight_render::{
    BackgroundInputs, BackgroundSamples, BackgroundSettings, CoarseSamples, NeusInputs,
    NeusSettings, NeusWeights, OccupancyGrid, OccupancySettings, RaySamples, Rays, RefreshMode,
    Sampler, SamplerSettings, add_background, background_depth_quantile, background_forward,
    composite, sharpness,
};

fn sphere(p: [f32; 3]) -> f32 {
    (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - 0.5
}

#[test]
fn a_miss_sees_the_background_alone_and_an_opaque_object_hides_it() {
    let sdf_batch = |pts: &[[f32; 3]], out: &mut [f32]| {
        for (o, &p) in out.iter_mut().zip(pts) {
            *o = sphere(p);
        }
    };
    // A sharp surface: s = e^10 ≈ 22,000.
    let v = 1.0f32;
    let (s, _) = sharpness(v);
    let mut grid = OccupancyGrid::new(OccupancySettings::default()).unwrap();
    grid.refresh(sdf_batch, s, RefreshMode::Full);
    let origins = vec![[0.0, 0.0, 3.0f32], [0.0, 0.0, 3.0], [0.0, 2.0, 3.0]];
    let dirs = vec![
        [0.0, 0.0, -1.0f32], // through the object
        [0.0, 0.6, -0.8],    // through the sphere, past the object
        [0.0, 0.0, -1.0],    // misses the unit sphere
    ];
    let rays = Rays {
        origins: &origins,
        dirs: &dirs,
    };
    let mut sampler = Sampler::new(SamplerSettings::default()).unwrap();
    let (mut coarse, mut samples) = (CoarseSamples::default(), RaySamples::default());
    sampler.sample(&grid, &rays, sdf_batch, s, None, &mut coarse, &mut samples);
    let phi: Vec<f32> = samples.positions.iter().map(|&p| sphere(p)).collect();
    let grad: Vec<[f32; 3]> = samples
        .positions
        .iter()
        .map(|p| {
            let l = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
            p.map(|x| x / l)
        })
        .collect();
    let mut w = NeusWeights::new();
    w.forward(
        &NeusInputs {
            offsets: &samples.offsets,
            ray_dirs: &dirs,
            sdf: &phi,
            sdf_grad: &grad,
            delta: &samples.delta,
        },
        v,
        &NeusSettings::default(),
    );
    let object_colour = vec![[0.7f32, 0.5, 0.3]; samples.len()];
    let mut colour = vec![[0.0f32; 3]; 3];
    composite(&samples.offsets, &w.weight, &object_colour, &mut colour);
    let object_only = colour.clone();

    let mut bg = BackgroundSamples::<f32>::new();
    bg.place(&origins, &dirs, &BackgroundSettings::default(), None);
    let n = bg.len();
    let density = vec![0.05f32; n];
    let ambient: Vec<[f32; 3]> = (0..n).map(|k| [0.1, 0.2, 0.01 * (k % 32) as f32]).collect();
    let response = vec![[0.3f32; 3]; n];
    let energy = vec![[10.0f32; 3]; 3];
    let mut background = vec![[0.0f32; 3]; 3];
    let mut bw = Vec::new();
    background_forward(
        &BackgroundInputs {
            samples: &bg,
            density: &density,
            ambient: &ambient,
            flash_response: &response,
            light_energy: &energy,
        },
        0.0,
        &mut background,
        &mut bw,
    );
    add_background(&w.acc_weight, &background, &mut colour);

    // The object ray: opaque (Σw = 1 to within 1e-4), so the background
    // adds at most 1e-4 of itself.
    assert!(w.acc_weight[0] > 1.0 - 1e-4, "Σw = {}", w.acc_weight[0]);
    for c in 0..3 {
        assert!((colour[0][c] - object_only[0][c]).abs() <= 1e-4 * background[0][c].max(1.0));
        assert!((object_only[0][c] - [0.7, 0.5, 0.3][c]).abs() < 1e-3);
    }
    // The ray past the object and the ray outside the sphere: no object,
    // the background alone.
    for r in [1, 2] {
        assert!(w.acc_weight[r] < 1e-3, "ray {r}: Σw = {}", w.acc_weight[r]);
        for c in 0..3 {
            let expected = background[r][c] * (1.0 - w.acc_weight[r]) + object_only[r][c];
            assert!((colour[r][c] - expected).abs() < 1e-6);
            assert!((colour[r][c] - background[r][c]).abs() <= 1e-3 * background[r][c].max(0.1));
        }
    }
    // The miss: no object sample at all, so exactly the background.
    assert_eq!(
        samples.offsets[3], samples.offsets[2],
        "no sample outside the sphere"
    );
    assert_eq!(colour[2], background[2]);
    // The background is not trivially black.
    assert!(background.iter().all(|b| b.iter().all(|&v| v > 0.05)));
}

/// The depth quantile of a background that is empty up to a wall at
/// distance 6 along the ray and dense beyond: the median lands in the
/// wall's first section; a background with no weight has no depth.
#[test]
fn the_background_depth_is_where_its_weights_pile_up() {
    let settings = BackgroundSettings {
        samples: 256,
        far_radius: 1000.0,
    };
    let mut samples = BackgroundSamples::<f64>::new();
    // from z = 3 straight through the centre: the background starts at t = 4
    samples.place(&[[0.0, 0.0, 3.0]], &[[0.0, 0.0, -1.0]], &settings, None);
    let wall = 6.0;
    let density: Vec<f64> = samples
        .t
        .iter()
        .map(|&t| if t >= wall { 50.0 } else { 0.0 })
        .collect();
    let zero = vec![[0.0f64; 3]; samples.len()];
    let inputs = BackgroundInputs {
        samples: &samples,
        density: &density,
        ambient: &zero,
        flash_response: &zero,
        light_energy: &[[0.0; 3]],
    };
    let (mut colour, mut weights) = (vec![[0.0f64; 3]; 1], Vec::new());
    background_forward(&inputs, 0.0, &mut colour, &mut weights);
    let first = samples.t.iter().position(|&t| t >= wall).unwrap();
    let (t0, t1) = (samples.t[first], samples.t[first + 1]);
    for fraction in [0.2, 0.5, 0.8] {
        let depth = background_depth_quantile(&samples, &weights, fraction)[0].unwrap();
        assert!(
            depth >= t0 && depth <= t1,
            "{fraction}: {depth} outside [{t0}, {t1}]"
        );
    }
    // The quantiles rise with the fraction, inside the first section that
    // holds 1 − e^(−50 δ) of the weight.
    let q = |f| background_depth_quantile(&samples, &weights, f)[0].unwrap();
    assert!(q(0.2) < q(0.5) && q(0.5) < q(0.8));
    let empty = vec![0.0f64; samples.len()];
    assert_eq!(background_depth_quantile(&samples, &empty, 0.5), vec![None]);
}
