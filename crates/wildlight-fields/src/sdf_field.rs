//! The SDF field: signed distance + geometry feature vector, with normals by
//! finite differences that are differentiable w.r.t. every parameter.
//!
//! Output row: `[sdf, feature_1 … feature_k]`. The network input is
//! `[x | hash encoding(x)]`.
//!
//! Geometric initialisation (Atzmon & Lipman, SAL; as used with hash-grid
//! features by Neuralangelo and instant-nsr-pl): weights of the `x` columns of
//! the first layer and of hidden layers `~ N(0, 2/width)`, weights of the
//! encoding columns 0, biases 0; the SDF row of the last layer
//! `~ N(√π/√width, 1e-4²)` with bias `−radius`, so the field starts as the
//! SDF of a sphere of that radius (with softplus hidden activations).
//!
//! Normals: the SDF gradient is estimated from extra evaluations at
//! `x + h·k_i`:
//! - tetrahedral: `k_i ∈ {(1,−1,−1), (−1,−1,1), (−1,1,−1), (1,1,1)}`,
//!   `∇φ ≈ Σ_i k_i φ(x + h k_i) / (4h)`;
//! - central: `∇φ_j ≈ (φ(x + h e_j) − φ(x − h e_j)) / (2h)`.
//!
//! All evaluations form one batch (point `p`'s main sample, then its offset
//! samples), so the backward pass is one field backward.

use crate::activation::Activation;
use crate::error::FieldError;
use crate::hash_grid::HashGridConfig;
use crate::neural_field::{FieldContext, FieldGrads, NeuralField, NeuralFieldConfig};
use crate::sdf_gradient::BatchedGradientContext;
use rand::SeedableRng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wildlight_real::Real;

/// Settings of an [`SdfField`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SdfFieldConfig {
    /// The position encoding.
    pub grid: HashGridConfig,
    /// Half edge of the encoded cube (normalized frame).
    pub bound: f32,
    /// Hidden layer widths.
    pub hidden: Vec<usize>,
    /// Activation after hidden layers (softplus with beta 100 for the sphere init).
    pub activation: Activation,
    /// Length of the geometry feature vector output next to the SDF.
    pub n_features: usize,
    /// Radius of the initial sphere of the geometric initialisation (`None`: plain init).
    pub sphere_init_radius: Option<f32>,
}

impl Default for SdfFieldConfig {
    /// 16×2 levels, 2^19 entries, resolutions 16…2048 over `[−1,1]³`, one
    /// hidden layer of 64 with softplus(100), 15 features, sphere of radius 0.5.
    fn default() -> Self {
        SdfFieldConfig {
            grid: HashGridConfig::default(),
            bound: 1.0,
            hidden: vec![64],
            activation: Activation::Softplus { beta: 100.0 },
            n_features: 15,
            sphere_init_radius: Some(0.5),
        }
    }
}

/// How normals are estimated.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum FdScheme {
    /// 4 extra evaluations.
    Tetrahedral,
    /// 6 extra evaluations.
    Central,
}

impl FdScheme {
    /// Offset directions `k_i` and the weights `c_i` with `∇φ ≈ Σ_i c_i k_i φ(x + h k_i) / h`.
    fn stencil(self) -> &'static [([f64; 3], f64)] {
        match self {
            FdScheme::Tetrahedral => &[
                ([1.0, -1.0, -1.0], 0.25),
                ([-1.0, -1.0, 1.0], 0.25),
                ([-1.0, 1.0, -1.0], 0.25),
                ([1.0, 1.0, 1.0], 0.25),
            ],
            FdScheme::Central => &[
                ([1.0, 0.0, 0.0], 0.5),
                ([-1.0, 0.0, 0.0], 0.5),
                ([0.0, 1.0, 0.0], 0.5),
                ([0.0, -1.0, 0.0], 0.5),
                ([0.0, 0.0, 1.0], 0.5),
                ([0.0, 0.0, -1.0], 0.5),
            ],
        }
    }
    /// Extra evaluations per point.
    pub fn n_offsets(self) -> usize {
        self.stencil().len()
    }
}

/// How [`SdfField::forward_with_normals`] computes the gradient ∇φ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NormalMethod {
    /// Finite differences with `scheme` and step `step` (normalized units).
    FiniteDifference {
        /// The offsets.
        scheme: FdScheme,
        /// Their length.
        step: f64,
    },
    /// The analytic gradient ([`crate::sdf_gradient`]): the field's forward
    /// pass and one reverse sweep instead of the offsets' evaluations.
    Analytic,
}

/// Buffers of a pass with normals (reused across calls).
#[derive(Clone, Debug, Default)]
pub struct NormalContext<T> {
    n: usize,
    method: Option<NormalMethod>,
    points: Vec<[T; 3]>,
    field: FieldContext<T>,
    analytic: BatchedGradientContext<T>,
    d_out: Vec<T>,
    /// SDF at each point.
    pub sdf: Vec<T>,
    /// Geometry features at each point (`n × n_features`).
    pub features: Vec<T>,
    /// Finite-difference SDF gradient at each point (not normalised).
    pub gradient: Vec<[T; 3]>,
}

impl<T: Real> NormalContext<T> {
    /// An empty context.
    pub fn new() -> Self {
        Self::default()
    }
}

/// Signed distance field (see module docs).
#[derive(Clone, Debug)]
pub struct SdfField<T> {
    config: SdfFieldConfig,
    /// The underlying encoding + MLP.
    pub field: NeuralField<T>,
}

impl<T: Real> SdfField<T> {
    /// Builds the field, with the geometric initialisation when configured.
    pub fn new(config: &SdfFieldConfig, seed: u64) -> Result<Self, FieldError> {
        let mut field = NeuralField::new(
            &NeuralFieldConfig {
                grid: config.grid.clone(),
                bound: config.bound,
                include_position: true,
                n_extra: 0,
                hidden: config.hidden.clone(),
                hidden_activation: config.activation,
                n_output: 1 + config.n_features,
                output_activation: Activation::None,
            },
            seed,
        )?;
        if let Some(radius) = config.sphere_init_radius {
            if !(radius.is_finite() && radius > 0.0) {
                return Err(FieldError::InvalidConfig(
                    "sdf: sphere_init_radius must be > 0".into(),
                ));
            }
            let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed ^ 0x5350_4845_5245);
            let mlp = &mut field.mlp;
            let layers = mlp.layers().to_vec();
            let last = layers.len() - 1;
            for (i, l) in layers.iter().enumerate() {
                if i < last {
                    let std = (2.0 / l.n_out as f64).sqrt();
                    let cols = if i == 0 { 0..3 } else { 0..l.n_in };
                    mlp.init_block(i, 0..l.n_out, cols, 0.0, std, Some(0.0), &mut rng);
                    if i == 0 {
                        // encoding columns start at 0: the field starts as a function of x only
                        mlp.init_block(i, 0..l.n_out, 3..l.n_in, 0.0, 0.0, None, &mut rng);
                    }
                } else {
                    let mean = std::f64::consts::PI.sqrt() / (l.n_in as f64).sqrt();
                    mlp.init_block(
                        i,
                        0..1,
                        0..l.n_in,
                        mean,
                        1e-4,
                        Some(-(radius as f64)),
                        &mut rng,
                    );
                    let std = (1.0 / l.n_in as f64).sqrt();
                    mlp.init_block(i, 1..l.n_out, 0..l.n_in, 0.0, std, Some(0.0), &mut rng);
                }
            }
            if layers.len() == 1 {
                // No hidden layer: a linear SDF cannot be a sphere; keep the x path linear.
                return Err(FieldError::InvalidConfig(
                    "sdf: the sphere initialisation needs at least one hidden layer".into(),
                ));
            }
        }
        Ok(SdfField {
            config: config.clone(),
            field,
        })
    }

    /// The settings.
    pub fn config(&self) -> &SdfFieldConfig {
        &self.config
    }
    /// Outputs per point (`1 + n_features`).
    pub fn n_output(&self) -> usize {
        1 + self.config.n_features
    }
    /// Zeroed gradient buffers.
    pub fn new_grads(&self) -> FieldGrads<T> {
        self.field.new_grads()
    }

    /// Batched forward: rows `[sdf, features…]` in `ctx.output()`.
    pub fn forward(&self, x: &[[T; 3]], ctx: &mut FieldContext<T>) {
        self.field.forward(x, &[], ctx);
    }

    /// Batched backward after [`SdfField::forward`]: accumulates parameter
    /// gradients, overwrites `d_x` (gradient w.r.t. the points) when given.
    pub fn backward(
        &self,
        ctx: &mut FieldContext<T>,
        d_out: &[T],
        grads: &mut FieldGrads<T>,
        d_x: Option<&mut [[T; 3]]>,
    ) {
        self.field.backward(ctx, d_out, grads, None, d_x);
    }

    /// Forward with normals: fills `ctx.sdf`, `ctx.features` and
    /// `ctx.gradient` (∇φ, not normalised) for every point, by `method`.
    pub fn forward_with_normals(
        &self,
        x: &[[T; 3]],
        method: NormalMethod,
        ctx: &mut NormalContext<T>,
    ) {
        let n = x.len();
        ctx.n = n;
        ctx.method = Some(method);
        let (scheme, step) = match method {
            NormalMethod::FiniteDifference { scheme, step } => (scheme, step),
            NormalMethod::Analytic => {
                self.forward_with_gradient_batched(x, &mut ctx.analytic);
                let (n_out, nf) = (self.n_output(), self.config.n_features);
                let out = ctx.analytic.output();
                ctx.sdf.clear();
                ctx.sdf.extend(out.chunks_exact(n_out).map(|r| r[0]));
                ctx.features.clear();
                ctx.features
                    .extend(out.chunks_exact(n_out).flat_map(|r| &r[1..1 + nf]));
                ctx.gradient.clear();
                ctx.gradient.extend_from_slice(&ctx.analytic.gradient);
                return;
            }
        };
        let stencil = scheme.stencil();
        let per = 1 + stencil.len();
        ctx.points.resize(n * per, [T::ZERO; 3]);
        let offs: Vec<[T; 3]> = stencil
            .iter()
            .map(|(k, _)| {
                [
                    T::from_f64(k[0] * step),
                    T::from_f64(k[1] * step),
                    T::from_f64(k[2] * step),
                ]
            })
            .collect();
        ctx.points
            .par_chunks_mut(per * 1024)
            .zip(x.par_chunks(1024))
            .for_each(|(dst, src)| {
                for (d, p) in dst.chunks_exact_mut(per).zip(src) {
                    d[0] = *p;
                    for (di, o) in d[1..].iter_mut().zip(&offs) {
                        *di = [p[0] + o[0], p[1] + o[1], p[2] + o[2]];
                    }
                }
            });
        self.field.forward(&ctx.points, &[], &mut ctx.field);
        let n_out = self.n_output();
        let nf = self.config.n_features;
        let out = ctx.field.output();
        ctx.sdf.resize(n, T::ZERO);
        ctx.features.resize(n * nf, T::ZERO);
        ctx.gradient.resize(n, [T::ZERO; 3]);
        let coef: Vec<[T; 3]> = stencil
            .iter()
            .map(|(k, c)| {
                [
                    T::from_f64(c * k[0] / step),
                    T::from_f64(c * k[1] / step),
                    T::from_f64(c * k[2] / step),
                ]
            })
            .collect();
        for p in 0..n {
            let base = p * per * n_out;
            ctx.sdf[p] = out[base];
            ctx.features[p * nf..(p + 1) * nf].copy_from_slice(&out[base + 1..base + n_out]);
            let mut g = [T::ZERO; 3];
            for (i, c) in coef.iter().enumerate() {
                let v = out[base + (i + 1) * n_out];
                for k in 0..3 {
                    g[k] += c[k] * v;
                }
            }
            ctx.gradient[p] = g;
        }
    }

    /// Backward after [`SdfField::forward_with_normals`]: upstream gradients for
    /// the SDF (`n`), the features (`n × n_features`) and the FD gradient
    /// vector (`n`); accumulates into `grads`.
    pub fn backward_with_normals(
        &self,
        ctx: &mut NormalContext<T>,
        d_sdf: &[T],
        d_features: &[T],
        d_gradient: &[[T; 3]],
        grads: &mut FieldGrads<T>,
    ) {
        let n = ctx.n;
        let nf = self.config.n_features;
        assert_eq!(d_sdf.len(), n, "backward_with_normals: d_sdf length");
        assert_eq!(
            d_features.len(),
            n * nf,
            "backward_with_normals: d_features length"
        );
        assert_eq!(
            d_gradient.len(),
            n,
            "backward_with_normals: d_gradient length"
        );
        let method = ctx
            .method
            .expect("backward_with_normals before forward_with_normals");
        let n_out = self.n_output();
        let (scheme, step) = match method {
            NormalMethod::FiniteDifference { scheme, step } => (scheme, step),
            NormalMethod::Analytic => {
                ctx.d_out.clear();
                for p in 0..n {
                    ctx.d_out.push(d_sdf[p]);
                    ctx.d_out
                        .extend_from_slice(&d_features[p * nf..(p + 1) * nf]);
                }
                self.backward_with_gradient_batched(
                    &mut ctx.analytic,
                    &ctx.d_out,
                    d_gradient,
                    grads,
                );
                return;
            }
        };
        let stencil = scheme.stencil();
        let per = 1 + stencil.len();
        let coef: Vec<[T; 3]> = stencil
            .iter()
            .map(|(k, c)| {
                [
                    T::from_f64(c * k[0] / step),
                    T::from_f64(c * k[1] / step),
                    T::from_f64(c * k[2] / step),
                ]
            })
            .collect();
        ctx.d_out.clear();
        ctx.d_out.resize(n * per * n_out, T::ZERO);
        for p in 0..n {
            let base = p * per * n_out;
            ctx.d_out[base] = d_sdf[p];
            ctx.d_out[base + 1..base + n_out].copy_from_slice(&d_features[p * nf..(p + 1) * nf]);
            let dg = d_gradient[p];
            for (i, c) in coef.iter().enumerate() {
                ctx.d_out[base + (i + 1) * n_out] = c[0] * dg[0] + c[1] * dg[1] + c[2] * dg[2];
            }
        }
        self.field
            .backward(&mut ctx.field, &ctx.d_out, grads, None, None);
    }
}
