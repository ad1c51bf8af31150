//! The binary-metallic prior: its value against the material field's own
//! metallic values, the direction it pushes them, and its parameter
//! gradient against central finite differences in f64.

mod common;

use wildlight_fields::FieldContext;
use wildlight_material::{METALLIC, PARAM_COUNT};
use wildlight_train::metallic_prior::BinaryMetallic;
use wildlight_train::model::Model;

fn tiny_material_model() -> Model<f64> {
    let mut model = common::tiny_model(13);
    // Tables away from their tiny initial values, so Θ varies in space.
    for (i, v) in model.material.grid.params.iter_mut().enumerate() {
        *v = 0.5 * (i as f64 * 0.37).cos();
    }
    model
}

const POINTS: [[f64; 3]; 5] = [
    [0.1, -0.2, 0.3],
    [-0.35, 0.05, 0.12],
    [0.42, 0.31, -0.27],
    [-0.1, -0.44, -0.05],
    [0.2, 0.25, 0.33],
];
const WEIGHT: f64 = 0.7;

fn loss(model: &Model<f64>, grads: Option<&mut wildlight_fields::FieldGrads<f64>>) -> f64 {
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
fn binary_metallic_pushes_each_point_to_the_nearer_end() {
    let mut model = tiny_material_model();
    let before = metallic(&model);
    // Plain gradient steps on the prior alone.
    for _ in 0..200 {
        let mut g = model.material.new_grads();
        loss(&model, Some(&mut g));
        for (p, d) in model.material.grid.params.iter_mut().zip(&g.grid) {
            *p -= 0.5 * d;
        }
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

#[test]
fn binary_metallic_gradient_matches_finite_differences() {
    let mut model = tiny_material_model();
    let mut grads = model.material.new_grads();
    loss(&model, Some(&mut grads));
    let probed =
        common::check_field_gradient(&mut model, |m| &mut m.material, &grads, |m| loss(m, None));
    assert!(probed >= 10, "only {probed} parameters had a gradient");
}
