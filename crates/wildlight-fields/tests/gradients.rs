//! Finite-difference gradient checks in f64 of every hand-written backward pass.

// Gradient checks index parameters, points and axes together.
#![allow(clippy::needless_range_loop)]

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use wildlight_fields::*;

fn rng(seed: u64) -> Pcg64Mcg {
    Pcg64Mcg::seed_from_u64(seed)
}

fn rand_vec(n: usize, lo: f64, hi: f64, r: &mut Pcg64Mcg) -> Vec<f64> {
    (0..n).map(|_| r.random_range(lo..hi)).collect()
}

/// `n` points with coordinates uniform in `[lo, hi)`.
fn rand_points(n: usize, lo: f64, hi: f64, r: &mut Pcg64Mcg) -> Vec<[f64; 3]> {
    (0..n)
        .map(|_| [0; 3].map(|_| r.random_range(lo..hi)))
        .collect()
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

/// (loss(p + h) − loss(p − h)) / 2h for the parameter `param` picks out of
/// `state`, which is left as it was.
fn central_difference<S>(
    state: &mut S,
    param: impl Fn(&mut S) -> &mut f64,
    loss: impl Fn(&S) -> f64,
    h: f64,
) -> f64 {
    let orig = *param(state);
    *param(state) = orig + h;
    let lp = loss(state);
    *param(state) = orig - h;
    let lm = loss(state);
    *param(state) = orig;
    (lp - lm) / (2.0 * h)
}

/// Asserts |a − b| ≤ atol + rtol·max(|a|, |b|).
fn assert_close(what: &str, analytic: f64, numeric: f64, atol: f64, rtol: f64) {
    let tol = atol + rtol * analytic.abs().max(numeric.abs());
    assert!(
        (analytic - numeric).abs() <= tol,
        "{what}: analytic {analytic:.10e} vs finite difference {numeric:.10e}"
    );
}

#[test]
fn activation_derivatives_match_finite_differences() {
    let acts = [
        Activation::None,
        Activation::Relu,
        Activation::Softplus { beta: 1.0 },
        Activation::Softplus { beta: 100.0 },
        Activation::Sigmoid,
    ];
    let h = 1e-7;
    for act in acts {
        for &z in &[-2.3, -0.31, -0.004, 0.007, 0.2, 1.7, 6.0] {
            let numeric = (act.apply(z + h) - act.apply(z - h)) / (2.0 * h);
            let analytic = act.derivative_from_output(act.apply(z));
            assert_close(&format!("{act:?} at {z}"), analytic, numeric, 1e-7, 1e-6);
        }
    }
}

#[test]
fn f32_activations_match_f64_references() {
    for act in [
        Activation::Softplus { beta: 100.0 },
        Activation::Softplus { beta: 1.0 },
        Activation::Sigmoid,
    ] {
        for i in 0..2001 {
            let z = -10.0 + i as f64 * 0.01;
            let reference = match act {
                Activation::Softplus { beta } => (1.0 + (beta as f64 * z).exp()).ln() / beta as f64,
                _ => 1.0 / (1.0 + (-z).exp()),
            };
            let fast = act.apply(z as f32) as f64;
            assert!(
                (fast - reference).abs() <= 1e-6 * reference.abs().max(1e-3),
                "{act:?}({z}) = {fast}, reference {reference}"
            );
        }
    }
}

fn small_grid(f: usize, interpolation: Interpolation) -> HashGridConfig {
    // Levels at resolution 2, 4, 8, 16: the first two dense (27, 125 vertices ≤ 128), the others hashed.
    HashGridConfig {
        n_levels: 4,
        n_features: f,
        log2_table_size: 7,
        base_resolution: 2,
        finest_resolution: 16,
        init_range: 1.0,
        interpolation,
    }
}

const INTERPOLATIONS: [Interpolation; 2] = [Interpolation::Linear, Interpolation::Smoothstep];

#[test]
fn hash_grid_table_gradient_matches_finite_differences() {
    for (f, interpolation) in [1, 2, 4, 8]
        .into_iter()
        .flat_map(|f| INTERPOLATIONS.map(|i| (f, i)))
    {
        let mut r = rng(1);
        let mut grid = HashGrid::<f64>::new(&small_grid(f, interpolation), 3).unwrap();
        assert!(grid.levels()[0].dense && grid.levels()[1].dense && !grid.levels()[3].dense);
        let n = 40;
        let x: Vec<[f64; 3]> = (0..n)
            .map(|_| [r.random(), r.random(), r.random()])
            .collect();
        let no = grid.n_outputs();
        let d_out = rand_vec(n * no, -1.0, 1.0, &mut r);
        let loss = |g: &HashGrid<f64>| {
            let mut out = vec![0.0; n * no];
            g.encode(&x, &mut out, no, 0, 4);
            dot(&out, &d_out)
        };
        let mut grad = vec![0.0; grid.n_params()];
        // Two blocks of rows to exercise the block addressing.
        let blocks: Vec<&[f64]> = d_out.chunks(25 * no).collect();
        grid.backward_params(&x, &blocks, 25, no, 0, 4, &mut grad);
        let h = 1e-6;
        for i in (0..grid.n_params()).step_by(3) {
            let numeric = central_difference(&mut grid, |g| &mut g.params[i], loss, h);
            assert_close(
                &format!("F={f} {interpolation:?} table entry {i}"),
                grad[i],
                numeric,
                1e-8,
                1e-6,
            );
        }
        assert!(
            grad.iter().any(|g| g.abs() > 1e-3),
            "gradient must not be all zero"
        );
    }
}

#[test]
fn hash_grid_input_gradient_matches_finite_differences() {
    for interpolation in INTERPOLATIONS {
        check_input_gradient(interpolation);
    }
}

fn check_input_gradient(interpolation: Interpolation) {
    let mut r = rng(2);
    let grid = HashGrid::<f64>::new(&small_grid(2, interpolation), 5).unwrap();
    // More than two blocks of the level walk; two points outside the cube
    // on one axis (clamped there: no gradient along that axis).
    let n = 70;
    let mut x: Vec<[f64; 3]> = (0..n)
        .map(|_| [r.random(), r.random(), r.random()])
        .collect();
    x[3][0] = -0.2;
    x[40][1] = 1.3;
    let no = grid.n_outputs();
    let d_out = rand_vec(n * no, -1.0, 1.0, &mut r);
    let mut d_x = vec![[0.0; 3]; n];
    grid.backward_input(&x, &d_out, no, 0, 4, &mut d_x);
    let h = 1e-8;
    for p in 0..n {
        for k in 0..3 {
            let eval = |delta: f64| {
                let mut xp = [x[p]];
                xp[0][k] += delta;
                let mut out = vec![0.0; no];
                grid.encode(&xp, &mut out, no, 0, 4);
                dot(&out, &d_out[p * no..(p + 1) * no])
            };
            let numeric = (eval(h) - eval(-h)) / (2.0 * h);
            if (p, k) == (3, 0) || (p, k) == (40, 1) {
                assert_eq!(d_x[p][k], 0.0, "clamped coordinate");
            }
            assert_close(
                &format!("{interpolation:?} point {p} axis {k}"),
                d_x[p][k],
                numeric,
                1e-5,
                1e-5,
            );
        }
    }
}

/// The encoding's directional derivative (forward mode) against central
/// differences of the encoding along the direction, and against the
/// transposed product of `backward_input` (⟨J v, d⟩ = ⟨v, Jᵀ d⟩); three of
/// the four levels active, so the last gives 0.
#[test]
fn hash_grid_directional_derivative_matches_finite_differences() {
    for (f, interpolation) in [1, 2, 4]
        .into_iter()
        .flat_map(|f| INTERPOLATIONS.map(|i| (f, i)))
    {
        let mut r = rng(6);
        let grid = HashGrid::<f64>::new(&small_grid(f, interpolation), 9).unwrap();
        // More than two blocks of the kernels' level walk.
        let n = 70;
        let no = grid.n_outputs();
        let x = rand_points(n, 0.01, 0.99, &mut r);
        let v = rand_points(n, -1.0, 1.0, &mut r);
        let active = 3;
        let mut jv = vec![0.0; n * no];
        grid.encode_directional(&x, &v, active, &mut jv);
        let h = 1e-7;
        for p in 0..n {
            let at = |t: f64| {
                let xp = [[
                    x[p][0] + t * v[p][0],
                    x[p][1] + t * v[p][1],
                    x[p][2] + t * v[p][2],
                ]];
                let mut out = vec![0.0; no];
                grid.encode(&xp, &mut out, no, 0, active);
                out
            };
            let (plus, minus) = (at(h), at(-h));
            for j in 0..no {
                assert_close(
                    &format!("F={f} {interpolation:?} point {p} output {j}"),
                    jv[p * no + j],
                    (plus[j] - minus[j]) / (2.0 * h),
                    1e-6,
                    1e-5,
                );
            }
            for j in active * f..no {
                assert_eq!(jv[p * no + j], 0.0, "inactive level");
            }
        }
        let d = rand_vec(n * no, -1.0, 1.0, &mut r);
        let mut jt_d = vec![[0.0; 3]; n];
        grid.backward_input(&x, &d, no, 0, active, &mut jt_d);
        let lhs = dot(&jv, &d);
        let rhs: f64 = (0..n).map(|p| dot(&v[p], &jt_d[p])).sum();
        assert_close("⟨J v, d⟩ = ⟨v, Jᵀ d⟩", lhs, rhs, 1e-10, 1e-10);
    }
}

/// The table gradient of ⟨J(x) v, d⟩ (the directional derivative is linear
/// in the table) against central differences over every table entry.
#[test]
fn hash_grid_directional_table_gradient_matches_finite_differences() {
    for interpolation in INTERPOLATIONS {
        let mut r = rng(7);
        let mut grid = HashGrid::<f64>::new(&small_grid(2, interpolation), 4).unwrap();
        let n = 70;
        let no = grid.n_outputs();
        let x: Vec<[f64; 3]> = (0..n)
            .map(|_| [r.random(), r.random(), r.random()])
            .collect();
        let v = rand_points(n, -1.0, 1.0, &mut r);
        let d = rand_vec(n * no, -1.0, 1.0, &mut r);
        let mut grad = vec![0.0; grid.params.len()];
        grid.backward_params_directional(&x, &v, &d, 4, &mut grad);
        let objective = |grid: &HashGrid<f64>| {
            let mut jv = vec![0.0; n * no];
            grid.encode_directional(&x, &v, 4, &mut jv);
            dot(&jv, &d)
        };
        for i in 0..grid.params.len() {
            let numeric = central_difference(&mut grid, |g| &mut g.params[i], objective, 1e-6);
            assert_close(
                &format!("{interpolation:?} table entry {i}"),
                grad[i],
                numeric,
                1e-7,
                1e-6,
            );
        }
        assert!(
            grad.iter().any(|g| g.abs() > 1e-2),
            "gradient must not be all zero"
        );
    }
}

/// The point of smoothstep: the encoding's spatial derivative is continuous
/// where a point crosses a cell face (x = 0.5 is a face of every level
/// here), while the trilinear one jumps there.
#[test]
fn smoothstep_encoding_has_a_continuous_derivative_across_cell_faces() {
    let jump = |interpolation: Interpolation| {
        let grid = HashGrid::<f64>::new(&small_grid(2, interpolation), 5).unwrap();
        let no = grid.n_outputs();
        let d_out = vec![1.0; no];
        let derivative = |x: f64| {
            let mut d_x = vec![[0.0; 3]; 1];
            grid.backward_input(&[[x, 0.3, 0.7]], &d_out, no, 0, 4, &mut d_x);
            d_x[0][0]
        };
        let (below, above) = (derivative(0.5 - 1e-9), derivative(0.5 + 1e-9));
        ((above - below).abs(), below.abs().max(above.abs()))
    };
    let (linear_jump, linear_size) = jump(Interpolation::Linear);
    let (smooth_jump, _) = jump(Interpolation::Smoothstep);
    assert!(
        linear_jump > 0.1 * linear_size,
        "trilinear derivative jumps: {linear_jump} of {linear_size}"
    );
    assert!(
        smooth_jump < 1e-5,
        "smoothstep derivative jumps by {smooth_jump}"
    );
}

#[test]
fn mlp_gradients_match_finite_differences() {
    let acts = [
        (Activation::Relu, Activation::None),
        (Activation::Softplus { beta: 3.0 }, Activation::Sigmoid),
        (Activation::Sigmoid, Activation::Softplus { beta: 1.0 }),
        (Activation::None, Activation::Relu),
    ];
    for (hidden, output) in acts {
        let cfg = MlpConfig {
            n_input: 5,
            hidden: vec![7, 6],
            n_output: 3,
            hidden_activation: hidden,
            output_activation: output,
        };
        let mut mlp = Mlp::<f64>::new(&cfg, 11).unwrap();
        let mut r = rng(3);
        for v in mlp.params.iter_mut() {
            *v += r.random_range(-0.2..0.2); // non-zero biases too
        }
        // More rows than one chunk, to check the chunked reduction.
        let n = CHUNK_ROWS + 37;
        let input = rand_vec(n * 5, -1.0, 1.0, &mut r);
        let d_out = rand_vec(n * 3, -1.0, 1.0, &mut r);
        let mut ctx = MlpContext::new();
        mlp.forward(&input, &mut ctx);
        let mut grad = vec![0.0; mlp.n_params()];
        let mut d_in = vec![0.0; n * 5];
        mlp.backward(&mut ctx, &d_out, &mut grad, Some(&mut d_in));
        let loss = |m: &Mlp<f64>, inp: &[f64]| {
            let mut c = MlpContext::new();
            m.forward(inp, &mut c);
            dot(c.output(), &d_out)
        };
        let h = 1e-6;
        for i in 0..mlp.n_params() {
            let v = mlp.params[i];
            mlp.params[i] = v + h;
            let lp = loss(&mlp, &input);
            mlp.params[i] = v - h;
            let lm = loss(&mlp, &input);
            mlp.params[i] = v;
            assert_close(
                &format!("{hidden:?}/{output:?} param {i}"),
                grad[i],
                (lp - lm) / (2.0 * h),
                1e-6,
                1e-5,
            );
        }
        for i in (0..n * 5).step_by(97) {
            let mut inp = input.clone();
            inp[i] += h;
            let lp = loss(&mlp, &inp);
            inp[i] -= 2.0 * h;
            let lm = loss(&mlp, &inp);
            assert_close(
                &format!("{hidden:?}/{output:?} input {i}"),
                d_in[i],
                (lp - lm) / (2.0 * h),
                1e-7,
                1e-5,
            );
        }
    }
}

fn field_config(n_extra: usize, include_position: bool) -> NeuralFieldConfig {
    NeuralFieldConfig {
        grid: HashGridConfig {
            init_range: 0.5,
            ..small_grid(2, Interpolation::Linear)
        },
        bound: 1.2,
        include_position,
        n_extra,
        hidden: vec![8],
        hidden_activation: Activation::Softplus { beta: 4.0 },
        n_output: 4,
        output_activation: Activation::Sigmoid,
    }
}

#[test]
fn neural_field_gradients_match_finite_differences() {
    let mut field = NeuralField::<f64>::new(&field_config(3, true), 21).unwrap();
    let mut r = rng(4);
    let n = 50;
    let x = rand_points(n, -1.0, 1.0, &mut r);
    let extra = rand_vec(n * 3, -1.0, 1.0, &mut r);
    let d_out = rand_vec(n * 4, -1.0, 1.0, &mut r);
    let mut ctx = FieldContext::new();
    field.forward(&x, &extra, &mut ctx);
    let mut grads = field.new_grads();
    let mut d_extra = vec![0.0; n * 3];
    let mut d_x = vec![[0.0; 3]; n];
    field.backward(
        &mut ctx,
        &d_out,
        &mut grads,
        Some(&mut d_extra),
        Some(&mut d_x),
    );
    let loss = |f: &NeuralField<f64>, x: &[[f64; 3]], e: &[f64]| {
        let mut c = FieldContext::new();
        f.forward(x, e, &mut c);
        dot(c.output(), &d_out)
    };
    let h = 1e-6;
    for i in (0..field.grid.n_params()).step_by(7) {
        let v = field.grid.params[i];
        field.grid.params[i] = v + h;
        let lp = loss(&field, &x, &extra);
        field.grid.params[i] = v - h;
        let lm = loss(&field, &x, &extra);
        field.grid.params[i] = v;
        assert_close(
            &format!("table {i}"),
            grads.grid[i],
            (lp - lm) / (2.0 * h),
            1e-8,
            1e-5,
        );
    }
    for i in 0..field.mlp.n_params() {
        let v = field.mlp.params[i];
        field.mlp.params[i] = v + h;
        let lp = loss(&field, &x, &extra);
        field.mlp.params[i] = v - h;
        let lm = loss(&field, &x, &extra);
        field.mlp.params[i] = v;
        assert_close(
            &format!("mlp {i}"),
            grads.mlp[i],
            (lp - lm) / (2.0 * h),
            1e-7,
            1e-5,
        );
    }
    for i in 0..n * 3 {
        let mut e = extra.clone();
        e[i] += h;
        let lp = loss(&field, &x, &e);
        e[i] -= 2.0 * h;
        let lm = loss(&field, &x, &e);
        assert_close(
            &format!("extra {i}"),
            d_extra[i],
            (lp - lm) / (2.0 * h),
            1e-7,
            1e-5,
        );
    }
    let hx = 1e-8;
    for p in 0..n {
        for k in 0..3 {
            let mut xp = x.clone();
            xp[p][k] += hx;
            let lp = loss(&field, &xp, &extra);
            xp[p][k] -= 2.0 * hx;
            let lm = loss(&field, &xp, &extra);
            assert_close(
                &format!("x[{p}][{k}]"),
                d_x[p][k],
                (lp - lm) / (2.0 * hx),
                1e-5,
                1e-4,
            );
        }
    }
}

fn small_sdf_config() -> SdfFieldConfig {
    SdfFieldConfig {
        grid: HashGridConfig {
            init_range: 0.3,
            ..small_grid(2, Interpolation::Linear)
        },
        bound: 1.0,
        hidden: vec![16],
        activation: Activation::Softplus { beta: 10.0 },
        n_features: 3,
        sphere_init_radius: None,
    }
}

/// The three ways of computing ∇φ in a pass with normals.
fn normal_methods(step: f64) -> [NormalMethod; 3] {
    let fd = |scheme| NormalMethod::FiniteDifference { scheme, step };
    [
        fd(FdScheme::Tetrahedral),
        fd(FdScheme::Central),
        NormalMethod::Analytic,
    ]
}

#[test]
fn normals_gradients_match_finite_differences() {
    for scheme in normal_methods(0.03) {
        let mut sdf = SdfField::<f64>::new(&small_sdf_config(), 8).unwrap();
        let mut r = rng(5);
        let n = 20;
        let x = rand_points(n, -0.8, 0.8, &mut r);
        let a = rand_vec(n, -1.0, 1.0, &mut r);
        let b = rand_vec(n * 3, -1.0, 1.0, &mut r);
        let c: Vec<[f64; 3]> = (0..n)
            .map(|_| [r.random(), r.random(), r.random()])
            .collect();
        let mut ctx = NormalContext::new();
        sdf.forward_with_normals(&x, scheme, &mut ctx);
        let mut grads = sdf.new_grads();
        sdf.backward_with_normals(&mut ctx, &a, &b, &c, &mut grads);
        let loss = |s: &SdfField<f64>| {
            let mut cx = NormalContext::new();
            s.forward_with_normals(&x, scheme, &mut cx);
            let g: f64 = cx
                .gradient
                .iter()
                .zip(&c)
                .map(|(g, c)| g[0] * c[0] + g[1] * c[1] + g[2] * c[2])
                .sum();
            dot(&cx.sdf, &a) + dot(&cx.features, &b) + g
        };
        let h = 1e-6;
        for i in (0..sdf.field.grid.n_params()).step_by(5) {
            let v = sdf.field.grid.params[i];
            sdf.field.grid.params[i] = v + h;
            let lp = loss(&sdf);
            sdf.field.grid.params[i] = v - h;
            let lm = loss(&sdf);
            sdf.field.grid.params[i] = v;
            assert_close(
                &format!("{scheme:?} table {i}"),
                grads.grid[i],
                (lp - lm) / (2.0 * h),
                1e-7,
                1e-5,
            );
        }
        for i in 0..sdf.field.mlp.n_params() {
            let v = sdf.field.mlp.params[i];
            sdf.field.mlp.params[i] = v + h;
            let lp = loss(&sdf);
            sdf.field.mlp.params[i] = v - h;
            let lm = loss(&sdf);
            sdf.field.mlp.params[i] = v;
            assert_close(
                &format!("{scheme:?} mlp {i}"),
                grads.mlp[i],
                (lp - lm) / (2.0 * h),
                1e-7,
                1e-5,
            );
        }
    }
}

#[test]
fn fd_normals_approximate_the_analytic_gradient() {
    // The SDF-field input gradient (analytic, via backward) and the FD estimate
    // agree to O(step²) for a smooth field.
    let cfg = SdfFieldConfig {
        grid: HashGridConfig {
            init_range: 0.02,
            ..small_grid(2, Interpolation::Linear)
        },
        ..small_sdf_config()
    };
    let sdf = SdfField::<f64>::new(&cfg, 9).unwrap();
    let mut r = rng(6);
    let n = 30;
    let x = rand_points(n, -0.6, 0.6, &mut r);
    let mut ctx = FieldContext::new();
    sdf.forward(&x, &mut ctx);
    let mut d_out = vec![0.0; n * 4];
    for p in 0..n {
        d_out[p * 4] = 1.0;
    }
    let mut grads = sdf.new_grads();
    let mut d_x = vec![[0.0; 3]; n];
    sdf.backward(&mut ctx, &d_out, &mut grads, Some(&mut d_x));
    for scheme in normal_methods(1e-4) {
        let mut nctx = NormalContext::new();
        sdf.forward_with_normals(&x, scheme, &mut nctx);
        // The analytic gradient is the input gradient itself.
        let tolerance = match scheme {
            NormalMethod::Analytic => 1e-10,
            NormalMethod::FiniteDifference { .. } => 2e-3,
        };
        for p in 0..n {
            for k in 0..3 {
                assert_close(
                    &format!("{scheme:?} point {p} axis {k}"),
                    d_x[p][k],
                    nctx.gradient[p][k],
                    tolerance,
                    tolerance * 10.0,
                );
            }
        }
    }
}

#[test]
fn per_part_buffer_backward_equals_level_parallel_backward() {
    let mut r = rng(9);
    let grid = HashGrid::<f64>::new(&small_grid(2, Interpolation::Linear), 3).unwrap();
    let n = 300;
    let x: Vec<[f64; 3]> = (0..n)
        .map(|_| [r.random(), r.random(), r.random()])
        .collect();
    let no = grid.n_outputs();
    let d_out = rand_vec(n * no, -1.0, 1.0, &mut r);
    let blocks: Vec<&[f64]> = d_out.chunks(64 * no).collect();
    let mut a = vec![0.0; grid.n_params()];
    grid.backward_params(&x, &blocks, 64, no, 0, 4, &mut a);
    for parts in [1, 2, 3] {
        let mut b = vec![0.0; grid.n_params()];
        let mut scratch = Vec::new();
        grid.backward_params_per_part_buffers(
            &x,
            &blocks,
            64,
            no,
            0,
            4,
            parts,
            &mut scratch,
            &mut b,
        );
        for (i, (u, v)) in a.iter().zip(&b).enumerate() {
            assert!((u - v).abs() < 1e-12, "parts {parts} entry {i}: {u} vs {v}");
        }
    }
}

#[test]
fn activation_second_derivatives_match_finite_differences() {
    let h = 1e-6;
    for act in [
        Activation::None,
        Activation::Relu,
        Activation::Softplus { beta: 1.0 },
        Activation::Softplus { beta: 100.0 },
        Activation::Sigmoid,
    ] {
        for &z in &[-2.3, -0.31, -0.004, 0.007, 0.2, 1.7] {
            let d = |z: f64| act.derivative_from_output(act.apply(z));
            let numeric = (d(z + h) - d(z - h)) / (2.0 * h);
            let analytic = second_derivative_from_output(act, act.apply(z));
            assert_close(&format!("{act:?} at {z}"), analytic, numeric, 1e-5, 1e-5);
        }
    }
}

/// A small SDF field in f64 with a random (not sphere-initialised) network
/// and a table of order-one entries, `hidden` its hidden widths.
fn analytic_test_field(hidden: Vec<usize>, interpolation: Interpolation) -> SdfField<f64> {
    SdfField::new(
        &SdfFieldConfig {
            grid: small_grid(2, interpolation),
            bound: 1.2,
            hidden,
            activation: Activation::Softplus { beta: 10.0 },
            n_features: 3,
            sphere_init_radius: None,
        },
        11,
    )
    .unwrap()
}

/// The analytic ∇φ: the outputs as the field's own forward pass gives
/// them, the gradient as central differences of φ.
#[test]
fn analytic_sdf_gradient_matches_finite_differences() {
    for (hidden, interpolation) in [
        (vec![8], Interpolation::Smoothstep),
        (vec![8, 6], Interpolation::Linear),
    ] {
        let field = analytic_test_field(hidden.clone(), interpolation);
        let mut r = rng(12);
        let x = rand_points(12, -0.9, 0.9, &mut r);
        let mut ctx = GradientContext::new();
        field.forward_with_gradient(&x, &mut ctx);
        let mut plain = FieldContext::new();
        field.forward(&x, &mut plain);
        for (a, b) in ctx.output.iter().zip(plain.output()) {
            assert_close("outputs", *a, *b, 1e-12, 1e-12);
        }
        let no = field.n_output();
        let h = 1e-7;
        for p in 0..x.len() {
            for k in 0..3 {
                let phi = |delta: f64| {
                    let mut q = x[p];
                    q[k] += delta;
                    let mut c = FieldContext::new();
                    field.forward(&[q], &mut c);
                    c.output()[0]
                };
                let numeric = (phi(h) - phi(-h)) / (2.0 * h);
                assert_close(
                    &format!("{hidden:?} point {p} axis {k}"),
                    ctx.gradient[p][k],
                    numeric,
                    1e-6,
                    1e-5,
                );
            }
            assert_eq!(ctx.output.len(), x.len() * no);
        }
    }
}

/// The backward pass of the analytic gradient: the parameter gradient of
/// L = ⟨D_out, outputs⟩ + ⟨D_∇, ∇φ⟩ against central differences over every
/// MLP parameter and every table entry.
#[test]
fn analytic_sdf_gradient_backward_matches_finite_differences() {
    for (hidden, interpolation) in [
        (vec![8], Interpolation::Smoothstep),
        (vec![6, 5], Interpolation::Linear),
    ] {
        let mut field = analytic_test_field(hidden.clone(), interpolation);
        let mut r = rng(13);
        let n = 10;
        let x = rand_points(n, -0.9, 0.9, &mut r);
        let no = field.n_output();
        let d_out = rand_vec(n * no, -1.0, 1.0, &mut r);
        let d_grad = rand_points(n, -1.0, 1.0, &mut r);
        let loss = |field: &SdfField<f64>| {
            let mut c = GradientContext::new();
            field.forward_with_gradient(&x, &mut c);
            dot(&c.output, &d_out) + (0..n).map(|p| dot(&c.gradient[p], &d_grad[p])).sum::<f64>()
        };
        let mut ctx = GradientContext::new();
        field.forward_with_gradient(&x, &mut ctx);
        let mut grads = field.new_grads();
        field.backward_with_gradient(&ctx, &d_out, &d_grad, &mut grads);
        let h = 1e-6;
        for i in 0..field.field.mlp.params.len() {
            let numeric = central_difference(&mut field, |f| &mut f.field.mlp.params[i], loss, h);
            assert_close(
                &format!("{hidden:?} MLP parameter {i}"),
                grads.mlp[i],
                numeric,
                1e-6,
                1e-5,
            );
        }
        for i in 0..field.field.grid.params.len() {
            let numeric = central_difference(&mut field, |f| &mut f.field.grid.params[i], loss, h);
            assert_close(
                &format!("{hidden:?} table entry {i}"),
                grads.grid[i],
                numeric,
                1e-6,
                1e-5,
            );
        }
        assert!(grads.mlp.iter().any(|g| g.abs() > 1e-3));
        assert!(grads.grid.iter().any(|g| g.abs() > 1e-3));
    }
}

/// The batched analytic gradient (chunks of rows, `dense` kernels) agrees
/// with the point-by-point reference: outputs, ∇φ and every parameter's
/// gradient, over more points than one chunk holds.
#[test]
fn batched_analytic_sdf_gradient_matches_the_reference() {
    for (hidden, interpolation) in [
        (vec![8], Interpolation::Smoothstep),
        (vec![6, 5], Interpolation::Linear),
    ] {
        let mut field = analytic_test_field(hidden.clone(), interpolation);
        field.field.active_levels = 3;
        let mut r = rng(14);
        let n = CHUNK_ROWS * 2 + 37;
        let x = rand_points(n, -1.1, 1.1, &mut r);
        let no = field.n_output();
        let d_out = rand_vec(n * no, -1.0, 1.0, &mut r);
        let d_grad = rand_points(n, -1.0, 1.0, &mut r);
        let mut reference = GradientContext::new();
        field.forward_with_gradient(&x, &mut reference);
        // A context used before on a larger batch: its kept buffers must
        // not leak into the next pass.
        let mut batched = BatchedGradientContext::new();
        let earlier = rand_points(n + 300, -1.1, 1.1, &mut r);
        field.forward_with_gradient_batched(&earlier, &mut batched);
        let d_earlier = (
            rand_vec((n + 300) * no, -1.0, 1.0, &mut r),
            rand_points(n + 300, -1.0, 1.0, &mut r),
        );
        let mut g_earlier = field.new_grads();
        let (d_o, d_g) = (&d_earlier.0, &d_earlier.1);
        field.backward_with_gradient_batched(&mut batched, d_o, d_g, &mut g_earlier);
        field.forward_with_gradient_batched(&x, &mut batched);
        for (a, b) in batched.output().iter().zip(&reference.output) {
            assert_close("outputs", *a, *b, 1e-12, 1e-12);
        }
        for (a, b) in batched.gradient.iter().zip(&reference.gradient) {
            for k in 0..3 {
                assert_close(&format!("{hidden:?} gradient"), a[k], b[k], 1e-12, 1e-10);
            }
        }
        let mut g_ref = field.new_grads();
        field.backward_with_gradient(&reference, &d_out, &d_grad, &mut g_ref);
        let mut g_bat = field.new_grads();
        field.backward_with_gradient_batched(&mut batched, &d_out, &d_grad, &mut g_bat);
        for (i, (a, b)) in g_bat.mlp.iter().zip(&g_ref.mlp).enumerate() {
            assert_close(
                &format!("{hidden:?} MLP parameter {i}"),
                *a,
                *b,
                1e-10,
                1e-10,
            );
        }
        for (i, (a, b)) in g_bat.grid.iter().zip(&g_ref.grid).enumerate() {
            assert_close(&format!("{hidden:?} table entry {i}"), *a, *b, 1e-10, 1e-10);
        }
        assert!(g_bat.grid.iter().any(|g| g.abs() > 1e-3));
    }
}
