//! Gradient check of a small end-to-end chain: rays → fast sampler → an
//! analytic field with parameters → NeuS weights → flash + linear ambient →
//! L1 colour loss + squared mask loss, against finite differences (f64).
//!
//! The field: φ(x) = κ(|x − c| − R) (a scaled sphere SDF, so |∇φ| = κ ≠ 1
//! exercises the normalisation of the flash normal), ambient
//! a(x) = a₀ + A·x, material Θ = sigmoid(m) (constant), sharpness v, flash
//! log-gain g. Sample positions are fixed (drawn once by the sampler).
#![allow(clippy::needless_range_loop)] // index-heavy test arithmetic over parallel arrays

mod common;

use common::TestRng;
use wildlight_material::BrdfSettings;
use wildlight_render::composite::{composite, composite_backward};
use wildlight_render::flash::{FlashCache, FlashInputs, flash_backward, flash_forward};
use wildlight_render::neus::{NeusInputs, NeusSettings, NeusWeights};
use wildlight_render::occupancy::RefreshMode;
use wildlight_render::sampler::{CoarseSamples, RaySamples, Rays, Sampler, SamplerSettings};

const N_PARAMS: usize = 3 + 1 + 1 + 3 + 9 + 9 + 1 + 1;
const C: usize = 0; // centre (3)
const R: usize = 3; // radius
const K: usize = 4; // SDF scale κ
const A0: usize = 5; // ambient offset (3)
const A: usize = 8; // ambient matrix (3×3, row-major)
const M: usize = 17; // material logits (9)
const V: usize = 26; // NeuS sharpness parameter
const G: usize = 27; // flash log-gain

struct Scene {
    origins: Vec<[f64; 3]>,
    dirs: Vec<[f64; 3]>,
    energy: Vec<[f64; 3]>,
    samples: RaySamples,
    target: Vec<[f64; 3]>,
    mask: Vec<f64>,
    settings: NeusSettings,
}

fn initial_params() -> [f64; N_PARAMS] {
    let mut p = [0.0; N_PARAMS];
    p[C..C + 3].copy_from_slice(&[0.05, -0.03, 0.02]);
    p[R] = 0.5;
    p[K] = 1.3;
    p[A0..A0 + 3].copy_from_slice(&[0.3, 0.25, 0.2]);
    let mut rng = TestRng(17);
    for x in &mut p[A..A + 9] {
        *x = rng.uniform(-0.2, 0.2);
    }
    for x in &mut p[M..M + 9] {
        *x = rng.uniform(-1.5, 1.5);
    }
    p[V] = 0.4; // s ≈ 55
    p[G] = 0.2;
    p
}

struct Forward {
    colour: Vec<[f64; 3]>,
    acc: Vec<f64>,
}

struct Eval {
    sdf: Vec<f64>,
    grad: Vec<[f64; 3]>,
    ambient: Vec<[f64; 3]>,
    theta: Vec<[f64; 9]>,
    pos: Vec<[f64; 3]>,
}

impl Scene {
    /// Distance t and spacing δ of each sample, in f64.
    fn t_delta(&self) -> (Vec<f64>, Vec<f64>) {
        let widen = |v: &[f32]| v.iter().map(|&x| f64::from(x)).collect();
        (widen(&self.samples.t), widen(&self.samples.delta))
    }
}

/// The NeuS kernel's inputs: the scene's samples with the field values `e`.
fn neus_inputs<'a>(scene: &'a Scene, e: &'a Eval, delta: &'a [f64]) -> NeusInputs<'a, f64> {
    NeusInputs {
        offsets: &scene.samples.offsets,
        ray_dirs: &scene.dirs,
        sdf: &e.sdf,
        sdf_grad: &e.grad,
        delta,
    }
}

/// The flash kernel's inputs: the scene's samples with the field values `e`.
fn flash_inputs<'a>(scene: &'a Scene, e: &'a Eval, t: &'a [f64]) -> FlashInputs<'a, f64> {
    FlashInputs {
        offsets: &scene.samples.offsets,
        ray_dirs: &scene.dirs,
        light_energy: &scene.energy,
        t,
        sdf_grad: &e.grad,
        params: &e.theta,
    }
}

fn eval_field(scene: &Scene, p: &[f64; N_PARAMS]) -> Eval {
    let n = scene.samples.len();
    let sig = |x: f64| 1.0 / (1.0 + (-x).exp());
    let theta_one: [f64; 9] = std::array::from_fn(|j| sig(p[M + j]));
    let mut e = Eval {
        sdf: vec![],
        grad: vec![],
        ambient: vec![],
        theta: vec![theta_one; n],
        pos: vec![],
    };
    for ray in 0..scene.dirs.len() {
        for k in scene.samples.offsets[ray] as usize..scene.samples.offsets[ray + 1] as usize {
            let t = f64::from(scene.samples.t[k]);
            let x: [f64; 3] =
                std::array::from_fn(|i| scene.origins[ray][i] + t * scene.dirs[ray][i]);
            let rel: [f64; 3] = std::array::from_fn(|i| x[i] - p[C + i]);
            let rho = (rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2]).sqrt();
            e.sdf.push(p[K] * (rho - p[R]));
            e.grad.push(rel.map(|r| p[K] * r / rho));
            e.ambient.push(std::array::from_fn(|i| {
                p[A0 + i] + (0..3).map(|j| p[A + 3 * i + j] * x[j]).sum::<f64>()
            }));
            e.pos.push(x);
        }
    }
    e
}

type ForwardState = (
    Forward,
    Eval,
    NeusWeights<f64>,
    Vec<[f64; 3]>,
    FlashCache<f64>,
);

fn forward(scene: &Scene, p: &[f64; N_PARAMS]) -> ForwardState {
    let e = eval_field(scene, p);
    let (t, delta) = scene.t_delta();
    let offsets = &scene.samples.offsets;
    let ninp = neus_inputs(scene, &e, &delta);
    let mut w = NeusWeights::new();
    w.forward(&ninp, p[V], &scene.settings);
    let finp = flash_inputs(scene, &e, &t);
    let mut flash = vec![[0.0; 3]; t.len()];
    let mut cache = FlashCache::new();
    flash_forward(
        &finp,
        p[G],
        &BrdfSettings::default(),
        &mut flash,
        Some(&mut cache),
    );
    let c: Vec<[f64; 3]> = e
        .ambient
        .iter()
        .zip(&flash)
        .map(|(a, f)| std::array::from_fn(|i| a[i] + f[i]))
        .collect();
    let mut colour = vec![[0.0; 3]; scene.dirs.len()];
    composite(offsets, &w.weight, &c, &mut colour);
    let acc = w.acc_weight.clone();
    (Forward { colour, acc }, e, w, c, cache)
}

const MASK_WEIGHT: f64 = 0.7;

fn loss(scene: &Scene, p: &[f64; N_PARAMS]) -> f64 {
    let (f, ..) = forward(scene, p);
    let mut l = 0.0;
    for r in 0..scene.dirs.len() {
        for i in 0..3 {
            l += (f.colour[r][i] - scene.target[r][i]).abs();
        }
        l += MASK_WEIGHT * (f.acc[r] - scene.mask[r]).powi(2);
    }
    l
}

fn analytic_grad(scene: &Scene, p: &[f64; N_PARAMS]) -> [f64; N_PARAMS] {
    let (f, e, w, c, cache) = forward(scene, p);
    let offsets = &scene.samples.offsets;
    let n = e.sdf.len();
    let n_rays = scene.dirs.len();
    let d_colour: Vec<[f64; 3]> = (0..n_rays)
        .map(|r| std::array::from_fn(|i| (f.colour[r][i] - scene.target[r][i]).signum()))
        .collect();
    let d_acc: Vec<f64> = (0..n_rays)
        .map(|r| 2.0 * MASK_WEIGHT * (f.acc[r] - scene.mask[r]))
        .collect();
    let mut d_w = vec![0.0; n];
    let mut d_c = vec![[0.0; 3]; n];
    composite_backward(offsets, &w.weight, &c, &d_colour, &mut d_w, Some(&mut d_c));
    let (t, delta) = scene.t_delta();
    let finp = flash_inputs(scene, &e, &t);
    let mut d_theta = vec![[0.0; 9]; n];
    let mut d_grad = vec![[0.0; 3]; n];
    let mut g = [0.0; N_PARAMS];
    g[G] = flash_backward(
        &finp,
        p[G],
        &BrdfSettings::default(),
        Some(&cache),
        &d_c,
        &mut d_theta,
        &mut d_grad,
    );
    let ninp = neus_inputs(scene, &e, &delta);
    let mut d_sdf = vec![0.0; n];
    g[V] = w.backward(
        &ninp,
        p[V],
        &scene.settings,
        &d_w,
        Some(&d_acc),
        &mut d_sdf,
        &mut d_grad,
    );
    // The field's own chain rule.
    for k in 0..n {
        let x = e.pos[k];
        let rel: [f64; 3] = std::array::from_fn(|i| x[i] - p[C + i]);
        let rho = (rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2]).sqrt();
        let nrm = rel.map(|r| r / rho);
        let kappa = p[K];
        // φ = κ(ρ − R)
        g[R] += -kappa * d_sdf[k];
        g[K] += (rho - p[R]) * d_sdf[k];
        for j in 0..3 {
            g[C + j] += -kappa * nrm[j] * d_sdf[k];
        }
        // ∇φ = κ n: ∂/∂κ = n, ∂∇φ_i/∂c_j = −κ(δ_ij − n_i n_j)/ρ
        for i in 0..3 {
            g[K] += nrm[i] * d_grad[k][i];
            for j in 0..3 {
                let dij = if i == j { 1.0 } else { 0.0 };
                g[C + j] += -kappa * (dij - nrm[i] * nrm[j]) / rho * d_grad[k][i];
            }
        }
        // a = a₀ + A x
        for i in 0..3 {
            g[A0 + i] += d_c[k][i];
            for j in 0..3 {
                g[A + 3 * i + j] += d_c[k][i] * x[j];
            }
        }
        // Θ = sigmoid(m)
        for j in 0..9 {
            let th = e.theta[k][j];
            g[M + j] += d_theta[k][j] * th * (1.0 - th);
        }
    }
    g
}

fn scene() -> Scene {
    let p0 = initial_params();
    // Rays from several cameras at distance ≈ 2.5, aimed near the sphere
    // (hits, grazing rays and misses).
    let mut rng = TestRng(99);
    let mut origins = Vec::new();
    let mut dirs = Vec::new();
    let mut energy = Vec::new();
    for r in 0..24 {
        let az = rng.uniform(0.0, std::f64::consts::TAU);
        let el = rng.uniform(-0.6, 0.6);
        let o = [
            2.5 * el.cos() * az.cos(),
            2.5 * el.sin(),
            2.5 * el.cos() * az.sin(),
        ];
        let aim = [
            rng.uniform(-0.6, 0.6),
            rng.uniform(-0.6, 0.6),
            rng.uniform(-0.6, 0.6),
        ];
        let d: [f64; 3] = std::array::from_fn(|i| aim[i] - o[i]);
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        origins.push(o);
        dirs.push(d.map(|x| x / l));
        energy.push(if r % 3 == 2 {
            [0.0; 3]
        } else {
            [2.0, 2.5, 3.0]
        });
    }
    let o32: Vec<[f32; 3]> = origins.iter().map(|o| o.map(|x| x as f32)).collect();
    let d32: Vec<[f32; 3]> = dirs.iter().map(|d| d.map(|x| x as f32)).collect();
    let rays = Rays {
        origins: &o32,
        dirs: &d32,
    };
    let sdf = |pts: &[[f32; 3]], out: &mut [f32]| {
        for (o, x) in out.iter_mut().zip(pts) {
            let rel: [f64; 3] = std::array::from_fn(|i| f64::from(x[i]) - p0[C + i]);
            *o = (p0[K] * ((rel[0] * rel[0] + rel[1] * rel[1] + rel[2] * rel[2]).sqrt() - p0[R]))
                as f32;
        }
    };
    let s = (10.0 * p0[V]).exp() as f32;
    let mut grid = common::occupancy_grid(32);
    grid.refresh(sdf, s, RefreshMode::Full);
    let mut sampler = Sampler::new(SamplerSettings {
        max_coarse: 24,
        n_fine: 8,
        ..Default::default()
    })
    .unwrap();
    let mut coarse = CoarseSamples::default();
    let mut samples = RaySamples::default();
    sampler.sample(&grid, &rays, sdf, s, Some(3), &mut coarse, &mut samples);
    let mut sc = Scene {
        origins,
        dirs,
        energy,
        samples,
        target: vec![],
        mask: vec![],
        settings: NeusSettings {
            cos_anneal_ratio: 0.7,
            ..Default::default()
        },
    };
    let (f, ..) = forward(&sc, &p0);
    sc.target = f
        .colour
        .iter()
        .map(|c| {
            c.map(|x| x + if rng.next_f64() < 0.5 { -1.0 } else { 1.0 } * rng.uniform(0.05, 0.2))
        })
        .collect();
    sc.mask = f
        .acc
        .iter()
        .map(|&a| if a > 0.5 { 1.0 } else { 0.0 })
        .collect();
    sc
}

#[test]
fn end_to_end_gradient_matches_finite_differences() {
    let sc = scene();
    let p0 = initial_params();
    let (f, ..) = forward(&sc, &p0);
    let hits = f.acc.iter().filter(|&&a| a > 0.5).count();
    let partial = f.acc.iter().filter(|&&a| a > 0.01 && a < 0.99).count();
    assert!((4..=20).contains(&hits), "hits {hits}");
    assert!(partial >= 1, "no ray with a partial accumulated weight");
    assert!(sc.samples.len() > 200);
    let g = analytic_grad(&sc, &p0);
    let h = 1e-6;
    for j in 0..N_PARAMS {
        let mut a = p0;
        let mut b = p0;
        a[j] += h;
        b[j] -= h;
        let fd = (loss(&sc, &a) - loss(&sc, &b)) / (2.0 * h);
        let tol = 1e-6 + 1e-5 * fd.abs().max(g[j].abs());
        assert!(
            (g[j] - fd).abs() <= tol,
            "parameter {j}: analytic {} vs finite difference {fd}",
            g[j]
        );
        assert!(g[j].abs() > 1e-6, "parameter {j} has no gradient");
    }
}
