//! Degenerate inputs: NaNs reach the outputs (so the trainer's guard sees
//! them) instead of being hidden, and nothing panics.

mod common;

use wildlight_material::BrdfSettings;
use wildlight_render::flash::{FlashInputs, flash_backward, flash_forward};
use wildlight_render::neus::{NeusInputs, NeusSettings, NeusWeights};
use wildlight_render::occupancy::RefreshMode;
use wildlight_render::sampler::{CoarseSamples, RaySamples, Rays, Sampler, SamplerSettings};

#[test]
fn a_nan_sdf_value_propagates_to_the_ray_it_belongs_to() {
    let offsets = [0u32, 3, 6];
    let dirs = [[0.0f32, 0.0, 1.0]; 2];
    let sdf = [0.1f32, f32::NAN, -0.1, 0.1, 0.0, -0.1];
    let grad = [[0.0f32, 0.0, -1.0]; 6];
    let delta = [0.1f32; 6];
    let inputs = NeusInputs {
        offsets: &offsets,
        ray_dirs: &dirs,
        sdf: &sdf,
        sdf_grad: &grad,
        delta: &delta,
    };
    let mut w = NeusWeights::new();
    w.forward(&inputs, 0.3, &NeusSettings::default());
    assert!(w.acc_weight[0].is_nan());
    assert!(w.acc_weight[1].is_finite() && w.acc_weight[1] > 0.5);
}

#[test]
fn a_zero_gradient_gives_no_flash_and_no_nan() {
    let offsets = [0u32, 1];
    let dirs = [[0.0f32, 0.0, -1.0]];
    let energy = [[1.0f32; 3]];
    let t = [2.0f32];
    let grad = [[0.0f32; 3]];
    let params = [[0.5f32; 9]];
    let inputs = FlashInputs {
        offsets: &offsets,
        ray_dirs: &dirs,
        light_energy: &energy,
        t: &t,
        sdf_grad: &grad,
        params: &params,
    };
    let mut f = [[1.0f32; 3]];
    flash_forward(&inputs, 0.0, &BrdfSettings::default(), &mut f, None);
    assert_eq!(f[0], [0.0; 3]);
    let (mut dp, mut dg) = ([[0.0f32; 9]], [[0.0f32; 3]]);
    let d = flash_backward(
        &inputs,
        0.0,
        &BrdfSettings::default(),
        None,
        &[[1.0; 3]],
        &mut dp,
        &mut dg,
    );
    assert!(
        d.is_finite() && dp[0].iter().all(|x| x.is_finite()) && dg[0].iter().all(|x| x.is_finite())
    );
}

#[test]
fn sampling_survives_nan_sdf_values_and_bad_rays() {
    let mut grid = common::occupancy_grid(16);
    // A field that is NaN everywhere: cells stay sampled.
    grid.refresh(
        |_: &[[f32; 3]], out: &mut [f32]| out.fill(f32::NAN),
        100.0,
        RefreshMode::Full,
    );
    assert!(grid.occupied_fraction() > 0.99);
    let origins = [[0.0f32, 0.0, 3.0], [f32::NAN, 0.0, 0.0], [0.0, 0.0, 3.0]];
    let dirs = [[0.0f32, 0.0, -1.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]];
    let rays = Rays {
        origins: &origins,
        dirs: &dirs,
    };
    let mut sampler = Sampler::new(SamplerSettings::default()).unwrap();
    let (mut coarse, mut out) = (CoarseSamples::default(), RaySamples::default());
    sampler.sample(
        &grid,
        &rays,
        |_: &[[f32; 3]], o: &mut [f32]| o.fill(f32::NAN),
        100.0,
        Some(1),
        &mut coarse,
        &mut out,
    );
    assert_eq!(out.offsets.len(), 4);
    // The valid ray through the sphere gets samples; the NaN ray and the
    // ray that misses the sphere get none.
    assert!(out.offsets[1] > 0);
    assert_eq!(out.offsets[2], out.offsets[1]);
    assert_eq!(out.offsets[3], out.offsets[2]);
    assert!(out.t.iter().all(|t| t.is_finite()) && out.delta.iter().all(|d| *d > 0.0));
}
