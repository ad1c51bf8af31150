//! Helpers shared by the gradient tests.

use wildlight_fields::{FieldGrads, NeuralField};
use wildlight_train::config::{FieldSize, ModelConfig};
use wildlight_train::model::Model;

/// A model whose three fields have two hash levels (3 and 9 cells), a
/// 64-entry table and one hidden layer of 8, in f64.
pub fn tiny_model(seed: u64) -> Model<f64> {
    Model::<f64>::new(&tiny_config(), seed).unwrap()
}

/// The settings of [`tiny_model`].
pub fn tiny_config() -> ModelConfig {
    let size = FieldSize {
        levels: 2,
        features_per_level: 2,
        log2_table_size: 6,
        base_resolution: 3,
        finest_resolution: 9,
        hidden: vec![8],
        interpolation: Default::default(),
    };
    ModelConfig {
        sdf: size.clone(),
        material: size.clone(),
        ambient: size,
        geometry_features: 3,
        ..ModelConfig::default()
    }
}

/// [`tiny_model`] with its material table away from its tiny initial
/// values, so Θ varies in space.
#[allow(dead_code)] // not every test crate checks the material field
pub fn tiny_material_model() -> Model<f64> {
    let mut model = tiny_model(11);
    for (i, v) in model.material.grid.params.iter_mut().enumerate() {
        *v = 0.4 * (i as f64 * 0.77).sin();
    }
    model
}

/// A prior on the material field: its value, filling the gradient when
/// given one.
#[allow(dead_code)]
pub type MaterialPrior = fn(&Model<f64>, Option<&mut FieldGrads<f64>>) -> f64;

/// Checks the material-field gradient of a prior `loss` on
/// [`tiny_material_model`] against central differences, and that at least
/// 10 probed parameters had one.
#[allow(dead_code)]
pub fn check_material_prior_gradient(loss: MaterialPrior) {
    let mut model = tiny_material_model();
    let mut grads = model.material.new_grads();
    loss(&model, Some(&mut grads));
    let probed = check_field_gradient(&mut model, |m| &mut m.material, &grads, |m| loss(m, None));
    assert!(probed >= 10, "only {probed} parameters had a gradient");
}

/// Surface-like points of the prior tests.
#[allow(dead_code)]
pub const CENTRES: [[f64; 3]; 4] = [
    [0.1, -0.2, 0.3],
    [-0.35, 0.05, 0.12],
    [0.42, 0.31, -0.27],
    [-0.1, -0.44, -0.05],
];

/// Entry `i` of the hash table (group 0) or the MLP (group 1) of the field
/// that `field` picks from the model.
fn entry(
    model: &mut Model<f64>,
    field: fn(&mut Model<f64>) -> &mut NeuralField<f64>,
    group: usize,
    i: usize,
) -> &mut f64 {
    let f = field(model);
    if group == 0 {
        &mut f.grid.params[i]
    } else {
        &mut f.mlp.params[i]
    }
}

/// Checks the gradient `grads` of `loss` with respect to the hash table
/// and the MLP of the field that `field` picks from the model, against
/// central differences (step 1e-6, relative tolerance 1e-4) on about 25
/// entries of each. Returns how many of them had a gradient above 1e-6.
#[allow(dead_code)] // each test crate uses one of the two checks
pub fn check_field_gradient(
    model: &mut Model<f64>,
    field: fn(&mut Model<f64>) -> &mut NeuralField<f64>,
    grads: &FieldGrads<f64>,
    loss: impl Fn(&Model<f64>) -> f64,
) -> usize {
    check_field_gradient_with_floor(model, field, grads, loss, 1e-6)
}

/// [`check_field_gradient`] with the tolerance 1e-4 relative to
/// max(|analytic|, |numeric|, `floor`): a larger floor for losses whose
/// central differences carry more rounding noise (normals taken by finite
/// differences divide the SDF's rounding by their step).
pub fn check_field_gradient_with_floor(
    model: &mut Model<f64>,
    field: fn(&mut Model<f64>) -> &mut NeuralField<f64>,
    grads: &FieldGrads<f64>,
    loss: impl Fn(&Model<f64>) -> f64,
    floor: f64,
) -> usize {
    let h = 1e-6;
    let mut probed = 0;
    for (group, analytic) in [(0, &grads.grid), (1, &grads.mlp)] {
        let len = analytic.len();
        for i in (0..len).step_by((len / 25).max(1)) {
            let v = *entry(model, field, group, i);
            *entry(model, field, group, i) = v + h;
            let up = loss(model);
            *entry(model, field, group, i) = v - h;
            let down = loss(model);
            *entry(model, field, group, i) = v;
            let numeric = (up - down) / (2.0 * h);
            let a = analytic[i];
            let scale = a.abs().max(numeric.abs()).max(floor);
            assert!(
                (a - numeric).abs() / scale < 1e-4,
                "{} parameter {i}: analytic {a:e} vs finite difference {numeric:e}",
                ["grid", "mlp"][group]
            );
            if a.abs() > 1e-6 {
                probed += 1;
            }
        }
    }
    probed
}
