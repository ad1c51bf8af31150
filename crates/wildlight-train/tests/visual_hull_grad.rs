//! The visual-hull prior's penalty: its value against a hand computation
//! from the SDF, its parameter gradient against central finite differences
//! in f64, and the direction it moves the SDF.

mod common;

use wildlight_fields::FieldContext;
use wildlight_train::model::Model;
use wildlight_train::visual_hull::HullPenalty;

/// Points of the tiny model's SDF: three of them inside (φ < 0,
/// penalised), two outside (φ > δ, free).
const POINTS: [[f64; 3]; 5] = [
    [0.1, -0.2, 0.15],
    [-0.25, 0.05, 0.12],
    [0.05, 0.3, -0.2],
    [0.0, 0.0, 0.48],
    [0.9, 0.1, -0.2],
];
const MARGIN: f64 = 0.05;
const WEIGHT: f64 = 0.7;

fn model() -> Model<f64> {
    let mut model = common::tiny_model(9);
    // Some structure in the table, so the entries' gradients differ.
    for (i, v) in model.sdf.field.grid.params.iter_mut().enumerate() {
        *v = 0.05 * (i as f64 * 0.37).sin();
    }
    model
}

fn loss(model: &Model<f64>, grads: Option<&mut wildlight_fields::FieldGrads<f64>>) -> f64 {
    let mut term = HullPenalty::<f64>::default();
    let mut scratch = model.sdf.new_grads();
    let g = grads.unwrap_or(&mut scratch);
    WEIGHT * term.forward_backward(&model.sdf, &POINTS, MARGIN, WEIGHT, g)
}

fn sdf(model: &Model<f64>) -> Vec<f64> {
    let mut ctx = FieldContext::default();
    model.sdf.forward(&POINTS, &mut ctx);
    ctx.output()
        .chunks_exact(model.sdf.n_output())
        .map(|row| row[0])
        .collect()
}

#[test]
fn the_penalty_is_the_mean_shortfall_below_the_margin() {
    let model = model();
    let phi = sdf(&model);
    // both sides of the kink are probed: penalised and free points
    assert!(phi.iter().filter(|v| **v < 0.0).count() >= 3, "{phi:?}");
    assert!(phi.iter().any(|v| *v > MARGIN), "{phi:?}");
    let by_hand = phi.iter().map(|v| (MARGIN - v).max(0.0)).sum::<f64>() / phi.len() as f64;
    let value = loss(&model, None) / WEIGHT;
    assert!(value > 0.05, "{value}");
    assert!((value - by_hand).abs() < 1e-14, "{value} vs {by_hand}");
}

#[test]
fn the_penalty_gradient_matches_finite_differences() {
    let mut model = model();
    let mut grads = model.sdf.new_grads();
    loss(&model, Some(&mut grads));
    let probed =
        common::check_field_gradient(&mut model, |m| &mut m.sdf.field, &grads, |m| loss(m, None));
    assert!(probed >= 10, "only {probed} parameters had a gradient");
}

#[test]
fn descent_on_the_penalty_raises_the_sdf_at_the_points() {
    let mut model = model();
    let before = sdf(&model);
    for _ in 0..100 {
        let mut g = model.sdf.new_grads();
        loss(&model, Some(&mut g));
        for (p, d) in model.sdf.field.grid.params.iter_mut().zip(&g.grid) {
            *p -= 0.5 * d;
        }
        for (p, d) in model.sdf.field.mlp.params.iter_mut().zip(&g.mlp) {
            *p -= 0.5 * d;
        }
    }
    let after = sdf(&model);
    let shortfall = |phi: &[f64]| phi.iter().map(|v| (MARGIN - v).max(0.0)).sum::<f64>();
    assert!(
        shortfall(&after) < 0.5 * shortfall(&before),
        "{before:?} -> {after:?}"
    );
}
