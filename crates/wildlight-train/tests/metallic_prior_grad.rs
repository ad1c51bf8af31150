//! The binary-metallic prior: its value against the material field's own
//! metallic values, the direction it pushes them, and its parameter
//! gradient against central finite differences in f64.

mod common;

use wildlight_fields::FieldContext;
use wildlight_material::{METALLIC, PARAM_COUNT};
use wildlight_train::metallic_prior::BinaryMetallic;
use wildlight_train::model::Model;

use common::{CENTRES as POINTS, tiny_material_model};

const WEIGHT: f64 = 0.7;

fn loss(model: &Model<f64>, grads: Option<&mut wildlight_fields::FieldGrads<f64>>) -> f64 {
    let mut term = BinaryMetallic::<f64>::default();
    let mut scratch = model.material.new_grads();
    let g = grads.unwrap_or(&mut scratch);
    WEIGHT * term.forward_backward(&model.material, &POINTS, WEIGHT, 1.0, None, g)
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
    common::check_material_prior_gradient(loss);
}

#[test]
fn binary_metallic_leaves_out_points_above_its_ceiling() {
    let model = tiny_material_model();
    let m = metallic(&model);
    let mut sorted = m.clone();
    sorted.sort_by(f64::total_cmp);
    // Halfway between two neighbouring values: about half the points above.
    let k = sorted.len() / 2;
    let ceiling = 0.5 * (sorted[k - 1] + sorted[k]);
    let by_hand = m
        .iter()
        .filter(|v| **v <= ceiling)
        .map(|v| v * (1.0 - v))
        .sum::<f64>()
        / m.len() as f64;
    let mut term = BinaryMetallic::<f64>::default();
    let mut g = model.material.new_grads();
    let value = term.forward_backward(&model.material, &POINTS, WEIGHT, ceiling, None, &mut g);
    assert!(
        by_hand > 0.0 && (value - by_hand).abs() < 1e-14,
        "{value} vs {by_hand}"
    );
    let full = term.forward_backward(
        &model.material,
        &POINTS,
        WEIGHT,
        1.0,
        None,
        &mut model.material.new_grads(),
    );
    assert!(value < full, "{value} vs {full}");
    // Below every point: no value and no gradient.
    let mut g = model.material.new_grads();
    let none = term.forward_backward(
        &model.material,
        &POINTS,
        WEIGHT,
        sorted[0] - 1e-9,
        None,
        &mut g,
    );
    assert_eq!(none, 0.0);
    assert!(g.grid.iter().chain(&g.mlp).all(|d| *d == 0.0));
}

/// A local push gives exactly the full gradient to the hash entries from
/// the given index on, and nothing to the entries before it or to the
/// network; it adds to what `grads` already holds.
#[test]
fn a_local_push_moves_only_the_fine_levels() {
    let model = tiny_material_model();
    let mut term = BinaryMetallic::<f64>::default();
    let mut full = model.material.new_grads();
    let value = term.forward_backward(&model.material, &POINTS, WEIGHT, 1.0, None, &mut full);
    let levels = model.material.grid.levels();
    let first = levels[levels.len() / 2].param_offset;
    assert!(first > 0 && first < full.grid.len());
    let mut local = model.material.new_grads();
    local.grid.fill(0.5);
    let local_value = term.forward_backward(
        &model.material,
        &POINTS,
        WEIGHT,
        1.0,
        Some(first),
        &mut local,
    );
    assert_eq!(value, local_value);
    assert!(local.grid[..first].iter().all(|d| *d == 0.5));
    assert!(local.mlp.iter().all(|d| *d == 0.0));
    let moved = full.grid[first..]
        .iter()
        .zip(&local.grid[first..])
        .filter(|(f, l)| {
            assert_eq!(**l, 0.5 + **f);
            **f != 0.0
        })
        .count();
    assert!(moved > 0, "no fine entry moved");
}
