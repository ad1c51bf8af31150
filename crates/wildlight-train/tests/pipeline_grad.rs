//! Finite-difference check, in f64, of the whole differentiable chain:
//! samples along rays → SDF field with finite-difference (or analytic)
//! normals → NeuS weights → material and ambient fields, flash term →
//! composited colour and Σw, plus the eikonal term → a loss; with a background (a run without
//! masks), its samples beyond the unit sphere → background field → its
//! volume rendering with the flash term → C += (1 − Σw) B. Every parameter
//! group of a tiny model is probed.

use wildlight_fields::{FdScheme, Interpolation, NormalMethod};
use wildlight_render::BackgroundSettings;
use wildlight_train::config::{AmbientModel, FieldSize, ModelConfig};
use wildlight_train::model::Model;
use wildlight_train::pipeline::{PassSettings, Pipeline, RayInputs};

fn tiny(levels: usize, log2: u32, hidden: usize) -> FieldSize {
    FieldSize {
        levels,
        features_per_level: 2,
        log2_table_size: log2,
        base_resolution: 3,
        finest_resolution: 9,
        hidden: vec![hidden],
        interpolation: Default::default(),
    }
}

fn tiny_config() -> ModelConfig {
    ModelConfig {
        // smoothstep corner weights, as the default SDF field has
        sdf: FieldSize {
            interpolation: Interpolation::Smoothstep,
            ..tiny(3, 7, 8)
        },
        geometry_features: 3,
        init_radius: 0.5,
        material: tiny(2, 6, 8),
        ambient: tiny(2, 6, 8),
        // the default ambient form's room, linear as by default
        ambient_room: FieldSize {
            hidden: vec![],
            ..tiny(2, 6, 8)
        },
        background: tiny(2, 6, 8),
        init_sharpness: 0.35,
        init_log_gain: 0.2,
        ..ModelConfig::default()
    }
}

#[derive(Clone)]
struct Setup {
    origins: Vec<[f64; 3]>,
    dirs: Vec<[f64; 3]>,
    energy: Vec<[f64; 3]>,
    eik: Vec<[f64; 3]>,
    d_colour: Vec<[f64; 3]>,
    d_acc: Vec<f64>,
    settings: PassSettings,
}

const EIKONAL_WEIGHT: f64 = 0.3;

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|x| x / l)
}

fn setup() -> Setup {
    let origins = vec![[0.1, 0.2, 2.5], [2.4, 0.3, 0.2], [-0.2, 2.3, 0.9]];
    let dirs = vec![
        normalize([-0.1, -0.25, -2.5]),
        normalize([-2.4, -0.2, 0.1]),
        normalize([0.3, -2.3, -0.85]),
    ];
    Setup {
        origins,
        dirs,
        energy: vec![[3.0, 2.5, 2.0], [0.0; 3], [1.5, 1.5, 1.5]],
        eik: vec![[0.3, -0.2, 0.1], [0.9, 0.5, -0.4], [-0.6, 0.1, 0.7]],
        d_colour: vec![[0.7, -0.4, 0.2], [0.3, 0.5, -0.9], [-0.6, 0.8, 0.4]],
        d_acc: vec![0.5, -0.3, 0.8],
        settings: PassSettings {
            normals: NormalMethod::FiniteDifference {
                scheme: FdScheme::Tetrahedral,
                step: 0.02,
            },
            cos_anneal_ratio: 0.6,
            jitter_seed: None,
            for_backward: true,
            alpha_eps: wildlight_render::neus::ALPHA_EPS,
            ambient_flash_gradient: 1.0,
        },
    }
}

/// Evaluates the loss L = Σ d_colour·C + Σ d_acc·Σw + w_e·eikonal and, with
/// `grads`, its gradient.
fn loss(
    model: &Model<f64>,
    s: &Setup,
    grads: Option<&mut wildlight_train::model::ModelGrads<f64>>,
) -> f64 {
    let mut p: Pipeline<f64> = Pipeline::default();
    // few background samples, near enough that the flash term counts
    p.background_settings = BackgroundSettings {
        samples: 6,
        far_radius: 20.0,
    };
    // 24 uniform sections over [1.5, 3.5] on every ray: they cross the
    // initial sphere of radius 0.5.
    let n = 24;
    p.samples.offsets = (0..=s.dirs.len() as u32).map(|r| r * n).collect();
    for (o, d) in s.origins.iter().zip(&s.dirs) {
        for k in 0..n {
            let t = 1.5 + (k as f64 + 0.5) * 2.0 / n as f64;
            p.samples.t.push(t);
            p.samples.delta.push(2.0 / n as f64);
            p.samples
                .positions
                .push([o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]]);
        }
    }
    let rays = RayInputs {
        origins: &s.origins,
        dirs: &s.dirs,
        energy: &s.energy,
    };
    p.forward_samples(model, &rays, &s.eik, &s.settings);
    let mut l = EIKONAL_WEIGHT * p.eikonal;
    for (c, d) in p.colour.iter().zip(&s.d_colour) {
        l += c[0] * d[0] + c[1] * d[1] + c[2] * d[2];
    }
    for (a, d) in p.acc_weight().iter().zip(&s.d_acc) {
        l += a * d;
    }
    if let Some(g) = grads {
        p.backward(
            model,
            &rays,
            &s.d_colour,
            &s.d_acc,
            EIKONAL_WEIGHT,
            &s.settings,
            g,
        );
    }
    l
}

fn check(name: &str, analytic: f64, numeric: f64) {
    // Central differences with h = 1e-6 on a loss of order 1 carry a
    // round-off of about 1e-10, hence the floor of the scale.
    let scale = analytic.abs().max(numeric.abs()).max(1e-5);
    assert!(
        (analytic - numeric).abs() / scale < 2e-4,
        "{name}: analytic {analytic:e} vs finite difference {numeric:e}"
    );
}

fn sdf_grid(m: &mut Model<f64>) -> &mut Vec<f64> {
    &mut m.sdf.field.grid.params
}
fn sdf_mlp(m: &mut Model<f64>) -> &mut Vec<f64> {
    &mut m.sdf.field.mlp.params
}
fn mat_grid(m: &mut Model<f64>) -> &mut Vec<f64> {
    &mut m.material.grid.params
}
fn mat_mlp(m: &mut Model<f64>) -> &mut Vec<f64> {
    &mut m.material.mlp.params
}
fn amb_grid(m: &mut Model<f64>) -> &mut Vec<f64> {
    &mut m.ambient.grid.params
}
fn amb_mlp(m: &mut Model<f64>) -> &mut Vec<f64> {
    &mut m.ambient.mlp.params
}
fn room_grid(m: &mut Model<f64>) -> &mut Vec<f64> {
    &mut m.room.as_mut().unwrap().grid.params
}
fn room_mlp(m: &mut Model<f64>) -> &mut Vec<f64> {
    &mut m.room.as_mut().unwrap().mlp.params
}
fn bg_grid(m: &mut Model<f64>) -> &mut Vec<f64> {
    &mut m.background.as_mut().unwrap().grid.params
}
fn bg_mlp(m: &mut Model<f64>) -> &mut Vec<f64> {
    &mut m.background.as_mut().unwrap().mlp.params
}

/// The default form: the neural ambient with the room of the reflected
/// direction, whose grid and linear map get their gradients and whose
/// ∂L/∂ω reaches the normals (and the SDF) next to the harmonics' Jacobian.
#[test]
fn whole_pipeline_matches_finite_differences() {
    check_whole_pipeline(&tiny_config());
}

/// With the analytic SDF gradient in place of the finite differences: its
/// second-order terms reach every SDF parameter through the normals and
/// the eikonal term.
#[test]
fn whole_pipeline_with_analytic_normals_matches_finite_differences() {
    let mut s = setup();
    s.settings.normals = NormalMethod::Analytic;
    check_model(&prepared_model(&tiny_config()), &s, false);
}

/// With the background of a run without masks, its samples jittered from
/// the pass's seed (the same placement in every evaluation) and its flash
/// response large enough that the flash term beyond the sphere weighs in
/// the gain's gradient.
#[test]
fn whole_pipeline_with_the_background_matches_finite_differences() {
    let config = tiny_config();
    let mut model = Model::<f64>::with_background(&config, 5).unwrap();
    prepare(&mut model);
    let bg = model.background.as_mut().unwrap();
    for (i, v) in bg.grid.params.iter_mut().enumerate() {
        *v = 0.4 * ((i as f64 * 0.6).sin());
    }
    // ρ starts at 3 (σ and a as initialised)
    let layer = *bg.mlp.layers().last().unwrap();
    for j in 4..7 {
        bg.mlp.params[layer.bias_offset + j] = 3.0f64.exp_m1().ln();
    }
    let mut s = setup();
    s.settings.jitter_seed = Some(17);
    // a ray that misses the initial sphere (radius 0.5) and sees the
    // background through the unit sphere, with the flash on
    s.origins.push([0.0, 0.8, 2.5]);
    s.dirs.push([0.0, 0.0, -1.0]);
    s.energy.push([2.0, 2.5, 3.0]);
    s.d_colour.push([0.4, -0.7, 0.9]);
    s.d_acc.push(-0.6);
    check_model(&model, &s, true);
}

/// The plain neural ambient, without the room of the reflected direction.
#[test]
fn whole_pipeline_with_the_plain_neural_ambient_matches_finite_differences() {
    let config = ModelConfig {
        ambient_model: AmbientModel::Neural,
        ..tiny_config()
    };
    check_whole_pipeline(&config);
}

/// The tiny model with its hash tables moved away from their tiny initial
/// values, so that their gradients are not negligible.
fn prepared_model(config: &ModelConfig) -> Model<f64> {
    let mut model = Model::<f64>::new(config, 5).unwrap();
    prepare(&mut model);
    model
}

/// Moves the tables of [`prepared_model`] away from their initial values.
fn prepare(model: &mut Model<f64>) {
    for (i, v) in model.material.grid.params.iter_mut().enumerate() {
        *v = 0.3 * ((i as f64 * 0.7).sin());
    }
    for (i, v) in model.ambient.grid.params.iter_mut().enumerate() {
        *v = 0.3 * ((i as f64 * 1.3).cos());
    }
    for (i, v) in model.sdf.field.grid.params.iter_mut().enumerate() {
        *v = 0.02 * ((i as f64 * 0.9).sin());
    }
    if let Some(f) = &mut model.room {
        for (i, v) in f.grid.params.iter_mut().enumerate() {
            *v = 0.3 * ((i as f64 * 1.1).sin());
        }
    }
}

/// Checks the analytic gradients against central differences.
fn check_whole_pipeline(config: &ModelConfig) {
    check_model(&prepared_model(config), &setup(), false);
}

/// Checks the analytic gradients of `model` on `s` against central
/// differences (and the background's, when `background`).
fn check_model(model: &Model<f64>, s: &Setup, background: bool) {
    let config = &model.config;
    let mut grads = model.new_grads();
    let base = loss(model, s, Some(&mut grads));
    assert!(base.is_finite());

    let h = 1e-6;
    let mut probed = 0;
    macro_rules! probe {
        ($name:expr, $params:expr, $grad:expr) => {{
            let len = $grad.len();
            // the entries with the largest gradients, plus a spread of others
            let mut idx: Vec<usize> = (0..len).collect();
            idx.sort_by(|&a, &b| $grad[b].abs().partial_cmp(&$grad[a].abs()).unwrap());
            let mut chosen: Vec<usize> = idx[..4.min(len)].to_vec();
            chosen.extend((0..len).step_by((len / 5).max(1)).take(5));
            for i in chosen {
                let mut plus = model.clone();
                $params(&mut plus)[i] += h;
                let mut minus = model.clone();
                $params(&mut minus)[i] -= h;
                let fd = (loss(&plus, s, None) - loss(&minus, s, None)) / (2.0 * h);
                check(&format!("{} [{}]", $name, i), $grad[i], fd);
                probed += 1;
            }
        }};
    }
    probe!("sdf.grid", sdf_grid, grads.sdf.grid);
    probe!("sdf.mlp", sdf_mlp, grads.sdf.mlp);
    probe!("material.grid", mat_grid, grads.material.grid);
    probe!("material.mlp", mat_mlp, grads.material.mlp);
    probe!("ambient.grid", amb_grid, grads.ambient.grid);
    probe!("ambient.mlp", amb_mlp, grads.ambient.mlp);
    assert_eq!(
        grads.room.is_some(),
        config.ambient_model == AmbientModel::NeuralRoom
    );
    if let Some(g) = &grads.room {
        probe!("room.grid", room_grid, g.grid);
        probe!("room.mlp", room_mlp, g.mlp);
        assert!(g.mlp.iter().any(|v| v.abs() > 1e-6));
        assert!(g.grid.iter().any(|v| v.abs() > 1e-6));
    }
    assert_eq!(grads.background.is_some(), background);
    if let Some(g) = &grads.background {
        probe!("background.grid", bg_grid, g.grid);
        probe!("background.mlp", bg_mlp, g.mlp);
        assert!(g.mlp.iter().any(|v| v.abs() > 1e-6));
        assert!(g.grid.iter().any(|v| v.abs() > 1e-6));
        // the background's flash term is part of the gain's gradient
        let mut no_flash = s.clone();
        no_flash.energy = vec![[0.0; 3]; s.energy.len()];
        let mut without = model.new_grads();
        loss(model, &no_flash, Some(&mut without));
        let mut object_only = model.clone();
        object_only.background = None;
        let mut g_obj = object_only.new_grads();
        loss(&object_only, s, Some(&mut g_obj));
        assert!(
            (grads.log_gain - g_obj.log_gain).abs() > 1e-4,
            "the background's flash term moves the gain's gradient: {} vs {}",
            grads.log_gain,
            g_obj.log_gain
        );
        assert_eq!(without.log_gain, 0.0);
    }
    for (name, get) in [
        (
            "sharpness",
            (|m: &mut Model<f64>| &mut m.sharpness) as fn(&mut Model<f64>) -> &mut f64,
        ),
        ("log_gain", |m: &mut Model<f64>| &mut m.log_gain),
    ] {
        let mut plus = model.clone();
        *get(&mut plus) += h;
        let mut minus = model.clone();
        *get(&mut minus) -= h;
        let fd = (loss(&plus, s, None) - loss(&minus, s, None)) / (2.0 * h);
        let an = if name == "sharpness" {
            grads.sharpness
        } else {
            grads.log_gain
        };
        check(name, an, fd);
        probed += 1;
    }
    assert!(probed >= 40, "{probed} parameters probed");
    // The gradients are not trivially zero.
    assert!(grads.sharpness.abs() > 1e-6 && grads.log_gain.abs() > 1e-6);
    assert!(grads.material.mlp.iter().any(|g| g.abs() > 1e-6));
}

/// The ambient fields' gradients of a pass: every parameter of the ambient
/// network and of its second field (the room of the reflected direction).
fn ambient_gradients(g: &wildlight_train::model::ModelGrads<f64>) -> Vec<f64> {
    let mut v = [g.ambient.grid.as_slice(), g.ambient.mlp.as_slice()].concat();
    if let Some(s) = &g.room {
        v.extend_from_slice(&s.grid);
        v.extend_from_slice(&s.mlp);
    }
    v
}

/// The pass's `ambient_flash_gradient` (the trainer's schedule of
/// `model.ambient_flash_gradient_late`) scales what the flash rays (rays 0 and 2
/// of the setup) send to the ambient fields: at 0 these get exactly the
/// gradient of the no-flash ray alone, at ½ the mean of 0 and 1, while the
/// flash term's own gradient (the gain) does not change.
#[test]
fn the_flash_rays_share_of_the_ambient_gradient_is_scaled() {
    let s = setup();
    let model = prepared_model(&tiny_config());
    let grads_at = |factor: f64, mut setup: Setup| {
        setup.settings.ambient_flash_gradient = factor;
        let mut grads = model.new_grads();
        loss(&model, &setup, Some(&mut grads));
        grads
    };
    let (full, none, half) = (
        grads_at(1.0, setup()),
        grads_at(0.0, setup()),
        grads_at(0.5, setup()),
    );
    // The no-flash ray alone: the flash rays' colour gradient zeroed.
    let mut only_no_flash = setup();
    for (d, e) in only_no_flash.d_colour.iter_mut().zip(&s.energy) {
        if e.iter().any(|v| *v != 0.0) {
            *d = [0.0; 3];
        }
    }
    let alone = grads_at(1.0, only_no_flash);

    let (a_full, a_none, a_half, a_alone) = (
        ambient_gradients(&full),
        ambient_gradients(&none),
        ambient_gradients(&half),
        ambient_gradients(&alone),
    );
    let largest = a_full.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(largest > 1e-4, "the ambient fields get a gradient");
    let differs = a_full
        .iter()
        .zip(&a_none)
        .fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
    assert!(
        differs > 1e-3 * largest,
        "the flash rays train the ambient at 1"
    );
    for (i, (((f, n), h), a)) in a_full
        .iter()
        .zip(&a_none)
        .zip(&a_half)
        .zip(&a_alone)
        .enumerate()
    {
        assert!(
            (n - a).abs() <= 1e-12 * largest,
            "[{i}] at 0: {n} vs the no-flash ray's {a}"
        );
        assert!(
            (h - 0.5 * (f + n)).abs() <= 1e-12 * largest,
            "[{i}] at ½: {h} vs {}",
            0.5 * (f + n)
        );
    }
    assert_eq!(full.log_gain, none.log_gain, "the flash term is untouched");
    assert!(full.log_gain.abs() > 1e-6);
}
