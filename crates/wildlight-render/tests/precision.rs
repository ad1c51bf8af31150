//! The f32 training path agrees with the f64 reference on a realistic batch
//! (sharp surface, s = 3000), forward and backward.
#![allow(clippy::needless_range_loop)] // index-heavy test arithmetic over parallel arrays

mod common;

use common::{Torus, camera_rays};
use wildlight_material::BrdfSettings;
use wildlight_real::Real;
use wildlight_render::composite::{composite, composite_backward};
use wildlight_render::flash::{FlashCache, FlashInputs, flash_backward, flash_forward};
use wildlight_render::neus::{NeusInputs, NeusSettings, NeusWeights};
use wildlight_render::occupancy::{OccupancyGrid, OccupancySettings, RefreshMode};
use wildlight_render::sampler::{RaySamples, Rays};

struct Outputs {
    colour: Vec<[f64; 3]>,
    acc: Vec<f64>,
    d_sdf: Vec<f64>,
    d_grad: Vec<[f64; 3]>,
    d_theta: Vec<[f64; 9]>,
    d_v: f64,
    d_gain: f64,
}

fn run<T: Real>(torus: Torus, dirs: &[[f32; 3]], samples: &RaySamples, v: f64) -> Outputs {
    let cast = |x: f64| T::from_f64(x);
    let n = samples.len();
    let (sdf, grad, colours) = torus.fields_at(&samples.positions);
    let sdf: Vec<T> = sdf.into_iter().map(cast).collect();
    let grad: Vec<[T; 3]> = grad.iter().map(|g| g.map(cast)).collect();
    let mut c: Vec<[T; 3]> = colours.iter().map(|k| k.map(|x| cast(0.3 * x))).collect();
    let dirs: Vec<[T; 3]> = dirs.iter().map(|d| d.map(|x| cast(f64::from(x)))).collect();
    let t: Vec<T> = samples.t.iter().map(|&x| cast(f64::from(x))).collect();
    let delta: Vec<T> = samples.delta.iter().map(|&x| cast(f64::from(x))).collect();
    let offsets = &samples.offsets;
    let ninp = NeusInputs {
        offsets,
        ray_dirs: &dirs,
        sdf: &sdf,
        sdf_grad: &grad,
        delta: &delta,
    };
    let mut w = NeusWeights::new();
    let settings = NeusSettings::default();
    w.forward(&ninp, cast(v), &settings);
    let energy = vec![[cast(2.0), cast(2.0), cast(2.0)]; dirs.len()];
    let theta = vec![[0.6, 0.5, 0.4, 0.3, 0.5, 0.2, 0.1, 0.5, 0.3].map(cast); n];
    let finp = FlashInputs {
        offsets,
        ray_dirs: &dirs,
        light_energy: &energy,
        t: &t,
        sdf_grad: &grad,
        params: &theta,
    };
    let mut flash = vec![[T::from_f64(0.0); 3]; n];
    let brdf = BrdfSettings::default();
    let mut cache = FlashCache::new();
    flash_forward(&finp, T::from_f64(0.1), &brdf, &mut flash, Some(&mut cache));
    for (ck, f) in c.iter_mut().zip(&flash) {
        for i in 0..3 {
            ck[i] += f[i];
        }
    }
    let mut col = vec![[T::from_f64(0.0); 3]; dirs.len()];
    composite(offsets, &w.weight, &c, &mut col);
    let d_col = vec![[T::from_f64(1.0), T::from_f64(-0.5), T::from_f64(0.25)]; dirs.len()];
    let d_acc = vec![T::from_f64(0.3); dirs.len()];
    let mut d_w = vec![T::from_f64(0.0); n];
    let mut d_c = vec![[T::from_f64(0.0); 3]; n];
    composite_backward(offsets, &w.weight, &c, &d_col, &mut d_w, Some(&mut d_c));
    let mut d_theta = vec![[T::from_f64(0.0); 9]; n];
    let mut d_grad = vec![[T::from_f64(0.0); 3]; n];
    let d_gain = flash_backward(
        &finp,
        T::from_f64(0.1),
        &brdf,
        Some(&cache),
        &d_c,
        &mut d_theta,
        &mut d_grad,
    );
    let mut d_sdf = vec![T::from_f64(0.0); n];
    let d_v = w.backward(
        &ninp,
        cast(v),
        &settings,
        &d_w,
        Some(&d_acc),
        &mut d_sdf,
        &mut d_grad,
    );
    Outputs {
        colour: col.iter().map(|c| c.map(|x| x.to_f64())).collect(),
        acc: w.acc_weight.iter().map(|x| x.to_f64()).collect(),
        d_sdf: d_sdf.iter().map(|x| x.to_f64()).collect(),
        d_grad: d_grad.iter().map(|g| g.map(|x| x.to_f64())).collect(),
        d_theta: d_theta.iter().map(|g| g.map(|x| x.to_f64())).collect(),
        d_v: d_v.to_f64(),
        d_gain: d_gain.to_f64(),
    }
}

/// max |a − b| / max(|b|) over a set of values.
fn rel_err(a: impl Iterator<Item = f64>, b: impl Iterator<Item = f64>) -> f64 {
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (x, y) in a.zip(b) {
        num = num.max((x - y).abs());
        den = den.max(y.abs());
    }
    num / den.max(1e-30)
}

#[test]
fn f32_kernels_match_f64_on_a_sharp_surface() {
    let torus = Torus::standard();
    let (origins, dirs) = camera_rays([0.3, 1.0, 2.4], 24, 24, 0.35);
    let rays = Rays {
        origins: &origins,
        dirs: &dirs,
    };
    let s = 3000.0f32;
    let batch = torus.batch_sdf();
    let mut grid = OccupancyGrid::new(OccupancySettings::default()).unwrap();
    grid.refresh(batch, s, RefreshMode::Full);
    let samples = common::fast_samples(&grid, &rays, batch, s, Some(5));
    let v = f64::from(s).ln() / 10.0;
    let a = run::<f32>(torus, &dirs, &samples, v);
    let b = run::<f64>(torus, &dirs, &samples, v);
    let e_col = rel_err(
        a.colour.iter().flatten().copied(),
        b.colour.iter().flatten().copied(),
    );
    let e_acc = rel_err(a.acc.iter().copied(), b.acc.iter().copied());
    let e_sdf = rel_err(a.d_sdf.iter().copied(), b.d_sdf.iter().copied());
    let e_grad = rel_err(
        a.d_grad.iter().flatten().copied(),
        b.d_grad.iter().flatten().copied(),
    );
    let e_theta = rel_err(
        a.d_theta.iter().flatten().copied(),
        b.d_theta.iter().flatten().copied(),
    );
    let e_v = (a.d_v - b.d_v).abs() / b.d_v.abs();
    let e_gain = (a.d_gain - b.d_gain).abs() / b.d_gain.abs();
    eprintln!(
        "f32 vs f64: colour {e_col:.1e}, Σw {e_acc:.1e}, dφ {e_sdf:.1e}, d∇φ {e_grad:.1e}, dΘ {e_theta:.1e}, \
         dv {e_v:.1e}, dg {e_gain:.1e}"
    );
    assert!(e_col < 1e-4 && e_acc < 1e-4, "forward: {e_col} {e_acc}");
    assert!(
        e_sdf < 1e-3 && e_grad < 1e-3 && e_theta < 3e-4,
        "backward: {e_sdf} {e_grad} {e_theta}"
    );
    assert!(e_v < 1e-3 && e_gain < 1e-4, "reductions: {e_v} {e_gain}");
}
