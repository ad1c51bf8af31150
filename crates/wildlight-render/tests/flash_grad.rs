//! The flash term: value against SPEC §2 written with positions, and
//! finite-difference checks (f64) of its backward pass.
#![allow(clippy::needless_range_loop)] // index-heavy test arithmetic over parallel arrays

mod common;

use common::TestRng;
use wildlight_material::{BrdfSettings, brdf};
use wildlight_render::flash::{FlashCache, FlashInputs, flash_backward, flash_forward, gain};

struct Problem {
    offsets: Vec<u32>,
    origins: Vec<[f64; 3]>,
    dirs: Vec<[f64; 3]>,
    energy: Vec<[f64; 3]>,
    t: Vec<f64>,
    grad: Vec<[f64; 3]>,
    params: Vec<[f64; 9]>,
    log_gain: f64,
    u: Vec<[f64; 3]>,
}

fn problem(seed: u64) -> Problem {
    let mut rng = TestRng(seed);
    let counts = [4u32, 0, 6, 3, 5];
    let mut offsets = vec![0u32];
    for &c in &counts {
        offsets.push(offsets.last().unwrap() + c);
    }
    let n = *offsets.last().unwrap() as usize;
    let mut origins = Vec::new();
    let mut dirs = Vec::new();
    let mut energy = Vec::new();
    for r in 0..counts.len() {
        origins.push([
            rng.uniform(-3.0, 3.0),
            rng.uniform(-3.0, 3.0),
            rng.uniform(2.0, 3.0),
        ]);
        let d = [rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), -1.0];
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        dirs.push(d.map(|x| x / l));
        // Ray 3 is a no-flash image.
        energy.push(if r == 3 {
            [0.0; 3]
        } else {
            [
                rng.uniform(1.0, 5.0),
                rng.uniform(1.0, 5.0),
                rng.uniform(1.0, 5.0),
            ]
        });
    }
    let mut t = Vec::new();
    let mut grad = Vec::new();
    let mut params = Vec::new();
    for (r, &c) in counts.iter().enumerate() {
        for _ in 0..c {
            t.push(rng.uniform(1.5, 3.5));
            // A gradient facing the camera (n·h well above 0) but not head-on.
            let d = dirs[r];
            let g = [
                -d[0] * 0.8 + rng.uniform(-0.4, 0.4),
                -d[1] * 0.8 + rng.uniform(-0.4, 0.4),
                -d[2] * 0.8 + rng.uniform(-0.4, 0.4),
            ];
            grad.push(g.map(|x| x * rng.uniform(0.7, 1.3)));
            let mut p = [0.0; 9];
            for x in &mut p {
                *x = rng.uniform(0.1, 0.9);
            }
            params.push(p);
        }
    }
    let u = (0..n)
        .map(|_| {
            [
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
                rng.uniform(-1.0, 1.0),
            ]
        })
        .collect();
    Problem {
        offsets,
        origins,
        dirs,
        energy,
        t,
        grad,
        params,
        log_gain: 0.3,
        u,
    }
}

fn inputs(p: &Problem) -> FlashInputs<'_, f64> {
    FlashInputs {
        offsets: &p.offsets,
        ray_dirs: &p.dirs,
        light_energy: &p.energy,
        t: &p.t,
        sdf_grad: &p.grad,
        params: &p.params,
    }
}

fn loss(p: &Problem, settings: &BrdfSettings) -> f64 {
    let mut f = vec![[0.0; 3]; p.t.len()];
    flash_forward(&inputs(p), p.log_gain, settings, &mut f, None);
    f.iter()
        .zip(&p.u)
        .map(|(a, b)| a[0] * b[0] + a[1] * b[1] + a[2] * b[2])
        .sum()
}

/// f = γ E ⊙ ρ(n, h; Θ) max(0, n·h) / |x − o|² with h = (o − x)/|o − x| (SPEC §2),
/// evaluated from the sample position, independently of the kernel.
#[test]
fn flash_value_matches_spec_formula_with_positions() {
    let p = problem(3);
    let settings = BrdfSettings::default();
    let mut f = vec![[0.0; 3]; p.t.len()];
    flash_forward(&inputs(&p), p.log_gain, &settings, &mut f, None);
    let gamma = p.log_gain.exp();
    let mut lit = 0;
    for r in 0..p.dirs.len() {
        let (o, d) = (p.origins[r], p.dirs[r]);
        for k in p.offsets[r] as usize..p.offsets[r + 1] as usize {
            let x: Vec<f64> = (0..3).map(|i| o[i] + p.t[k] * d[i]).collect();
            let ox: Vec<f64> = (0..3).map(|i| o[i] - x[i]).collect();
            let dist2: f64 = ox.iter().map(|v| v * v).sum();
            let h: Vec<f64> = ox.iter().map(|v| v / dist2.sqrt()).collect();
            let gl = p.grad[k].iter().map(|v| v * v).sum::<f64>().sqrt();
            let c: f64 = (0..3).map(|i| p.grad[k][i] / gl * h[i]).sum();
            let rho = brdf::eval(&p.params[k], c, &settings);
            for i in 0..3 {
                let want = gamma * p.energy[r][i] * rho[i] * c.max(0.0) / dist2;
                assert!(
                    (f[k][i] - want).abs() <= 1e-12 * want.abs().max(1e-12),
                    "sample {k}"
                );
                if want > 0.0 {
                    lit += 1;
                }
            }
        }
    }
    assert!(lit > 30);
    assert!((gain(0.3f64) - 0.3f64.exp()).abs() < 1e-15);
}

#[test]
fn flash_backward_matches_finite_differences() {
    let settings = BrdfSettings::default();
    let p = problem(9);
    let n = p.t.len();
    let mut d_params = vec![[0.0; 9]; n];
    let mut d_grad = vec![[0.0; 3]; n];
    let d_g = flash_backward(
        &inputs(&p),
        p.log_gain,
        &settings,
        None,
        &p.u,
        &mut d_params,
        &mut d_grad,
    );
    // The cached path gives the same gradients, bit for bit.
    let mut cache = FlashCache::new();
    let mut f = vec![[0.0; 3]; n];
    flash_forward(&inputs(&p), p.log_gain, &settings, &mut f, Some(&mut cache));
    let mut f_plain = vec![[0.0; 3]; n];
    flash_forward(&inputs(&p), p.log_gain, &settings, &mut f_plain, None);
    assert_eq!(f, f_plain);
    let mut d_params_c = vec![[0.0; 9]; n];
    let mut d_grad_c = vec![[0.0; 3]; n];
    let d_g_c = flash_backward(
        &inputs(&p),
        p.log_gain,
        &settings,
        Some(&cache),
        &p.u,
        &mut d_params_c,
        &mut d_grad_c,
    );
    assert_eq!((d_g_c, &d_params_c, &d_grad_c), (d_g, &d_params, &d_grad));
    let h = 1e-6;
    let fd = |f: &dyn Fn(&mut Problem, f64)| {
        let mut a = problem(9);
        let mut b = problem(9);
        f(&mut a, h);
        f(&mut b, -h);
        (loss(&a, &settings) - loss(&b, &settings)) / (2.0 * h)
    };
    let check = |name: String, an: f64, nu: f64| {
        let tol = 1e-7 + 1e-5 * an.abs().max(nu.abs());
        assert!(
            (an - nu).abs() <= tol,
            "{name}: analytic {an} vs finite difference {nu}"
        );
    };
    let mut nonzero = 0;
    for k in 0..n {
        for j in 0..9 {
            check(
                format!("d params[{k}][{j}]"),
                d_params[k][j],
                fd(&|q, e| q.params[k][j] += e),
            );
            if d_params[k][j].abs() > 1e-6 {
                nonzero += 1;
            }
        }
        for i in 0..3 {
            check(
                format!("d grad[{k}][{i}]"),
                d_grad[k][i],
                fd(&|q, e| q.grad[k][i] += e),
            );
        }
    }
    check("d log_gain".into(), d_g, fd(&|q, e| q.log_gain += e));
    assert!(
        nonzero > 9 * n / 2,
        "too few non-zero parameter gradients: {nonzero}"
    );
    assert!(d_g.abs() > 1e-4);
    // The no-flash ray gets no gradient.
    for k in p.offsets[3] as usize..p.offsets[4] as usize {
        assert_eq!(d_params[k], [0.0; 9]);
        assert_eq!(d_grad[k], [0.0; 3]);
    }
}

/// Back-facing samples (n·h ≤ 0) have no flash radiance and no gradient.
#[test]
fn back_facing_samples_are_dark() {
    let settings = BrdfSettings::default();
    let offsets = vec![0u32, 1];
    let dirs = vec![[0.0, 0.0, -1.0f64]];
    let energy = vec![[1.0; 3]];
    let t = vec![2.0];
    let grad = vec![[0.1, 0.0, -1.0]];
    let params = vec![[0.5; 9]];
    let inp = FlashInputs {
        offsets: &offsets,
        ray_dirs: &dirs,
        light_energy: &energy,
        t: &t,
        sdf_grad: &grad,
        params: &params,
    };
    let mut f = vec![[1.0; 3]];
    flash_forward(&inp, 0.0, &settings, &mut f, None);
    assert_eq!(f[0], [0.0; 3]);
    let mut dp = vec![[0.0; 9]];
    let mut dg = vec![[0.0; 3]];
    let d = flash_backward(&inp, 0.0, &settings, None, &[[1.0; 3]], &mut dp, &mut dg);
    assert_eq!((d, dp[0], dg[0]), (0.0, [0.0; 9], [0.0; 3]));
}

/// A cache reused across batches of the same size (it is then not
/// zero-filled again) gives the same forward values and gradients as no
/// cache, bit for bit, whatever the previous batch left in it.
#[test]
fn a_reused_cache_matches_the_uncached_pass() {
    let settings = BrdfSettings::default();
    let first = problem(31);
    let mut second = problem(32);
    assert_eq!(first.t.len(), second.t.len());
    // In the second batch ray 0's flash is off and some samples face away.
    second.energy[0] = [0.0; 3];
    for k in [5usize, 8, 12, 17] {
        second.grad[k] = second.grad[k].map(|x| -x);
    }
    let n = second.t.len();
    let mut cache = FlashCache::new();
    let mut f = vec![[0.0; 3]; n];
    flash_forward(
        &inputs(&first),
        first.log_gain,
        &settings,
        &mut f,
        Some(&mut cache),
    );
    for batch in [&second, &first, &second] {
        flash_forward(
            &inputs(batch),
            batch.log_gain,
            &settings,
            &mut f,
            Some(&mut cache),
        );
        let mut f_plain = vec![[0.0; 3]; n];
        flash_forward(
            &inputs(batch),
            batch.log_gain,
            &settings,
            &mut f_plain,
            None,
        );
        assert_eq!(f, f_plain);
        let run = |cache: Option<&FlashCache<f64>>| {
            let mut dp = vec![[0.0; 9]; n];
            let mut dg = vec![[0.0; 3]; n];
            let d = flash_backward(
                &inputs(batch),
                batch.log_gain,
                &settings,
                cache,
                &batch.u,
                &mut dp,
                &mut dg,
            );
            (d, dp, dg)
        };
        let cached = run(Some(&cache));
        let plain = run(None);
        assert_eq!(cached, plain);
        // The batch has lit, front-facing samples with non-zero gradients.
        assert!(
            cached
                .1
                .iter()
                .filter(|d| d.iter().any(|x| *x != 0.0))
                .count()
                >= 8
        );
    }
}
