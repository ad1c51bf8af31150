//! The normal smoothness prior: its value against a hand computation from
//! the SDF's finite-difference normals, and its parameter gradient against
//! central finite differences in f64.

mod common;

use wildlight_fields::{FdScheme, NormalContext};
use wildlight_train::model::Model;
use wildlight_train::normal_smoothness::{HUBER_ETA, NormalSmoothness, pseudo_huber};

fn tiny_sdf_model() -> Model<f64> {
    let mut model = common::tiny_model(5);
    // Bumps on the initial sphere, so the normals turn between the points.
    for (i, v) in model.sdf.field.grid.params.iter_mut().enumerate() {
        *v = 0.3 * (i as f64 * 0.61).sin();
    }
    model
}

const CENTRES: [[f64; 3]; 4] = [
    [0.3, -0.2, 0.3],
    [-0.35, 0.25, 0.12],
    [0.42, 0.31, -0.27],
    [-0.1, -0.44, -0.25],
];
const OFFSETS: [[f64; 3]; 4] = [
    [0.04, -0.03, 0.02],
    [-0.05, 0.02, 0.06],
    [0.03, 0.05, -0.04],
    [0.06, -0.02, -0.03],
];
const STEP: f64 = 0.02;
const WEIGHT: f64 = 0.7;

/// λ · L_normal and (when asked) its gradient.
fn loss(model: &Model<f64>, grads: Option<&mut wildlight_fields::FieldGrads<f64>>) -> f64 {
    let mut term = NormalSmoothness::<f64>::default();
    let mut scratch = model.sdf.new_grads();
    let g = grads.unwrap_or(&mut scratch);
    WEIGHT * term.forward_backward(&model.sdf, &CENTRES, &OFFSETS, STEP, WEIGHT, g)
}

fn unit(g: [f64; 3]) -> [f64; 3] {
    let l = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    g.map(|v| v / l)
}

#[test]
fn normal_smoothness_is_the_mean_pseudo_huber_difference_of_the_normals() {
    let model = tiny_sdf_model();
    let mut ctx = NormalContext::new();
    let mut by_hand = 0.0;
    for (c, e) in CENTRES.iter().zip(&OFFSETS) {
        let far = [c[0] + e[0], c[1] + e[1], c[2] + e[2]];
        model
            .sdf
            .forward_with_normals(&[*c, far], FdScheme::Tetrahedral, STEP, &mut ctx);
        let (a, b) = (unit(ctx.gradient[0]), unit(ctx.gradient[1]));
        let d2: f64 = (0..3).map(|k| (a[k] - b[k]).powi(2)).sum();
        by_hand += (d2 + HUBER_ETA * HUBER_ETA).sqrt() - HUBER_ETA;
    }
    by_hand /= CENTRES.len() as f64;
    let value = loss(&model, None) / WEIGHT;
    assert!(
        value > 1e-2,
        "the normals must turn across the pairs: {value}"
    );
    assert!((value - by_hand).abs() < 1e-12, "{value} vs {by_hand}");

    // No offset, no penalty and no gradient.
    let mut term = NormalSmoothness::<f64>::default();
    let mut g = model.sdf.new_grads();
    let zero = term.forward_backward(&model.sdf, &CENTRES, &[[0.0; 3]; 4], STEP, 1.0, &mut g);
    assert_eq!(zero, 0.0);
    assert!(g.grid.iter().chain(&g.mlp).all(|v| *v == 0.0));
}

#[test]
fn pseudo_huber_is_quadratic_below_eta_and_linear_above() {
    let (small, _) = pseudo_huber([1e-4f64, 0.0, 0.0]);
    let quadratic = 1e-8 / (2.0 * HUBER_ETA);
    assert!((small - quadratic).abs() < 1e-3 * quadratic, "{small}");
    let (large, d) = pseudo_huber([0.0, 1.0f64, 0.0]);
    assert!((large - (1.0 - HUBER_ETA)).abs() < 1e-4, "{large}");
    assert!((d[1] - 1.0).abs() < 1e-4 && d[0] == 0.0, "{d:?}");
}

#[test]
fn normal_smoothness_gradient_matches_finite_differences() {
    let mut model = tiny_sdf_model();
    let mut grads = model.sdf.new_grads();
    loss(&model, Some(&mut grads));
    let probed =
        common::check_field_gradient(&mut model, |m| &mut m.sdf.field, &grads, |m| loss(m, None));
    assert!(probed >= 10, "only {probed} parameters had a gradient");
}
