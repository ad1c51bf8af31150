//! The batched field pass (level-major encoding over the whole batch,
//! column-major chunk inputs, parallel groups of chunks) against simple
//! references: the row-major encoder + MLP, and the same batch cut in pieces.

use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64Mcg;
use wildlight_fields::*;

fn config() -> NeuralFieldConfig {
    NeuralFieldConfig {
        grid: HashGridConfig {
            n_levels: 5,
            n_features: 2,
            log2_table_size: 9,
            base_resolution: 3,
            finest_resolution: 40,
            init_range: 0.5,
            interpolation: Default::default(),
        },
        bound: 1.2,
        include_position: true,
        n_extra: 2,
        hidden: vec![8],
        hidden_activation: Activation::Softplus { beta: 4.0 },
        n_output: 3,
        output_activation: Activation::None,
    }
}

fn inputs(n: usize, seed: u64) -> (Vec<[f64; 3]>, Vec<f64>) {
    let mut r = Pcg64Mcg::seed_from_u64(seed);
    // Some points outside the encoded cube, to exercise the clamping.
    let x = (0..n)
        .map(|_| {
            [
                r.random_range(-1.3..1.3),
                r.random_range(-1.3..1.3),
                r.random_range(-1.3..1.3),
            ]
        })
        .collect();
    let extra = (0..n * 2).map(|_| r.random_range(-1.0..1.0)).collect();
    (x, extra)
}

/// Row-major reference: `[x | extra | encoding]` rows through [`Mlp::forward`].
fn reference_forward(field: &NeuralField<f64>, x: &[[f64; 3]], extra: &[f64]) -> Vec<f64> {
    let n_in = field.mlp.config().n_input;
    let enc_col = field.encoding_column();
    let b = field.config().bound as f64;
    let unit: Vec<[f64; 3]> = x.iter().map(|p| p.map(|v| (v + b) / (2.0 * b))).collect();
    let mut rows = vec![0.0; x.len() * n_in];
    field
        .grid
        .encode(&unit, &mut rows, n_in, enc_col, field.active_levels);
    for (p, row) in rows.chunks_exact_mut(n_in).enumerate() {
        row[..3].copy_from_slice(&x[p]);
        row[3..5].copy_from_slice(&extra[p * 2..p * 2 + 2]);
    }
    let mut ctx = MlpContext::new();
    field.mlp.forward(&rows, &mut ctx);
    ctx.output().to_vec()
}

#[test]
fn batched_forward_matches_row_major_reference() {
    // More points than one encoding task (4096), a partial last chunk.
    let n = 2 * 4096 + CHUNK_ROWS + 37;
    let (x, extra) = inputs(n, 1);
    let mut field = NeuralField::<f64>::new(&config(), 3).unwrap();
    for active in [5, 2] {
        field.active_levels = active;
        let mut ctx = FieldContext::new();
        field.forward(&x, &extra, &mut ctx);
        let want = reference_forward(&field, &x, &extra);
        assert_eq!(ctx.output().len(), want.len());
        for (i, (a, b)) in ctx.output().iter().zip(&want).enumerate() {
            assert!(
                (a - b).abs() <= 1e-12 * (1.0 + b.abs()),
                "active {active}, value {i}: {a} vs {b}"
            );
        }
    }
}

#[test]
fn batched_backward_equals_sum_over_pieces() {
    let n = 4096 + 3 * CHUNK_ROWS + 11;
    let (x, extra) = inputs(n, 2);
    let field = NeuralField::<f64>::new(&config(), 4).unwrap();
    let mut r = Pcg64Mcg::seed_from_u64(5);
    let d_out: Vec<f64> = (0..n * 3).map(|_| r.random_range(-1.0..1.0)).collect();
    let run = |lo: usize, hi: usize, grads: &mut FieldGrads<f64>| {
        let mut ctx = FieldContext::new();
        field.forward(&x[lo..hi], &extra[lo * 2..hi * 2], &mut ctx);
        let mut d_extra = vec![0.0; (hi - lo) * 2];
        let mut d_x = vec![[0.0; 3]; hi - lo];
        field.backward(
            &mut ctx,
            &d_out[lo * 3..hi * 3],
            grads,
            Some(&mut d_extra),
            Some(&mut d_x),
        );
        (d_extra, d_x)
    };
    let mut whole = field.new_grads();
    let (de_whole, dx_whole) = run(0, n, &mut whole);
    let mut pieces = field.new_grads();
    let mut de_pieces = Vec::new();
    let mut dx_pieces = Vec::new();
    for (lo, hi) in [(0, 1), (1, CHUNK_ROWS + 5), (CHUNK_ROWS + 5, n)] {
        let (de, dx) = run(lo, hi, &mut pieces);
        de_pieces.extend(de);
        dx_pieces.extend(dx);
    }
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-10 * (1.0 + b.abs());
    for (i, (a, b)) in whole.grid.iter().zip(&pieces.grid).enumerate() {
        assert!(close(*a, *b), "table gradient {i}: {a} vs {b}");
    }
    for (i, (a, b)) in whole.mlp.iter().zip(&pieces.mlp).enumerate() {
        assert!(close(*a, *b), "mlp gradient {i}: {a} vs {b}");
    }
    assert!(whole.grid.iter().any(|g| g.abs() > 1e-3));
    for (i, (a, b)) in de_whole.iter().zip(&de_pieces).enumerate() {
        assert!(close(*a, *b), "d_extra {i}: {a} vs {b}");
    }
    for (p, (a, b)) in dx_whole.iter().zip(&dx_pieces).enumerate() {
        for k in 0..3 {
            assert!(close(a[k], b[k]), "d_x[{p}][{k}]: {} vs {}", a[k], b[k]);
        }
    }
}
