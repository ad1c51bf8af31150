//! The material smoothness prior: its value, its invariance to the flash
//! scale, and its parameter gradient against central finite differences in
//! f64.

mod common;

use wildlight_train::model::Model;
use wildlight_train::smoothness::{MaterialSmoothness, RelativeDifference, SmoothnessSettings};

use common::{CENTRES, tiny_material_model};

const OFFSETS: [[f64; 3]; 4] = [
    [0.04, -0.03, 0.02],
    [-0.05, 0.02, 0.06],
    [0.03, 0.05, -0.04],
    [0.06, -0.02, -0.03],
];
const WEIGHT: f64 = 0.7;

/// λ · L_smooth with `settings` and (when asked) its gradient.
fn loss_with(
    settings: SmoothnessSettings<f64>,
    model: &Model<f64>,
    grads: Option<&mut wildlight_train::material_field::MaterialGrads<f64>>,
) -> f64 {
    let mut term = MaterialSmoothness::<f64>::default();
    let mut scratch = model.material.new_grads();
    let g = grads.unwrap_or(&mut scratch);
    settings.weight * term.forward_backward(&model.material, &CENTRES, &OFFSETS, &settings, g)
}

/// λ · L_smooth and (when asked) its gradient.
fn loss(
    model: &Model<f64>,
    grads: Option<&mut wildlight_train::material_field::MaterialGrads<f64>>,
) -> f64 {
    loss_with(SmoothnessSettings::uniform(WEIGHT), model, grads)
}

/// The same with the per-parameter factors of `FACTORS`.
fn factored_loss(
    model: &Model<f64>,
    grads: Option<&mut wildlight_train::material_field::MaterialGrads<f64>>,
) -> f64 {
    let settings = SmoothnessSettings {
        factors: FACTORS,
        ..SmoothnessSettings::uniform(WEIGHT)
    };
    loss_with(settings, model, grads)
}

/// The same with batch-relative differences and the factors of `FACTORS`.
fn batch_loss(
    model: &Model<f64>,
    grads: Option<&mut wildlight_train::material_field::MaterialGrads<f64>>,
) -> f64 {
    let settings = SmoothnessSettings {
        factors: FACTORS,
        relative: RelativeDifference::Batch,
        ..SmoothnessSettings::uniform(WEIGHT)
    };
    loss_with(settings, model, grads)
}

/// Saturation scale of the tests of ψ(δ) = c · ln(1 + δ/c).
const SATURATION: f64 = 0.05;

/// The same as `factored_loss` with saturated differences.
fn saturated_loss(
    model: &Model<f64>,
    grads: Option<&mut wildlight_train::material_field::MaterialGrads<f64>>,
) -> f64 {
    let settings = SmoothnessSettings {
        factors: FACTORS,
        saturation: [SATURATION; 9],
        ..SmoothnessSettings::uniform(WEIGHT)
    };
    loss_with(settings, model, grads)
}

/// The same as `batch_loss` with saturated differences.
fn saturated_batch_loss(
    model: &Model<f64>,
    grads: Option<&mut wildlight_train::material_field::MaterialGrads<f64>>,
) -> f64 {
    let settings = SmoothnessSettings {
        factors: FACTORS,
        relative: RelativeDifference::Batch,
        saturation: [SATURATION; 9],
        ..SmoothnessSettings::uniform(WEIGHT)
    };
    loss_with(settings, model, grads)
}

/// The same as `factored_loss` with metallic's differences alone saturated.
fn metallic_saturated_loss(
    model: &Model<f64>,
    grads: Option<&mut wildlight_train::material_field::MaterialGrads<f64>>,
) -> f64 {
    let mut saturation = [0.0; 9];
    saturation[wildlight_material::METALLIC] = SATURATION;
    let settings = SmoothnessSettings {
        factors: FACTORS,
        saturation,
        ..SmoothnessSettings::uniform(WEIGHT)
    };
    loss_with(settings, model, grads)
}

/// Unequal factors, one of them 0.
const FACTORS: [f64; 9] = [2.0, 2.0, 2.0, 3.0, 0.5, 0.0, 1.5, 1.0, 0.25];

#[test]
fn smoothness_value_is_the_mean_l1_difference_of_theta() {
    let model = tiny_material_model();
    let mut ctx = wildlight_train::material_field::MaterialContext::default();
    let (mut by_hand, mut factored_by_hand) = (0.0, 0.0);
    let (mut diff, mut sums) = ([0.0; 9], [0.0; 9]);
    let (mut saturated_by_hand, mut saturated_diff) = (0.0, [0.0; 9]);
    let mut metallic_saturated_by_hand = 0.0;
    let psi = |d: f64| SATURATION * (1.0 + d / SATURATION).ln();
    for (c, e) in CENTRES.iter().zip(&OFFSETS) {
        let far = [c[0] + e[0], c[1] + e[1], c[2] + e[2]];
        model.material.forward(&[*c, far], &mut ctx);
        let (a, b) = ctx.output().split_at(9);
        for (i, (x, y)) in a.iter().zip(b).enumerate() {
            // relative for base colour (0–2), dielectric (7) and clearcoat (8)
            let delta = if i <= 2 || i == 7 || i == 8 {
                (x - y).abs() / (x + y + 0.01)
            } else {
                (x - y).abs()
            };
            by_hand += delta;
            factored_by_hand += FACTORS[i] * delta;
            saturated_by_hand += FACTORS[i] * psi(delta);
            metallic_saturated_by_hand += FACTORS[i] * if i == 6 { psi(delta) } else { delta };
            diff[i] += (x - y).abs();
            saturated_diff[i] += psi((x - y).abs());
            sums[i] += x + y;
        }
    }
    by_hand /= CENTRES.len() as f64;
    factored_by_hand /= CENTRES.len() as f64;
    saturated_by_hand /= CENTRES.len() as f64;
    metallic_saturated_by_hand /= CENTRES.len() as f64;
    let value = loss(&model, None) / WEIGHT;
    assert!(value > 1e-3, "Θ must differ across the pairs: {value}");
    assert!((value - by_hand).abs() < 1e-12, "{value} vs {by_hand}");
    // Batch-relative: Σ_i w_i D_i / (M_i + 0.01) over the pairs' count.
    let n = CENTRES.len() as f64;
    let batch_of = |diff: [f64; 9]| {
        (0..9)
            .map(|i| {
                let relative = i <= 2 || i == 7 || i == 8;
                let s = if relative { sums[i] / n + 0.01 } else { 1.0 };
                FACTORS[i] * diff[i] / s
            })
            .sum::<f64>()
            / n
    };
    let batch_by_hand = batch_of(diff);
    let batch = batch_loss(&model, None) / WEIGHT;
    assert!(
        (batch - batch_by_hand).abs() < 1e-12,
        "{batch} vs {batch_by_hand}"
    );
    // Saturated: each δ (pairwise) or |a − b| (batch) enters as ψ.
    let saturated = saturated_loss(&model, None) / WEIGHT;
    assert!(
        (saturated - saturated_by_hand).abs() < 1e-12,
        "{saturated} vs {saturated_by_hand}"
    );
    let metallic_saturated = metallic_saturated_loss(&model, None) / WEIGHT;
    assert!(
        (metallic_saturated - metallic_saturated_by_hand).abs() < 1e-12,
        "{metallic_saturated} vs {metallic_saturated_by_hand}"
    );
    let factored = factored_loss(&model, None) / WEIGHT;
    assert!(
        saturated < metallic_saturated && metallic_saturated < factored,
        "ψ(δ) < δ for δ > 0: {saturated} < {metallic_saturated} < {factored}"
    );
    let saturated_batch_by_hand = batch_of(saturated_diff);
    let saturated_batch = saturated_batch_loss(&model, None) / WEIGHT;
    assert!(
        (saturated_batch - saturated_batch_by_hand).abs() < 1e-12,
        "{saturated_batch} vs {saturated_batch_by_hand}"
    );
    assert!((factored - value).abs() > 1e-4, "the factors must matter");
    assert!(
        (factored - factored_by_hand).abs() < 1e-12,
        "{factored} vs {factored_by_hand}"
    );

    // No offset, no penalty and no gradient.
    let mut term = MaterialSmoothness::<f64>::default();
    let mut g = model.material.new_grads();
    let zero = term.forward_backward(
        &model.material,
        &CENTRES,
        &[[0.0; 3]; 4],
        &SmoothnessSettings::uniform(1.0),
        &mut g,
    );
    assert_eq!(zero, 0.0);
    assert!(g.params.grid.iter().chain(&g.params.mlp).all(|v| *v == 0.0));
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
    common::check_material_prior_gradient(factored_loss);
    common::check_material_prior_gradient(batch_loss);
    common::check_material_prior_gradient(saturated_loss);
    common::check_material_prior_gradient(saturated_batch_loss);
    common::check_material_prior_gradient(metallic_saturated_loss);
}

/// Across a large difference the saturated prior pushes less than L1, by
/// ψ'(δ) = c / (c + δ); across a small one nearly as much.
#[test]
fn saturation_fades_the_push_across_large_differences() {
    let model = tiny_material_model();
    let (mut l1, mut sat) = (model.material.new_grads(), model.material.new_grads());
    loss_with(SmoothnessSettings::uniform(WEIGHT), &model, Some(&mut l1));
    let settings = SmoothnessSettings {
        saturation: [SATURATION; 9],
        ..SmoothnessSettings::uniform(WEIGHT)
    };
    loss_with(settings, &model, Some(&mut sat));
    let norm = |g: &wildlight_train::material_field::MaterialGrads<f64>| {
        g.params
            .grid
            .iter()
            .chain(&g.params.mlp)
            .map(|v| v * v)
            .sum::<f64>()
            .sqrt()
    };
    let (n1, ns) = (norm(&l1), norm(&sat));
    assert!(n1 > 0.0 && ns > 0.0, "{n1} {ns}");
    assert!(
        ns < 0.9 * n1,
        "saturation must weaken the push: {ns} vs {n1}"
    );
    // A scale far above every difference is L1 again.
    let mut wide = model.material.new_grads();
    let settings = SmoothnessSettings {
        saturation: [1e6; 9],
        ..SmoothnessSettings::uniform(WEIGHT)
    };
    loss_with(settings, &model, Some(&mut wide));
    let diff = wide
        .params
        .grid
        .iter()
        .chain(&wide.params.mlp)
        .zip(l1.params.grid.iter().chain(&l1.params.mlp))
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f64, f64::max);
    assert!(diff < 1e-6 * n1, "{diff}");
}
