//! The binary-metallic prior: its value against the material field's own
//! metallic values, the direction it pushes them, and its gradient (the
//! metallic row of the network's last layer alone) against central finite
//! differences in f64.

mod common;

use wildlight_fields::{FieldContext, FieldGrads};
use wildlight_material::{METALLIC, PARAM_COUNT};
use wildlight_train::metallic_prior::BinaryMetallic;
use wildlight_train::model::Model;

use common::{CENTRES as POINTS, tiny_material_model};

const WEIGHT: f64 = 0.7;

/// λ · L_binary and (when asked) its gradient.
fn loss(model: &Model<f64>, grads: Option<&mut FieldGrads<f64>>) -> f64 {
    let mut term = BinaryMetallic::<f64>::default();
    let mut scratch = model.material.new_grads();
    let g = grads.unwrap_or(&mut scratch);
    WEIGHT * term.forward_backward(&model.material, &POINTS, WEIGHT, g)
}

fn metallic(model: &Model<f64>) -> Vec<f64> {
    let mut ctx = FieldContext::default();
    model.material.forward(&POINTS, &[], &mut ctx);
    ctx.output()
        .chunks_exact(PARAM_COUNT)
        .map(|theta| theta[METALLIC])
        .collect()
}

#[test]
fn binary_metallic_is_the_mean_of_m_times_one_minus_m() {
    let model = tiny_material_model();
    let m = metallic(&model);
    let by_hand = m.iter().map(|v| v * (1.0 - v)).sum::<f64>() / m.len() as f64;
    let value = loss(&model, None) / WEIGHT;
    assert!(value > 0.01, "{value}");
    assert!((value - by_hand).abs() < 1e-14, "{value} vs {by_hand}");
    assert!(value <= 0.25, "m (1 − m) is at most 1/4: {value}");
}

#[test]
fn binary_metallic_pushes_the_points_to_an_end() {
    let mut model = tiny_material_model();
    let before = metallic(&model);
    // Plain gradient steps on the prior alone.
    for _ in 0..200 {
        let mut g = model.material.new_grads();
        loss(&model, Some(&mut g));
        for (p, d) in model.material.mlp.params.iter_mut().zip(&g.mlp) {
            *p -= 0.5 * d;
        }
    }
    let after = metallic(&model);
    let mean = |m: &[f64]| m.iter().map(|v| v * (1.0 - v)).sum::<f64>() / m.len() as f64;
    assert!(
        mean(&after) < 0.5 * mean(&before),
        "{before:?} -> {after:?}"
    );
}

/// The push moves only the metallic row of the network's last layer
/// (weights and bias), each entry by its exact gradient (central
/// differences), and nothing of the hash table, the hidden layers or the
/// other rows; it adds to what `grads` already holds.
#[test]
fn the_push_moves_only_the_metallic_readout() {
    let mut model = tiny_material_model();
    let mut g = model.material.new_grads();
    g.mlp.fill(0.5);
    loss(&model, Some(&mut g));
    assert!(g.grid.iter().all(|d| *d == 0.0));
    let last = *model.material.mlp.layers().last().unwrap();
    let row = last.weight_offset + METALLIC * last.n_in;
    let kept: Vec<usize> = (row..row + last.n_in)
        .chain([last.bias_offset + METALLIC])
        .collect();
    let h = 1e-6;
    for (i, d) in g.mlp.iter().enumerate() {
        if !kept.contains(&i) {
            assert_eq!(*d, 0.5, "entry {i}");
            continue;
        }
        let v = model.material.mlp.params[i];
        model.material.mlp.params[i] = v + h;
        let up = loss(&model, None);
        model.material.mlp.params[i] = v - h;
        let down = loss(&model, None);
        model.material.mlp.params[i] = v;
        let numeric = (up - down) / (2.0 * h);
        let analytic = d - 0.5;
        let scale = analytic.abs().max(numeric.abs()).max(1e-6);
        assert!(
            (analytic - numeric).abs() / scale < 1e-4,
            "entry {i}: {analytic:e} vs {numeric:e}"
        );
    }
    assert!(kept.iter().any(|&i| g.mlp[i] != 0.5));
}
