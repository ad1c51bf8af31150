//! A neural field: hash encoding of the position + MLP, with optional raw
//! inputs concatenated in front of the encoding.
//!
//! MLP input row of point `p`: `[x_p (3, when include_position) | extra_p (n_extra) | encoding(x_p)]`.
//! Positions live in the normalized frame; the encoding sees
//! `(x + bound) / (2·bound)` ∈ `[0,1]³` (points outside are clamped).
//!
//! This is the building block of the SDF field and of the colour/material and
//! ambient-radiance fields the trainer builds (extra inputs: geometry
//! features, SH-encoded directions, normals, …).

use crate::activation::Activation;
use crate::error::FieldError;
use crate::hash_grid::{BlockLayout, HashGrid, HashGridConfig};
use crate::mlp::{CHUNK_ROWS, Mlp, MlpChunk, MlpConfig, MlpScratch};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wildlight_real::Real;

/// Settings of a [`NeuralField`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NeuralFieldConfig {
    /// The position encoding.
    pub grid: HashGridConfig,
    /// Half edge of the encoded cube `[−bound, bound]³` (normalized frame).
    pub bound: f32,
    /// Feed the raw position to the MLP too.
    pub include_position: bool,
    /// Extra per-point inputs supplied by the caller.
    pub n_extra: usize,
    /// Hidden layer widths.
    pub hidden: Vec<usize>,
    /// Activation after hidden layers.
    pub hidden_activation: Activation,
    /// Outputs per point.
    pub n_output: usize,
    /// Activation of the outputs.
    pub output_activation: Activation,
}

/// Parameter gradients of a [`NeuralField`] (flat, same layouts as the parameters).
#[derive(Clone, Debug)]
pub struct FieldGrads<T> {
    /// Gradient of the hash-table entries.
    pub grid: Vec<T>,
    /// Gradient of the MLP parameters.
    pub mlp: Vec<T>,
}

impl<T: Real> FieldGrads<T> {
    /// Sets every gradient to zero.
    pub fn zero(&mut self) {
        self.grid.fill(T::ZERO);
        self.mlp.fill(T::ZERO);
    }

    /// Whether every gradient is finite ([`crate::all_finite`]).
    pub fn all_finite(&self) -> bool {
        crate::all_finite(&self.grid) && crate::all_finite(&self.mlp)
    }
}

/// Buffers of a batched pass through a [`NeuralField`] (reused across calls).
#[derive(Clone, Debug, Default)]
pub struct FieldContext<T> {
    n: usize,
    /// Encoder coordinates in `[0,1]³` (before clamping).
    unit: Vec<[T; 3]>,
    chunks: Vec<MlpChunk<T>>,
    output: Vec<T>,
}

impl<T: Real> FieldContext<T> {
    /// An empty context.
    pub fn new() -> Self {
        FieldContext {
            n: 0,
            unit: Vec::new(),
            chunks: Vec::new(),
            output: Vec::new(),
        }
    }
    /// Points of the last forward pass.
    pub fn len(&self) -> usize {
        self.n
    }
    /// Whether the last forward pass had no points.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }
    /// Outputs of the last forward pass (`n × n_output`, row-major).
    pub fn output(&self) -> &[T] {
        &self.output
    }
    /// The encoder coordinates of the last forward pass.
    pub(crate) fn unit(&self) -> &[[T; 3]] {
        &self.unit
    }
    /// The network's chunks of the last forward pass (inputs and layer
    /// outputs, column-major).
    pub(crate) fn chunks(&self) -> &[MlpChunk<T>] {
        &self.chunks
    }
}

/// Hash encoding + MLP (see module docs).
#[derive(Clone, Debug)]
pub struct NeuralField<T> {
    config: NeuralFieldConfig,
    /// The position encoding.
    pub grid: HashGrid<T>,
    /// The network.
    pub mlp: Mlp<T>,
    /// Levels in use (coarse-to-fine training); finer levels output 0.
    pub active_levels: usize,
}

impl<T: Real> NeuralField<T> {
    /// Builds the field (seeded initialisation: hash entries uniform in
    /// `±init_range`, MLP Glorot-uniform).
    pub fn new(config: &NeuralFieldConfig, seed: u64) -> Result<Self, FieldError> {
        if !(config.bound.is_finite() && config.bound > 0.0) {
            return Err(FieldError::InvalidConfig(
                "field: bound must be finite and > 0".into(),
            ));
        }
        let grid = HashGrid::new(&config.grid, seed)?;
        let n_input = 3 * usize::from(config.include_position) + config.n_extra + grid.n_outputs();
        let mlp = Mlp::new(
            &MlpConfig {
                n_input,
                hidden: config.hidden.clone(),
                n_output: config.n_output,
                hidden_activation: config.hidden_activation,
                output_activation: config.output_activation,
            },
            seed.wrapping_add(1),
        )?;
        Ok(NeuralField {
            config: config.clone(),
            active_levels: config.grid.n_levels,
            grid,
            mlp,
        })
    }

    /// The settings.
    pub fn config(&self) -> &NeuralFieldConfig {
        &self.config
    }
    /// Outputs per point.
    pub fn n_output(&self) -> usize {
        self.config.n_output
    }
    /// Column of the first encoding value in the MLP input.
    pub fn encoding_column(&self) -> usize {
        3 * usize::from(self.config.include_position) + self.config.n_extra
    }
    /// Column of the first extra input in the MLP input.
    pub fn extra_column(&self) -> usize {
        3 * usize::from(self.config.include_position)
    }
    /// Whether every parameter (hash table and MLP) is finite
    /// ([`crate::all_finite`]).
    pub fn all_finite(&self) -> bool {
        crate::all_finite(&self.grid.params) && crate::all_finite(&self.mlp.params)
    }
    /// Zeroed gradient buffers of the right sizes.
    pub fn new_grads(&self) -> FieldGrads<T> {
        FieldGrads {
            grid: crate::memory::huge_vec(self.grid.n_params()),
            mlp: vec![T::ZERO; self.mlp.n_params()],
        }
    }
    /// Edge of a cell of `level` in normalized-frame units (e.g. for the FD step).
    pub fn cell_size(&self, level: usize) -> f64 {
        self.grid.cell_size(level) * 2.0 * self.config.bound as f64
    }

    /// Batched forward pass: `x` (n points), `extra` (`n × n_extra`, row-major;
    /// empty when `n_extra = 0`). Results in `ctx.output()`. Parallel over
    /// fixed chunks of [`CHUNK_ROWS`] points.
    ///
    /// The encoding runs level-major over the whole batch (all points visit
    /// level 0, then level 1, …), so that one level's table stays in the
    /// cache while it is used; the MLP then runs chunk by chunk.
    pub fn forward(&self, x: &[[T; 3]], extra: &[T], ctx: &mut FieldContext<T>) {
        let n = x.len();
        let ne = self.config.n_extra;
        assert_eq!(extra.len(), n * ne, "field forward: extra length");
        ctx.n = n;
        let b = T::from_f64(self.config.bound as f64);
        let inv = T::ONE / (b + b);
        ctx.unit.resize(n, [T::ZERO; 3]);
        ctx.chunks
            .resize_with(n.div_ceil(CHUNK_ROWS), MlpChunk::default);
        let n_out = self.config.n_output;
        ctx.output.resize(n * n_out, T::ZERO);
        let enc_col = self.encoding_column();
        let ex_col = self.extra_column();
        let pos = self.config.include_position;
        // Raw inputs (column-major chunk inputs) and encoder coordinates.
        ctx.chunks
            .par_iter_mut()
            .zip(ctx.unit.par_chunks_mut(CHUNK_ROWS))
            .enumerate()
            .for_each(|(c, (ch, unit))| {
                let start = c * CHUNK_ROWS;
                let rows = unit.len();
                self.mlp.prepare_chunk(ch, rows);
                let ld = ch.ld;
                for (r, (u, p)) in unit.iter_mut().zip(&x[start..start + rows]).enumerate() {
                    *u = [(p[0] + b) * inv, (p[1] + b) * inv, (p[2] + b) * inv];
                    if pos {
                        for k in 0..3 {
                            ch.input[k * ld + r] = p[k];
                        }
                    }
                    for e in 0..ne {
                        ch.input[(ex_col + e) * ld + r] = extra[(start + r) * ne + e];
                    }
                }
            });
        // Encoding, level-major over the whole batch.
        let mut outs: Vec<&mut [T]> = ctx
            .chunks
            .iter_mut()
            .map(|ch| ch.input.as_mut_slice())
            .collect();
        self.grid.encode_blocks(
            &ctx.unit,
            &mut outs,
            BlockLayout::column_major(CHUNK_ROWS),
            enc_col,
            self.active_levels,
        );
        drop(outs);
        ctx.chunks
            .par_iter_mut()
            .zip(ctx.output.par_chunks_mut(CHUNK_ROWS * n_out))
            .for_each(|(ch, out)| {
                self.mlp.forward_chunk(ch);
                ch.write_output_rows(out);
            });
    }

    /// The network's half of [`NeuralField::backward`]: accumulates (`+=`)
    /// the MLP's parameter gradient into `grad_mlp` and leaves the gradient
    /// with respect to the network's inputs in `ctx`. For a caller that
    /// needs the network's gradient alone, it spares the hash table's
    /// scatter.
    pub fn backward_network(&self, ctx: &mut FieldContext<T>, d_out: &[T], grad_mlp: &mut [T]) {
        let n_out = self.config.n_output;
        assert_eq!(d_out.len(), ctx.n * n_out, "field backward: d_out length");
        ctx.chunks
            .par_iter_mut()
            .zip(d_out.par_chunks(CHUNK_ROWS * n_out))
            .for_each_init(MlpScratch::default, |sc, (ch, d)| {
                self.mlp.backward_chunk(ch, d, sc)
            });
        Mlp::reduce_chunk_grads(&ctx.chunks, grad_mlp);
    }

    /// Batched backward pass after [`NeuralField::forward`] with upstream
    /// gradients `d_out` (`n × n_output`). Accumulates (`+=`) into `grads`;
    /// overwrites `d_extra` (`n × n_extra`) and `d_x` when given.
    pub fn backward(
        &self,
        ctx: &mut FieldContext<T>,
        d_out: &[T],
        grads: &mut FieldGrads<T>,
        d_extra: Option<&mut [T]>,
        d_x: Option<&mut [[T; 3]]>,
    ) {
        let n = ctx.n;
        self.backward_network(ctx, d_out, &mut grads.mlp);
        let enc_col = self.encoding_column();
        let blocks: Vec<&[T]> = ctx.chunks.iter().map(|c| c.d_input.as_slice()).collect();
        let layout = BlockLayout::column_major(CHUNK_ROWS);
        self.grid.backward_params_blocks(
            &ctx.unit,
            &blocks,
            layout,
            enc_col,
            self.active_levels,
            &mut grads.grid,
        );
        if let Some(de) = d_extra {
            let ne = self.config.n_extra;
            let ex_col = self.extra_column();
            assert_eq!(de.len(), n * ne, "field backward: d_extra length");
            for (p, row) in
                de.chunks_exact_mut(ne.max(1))
                    .enumerate()
                    .take(if ne == 0 { 0 } else { n })
            {
                let ch = &ctx.chunks[p / CHUNK_ROWS];
                let r = p % CHUNK_ROWS;
                for (e, v) in row.iter_mut().enumerate() {
                    *v = ch.d_input[(ex_col + e) * ch.ld + r];
                }
            }
        }
        if let Some(dx) = d_x {
            assert_eq!(dx.len(), n, "field backward: d_x length");
            let b = T::from_f64(self.config.bound as f64);
            let inv = T::ONE / (b + b);
            let pos = self.config.include_position;
            let unit = &ctx.unit;
            ctx.chunks
                .par_iter()
                .zip(dx.par_chunks_mut(CHUNK_ROWS))
                .enumerate()
                .for_each(|(c, (ch, dxc))| {
                    let start = c * CHUNK_ROWS;
                    dxc.fill([T::ZERO; 3]);
                    self.grid.backward_input_block(
                        &unit[start..start + dxc.len()],
                        &ch.d_input,
                        layout,
                        enc_col,
                        self.active_levels,
                        dxc,
                    );
                    for (r, g) in dxc.iter_mut().enumerate() {
                        for k in 0..3 {
                            g[k] *= inv;
                            if pos {
                                g[k] += ch.d_input[k * ch.ld + r];
                            }
                        }
                    }
                });
        }
    }
}
