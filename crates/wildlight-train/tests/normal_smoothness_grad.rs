//! The normal smoothness prior, the second difference of the normals: its
//! value against a hand computation from the SDF's finite-difference
//! normals, its parameter gradient against central finite differences in
//! f64, what it costs on a sphere (nothing, where a first difference would
//! cost), and the offsets of its pairs.

mod common;

use wildlight_fields::{FdScheme, NormalContext, NormalMethod};
use wildlight_train::model::Model;
use wildlight_train::normal_smoothness::{
    HUBER_ETA, NormalSmoothness, pair_offsets, pseudo_huber, second_difference,
};

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
const WEIGHT: f64 = 0.7;
/// Both ways of computing the normals: finite differences of step 0.02
/// and the analytic gradient.
const METHODS: [NormalMethod; 2] = [
    NormalMethod::FiniteDifference {
        scheme: FdScheme::Tetrahedral,
        step: 0.02,
    },
    NormalMethod::Analytic,
];

/// λ · L_normal and (when asked) its gradient.
fn loss(
    model: &Model<f64>,
    method: NormalMethod,
    grads: Option<&mut wildlight_fields::FieldGrads<f64>>,
) -> f64 {
    let mut term = NormalSmoothness::<f64>::default();
    let mut scratch = model.sdf.new_grads();
    let g = grads.unwrap_or(&mut scratch);
    WEIGHT * term.forward_backward(&model.sdf, &CENTRES, &OFFSETS, method, WEIGHT, g)
}

fn unit(g: [f64; 3]) -> [f64; 3] {
    let l = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt();
    g.map(|v| v / l)
}

/// The unit normal of the model's SDF at `x`.
fn normal_at(model: &Model<f64>, method: NormalMethod, x: [f64; 3]) -> [f64; 3] {
    let mut ctx = NormalContext::new();
    model.sdf.forward_with_normals(&[x], method, &mut ctx);
    unit(ctx.gradient[0])
}

fn pseudo_huber_by_hand(d: [f64; 3]) -> f64 {
    let d2: f64 = d.iter().map(|v| v * v).sum();
    (d2 + HUBER_ETA * HUBER_ETA).sqrt() - HUBER_ETA
}

/// Δ by hand, from the normals at x − ε, x and x + ε.
fn difference_by_hand(
    model: &Model<f64>,
    method: NormalMethod,
    c: [f64; 3],
    e: [f64; 3],
) -> [f64; 3] {
    let n0 = normal_at(model, method, c);
    let n1 = normal_at(model, method, [0, 1, 2].map(|a| c[a] + e[a]));
    let n2 = normal_at(model, method, [0, 1, 2].map(|a| c[a] - e[a]));
    let s = [0, 1, 2].map(|a| n1[a] + n2[a] - 2.0 * n0[a]);
    let sn: f64 = (0..3).map(|a| s[a] * n0[a]).sum();
    [0, 1, 2].map(|a| s[a] - sn * n0[a])
}

#[test]
fn normal_smoothness_is_the_mean_pseudo_huber_difference_of_the_normals() {
    let model = tiny_sdf_model();
    for method in METHODS {
        let by_hand = CENTRES
            .iter()
            .zip(&OFFSETS)
            .map(|(c, e)| pseudo_huber_by_hand(difference_by_hand(&model, method, *c, *e)))
            .sum::<f64>()
            / CENTRES.len() as f64;
        let value = loss(&model, method, None) / WEIGHT;
        assert!(
            value > 1e-2,
            "{method:?}: the normals must turn across the points: {value}"
        );
        assert!(
            (value - by_hand).abs() < 1e-12,
            "{method:?}: {value} vs {by_hand}"
        );

        // No offset, no penalty and no gradient.
        let mut term = NormalSmoothness::<f64>::default();
        let mut g = model.sdf.new_grads();
        let still = [[0.0; 3]; 4];
        let zero = term.forward_backward(&model.sdf, &CENTRES, &still, method, 1.0, &mut g);
        assert_eq!(zero, 0.0);
        assert!(g.grid.iter().chain(&g.mlp).all(|v| *v == 0.0));
    }
}

/// Along circles of any radius the tangential second difference vanishes
/// (a sphere, a cylinder cost nothing), while the first difference grows
/// with the offset over the radius; a bump in the middle is penalised.
#[test]
fn the_second_difference_ignores_constant_curvature() {
    let norm = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    // x on both surfaces, ε tangent to both there (the prior's offsets are
    // projected onto the tangent plane).
    let c = [0.0, 0.25, 0.0];
    let e = [0.03, 0.0, 0.02];
    // A sphere of radius 0.25 and a cylinder of radius 0.25 along z.
    let sphere = |x: [f64; 3]| unit(x);
    let cylinder = |x: [f64; 3]| unit([x[0], x[1], 0.0]);
    for (name, normal) in [
        ("sphere", &sphere as &dyn Fn([f64; 3]) -> [f64; 3]),
        ("cylinder", &cylinder),
    ] {
        let n0 = normal(c);
        let n1 = normal([0, 1, 2].map(|a| c[a] + e[a]));
        let n2 = normal([0, 1, 2].map(|a| c[a] - e[a]));
        let first = norm([0, 1, 2].map(|a| n1[a] - n0[a]));
        let second = second_difference(n0, n1, n2);
        assert!(first > 0.1, "{name}: {first}");
        assert!(
            norm(second.tangential) < 1e-12,
            "{name}: {:?}",
            second.tangential
        );
        assert!(
            norm(second.sum) > 1e-3,
            "{name}: s must be along the normal, not zero"
        );
        // A tilted normal at x (a bump) shows up in Δ.
        let tilted = unit([n0[0] + 0.05, n0[1], n0[2]]);
        let bump = second_difference(tilted, n1, n2);
        assert!(
            norm(bump.tangential) > 0.05,
            "{name}: {:?}",
            bump.tangential
        );
    }
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
    for method in METHODS {
        let mut model = tiny_sdf_model();
        let mut grads = model.sdf.new_grads();
        loss(&model, method, Some(&mut grads));
        // With finite-difference normals of step 0.02 the loss's rounding
        // (~1e-16 of the SDF's values) reaches ~1e-10 in its own central
        // differences: an absolute floor of 1e-5 (tolerance 1e-9).
        let probed = common::check_field_gradient_with_floor(
            &mut model,
            |m| &mut m.sdf.field,
            &grads,
            |m| loss(m, method, None),
            1e-5,
        );
        assert!(
            probed >= 10,
            "{method:?}: only {probed} parameters had a gradient"
        );
    }
}

/// SecondDifference::backward, the prior's ∂ρ(Δ)/∂n for each of the three
/// normals, against central differences in n.
#[test]
fn second_difference_backward_matches_finite_differences() {
    let n = [[0.3, 0.8, 0.5], [0.35, 0.75, 0.52], [0.28, 0.82, 0.45]];
    let rho = |n: [[f64; 3]; 3]| pseudo_huber(second_difference(n[0], n[1], n[2]).tangential).0;
    let sd = second_difference(n[0], n[1], n[2]);
    let (_, u) = pseudo_huber(sd.tangential);
    let (d0, d12) = sd.backward(n[0], u);
    let analytic = [d0, d12, d12];
    let h = 1e-6;
    for k in 0..3 {
        for a in 0..3 {
            let (mut up, mut down) = (n, n);
            up[k][a] += h;
            down[k][a] -= h;
            let numeric = (rho(up) - rho(down)) / (2.0 * h);
            assert!(
                (analytic[k][a] - numeric).abs() < 1e-7 * numeric.abs().max(1.0),
                "normal {k} component {a}: {} vs {numeric}",
                analytic[k][a]
            );
        }
    }
}

/// The pairs' offsets: the material prior's offsets without their part
/// along the normal.
#[test]
fn the_pairs_offsets_are_tangent() {
    let offsets = [[0.01f32, -0.02, 0.015], [0.0, 0.0, 0.02]];
    let s = 1.0 / 3f32.sqrt();
    let normals = [[0.0f32, 0.0, 1.0], [s, s, s]];
    let tangent = pair_offsets(&offsets, &normals);
    assert_eq!(tangent[0], [0.01, -0.02, 0.0]);
    // (0, 0, 0.02) less its part along n: 0.02 · (−1/3, −1/3, 2/3)
    let expected = [-0.02 / 3.0, -0.02 / 3.0, 0.04 / 3.0];
    for a in 0..3 {
        assert!(
            (tangent[1][a] - expected[a]).abs() < 1e-8,
            "{:?}",
            tangent[1]
        );
    }
    let along: f32 = (0..3).map(|a| tangent[1][a] * normals[1][a]).sum();
    assert!(along.abs() < 1e-9);
}
