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
//! `loss.binary_metallic`, 0 (off) by default.
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

use crate::float::{Float, of, to_f64};
use wildlight_fields::{FieldContext, FieldGrads, NeuralField};
use wildlight_material::{METALLIC, PARAM_COUNT};

/// Buffers of the binary-metallic term between calls.
#[derive(Default)]
pub struct BinaryMetallic<T> {
    ctx: FieldContext<T>,
    d_out: Vec<T>,
    /// The whole gradient of a local push, before its fine levels are kept.
    local: Option<FieldGrads<T>>,
}

impl<T: Float + Default> BinaryMetallic<T> {
    /// Evaluates λ · L_binary at `points` and ADDS its gradient with
    /// respect to the material field's parameters into `grads`; points
    /// whose metallic value is above `ceiling` contribute nothing. Returns
    /// the unweighted mean of m (1 − m) over the points at or below it
    /// (divided by all the points). With `local_from = Some(k)` only the
    /// hash-table parameters from index k on receive the gradient (the
    /// network and the entries before k none).
    pub fn forward_backward(
        &mut self,
        field: &NeuralField<T>,
        points: &[[T; 3]],
        weight: T,
        ceiling: T,
        local_from: Option<usize>,
        grads: &mut FieldGrads<T>,
    ) -> f64 {
        let m = points.len();
        if m == 0 {
            return 0.0;
        }
        field.forward(points, &[], &mut self.ctx);
        let k = field.n_output();
        debug_assert_eq!(k, PARAM_COUNT, "the material field gives Θ");
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
            let metal = theta[METALLIC];
            if metal > ceiling {
                continue;
            }
            sum += to_f64(metal * (T::ONE - metal));
            d[METALLIC] = scale * (T::ONE - of::<T>(2.0) * metal);
        }
        match local_from {
            None => field.backward(&mut self.ctx, &self.d_out, grads, None, None),
            Some(first) => {
                let local = self.local.get_or_insert_with(|| field.new_grads());
                local.zero();
                field.backward(&mut self.ctx, &self.d_out, local, None, None);
                for (g, l) in grads.grid[first..].iter_mut().zip(&local.grid[first..]) {
                    *g += *l;
                }
            }
        }
        sum / m as f64
    }
}
