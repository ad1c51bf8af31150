//! The binary-metallic prior: its value against the material field's own
//! metallic values, the direction it pushes them, and its parameter
//! gradient against central finite differences in f64.

mod common;

use wildlight_material::{METALLIC, PARAM_COUNT};
use wildlight_train::material_field::{MaterialContext, MaterialGrads};
use wildlight_train::metallic_prior::{BinaryMetallic, MetalAnchor, PushScope};
use wildlight_train::model::Model;

use common::{CENTRES as POINTS, tiny_material_model, tiny_model_with_a_metallic_field};

const WEIGHT: f64 = 0.7;

fn loss(model: &Model<f64>, grads: Option<&mut MaterialGrads<f64>>) -> f64 {
    loss_in(model, PushScope::Everywhere, grads)
}

fn loss_in(model: &Model<f64>, scope: PushScope, grads: Option<&mut MaterialGrads<f64>>) -> f64 {
    let mut term = BinaryMetallic::<f64>::default();
    let mut scratch = model.material.new_grads();
    let g = grads.unwrap_or(&mut scratch);
    WEIGHT * term.forward_backward(&model.material, &POINTS, WEIGHT, 1.0, scope, g)
}

fn metallic(model: &Model<f64>) -> Vec<f64> {
    let mut ctx = MaterialContext::default();
    model.material.forward(&POINTS, &mut ctx);
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
        let (f, g) = (&mut model.material.params, &g.params);
        for (p, d) in f.grid.params.iter_mut().zip(&g.grid) {
            *p -= 0.5 * d;
        }
        for (p, d) in f.mlp.params.iter_mut().zip(&g.mlp) {
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
    let value = term.forward_backward(
        &model.material,
        &POINTS,
        WEIGHT,
        ceiling,
        PushScope::Everywhere,
        &mut g,
    );
    assert!(
        by_hand > 0.0 && (value - by_hand).abs() < 1e-14,
        "{value} vs {by_hand}"
    );
    let full = term.forward_backward(
        &model.material,
        &POINTS,
        WEIGHT,
        1.0,
        PushScope::Everywhere,
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
        PushScope::Everywhere,
        &mut g,
    );
    assert_eq!(none, 0.0);
    assert!(g.params.grid.iter().chain(&g.params.mlp).all(|d| *d == 0.0));
}

/// A local push gives exactly the full gradient to the hash entries from
/// the given index on, and nothing to the entries before it or to the
/// network; it adds to what `grads` already holds.
#[test]
fn a_local_push_moves_only_the_fine_levels() {
    let model = tiny_material_model();
    let mut term = BinaryMetallic::<f64>::default();
    let mut full = model.material.new_grads();
    let value = term.forward_backward(
        &model.material,
        &POINTS,
        WEIGHT,
        1.0,
        PushScope::Everywhere,
        &mut full,
    );
    let levels = model.material.params.grid.levels();
    let first = levels[levels.len() / 2].param_offset;
    let full = full.params;
    assert!(first > 0 && first < full.grid.len());
    let mut local = model.material.new_grads();
    local.params.grid.fill(0.5);
    let local_value = term.forward_backward(
        &model.material,
        &POINTS,
        WEIGHT,
        1.0,
        PushScope::TableFrom(first),
        &mut local,
    );
    let local = local.params;
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

/// A readout push gives exactly the full gradient to the metallic row of
/// the network's last layer (weights and bias), and nothing to the hash
/// table, the hidden layers or the other rows.
#[test]
fn a_readout_push_moves_only_the_metallic_row() {
    let model = tiny_material_model();
    let mut full = model.material.new_grads();
    let value = loss_in(&model, PushScope::Everywhere, Some(&mut full));
    let mut readout = model.material.new_grads();
    let readout_value = loss_in(&model, PushScope::MetallicReadout, Some(&mut readout));
    assert_eq!(value, readout_value);
    let (full, readout) = (full.params, readout.params);
    assert!(readout.grid.iter().all(|d| *d == 0.0));
    let last = *model.material.params.mlp.layers().last().unwrap();
    let row = last.weight_offset + METALLIC * last.n_in;
    let kept: Vec<usize> = (row..row + last.n_in)
        .chain([last.bias_offset + METALLIC])
        .collect();
    for (i, (f, r)) in full.mlp.iter().zip(&readout.mlp).enumerate() {
        if kept.contains(&i) {
            assert_eq!(f, r, "entry {i}");
        } else {
            assert_eq!(*r, 0.0, "entry {i}");
        }
    }
    assert!(kept.iter().any(|&i| readout.mlp[i] != 0.0));
}

/// With metallic from a field of its own, the prior moves that field and
/// nothing of the material field (base colour, roughness and the rest),
/// and its gradient matches central differences.
#[test]
fn with_a_metallic_field_the_prior_moves_only_that_field() {
    let model = tiny_model_with_a_metallic_field();
    let mut g = model.material.new_grads();
    let value = loss(&model, Some(&mut g));
    assert!(value > 0.0);
    let (params, own) = (&g.params, g.metallic.as_ref().unwrap());
    assert!(params.grid.iter().chain(&params.mlp).all(|d| *d == 0.0));
    assert!(own.grid.iter().any(|d| *d != 0.0) && own.mlp.iter().any(|d| *d != 0.0));
    // Its value is the mean m (1 − m) of the metallic field's output.
    let m = metallic(&model);
    let by_hand = m.iter().map(|v| v * (1.0 - v)).sum::<f64>() / m.len() as f64;
    assert!(
        (value / WEIGHT - by_hand).abs() < 1e-14,
        "{value} vs {by_hand}"
    );
    common::check_material_prior_gradient_on(tiny_model_with_a_metallic_field(), loss);
}

/// The metal anchor: zero where nothing moved, the squared change of base
/// colour and roughness at the snapshot's metals (and nowhere else), and a
/// gradient that matches central differences.
#[test]
fn the_metal_anchor_holds_the_metals_base_colour_and_roughness() {
    let snapshot = metals_and_dielectrics();
    let m = metallic(&snapshot);
    assert!(
        m.iter().any(|v| *v > 0.5) && m.iter().any(|v| *v <= 0.5),
        "{m:?}"
    );
    let mut anchor = MetalAnchor::<f64>::default();
    let mut g = snapshot.material.new_grads();
    let still =
        anchor.forward_backward(&snapshot.material, &snapshot.material, &POINTS, 2.0, &mut g);
    assert_eq!(still, 0.0);
    assert!(g.params.grid.iter().chain(&g.params.mlp).all(|d| *d == 0.0));

    let mut moved = metals_and_dielectrics();
    for (i, v) in moved.material.params.mlp.params.iter_mut().enumerate() {
        *v += 0.05 * (i as f64 * 0.37).sin();
    }
    let theta = |model: &Model<f64>| {
        let mut ctx = MaterialContext::default();
        model.material.forward(&POINTS, &mut ctx);
        ctx.output().to_vec()
    };
    let (now, held) = (theta(&moved), theta(&snapshot));
    let by_hand = now
        .chunks_exact(PARAM_COUNT)
        .zip(held.chunks_exact(PARAM_COUNT))
        .filter(|(_, h)| h[METALLIC] > 0.5)
        .map(|(t, h)| (0..4).map(|i| (t[i] - h[i]).powi(2)).sum::<f64>())
        .sum::<f64>()
        / POINTS.len() as f64;
    let value = anchor.forward_backward(
        &moved.material,
        &snapshot.material,
        &POINTS,
        2.0,
        &mut moved.material.new_grads(),
    );
    assert!(
        by_hand > 1e-6 && (value - by_hand).abs() < 1e-14,
        "{value} vs {by_hand}"
    );

    fn anchor_loss(model: &Model<f64>, grads: Option<&mut MaterialGrads<f64>>) -> f64 {
        let snapshot = metals_and_dielectrics();
        let mut scratch = model.material.new_grads();
        let g = grads.unwrap_or(&mut scratch);
        let mut anchor = MetalAnchor::<f64>::default();
        2.0 * anchor.forward_backward(&model.material, &snapshot.material, &POINTS, 2.0, g)
    }
    // Probed away from the snapshot, where the anchor has a gradient.
    let mut probe = moved;
    for (i, v) in probe.material.params.grid.params.iter_mut().enumerate() {
        *v += 0.05 * (i as f64 * 0.21).cos();
    }
    common::check_material_prior_gradient_on(probe, anchor_loss);
}

/// [`tiny_material_model`] with metallic around one half (its output bias
/// at 0 and its weights scaled up): some points metals, some not.
fn metals_and_dielectrics() -> Model<f64> {
    let mut model = tiny_material_model();
    let mlp = &mut model.material.params.mlp;
    let last = *mlp.layers().last().unwrap();
    let row = last.weight_offset + METALLIC * last.n_in;
    for w in &mut mlp.params[row..row + last.n_in] {
        *w *= 30.0;
    }
    mlp.params[last.bias_offset + METALLIC] = 0.0;
    model
}
