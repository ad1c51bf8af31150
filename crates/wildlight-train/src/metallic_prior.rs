//! A prior pushing the metallic parameter towards 0 or 1: real surfaces are
//! metals or dielectrics, and mixtures of the two are rare.
//!
//! Under a co-located flash a rough metal lobe and a diffuse lobe look
//! alike, so a rough dielectric (the kettle's terracotta, roughness 0.85)
//! can be fitted as a partly metallic material whose base colour then
//! mixes an albedo with an F0 (it came out 0.35 metallic and too bright
//! after 30 minutes). For the surface points x_j (expected hit points of
//! foreground rays) and their metallic values m_j = Θ_metallic(x_j),
//!
//! L_binary = λ · (1/m) Σ_j m_j (1 − m_j),
//!
//! zero at m = 0 and m = 1 and largest (λ/4) at one half; its gradient
//! λ (1 − 2 m_j) / m pushes each point towards the nearer end. Only the
//! material field receives the gradient (the points are held fixed). The
//! prior is the project's addition to SPEC §4; its weight is
//! `loss.binary_metallic` (0 turns it off). By default (since session 30)
//! it is a readout push (below) with λ = 0.3 from 0.5 to 0.7 of the run.
//!
//! A ceiling c (`loss.binary_metallic_ceiling`, default 1: every point)
//! leaves the points with m_j > c out of the sum (they still count in m):
//! at c = 0.5 the prior only pushes partial metals down to 0, and the
//! metals are left to the photographs.
//!
//! A local push (`loss.binary_metallic_min_resolution` R > 0) gives the
//! gradient only to the hash-table levels of at least R cells per axis:
//! the network's weights and the coarse levels, which every point of a
//! part and its neighbours share, receive none of it, so that pushing one
//! part does not carry the parts beside it along.
//!
//! A readout push (`loss.binary_metallic_readout_only`) goes further: only
//! the metallic row of the network's last layer (its weights and bias)
//! receives the gradient, the one set of parameters that reads metallic
//! and nothing else, so the push cannot move base colour or roughness
//! anywhere; it can only re-weigh the features the network already has.
//!
//! A metal anchor (`loss.binary_metallic_anchor`, [`MetalAnchor`]) holds
//! the points that were metals when the push began to their base colour
//! and roughness of then, for as long as the push lasts, so that what the
//! push moves through the parameters those points share with the part
//! pushed is pulled back at once.
//!
//! When metallic comes from a field of its own (`model.metallic_field`,
//! [`crate::material_field`]), the prior moves that field alone (in the
//! scope chosen), and base colour and roughness receive none of it.

use crate::float::{Float, of, to_f64};
use crate::material_field::{MaterialContext, MaterialField, MaterialGrads};
use wildlight_fields::{FieldContext, FieldGrads};
use wildlight_material::{BASE_COLOR, METALLIC, PARAM_COUNT, ROUGHNESS};

/// Which parameters of the material field the binary-metallic prior moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PushScope {
    /// Every parameter: the hash table and the network.
    Everywhere,
    /// The hash-table parameters from this index on (the fine levels).
    TableFrom(usize),
    /// The metallic row of the network's last layer, weights and bias (the
    /// whole last layer of a metallic field of its own).
    MetallicReadout,
}

/// Buffers of the binary-metallic term between calls.
#[derive(Default)]
pub struct BinaryMetallic<T> {
    ctx: FieldContext<T>,
    d_out: Vec<T>,
    /// The whole gradient of a local push, before its fine levels are kept.
    local: Option<FieldGrads<T>>,
    /// The network's gradient of a readout push, before its metallic row is
    /// kept.
    network: Vec<T>,
}

impl<T: Float + Default> BinaryMetallic<T> {
    /// Evaluates λ · L_binary at `points` and ADDS its gradient with
    /// respect to the parameters of the field giving metallic into `grads`; points
    /// whose metallic value is above `ceiling` contribute nothing. Returns
    /// the unweighted mean of m (1 − m) over the points at or below it
    /// (divided by all the points). `scope` says which parameters receive
    /// the gradient.
    pub fn forward_backward(
        &mut self,
        material: &MaterialField<T>,
        points: &[[T; 3]],
        weight: T,
        ceiling: T,
        scope: PushScope,
        grads: &mut MaterialGrads<T>,
    ) -> f64 {
        let m = points.len();
        if m == 0 {
            return 0.0;
        }
        let (field, channel) = material.metallic_source();
        let grads = match &mut grads.metallic {
            Some(g) => g,
            None => &mut grads.params,
        };
        field.forward(points, &[], &mut self.ctx);
        let k = field.n_output();
        let scale = weight / of(m as f64);
        self.d_out.clear();
        self.d_out.resize(m * k, T::ZERO);
        let mut sum = 0.0f64;
        for (theta, d) in self
            .ctx
            .output()
            .chunks_exact(k)
            .zip(self.d_out.chunks_exact_mut(k))
        {
            let metal = theta[channel];
            if metal > ceiling {
                continue;
            }
            sum += to_f64(metal * (T::ONE - metal));
            d[channel] = scale * (T::ONE - of::<T>(2.0) * metal);
        }
        match scope {
            PushScope::Everywhere => {
                field.backward(&mut self.ctx, &self.d_out, grads, None, None);
            }
            PushScope::TableFrom(first) => {
                let local = self.local.get_or_insert_with(|| field.new_grads());
                local.zero();
                field.backward(&mut self.ctx, &self.d_out, local, None, None);
                for (g, l) in grads.grid[first..].iter_mut().zip(&local.grid[first..]) {
                    *g += *l;
                }
            }
            PushScope::MetallicReadout => {
                // only the network's gradient is kept: the hash table's
                // backward is skipped
                self.network.clear();
                self.network.resize(field.mlp.n_params(), T::ZERO);
                field.backward_network(&mut self.ctx, &self.d_out, &mut self.network);
                let last = *field.mlp.layers().last().expect("an MLP has layers");
                let row = last.weight_offset + channel * last.n_in;
                let bias = last.bias_offset + channel;
                for i in (row..row + last.n_in).chain([bias]) {
                    grads.mlp[i] += self.network[i];
                }
            }
        }
        sum / m as f64
    }
}

/// Holds the metals' base colour and roughness while the binary-metallic
/// prior pushes: for the points that a snapshot of the material field
/// (taken when the push began) calls metals (metallic above one half),
///
/// L_anchor = μ · (1/m) Σ_j Σ_{i ∈ base colour, roughness} (Θ_i(x_j) − Θ⁰_i(x_j))²,
///
/// so that what the push moves through parameters the metals share with
/// the part it pushes is pulled back at once, not left to the photos.
#[derive(Default)]
pub struct MetalAnchor<T> {
    snapshot_ctx: MaterialContext<T>,
    ctx: MaterialContext<T>,
    d_theta: Vec<T>,
}

impl<T: Float + Default> MetalAnchor<T> {
    /// Evaluates L_anchor (weight `weight`) at `points` and ADDS its
    /// gradient into `grads`; returns the unweighted mean.
    pub fn forward_backward(
        &mut self,
        material: &MaterialField<T>,
        snapshot: &MaterialField<T>,
        points: &[[T; 3]],
        weight: T,
        grads: &mut MaterialGrads<T>,
    ) -> f64 {
        let m = points.len();
        if m == 0 {
            return 0.0;
        }
        snapshot.forward(points, &mut self.snapshot_ctx);
        material.forward(points, &mut self.ctx);
        self.d_theta.clear();
        self.d_theta.resize(m * PARAM_COUNT, T::ZERO);
        let scale = weight / of(m as f64);
        let mut sum = 0.0;
        for ((theta, held), d) in self
            .ctx
            .output()
            .chunks_exact(PARAM_COUNT)
            .zip(self.snapshot_ctx.output().chunks_exact(PARAM_COUNT))
            .zip(self.d_theta.chunks_exact_mut(PARAM_COUNT))
        {
            if held[METALLIC] <= of(0.5) {
                continue;
            }
            for i in [BASE_COLOR, BASE_COLOR + 1, BASE_COLOR + 2, ROUGHNESS] {
                let diff = theta[i] - held[i];
                sum += to_f64(diff * diff);
                d[i] = of::<T>(2.0) * scale * diff;
            }
        }
        material.backward(&mut self.ctx, &self.d_theta, grads);
        sum / m as f64
    }
}
