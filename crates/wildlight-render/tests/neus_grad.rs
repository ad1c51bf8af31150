//! Finite-difference checks (f64) of the NeuS weights and compositing backward passes.
#![allow(clippy::needless_range_loop)] // index-heavy test arithmetic over parallel arrays

mod common;

use common::TestRng;
use wildlight_render::composite::{
    add_background, add_background_backward, composite, composite_backward,
};
use wildlight_render::neus::{NeusInputs, NeusSettings, NeusWeights, sharpness};

struct Problem {
    offsets: Vec<u32>,
    dirs: Vec<[f64; 3]>,
    sdf: Vec<f64>,
    grad: Vec<[f64; 3]>,
    delta: Vec<f64>,
    colour: Vec<[f64; 3]>,
    v: f64,
    /// Loss weights: per ray on C (3) and Σw, per sample on w.
    u: Vec<[f64; 3]>,
    beta: Vec<f64>,
    eta: Vec<f64>,
    /// Per-ray background radiance composited behind the samples.
    background: Vec<[f64; 3]>,
}

fn problem(seed: u64, counts: &[u32]) -> Problem {
    let mut rng = TestRng(seed);
    let mut offsets = vec![0u32];
    for &c in counts {
        offsets.push(offsets.last().unwrap() + c);
    }
    let n = *offsets.last().unwrap() as usize;
    let mut dirs = Vec::new();
    for _ in counts {
        let d = [
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
            rng.uniform(-1.0, 1.0),
        ];
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        dirs.push(d.map(|x| x / l));
    }
    let mut sdf = Vec::new();
    let mut grad = Vec::new();
    let mut delta = Vec::new();
    for (ray, &c) in counts.iter().enumerate() {
        let d = dirs[ray];
        let mut phi = rng.uniform(0.05, 0.2);
        for _ in 0..c {
            // A gradient whose slope along the ray avoids the kinks of the
            // cos annealing (q = 0 and q = 1).
            let g = loop {
                let g = [
                    rng.uniform(-1.2, 1.2),
                    rng.uniform(-1.2, 1.2),
                    rng.uniform(-1.2, 1.2),
                ];
                let q = g[0] * d[0] + g[1] * d[1] + g[2] * d[2];
                if q.abs() > 0.05 && (q - 1.0).abs() > 0.05 {
                    break g;
                }
            };
            let del = rng.uniform(0.01, 0.06);
            sdf.push(phi);
            grad.push(g);
            delta.push(del);
            phi -= rng.uniform(0.0, 0.08);
        }
    }
    let colour = (0..n)
        .map(|_| [rng.next_f64(), rng.next_f64(), rng.next_f64()])
        .collect();
    let u = counts
        .iter()
        .map(|_| {
            [
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
            ]
        })
        .collect();
    let beta = counts.iter().map(|_| rng.uniform(-1.0, 1.0)).collect();
    let eta = (0..n).map(|_| rng.uniform(-0.5, 0.5)).collect();
    let background = counts
        .iter()
        .map(|_| [rng.next_f64(), rng.next_f64(), rng.next_f64()])
        .collect();
    Problem {
        offsets,
        dirs,
        sdf,
        grad,
        delta,
        colour,
        v: 0.35,
        u,
        beta,
        eta,
        background,
    }
}

impl Problem {
    /// The problem's samples as the kernels' inputs.
    fn inputs(&self) -> NeusInputs<'_, f64> {
        NeusInputs {
            offsets: &self.offsets,
            ray_dirs: &self.dirs,
            sdf: &self.sdf,
            sdf_grad: &self.grad,
            delta: &self.delta,
        }
    }
}

fn loss(p: &Problem, settings: &NeusSettings) -> f64 {
    let inputs = p.inputs();
    let mut w = NeusWeights::new();
    w.forward(&inputs, p.v, settings);
    let mut c = vec![[0.0; 3]; p.dirs.len()];
    composite(&p.offsets, &w.weight, &p.colour, &mut c);
    add_background(&w.acc_weight, &p.background, &mut c);
    let mut l = 0.0;
    for r in 0..p.dirs.len() {
        l += (0..3).map(|i| p.u[r][i] * c[r][i]).sum::<f64>() + p.beta[r] * w.acc_weight[r];
    }
    l + w.weight.iter().zip(&p.eta).map(|(a, b)| a * b).sum::<f64>()
}

struct Grads {
    sdf: Vec<f64>,
    grad: Vec<[f64; 3]>,
    colour: Vec<[f64; 3]>,
    background: Vec<[f64; 3]>,
    v: f64,
}

fn analytic(p: &Problem, settings: &NeusSettings) -> Grads {
    let inputs = p.inputs();
    let mut w = NeusWeights::new();
    w.forward(&inputs, p.v, settings);
    let n = p.sdf.len();
    let mut d_w = p.eta.clone();
    let mut d_colour = vec![[0.0; 3]; n];
    composite_backward(
        &p.offsets,
        &w.weight,
        &p.colour,
        &p.u,
        &mut d_w,
        Some(&mut d_colour),
    );
    let mut d_acc = p.beta.clone();
    let mut d_background = vec![[0.0; 3]; p.dirs.len()];
    add_background_backward(
        &w.acc_weight,
        &p.background,
        &p.u,
        &mut d_acc,
        Some(&mut d_background),
    );
    let mut d_sdf = vec![0.0; n];
    let mut d_grad = vec![[0.0; 3]; n];
    let d_v = w.backward(
        &inputs,
        p.v,
        settings,
        &d_w,
        Some(&d_acc),
        &mut d_sdf,
        &mut d_grad,
    );
    Grads {
        sdf: d_sdf,
        grad: d_grad,
        colour: d_colour,
        background: d_background,
        v: d_v,
    }
}

fn check(name: &str, analytic: f64, numeric: f64) {
    let tol = 1e-6 + 1e-5 * numeric.abs().max(analytic.abs());
    assert!(
        (analytic - numeric).abs() <= tol,
        "{name}: analytic {analytic} vs finite difference {numeric}"
    );
}

fn fd_check_all(seed: u64, ratio: f64) {
    let settings = NeusSettings {
        cos_anneal_ratio: ratio,
        ..Default::default()
    };
    let p = problem(seed, &[0, 3, 7, 1, 12, 5]);
    let g = analytic(&p, &settings);
    let h = 1e-6;
    let fd = |f: &dyn Fn(&mut Problem, f64)| {
        let mut a = problem(seed, &[0, 3, 7, 1, 12, 5]);
        let mut b = problem(seed, &[0, 3, 7, 1, 12, 5]);
        f(&mut a, h);
        f(&mut b, -h);
        (loss(&a, &settings) - loss(&b, &settings)) / (2.0 * h)
    };
    let mut nonzero = 0;
    for k in 0..p.sdf.len() {
        check(&format!("d sdf[{k}]"), g.sdf[k], fd(&|q, e| q.sdf[k] += e));
        for i in 0..3 {
            check(
                &format!("d grad[{k}][{i}]"),
                g.grad[k][i],
                fd(&|q, e| q.grad[k][i] += e),
            );
            check(
                &format!("d colour[{k}][{i}]"),
                g.colour[k][i],
                fd(&|q, e| q.colour[k][i] += e),
            );
        }
        if g.sdf[k].abs() > 1e-3 {
            nonzero += 1;
        }
    }
    check("d v", g.v, fd(&|q, e| q.v += e));
    for r in 0..p.dirs.len() {
        for i in 0..3 {
            check(
                &format!("d background[{r}][{i}]"),
                g.background[r][i],
                fd(&|q, e| q.background[r][i] += e),
            );
        }
    }
    // The check must not pass vacuously.
    assert!(
        nonzero > p.sdf.len() / 2,
        "too few non-zero SDF gradients: {nonzero}"
    );
    assert!(g.v.abs() > 1e-4);
}

#[test]
fn neus_backward_matches_finite_differences_after_annealing() {
    fd_check_all(7, 1.0);
}

#[test]
fn neus_backward_matches_finite_differences_during_annealing() {
    fd_check_all(11, 0.4);
}

#[test]
fn neus_backward_matches_finite_differences_at_start_of_annealing() {
    fd_check_all(13, 0.0);
}

/// For an exactly linear SDF along a ray and contiguous sections, the NeuS
/// transmittance (with ε = 0) telescopes: 1 − Σw ≈ Φ_s(φ(end)) / Φ_s(φ(start)), whatever
/// the number of sections.
#[test]
fn accumulated_weight_telescopes_for_a_linear_sdf() {
    let v = 0.5; // s = e^5 ≈ 148
    let (s, _) = sharpness(v);
    let sig = |x: f64| 1.0 / (1.0 + (-x).exp());
    for &n in &[4usize, 37, 500] {
        let (t0, t1) = (0.0, 1.0);
        let phi0 = 0.3;
        let slope = -0.7; // d·∇φ
        let delta = (t1 - t0) / n as f64;
        let t: Vec<f64> = (0..n).map(|j| t0 + (j as f64 + 0.5) * delta).collect();
        let sdf: Vec<f64> = t.iter().map(|&t| phi0 + slope * t).collect();
        let dirs = vec![[0.0, 0.0, 1.0]];
        let grads = vec![[0.3, 0.2, slope]; n];
        let deltas = vec![delta; n];
        let offsets = vec![0u32, n as u32];
        let inputs = NeusInputs {
            offsets: &offsets,
            ray_dirs: &dirs,
            sdf: &sdf,
            sdf_grad: &grads,
            delta: &deltas,
        };
        let mut w = NeusWeights::new();
        // ε = 0: the exact telescoping (the SPEC's ε adds ≈ ε opacity per section).
        let exact = NeusSettings {
            alpha_eps: 0.0,
            ..Default::default()
        };
        w.forward(&inputs, v, &exact);
        let expected = 1.0 - sig(s * (phi0 + slope * t1)) / sig(s * phi0);
        assert!(
            (w.acc_weight[0] - expected).abs() < 1e-3,
            "n = {n}: Σw = {} vs {expected}",
            w.acc_weight[0]
        );
        let sum: f64 = w.weight.iter().sum();
        assert!((sum - w.acc_weight[0]).abs() < 1e-12);
    }
}

/// Forward and backward give bit-identical results on 1 and 2 threads.
#[test]
fn results_do_not_depend_on_the_thread_count() {
    let counts: Vec<u32> = (0..700).map(|i| (i * 7 % 13) as u32).collect();
    let p = problem(5, &counts);
    let settings = NeusSettings::default();
    let run = |threads: usize| {
        common::on_threads(threads, || {
            let g = analytic(&p, &settings);
            (g.sdf, g.v)
        })
    };
    let (a, va) = run(1);
    let (b, vb) = run(2);
    assert_eq!(va.to_bits(), vb.to_bits());
    assert!(a.iter().zip(&b).all(|(x, y)| x.to_bits() == y.to_bits()));
}
