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
//! scheme. [`SdfField::forward_with_gradient`] and its backward pass work
//! point by point, as the oracle of the batched kernels
//! ([`SdfField::forward_with_gradient_batched`]) that passes with
//! [`crate::NormalMethod::Analytic`] run: chunks of rows through the
//! `dense` kernels, the table's derivatives through the hash grid's blocked
//! level walk ([`crate::HashGrid::encode_directional_blocks`],
//! [`crate::HashGrid::backward_params_directional_blocks`]).

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

/// σ''(z) of `act` from its output `a` and its slope `s = σ'(z)` (both
/// known in the passes below, so no activation is evaluated again).
#[inline(always)]
fn curvature<T: Real>(act: Activation, a: T, s: T) -> T {
    match act {
        Activation::None | Activation::Relu => T::ZERO,
        // σ' = s, σ'' = β s (1 − s)
        Activation::Softplus { beta } => T::from_f64(beta as f64) * s * (T::ONE - s),
        // σ' = a (1 − a) = s, σ'' = s (1 − 2a)
        Activation::Sigmoid => s * (T::ONE - a - a),
    }
}

/// The per-chunk buffers of [`SdfField::forward_with_gradient_batched`],
/// column-major with leading dimension [`crate::CHUNK_ROWS`], kept across calls.
#[derive(Clone, Debug, Default)]
struct GradientChunk<T> {
    /// σ'(z_l) of each hidden layer.
    slope: Vec<Vec<T>>,
    /// g_{a_l} = ∂φ/∂a_l of each hidden layer.
    g_hidden: Vec<Vec<T>>,
    /// g_{a₀}.
    g_input: Vec<T>,
    /// D g_{a₀} = [D_∇ | D g_e] of the backward pass.
    d_g_input: Vec<T>,
    /// The second-order terms D z_l of each hidden layer.
    second: Vec<Vec<T>>,
    /// D a₀ of the ordinary backward pass, for the table.
    d_input: Vec<T>,
    /// Scratch of the widest layer: products and the gradient's chain.
    scratch: [Vec<T>; 3],
    /// J_eᵀ g_e of each row.
    from_grid: Vec<[T; 3]>,
    /// The chunk's MLP gradient partial.
    grad: Vec<T>,
}

/// What [`SdfField::forward_with_gradient_batched`] keeps for its backward
/// pass: the field's own forward context and the gradient's chain.
#[derive(Clone, Debug, Default)]
pub struct BatchedGradientContext<T> {
    field: crate::neural_field::FieldContext<T>,
    chunks: Vec<GradientChunk<T>>,
    /// D_∇ / (2b) of each point (the backward pass's table directions).
    directions: Vec<[T; 3]>,
    /// ∇φ of each point (normalized frame).
    pub gradient: Vec<[T; 3]>,
}

impl<T: Real> BatchedGradientContext<T> {
    /// An empty context.
    pub fn new() -> Self {
        Self::default()
    }
    /// `[sdf, features…]` of each point (`n × n_output`, row-major).
    pub fn output(&self) -> &[T] {
        self.field.output()
    }
}

/// `out = Wᵀ · values` for layer `info` (its weights in `w`, the MLP's flat
/// parameters): `info.n_out` columns of `rows` rows in, `info.n_in` out,
/// column-major with leading dimension `ld`.
fn transposed_product<T: Real>(
    info: &crate::mlp::LayerInfo,
    w: &[T],
    rows: usize,
    ld: usize,
    values: &[T],
    out: &mut [T],
) {
    crate::dense::linear_forward(
        info.n_out,
        info.n_in,
        rows,
        ld,
        &w[info.weight_offset..info.bias_offset],
        (1, info.n_in),
        &[],
        values,
        &mut out[..info.n_in * ld],
    );
}

/// Sizes `buf` to `len` values (contents unspecified: every user overwrites).
fn sized<T: Real>(buf: &mut Vec<T>, len: usize) -> &mut [T] {
    buf.resize(len, T::ZERO);
    &mut buf[..len]
}

impl<T: Real + Send + Sync> SdfField<T> {
    /// [`SdfField::forward_with_gradient`] over the field's batched kernels:
    /// the field's chunked forward pass, then per chunk of rows the
    /// network run backwards from the SDF output (`dense` kernels) and the
    /// encoding's Jacobian transposed. Parallel over chunks.
    pub fn forward_with_gradient_batched(&self, x: &[[T; 3]], ctx: &mut BatchedGradientContext<T>) {
        use crate::hash_grid::BlockLayout;
        use rayon::prelude::*;
        let field = &self.field;
        let cfg = field.config();
        assert!(cfg.include_position && cfg.n_extra == 0);
        assert_eq!(cfg.output_activation, Activation::None);
        let act = cfg.hidden_activation;
        field.forward(x, &[], &mut ctx.field);
        let layers = field.mlp.layers();
        let hidden = &layers[..layers.len() - 1];
        let top = layers[layers.len() - 1];
        let w = &field.mlp.params;
        let w0 = &w[top.weight_offset..top.weight_offset + top.n_in];
        let n_in = layers[0].n_in;
        let widest = layers
            .iter()
            .map(|l| l.n_out.max(l.n_in))
            .max()
            .unwrap_or(0);
        let active = field.active_levels;
        let b = T::from_f64(cfg.bound as f64);
        let inv = T::ONE / (b + b);
        let ld = crate::CHUNK_ROWS;
        let n_chunks = ctx.field.chunks().len();
        ctx.chunks.resize_with(n_chunks, GradientChunk::default);
        ctx.gradient.resize(x.len(), [T::ZERO; 3]);
        let unit = ctx.field.unit();
        let fchunks = ctx.field.chunks();
        ctx.chunks
            .par_iter_mut()
            .zip(ctx.gradient.par_chunks_mut(ld))
            .enumerate()
            .for_each(|(c, (gc, grad_rows))| {
                let fc = &fchunks[c];
                let rows = fc.rows;
                debug_assert_eq!(fc.ld, ld);
                gc.slope.resize_with(hidden.len(), Vec::new);
                gc.g_hidden.resize_with(hidden.len(), Vec::new);
                for (l, info) in hidden.iter().enumerate() {
                    let s = sized(&mut gc.slope[l], info.n_out * ld);
                    for col in 0..info.n_out {
                        let (sc, a) = (&mut s[col * ld..col * ld + rows], &fc.acts[l]);
                        sc.fill(T::ONE);
                        act.backward_in_place(&a[col * ld..col * ld + rows], sc);
                    }
                    sized(&mut gc.g_hidden[l], info.n_out * ld);
                }
                let g_input = sized(&mut gc.g_input, n_in * ld);
                // g_{a_L} = W_{L+1}[0, :]ᵀ, then down: g_{a_{l−1}} = W_lᵀ (σ'(z_l) ⊙ g_{a_l}).
                let top_g: &mut [T] = match hidden.len() {
                    0 => g_input,
                    k => &mut gc.g_hidden[k - 1],
                };
                for (i, wi) in w0.iter().enumerate() {
                    top_g[i * ld..i * ld + rows].fill(*wi);
                }
                let gz = sized(&mut gc.scratch[0], widest * ld);
                for (l, info) in hidden.iter().enumerate().rev() {
                    let (g, s) = (&gc.g_hidden[l], &gc.slope[l]);
                    for col in 0..info.n_out {
                        let r = col * ld..col * ld + rows;
                        for ((z, gv), sv) in gz[r.clone()].iter_mut().zip(&g[r.clone()]).zip(&s[r])
                        {
                            *z = *gv * *sv;
                        }
                    }
                    let below: &mut [T] = if l == 0 {
                        &mut gc.g_input
                    } else {
                        &mut gc.g_hidden[l - 1]
                    };
                    transposed_product(info, w, rows, ld, gz, below);
                }
                let start = c * ld;
                gc.from_grid.clear();
                gc.from_grid.resize(rows, [T::ZERO; 3]);
                field.grid.backward_input_block(
                    &unit[start..start + rows],
                    &gc.g_input,
                    BlockLayout::column_major(ld),
                    3,
                    active,
                    &mut gc.from_grid,
                );
                for (r, out) in grad_rows.iter_mut().enumerate() {
                    *out = [0, 1, 2].map(|k| gc.g_input[k * ld + r] + gc.from_grid[r][k] * inv);
                }
            });
    }

    /// Backward pass of [`SdfField::forward_with_gradient_batched`], as
    /// [`SdfField::backward_with_gradient`]: accumulates into `grads`.
    /// Deterministic: chunk partials are summed in chunk order, the table's
    /// scatters are level-parallel.
    pub fn backward_with_gradient_batched(
        &self,
        ctx: &mut BatchedGradientContext<T>,
        d_out: &[T],
        d_gradient: &[[T; 3]],
        grads: &mut FieldGrads<T>,
    ) {
        use crate::dense::{linear_backward_params, linear_forward};
        use crate::hash_grid::BlockLayout;
        use rayon::prelude::*;
        let field = &self.field;
        let act = field.config().hidden_activation;
        let layers = field.mlp.layers();
        let hidden = &layers[..layers.len() - 1];
        let top = layers[layers.len() - 1];
        let w = &field.mlp.params;
        let n = d_gradient.len();
        let n_in = layers[0].n_in;
        let n_out = top.n_out;
        let widest = layers
            .iter()
            .map(|l| l.n_out.max(l.n_in))
            .max()
            .unwrap_or(0);
        let active = field.active_levels;
        let b = T::from_f64(field.config().bound as f64);
        let inv = T::ONE / (b + b);
        let ld = crate::CHUNK_ROWS;
        let layout = BlockLayout::column_major(ld);
        assert_eq!(d_out.len(), n * n_out, "d_out length");
        assert_eq!(n, ctx.gradient.len(), "d_gradient length");
        let unit = ctx.field.unit();
        let fchunks = ctx.field.chunks();
        // The table's share of J_eᵀ g_e: its derivative along D_∇ / (2b).
        ctx.directions.clear();
        ctx.directions
            .extend(d_gradient.iter().map(|d| d.map(|c| c * inv)));
        let v = &ctx.directions;
        {
            let blocks: Vec<&[T]> = ctx.chunks.iter().map(|c| c.g_input.as_slice()).collect();
            field.grid.backward_params_directional_blocks(
                unit,
                v,
                &blocks,
                layout,
                3,
                active,
                &mut grads.grid,
            );
        }
        // D g_{a₀} = [D_∇ | D g_e], D g_e = J_e D_∇ / (2b).
        ctx.chunks.par_iter_mut().enumerate().for_each(|(c, gc)| {
            let rows = fchunks[c].rows;
            let dg = sized(&mut gc.d_g_input, n_in * ld);
            for r in 0..rows {
                for k in 0..3 {
                    dg[k * ld + r] = d_gradient[c * ld + r][k];
                }
            }
        });
        {
            let mut blocks: Vec<&mut [T]> = ctx
                .chunks
                .iter_mut()
                .map(|c| c.d_g_input.as_mut_slice())
                .collect();
            field
                .grid
                .encode_directional_blocks(unit, v, &mut blocks, layout, 3, active);
        }
        let n_params = field.mlp.params.len();
        ctx.chunks.par_iter_mut().enumerate().for_each(|(c, gc)| {
            let fc = &fchunks[c];
            let rows = fc.rows;
            let start = c * ld;
            gc.grad.clear();
            gc.grad.resize(n_params, T::ZERO);
            let mut bias_scratch = vec![T::ZERO; widest];
            let [s0, s1, s2] = &mut gc.scratch;
            let (gz, mut dg_cur, mut dg_next) = (
                sized(s0, widest * ld),
                sized(s1, widest * ld),
                sized(s2, widest * ld),
            );
            dg_cur[..n_in * ld].copy_from_slice(&gc.d_g_input[..n_in * ld]);
            // Up the gradient's chain.
            gc.second.resize_with(hidden.len(), Vec::new);
            for (l, info) in hidden.iter().enumerate() {
                let (a_l, g_l, s_l) = (&fc.acts[l], &gc.g_hidden[l], &gc.slope[l]);
                for k in 0..info.n_out * ld {
                    gz[k] = g_l[k] * s_l[k];
                }
                let (gw, _) = gc.grad[info.weight_offset..].split_at_mut(info.n_out * info.n_in);
                linear_backward_params(
                    info.n_in,
                    info.n_out,
                    rows,
                    ld,
                    gz,
                    dg_cur,
                    gw,
                    &mut bias_scratch[..info.n_out],
                );
                let wl = &w[info.weight_offset..info.bias_offset];
                let dgz = &mut dg_next[..info.n_out * ld];
                linear_forward(
                    info.n_in,
                    info.n_out,
                    rows,
                    ld,
                    wl,
                    (info.n_in, 1),
                    &[],
                    dg_cur,
                    dgz,
                );
                let second = sized(&mut gc.second[l], info.n_out * ld);
                for col in 0..info.n_out {
                    for k in col * ld..col * ld + rows {
                        let (a, s) = (a_l[k], s_l[k]);
                        second[k] = curvature(act, a, s) * g_l[k] * dgz[k];
                        dgz[k] *= s;
                    }
                }
                std::mem::swap(&mut dg_cur, &mut dg_next);
            }
            for i in 0..top.n_in {
                let mut s = T::ZERO;
                for r in 0..rows {
                    s += dg_cur[i * ld + r];
                }
                gc.grad[top.weight_offset + i] += s;
            }
            // Down the network from D_out, the second-order terms joining.
            let delta = &mut dg_cur[..n_out * ld];
            for r in 0..rows {
                for o in 0..n_out {
                    delta[o * ld + r] = d_out[(start + r) * n_out + o];
                }
            }
            let a_top: &[T] = match hidden.len() {
                0 => &fc.input,
                k => &fc.acts[k - 1],
            };
            {
                let (gw, gb) = gc.grad[top.weight_offset..top.bias_offset + n_out]
                    .split_at_mut(top.n_in * n_out);
                linear_backward_params(top.n_in, n_out, rows, ld, delta, a_top, gw, gb);
            }
            let d_input = sized(&mut gc.d_input, n_in * ld);
            let da: &mut [T] = if hidden.is_empty() { d_input } else { dg_next };
            transposed_product(&top, w, rows, ld, delta, da);
            for (l, info) in hidden.iter().enumerate().rev() {
                let (s_l, second) = (&gc.slope[l], &gc.second[l]);
                for col in 0..info.n_out {
                    for k in col * ld..col * ld + rows {
                        gz[k] = dg_next[k] * s_l[k] + second[k];
                    }
                }
                let a_below: &[T] = if l == 0 { &fc.input } else { &fc.acts[l - 1] };
                {
                    let (gw, gb) = gc.grad[info.weight_offset..info.bias_offset + info.n_out]
                        .split_at_mut(info.n_in * info.n_out);
                    linear_backward_params(info.n_in, info.n_out, rows, ld, gz, a_below, gw, gb);
                }
                let below: &mut [T] = if l == 0 { &mut gc.d_input } else { dg_next };
                transposed_product(info, w, rows, ld, gz, below);
            }
        });
        for gc in &ctx.chunks {
            for (g, c) in grads.mlp.iter_mut().zip(&gc.grad) {
                *g += *c;
            }
        }
        let blocks: Vec<&[T]> = ctx.chunks.iter().map(|c| c.d_input.as_slice()).collect();
        field
            .grid
            .backward_params_blocks(unit, &blocks, layout, 3, active, &mut grads.grid);
    }
}
