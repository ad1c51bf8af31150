//! Small fully connected networks with explicit forward and backward passes.
//!
//! Batches are row-major matrices (one row per point). Work is done per
//! [`MlpChunk`] of at most [`CHUNK_ROWS`] rows; each chunk owns its buffers
//! (input, the output of every layer, scratch for the backward pass and its
//! own parameter-gradient partial). The partials are summed in chunk order,
//! so results do not depend on the number of threads.
//!
//! A chunk's input rows and their gradient are stored column-major (each
//! input column contiguous, leading dimension [`MlpChunk::ld`]), so that an
//! encoder filling one column group for many chunks writes and reads
//! contiguous runs; the layer outputs are stored the same way, and the
//! layers run on the kernels of [`crate::dense`].
//!
//! Parameter layout: layer after layer, the weight matrix `W` (`out × in`,
//! row-major) followed by the bias (`out`). A layer computes
//! `a = act(W · input + b)`.

use crate::activation::Activation;
use crate::dense::{linear_backward_params, linear_forward};
use crate::error::FieldError;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wildlight_real::Real;

/// Rows per chunk: the unit of parallel work and of the deterministic reductions.
pub const CHUNK_ROWS: usize = 256;

/// Shape and activations of an MLP.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MlpConfig {
    /// Inputs per point.
    pub n_input: usize,
    /// Width of each hidden layer (may be empty: a single linear layer).
    pub hidden: Vec<usize>,
    /// Outputs per point.
    pub n_output: usize,
    /// Activation after every hidden layer.
    pub hidden_activation: Activation,
    /// Activation after the last layer.
    pub output_activation: Activation,
}

/// Where one layer's parameters are.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayerInfo {
    /// Inputs of the layer.
    pub n_in: usize,
    /// Outputs of the layer.
    pub n_out: usize,
    /// Offset of `W` in the flat parameters.
    pub weight_offset: usize,
    /// Offset of `b` in the flat parameters.
    pub bias_offset: usize,
}

/// An MLP with its parameters.
#[derive(Clone, Debug)]
pub struct Mlp<T> {
    config: MlpConfig,
    layers: Vec<LayerInfo>,
    /// All weights and biases (layout in the module docs).
    pub params: Vec<T>,
}

/// Buffers of one chunk of rows (reused across calls).
#[derive(Clone, Debug, Default)]
pub struct MlpChunk<T> {
    /// Rows in use.
    pub rows: usize,
    /// Leading dimension of `input` and `d_input`: input `j` of row `r` is at
    /// `j · ld + r` (`ld ≥ rows`; [`CHUNK_ROWS`] for chunks of at most that many rows).
    pub ld: usize,
    /// Input values (column-major, see `ld`), filled by the caller before [`Mlp::forward_chunk`].
    pub input: Vec<T>,
    /// Output of each layer after its activation (column-major: unit `o` of
    /// row `r` at `o · ld + r`).
    pub acts: Vec<Vec<T>>,
    /// Gradient w.r.t. the inputs (column-major like `input`), written by [`Mlp::backward_chunk`].
    pub d_input: Vec<T>,
    /// This chunk's parameter-gradient partial, written by [`Mlp::backward_chunk`].
    pub grad: Vec<T>,
}

impl<T: Real> MlpChunk<T> {
    /// The last layer's outputs (column-major, leading dimension `ld`).
    pub fn output(&self) -> &[T] {
        self.acts.last().map(|a| a.as_slice()).unwrap_or(&[])
    }
    /// Writes the last layer's outputs as `rows × n_output` row-major values into `out`.
    pub fn write_output_rows(&self, out: &mut [T]) {
        let src = self.output();
        let n_out = src.len() / self.ld.max(1);
        assert!(
            out.len() >= self.rows * n_out,
            "write_output_rows: out too small"
        );
        if n_out == 0 {
            return;
        }
        for (r, row) in out.chunks_exact_mut(n_out).take(self.rows).enumerate() {
            for (o, v) in row.iter_mut().enumerate() {
                *v = src[o * self.ld + r];
            }
        }
    }
}

/// Scratch of the backward pass of one chunk (per worker, not per chunk, so
/// that large batches do not hold it for every chunk).
#[derive(Clone, Debug, Default)]
pub struct MlpScratch<T> {
    delta: Vec<T>,
    delta_prev: Vec<T>,
}

/// Buffers of a batched forward/backward through an [`Mlp`] (reused across calls).
#[derive(Clone, Debug, Default)]
pub struct MlpContext<T> {
    n: usize,
    chunks: Vec<MlpChunk<T>>,
    output: Vec<T>,
}

impl<T: Real> MlpContext<T> {
    /// An empty context; buffers grow on first use.
    pub fn new() -> Self {
        MlpContext {
            n: 0,
            chunks: Vec::new(),
            output: Vec::new(),
        }
    }
    /// Output rows of the last forward pass (`n × n_output`).
    pub fn output(&self) -> &[T] {
        &self.output
    }
}

/// Standard normal sample (Box–Muller).
pub(crate) fn normal<R: Rng>(rng: &mut R) -> f64 {
    let u1: f64 = rng.random_range(f64::MIN_POSITIVE..1.0);
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

impl<T: Real> Mlp<T> {
    /// Builds the network with Glorot-uniform weights and zero biases (seeded).
    pub fn new(config: &MlpConfig, seed: u64) -> Result<Self, FieldError> {
        let bad = |m: &str| Err(FieldError::InvalidConfig(format!("mlp: {m}")));
        if config.n_input == 0 || config.n_output == 0 || config.hidden.contains(&0) {
            return bad("every layer needs at least one unit");
        }
        if !config.hidden_activation.is_valid() || !config.output_activation.is_valid() {
            return bad("softplus beta must be finite and > 0");
        }
        let mut dims = vec![config.n_input];
        dims.extend(&config.hidden);
        dims.push(config.n_output);
        let mut layers = Vec::new();
        let mut off = 0;
        for w in dims.windows(2) {
            layers.push(LayerInfo {
                n_in: w[0],
                n_out: w[1],
                weight_offset: off,
                bias_offset: off + w[0] * w[1],
            });
            off += w[0] * w[1] + w[1];
        }
        let mut mlp = Mlp {
            config: config.clone(),
            layers,
            params: vec![T::ZERO; off],
        };
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed ^ 0x006d_6c70);
        for li in mlp.layers.clone() {
            let lim = (6.0 / (li.n_in + li.n_out) as f64).sqrt();
            for v in &mut mlp.params[li.weight_offset..li.bias_offset] {
                *v = T::from_f64(rng.random_range(-lim..=lim));
            }
        }
        Ok(mlp)
    }

    /// The settings.
    pub fn config(&self) -> &MlpConfig {
        &self.config
    }
    /// Parameter locations of every layer.
    pub fn layers(&self) -> &[LayerInfo] {
        &self.layers
    }
    /// Number of parameters.
    pub fn n_params(&self) -> usize {
        self.params.len()
    }

    fn activation(&self, layer: usize) -> Activation {
        if layer + 1 == self.layers.len() {
            self.config.output_activation
        } else {
            self.config.hidden_activation
        }
    }

    /// Sizes the buffers of `ch` for `rows` rows (no allocation when already large enough).
    pub fn prepare_chunk(&self, ch: &mut MlpChunk<T>, rows: usize) {
        ch.rows = rows;
        ch.ld = rows.max(CHUNK_ROWS);
        ch.input.resize(ch.ld * self.config.n_input, T::ZERO);
        ch.acts.resize_with(self.layers.len(), Vec::new);
        for (a, l) in ch.acts.iter_mut().zip(&self.layers) {
            a.resize(ch.ld * l.n_out, T::ZERO);
        }
        ch.d_input.resize(ch.ld * self.config.n_input, T::ZERO);
        ch.grad.resize(self.params.len(), T::ZERO);
    }

    /// Forward pass of one chunk whose `input` is filled (after [`Mlp::prepare_chunk`]).
    pub fn forward_chunk(&self, ch: &mut MlpChunk<T>) {
        let (rows, ld) = (ch.rows, ch.ld);
        for (i, l) in self.layers.iter().enumerate() {
            let (before, after) = ch.acts.split_at_mut(i);
            let input: &[T] = if i == 0 { &ch.input } else { &before[i - 1] };
            let out = &mut after[0][..l.n_out * ld];
            let w = &self.params[l.weight_offset..l.bias_offset];
            let bias = &self.params[l.bias_offset..l.bias_offset + l.n_out];
            linear_forward(l.n_in, l.n_out, rows, ld, w, (l.n_in, 1), bias, input, out);
            let act = self.activation(i);
            if rows == ld {
                act.forward_in_place(out);
            } else {
                for col in out.chunks_exact_mut(ld) {
                    act.forward_in_place(&mut col[..rows]);
                }
            }
        }
    }

    /// Backward pass of one chunk after [`Mlp::forward_chunk`]: given `d_out`
    /// (`rows × n_output`, row-major, w.r.t. the activated outputs), overwrites
    /// `ch.grad` with this chunk's parameter gradient and `ch.d_input` with the
    /// gradient w.r.t. the inputs.
    pub fn backward_chunk(&self, ch: &mut MlpChunk<T>, d_out: &[T], sc: &mut MlpScratch<T>) {
        let (rows, ld) = (ch.rows, ch.ld);
        let max_w = self
            .layers
            .iter()
            .map(|l| l.n_out.max(l.n_in))
            .max()
            .unwrap_or(0);
        if sc.delta.len() < ld * max_w {
            sc.delta.resize(ld * max_w, T::ZERO);
            sc.delta_prev.resize(ld * max_w, T::ZERO);
        }
        let n_layers = self.layers.len();
        ch.grad.fill(T::ZERO);
        let last = self.layers[n_layers - 1];
        let n_out = last.n_out;
        assert!(d_out.len() >= rows * n_out, "mlp backward: d_out length");
        for (r, row) in d_out[..rows * n_out].chunks_exact(n_out).enumerate() {
            for (o, &v) in row.iter().enumerate() {
                sc.delta[o * ld + r] = v;
            }
        }
        let act_backward = |act: Activation, a: &[T], d: &mut [T], width: usize| {
            for (ac, dc) in a[..width * ld]
                .chunks_exact(ld)
                .zip(d[..width * ld].chunks_exact_mut(ld))
            {
                act.backward_in_place(&ac[..rows], &mut dc[..rows]);
            }
        };
        act_backward(
            self.activation(n_layers - 1),
            &ch.acts[n_layers - 1],
            &mut sc.delta,
            n_out,
        );
        for i in (0..n_layers).rev() {
            let l = self.layers[i];
            let input: &[T] = if i == 0 { &ch.input } else { &ch.acts[i - 1] };
            let delta = &sc.delta[..l.n_out * ld];
            // dW += delta · inputᵀ, db += Σ_r delta
            let (gw, gb) =
                ch.grad[l.weight_offset..l.bias_offset + l.n_out].split_at_mut(l.n_in * l.n_out);
            linear_backward_params(l.n_in, l.n_out, rows, ld, delta, input, gw, gb);
            // d input = Wᵀ · delta
            let w = &self.params[l.weight_offset..l.bias_offset];
            let dst: &mut [T] = if i == 0 {
                &mut ch.d_input[..l.n_in * ld]
            } else {
                &mut sc.delta_prev[..l.n_in * ld]
            };
            linear_forward(l.n_out, l.n_in, rows, ld, w, (1, l.n_in), &[], delta, dst);
            if i > 0 {
                act_backward(
                    self.activation(i - 1),
                    &ch.acts[i - 1],
                    &mut sc.delta_prev,
                    l.n_in,
                );
                std::mem::swap(&mut sc.delta, &mut sc.delta_prev);
            }
        }
    }

    /// Adds the chunk partials to `grad` in chunk order (deterministic).
    pub fn reduce_chunk_grads(chunks: &[MlpChunk<T>], grad: &mut [T]) {
        for ch in chunks {
            for (g, &c) in grad.iter_mut().zip(&ch.grad) {
                *g += c;
            }
        }
    }

    /// Batched forward pass of `n = input.len() / n_input` rows; the output is
    /// in `ctx.output()`. Parallel over chunks.
    pub fn forward(&self, input: &[T], ctx: &mut MlpContext<T>) {
        let n_in = self.config.n_input;
        assert_eq!(input.len() % n_in, 0, "mlp forward: input length");
        let n = input.len() / n_in;
        ctx.n = n;
        let n_chunks = n.div_ceil(CHUNK_ROWS);
        ctx.chunks.resize_with(n_chunks, MlpChunk::default);
        let n_out = self.config.n_output;
        ctx.output.resize(n * n_out, T::ZERO);
        ctx.chunks
            .par_iter_mut()
            .zip(input.par_chunks(CHUNK_ROWS * n_in))
            .zip(ctx.output.par_chunks_mut(CHUNK_ROWS * n_out))
            .for_each(|((ch, inp), out)| {
                self.prepare_chunk(ch, inp.len() / n_in);
                let ld = ch.ld;
                for (r, row) in inp.chunks_exact(n_in).enumerate() {
                    for (j, &v) in row.iter().enumerate() {
                        ch.input[j * ld + r] = v;
                    }
                }
                self.forward_chunk(ch);
                ch.write_output_rows(out);
            });
    }

    /// Batched backward pass after [`Mlp::forward`]: accumulates the parameter
    /// gradient into `grad` and, when given, overwrites `d_input` (`n × n_input`).
    pub fn backward(
        &self,
        ctx: &mut MlpContext<T>,
        d_out: &[T],
        grad: &mut [T],
        d_input: Option<&mut [T]>,
    ) {
        let n_out = self.config.n_output;
        let n_in = self.config.n_input;
        assert_eq!(d_out.len(), ctx.n * n_out, "mlp backward: d_out length");
        assert_eq!(grad.len(), self.params.len(), "mlp backward: grad length");
        ctx.chunks
            .par_iter_mut()
            .zip(d_out.par_chunks(CHUNK_ROWS * n_out))
            .for_each_init(MlpScratch::default, |sc, (ch, d)| {
                self.backward_chunk(ch, d, sc)
            });
        Self::reduce_chunk_grads(&ctx.chunks, grad);
        if let Some(di) = d_input {
            assert_eq!(di.len(), ctx.n * n_in, "mlp backward: d_input length");
            for (dst, ch) in di.chunks_mut(CHUNK_ROWS * n_in).zip(&ctx.chunks) {
                for (r, row) in dst.chunks_exact_mut(n_in).enumerate() {
                    for (j, v) in row.iter_mut().enumerate() {
                        *v = ch.d_input[j * ch.ld + r];
                    }
                }
            }
        }
    }

    /// Re-initialises layer `layer`'s weights with `N(mean, std²)` for columns
    /// `cols` of rows `rows`, and sets those rows' biases to `bias` (when given).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn init_block<R: Rng>(
        &mut self,
        layer: usize,
        rows: std::ops::Range<usize>,
        cols: std::ops::Range<usize>,
        mean: f64,
        std: f64,
        bias: Option<f64>,
        rng: &mut R,
    ) {
        let l = self.layers[layer];
        for r in rows {
            for c in cols.clone() {
                self.params[l.weight_offset + r * l.n_in + c] =
                    T::from_f64(mean + std * normal(rng));
            }
            if let Some(b) = bias {
                self.params[l.bias_offset + r] = T::from_f64(b);
            }
        }
    }
}
