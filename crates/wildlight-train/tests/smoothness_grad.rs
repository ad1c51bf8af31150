//! The material smoothness prior: its value, its invariance to the flash
//! scale, and its parameter gradient against central finite differences in
//! f64.

mod common;

use wildlight_fields::{FieldContext, FieldGrads};
use wildlight_train::model::Model;
use wildlight_train::smoothness::MaterialSmoothness;

use common::{CENTRES, tiny_material_model};

const OFFSETS: [[f64; 3]; 4] = [
    [0.04, -0.03, 0.02],
    [-0.05, 0.02, 0.06],
    [0.03, 0.05, -0.04],
    [0.06, -0.02, -0.03],
];
const WEIGHT: f64 = 0.7;

/// λ · L_smooth and (when asked) its gradient.
fn loss(model: &Model<f64>, grads: Option<&mut FieldGrads<f64>>) -> f64 {
    let mut term = MaterialSmoothness::<f64>::default();
    let mut scratch = model.material.new_grads();
    let g = grads.unwrap_or(&mut scratch);
    WEIGHT * term.forward_backward(&model.material, &CENTRES, &OFFSETS, WEIGHT, g)
}

#[test]
fn smoothness_value_is_the_mean_l1_difference_of_theta() {
    let model = tiny_material_model();
    let mut ctx = FieldContext::default();
    let mut by_hand = 0.0;
    for (c, e) in CENTRES.iter().zip(&OFFSETS) {
        let far = [c[0] + e[0], c[1] + e[1], c[2] + e[2]];
        model.material.forward(&[*c, far], &[], &mut ctx);
        let (a, b) = ctx.output().split_at(9);
        for (i, (x, y)) in a.iter().zip(b).enumerate() {
            // relative for base colour (0–2), dielectric (7) and clearcoat (8)
            by_hand += if i <= 2 || i == 7 || i == 8 {
                (x - y).abs() / (x + y + 0.01)
            } else {
                (x - y).abs()
            };
        }
    }
    by_hand /= CENTRES.len() as f64;
    let value = loss(&model, None) / WEIGHT;
    assert!(value > 1e-3, "Θ must differ across the pairs: {value}");
    assert!((value - by_hand).abs() < 1e-12, "{value} vs {by_hand}");

    // No offset, no penalty and no gradient.
    let mut term = MaterialSmoothness::<f64>::default();
    let mut g = model.material.new_grads();
    let zero = term.forward_backward(&model.material, &CENTRES, &[[0.0; 3]; 4], 1.0, &mut g);
    assert_eq!(zero, 0.0);
    assert!(g.grid.iter().chain(&g.mlp).all(|v| *v == 0.0));
}

#[test]
fn flash_scaling_parameters_are_compared_relatively() {
    use wildlight_material::{BASE_COLOR, CLEARCOAT, DIELECTRIC, ROUGHNESS};
    use wildlight_train::smoothness::pair_difference;
    for i in [BASE_COLOR, BASE_COLOR + 2, DIELECTRIC, CLEARCOAT] {
        let (d1, ..) = pair_difference(i, 0.6f64, 0.3);
        let (d2, ..) = pair_difference(i, 0.06f64, 0.03);
        assert!((d1 - 0.3 / 0.91).abs() < 1e-12, "{d1}");
        assert!((d2 - 0.03 / 0.1).abs() < 1e-12, "{d2}");
    }
    let (d1, ..) = pair_difference(ROUGHNESS, 0.6f64, 0.3);
    let (d2, ..) = pair_difference(ROUGHNESS, 0.06f64, 0.03);
    assert!((d1 - 0.3).abs() < 1e-12 && (d2 - 0.03).abs() < 1e-12);
}

#[test]
fn smoothness_gradient_matches_finite_differences() {
    common::check_material_prior_gradient(loss);
}
