//! The SDF's gradient ∇φ computed analytically, with its backward pass: the
//! reference implementation (point by point) of what the finite-difference
//! normals of [`crate::sdf_field`] estimate with four extra evaluations.
//!
//! The field is φ = MLP(a₀) with a₀ = [x | e(u)], u = (x + b)/(2b) the
//! encoder's coordinates. With z_l = W_l a_{l−1} + b_l and a_l = σ(z_l) for
//! the hidden layers l = 1 … L and a linear output layer L + 1:
//!
//! - the gradient runs the network backwards from the SDF output:
//!   g_{a_L} = W_{L+1}[0, :]ᵀ, g_{z_l} = σ'(z_l) ⊙ g_{a_l},
//!   g_{a_{l−1}} = W_lᵀ g_{z_l}; then g_{a₀} = [g_x | g_e] and
//!   ∇φ = g_x + J_eᵀ g_e / (2b), J_e the encoding's Jacobian
//!   ([`crate::HashGrid::backward_input`]);
//! - its backward pass, from upstream gradients D_out (of the outputs) and
//!   D_∇ (of ∇φ), reverses that chain first: D g_x = D_∇,
//!   D g_e = J_e D_∇ / (2b) ([`crate::HashGrid::encode_directional`]), the
//!   table gets the derivative of J_eᵀ g_e
//!   ([`crate::HashGrid::backward_params_directional`]); going up,
//!   ∂W_l += g_{z_l} ⊗ D g_{a_{l−1}}, D g_{z_l} = W_l D g_{a_{l−1}},
//!   D g_{a_l} = σ'(z_l) ⊙ D g_{z_l} and a second-order term
//!   D z_l = σ''(z_l) ⊙ g_{a_l} ⊙ D g_{z_l}; at the top ∂W_{L+1}[0, :] += D g_{a_L}.
//!   Then the ordinary backward pass from D_out runs down, each D z_l
//!   joining σ'(z_l) ⊙ D a_l, and ends in the table through e(u).
//!
//! One forward, one reverse sweep for the gradient and two sweeps back
//! replace the five forward and backward evaluations of the tetrahedral
//! scheme; this module is the oracle for the batched kernels that will
//! use it in training.

use crate::activation::Activation;
use crate::neural_field::FieldGrads;
use crate::sdf_field::SdfField;
use wildlight_real::Real;

/// What [`SdfField::forward_with_gradient`] keeps for the backward pass.
#[derive(Clone, Debug, Default)]
pub struct GradientContext<T> {
    n: usize,
    unit: Vec<[T; 3]>,
    /// a₀ of each point (`n × n_in`, row-major).
    input: Vec<T>,
    /// a_l of each hidden layer (`n × width_l`).
    hidden: Vec<Vec<T>>,
    /// g_{a_l} = ∂φ/∂a_l of each hidden layer.
    g_hidden: Vec<Vec<T>>,
    /// g_{a₀} = ∂φ/∂a₀.
    g_input: Vec<T>,
    /// `[sdf, features…]` of each point (`n × n_output`).
    pub output: Vec<T>,
    /// ∇φ of each point (normalized frame).
    pub gradient: Vec<[T; 3]>,
}

impl<T: Real> GradientContext<T> {
    /// An empty context.
    pub fn new() -> Self {
        Self::default()
    }
}

/// The second derivative d²a/dz² of `act`, written as a function of its
/// output `a` (as [`Activation::derivative_from_output`]).
pub fn second_derivative_from_output<T: Real>(act: Activation, a: T) -> T {
    match act {
        Activation::None | Activation::Relu => T::ZERO,
        Activation::Softplus { beta } => {
            // σ' = s = sigmoid(βz) = 1 − e^(−βa), σ'' = β s (1 − s)
            let b = T::from_f64(beta as f64);
            let s = act.derivative_from_output(a);
            b * s * (T::ONE - s)
        }
        Activation::Sigmoid => a * (T::ONE - a) * (T::ONE - a - a),
    }
}

impl<T: Real> SdfField<T> {
    /// `[sdf, features…]` and the analytic ∇φ of each point of `x`
    /// (normalized frame) into `ctx` (see the module docs).
    pub fn forward_with_gradient(&self, x: &[[T; 3]], ctx: &mut GradientContext<T>) {
        let field = &self.field;
        let cfg = field.config();
        assert!(
            cfg.include_position && cfg.n_extra == 0,
            "the SDF network reads [x | encoding]"
        );
        assert_eq!(
            cfg.output_activation,
            Activation::None,
            "the SDF output is linear"
        );
        let act = cfg.hidden_activation;
        let layers = field.mlp.layers();
        let w = &field.mlp.params;
        let n = x.len();
        let n_in = layers[0].n_in;
        let ne = field.grid.n_outputs();
        let active = field.active_levels;
        let b = T::from_f64(cfg.bound as f64);
        let inv = T::ONE / (b + b);
        ctx.n = n;
        ctx.unit = x.iter().map(|p| p.map(|v| (v + b) * inv)).collect();
        let mut enc = vec![T::ZERO; n * ne];
        field.grid.encode(&ctx.unit, &mut enc, ne, 0, active);
        ctx.input = vec![T::ZERO; n * n_in];
        for p in 0..n {
            let row = &mut ctx.input[p * n_in..(p + 1) * n_in];
            row[..3].copy_from_slice(&x[p]);
            row[3..].copy_from_slice(&enc[p * ne..(p + 1) * ne]);
        }
        let hidden = &layers[..layers.len() - 1];
        let top = layers[layers.len() - 1];
        ctx.hidden = hidden.iter().map(|l| vec![T::ZERO; n * l.n_out]).collect();
        ctx.g_hidden = ctx.hidden.clone();
        ctx.g_input = vec![T::ZERO; n * n_in];
        ctx.output = vec![T::ZERO; n * top.n_out];
        for p in 0..n {
            // forward
            let mut a: Vec<T> = ctx.input[p * n_in..(p + 1) * n_in].to_vec();
            for (l, info) in hidden.iter().enumerate() {
                let next: Vec<T> = (0..info.n_out)
                    .map(|o| {
                        let row = &w[info.weight_offset + o * info.n_in..][..info.n_in];
                        let z = row
                            .iter()
                            .zip(&a)
                            .fold(w[info.bias_offset + o], |s, (wi, ai)| s + *wi * *ai);
                        act.apply(z)
                    })
                    .collect();
                ctx.hidden[l][p * info.n_out..(p + 1) * info.n_out].copy_from_slice(&next);
                a = next;
            }
            for o in 0..top.n_out {
                let row = &w[top.weight_offset + o * top.n_in..][..top.n_in];
                ctx.output[p * top.n_out + o] = row
                    .iter()
                    .zip(&a)
                    .fold(w[top.bias_offset + o], |s, (wi, ai)| s + *wi * *ai);
            }
            // ∂φ/∂a, from the top down
            let mut g: Vec<T> = w[top.weight_offset..][..top.n_in].to_vec();
            for (l, info) in hidden.iter().enumerate().rev() {
                ctx.g_hidden[l][p * info.n_out..(p + 1) * info.n_out].copy_from_slice(&g);
                let a_l = &ctx.hidden[l][p * info.n_out..(p + 1) * info.n_out];
                let gz: Vec<T> = g
                    .iter()
                    .zip(a_l)
                    .map(|(gi, ai)| *gi * act.derivative_from_output(*ai))
                    .collect();
                let mut below = vec![T::ZERO; info.n_in];
                for (o, gzo) in gz.iter().enumerate() {
                    let row = &w[info.weight_offset + o * info.n_in..][..info.n_in];
                    for (bi, wi) in below.iter_mut().zip(row) {
                        *bi += *gzo * *wi;
                    }
                }
                g = below;
            }
            ctx.g_input[p * n_in..(p + 1) * n_in].copy_from_slice(&g);
        }
        // ∇φ = g_x + J_eᵀ g_e / (2b)
        let g_e: Vec<T> = (0..n)
            .flat_map(|p| ctx.g_input[p * n_in + 3..(p + 1) * n_in].to_vec())
            .collect();
        let mut from_grid = vec![[T::ZERO; 3]; n];
        field
            .grid
            .backward_input(&ctx.unit, &g_e, ne, 0, active, &mut from_grid);
        ctx.gradient = (0..n)
            .map(|p| {
                let gx = &ctx.g_input[p * n_in..p * n_in + 3];
                [0, 1, 2].map(|k| gx[k] + from_grid[p][k] * inv)
            })
            .collect();
    }

    /// Backward pass of [`SdfField::forward_with_gradient`]: accumulates
    /// (`+=`) into `grads` the parameter gradient of a loss whose gradient
    /// is `d_out` with respect to the outputs (`n × n_output`) and
    /// `d_gradient` with respect to ∇φ (see the module docs).
    pub fn backward_with_gradient(
        &self,
        ctx: &GradientContext<T>,
        d_out: &[T],
        d_gradient: &[[T; 3]],
        grads: &mut FieldGrads<T>,
    ) {
        let field = &self.field;
        let act = field.config().hidden_activation;
        let layers = field.mlp.layers();
        let w = &field.mlp.params;
        let gw = &mut grads.mlp;
        let n = ctx.n;
        let n_in = layers[0].n_in;
        let ne = field.grid.n_outputs();
        let active = field.active_levels;
        let b = T::from_f64(field.config().bound as f64);
        let inv = T::ONE / (b + b);
        let hidden = &layers[..layers.len() - 1];
        let top = layers[layers.len() - 1];
        assert_eq!(d_out.len(), n * top.n_out, "d_out length");
        assert_eq!(d_gradient.len(), n, "d_gradient length");
        // D g_e = J_e D_∇ / (2b); the table's share of J_eᵀ g_e.
        let v: Vec<[T; 3]> = d_gradient.iter().map(|d| d.map(|c| c * inv)).collect();
        let mut d_ge = vec![T::ZERO; n * ne];
        field
            .grid
            .encode_directional(&ctx.unit, &v, active, &mut d_ge);
        let g_e: Vec<T> = (0..n)
            .flat_map(|p| ctx.g_input[p * n_in + 3..(p + 1) * n_in].to_vec())
            .collect();
        field
            .grid
            .backward_params_directional(&ctx.unit, &v, &g_e, active, &mut grads.grid);
        let mut d_enc = vec![T::ZERO; n * ne];
        for p in 0..n {
            // Up the gradient's chain: D g_{a_{l−1}} → D g_{z_l} → D g_{a_l}.
            let mut dg: Vec<T> = d_gradient[p]
                .iter()
                .copied()
                .chain(d_ge[p * ne..(p + 1) * ne].iter().copied())
                .collect();
            let mut dz2: Vec<Vec<T>> = Vec::with_capacity(hidden.len());
            for (l, info) in hidden.iter().enumerate() {
                let a_l = &ctx.hidden[l][p * info.n_out..(p + 1) * info.n_out];
                let g_l = &ctx.g_hidden[l][p * info.n_out..(p + 1) * info.n_out];
                let mut next = vec![T::ZERO; info.n_out];
                let mut second = vec![T::ZERO; info.n_out];
                for o in 0..info.n_out {
                    let d1 = act.derivative_from_output(a_l[o]);
                    let gz = g_l[o] * d1;
                    let row = info.weight_offset + o * info.n_in;
                    let mut dgz = T::ZERO;
                    for i in 0..info.n_in {
                        gw[row + i] += gz * dg[i];
                        dgz += w[row + i] * dg[i];
                    }
                    next[o] = d1 * dgz;
                    second[o] = second_derivative_from_output(act, a_l[o]) * g_l[o] * dgz;
                }
                dz2.push(second);
                dg = next;
            }
            for (i, d) in dg.iter().enumerate() {
                gw[top.weight_offset + i] += *d;
            }
            // Down the network from D_out, the second-order terms joining.
            let a_top: &[T] = match hidden.last() {
                Some(info) => &ctx.hidden[hidden.len() - 1][p * info.n_out..(p + 1) * info.n_out],
                None => &ctx.input[p * n_in..(p + 1) * n_in],
            };
            let delta = &d_out[p * top.n_out..(p + 1) * top.n_out];
            let mut da = vec![T::ZERO; top.n_in];
            for (o, d) in delta.iter().enumerate() {
                let row = top.weight_offset + o * top.n_in;
                for i in 0..top.n_in {
                    gw[row + i] += *d * a_top[i];
                    da[i] += *d * w[row + i];
                }
                gw[top.bias_offset + o] += *d;
            }
            for (l, info) in hidden.iter().enumerate().rev() {
                let a_l = &ctx.hidden[l][p * info.n_out..(p + 1) * info.n_out];
                let a_below: &[T] = if l == 0 {
                    &ctx.input[p * n_in..(p + 1) * n_in]
                } else {
                    let prev = hidden[l - 1];
                    &ctx.hidden[l - 1][p * prev.n_out..(p + 1) * prev.n_out]
                };
                let mut da_below = vec![T::ZERO; info.n_in];
                for o in 0..info.n_out {
                    let dz = act.derivative_from_output(a_l[o]) * da[o] + dz2[l][o];
                    let row = info.weight_offset + o * info.n_in;
                    for i in 0..info.n_in {
                        gw[row + i] += dz * a_below[i];
                        da_below[i] += dz * w[row + i];
                    }
                    gw[info.bias_offset + o] += dz;
                }
                da = da_below;
            }
            d_enc[p * ne..(p + 1) * ne].copy_from_slice(&da[3..]);
        }
        field.grid.backward_params(
            &ctx.unit,
            &[&d_enc],
            n.max(1),
            ne,
            0,
            active,
            &mut grads.grid,
        );
    }
}
