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
//! λ (1 − 2 m_j) / m pushes each point towards the nearer end. The push
//! moves only the metallic row of the material network's last layer (its
//! weights and bias), the one set of parameters that reads metallic and
//! nothing else, so it cannot move base colour or roughness anywhere; it
//! can only re-weigh the features the network already has. The prior is
//! the project's addition to SPEC §4; its weight is `loss.binary_metallic`
//! (0 turns it off), by default 0.3 from 0.5 to 0.7 of the run
//! (`loss.binary_metallic_from`, `loss.binary_metallic_until`).

use crate::float::{Float, of, to_f64};
use wildlight_fields::{FieldContext, FieldGrads, NeuralField};
use wildlight_material::METALLIC;

/// Buffers of the binary-metallic term between calls.
#[derive(Default)]
pub struct BinaryMetallic<T> {
    ctx: FieldContext<T>,
    d_out: Vec<T>,
    /// The network's whole gradient, before its metallic row is kept.
    network: Vec<T>,
}

impl<T: Float + Default> BinaryMetallic<T> {
    /// Evaluates λ · L_binary (λ = `weight`) at `points` and ADDS its
    /// gradient with respect to the metallic row of the material network's
    /// last layer into `grads`. Returns the unweighted mean of m (1 − m).
    pub fn forward_backward(
        &mut self,
        material: &NeuralField<T>,
        points: &[[T; 3]],
        weight: T,
        grads: &mut FieldGrads<T>,
    ) -> f64 {
        let m = points.len();
        if m == 0 {
            return 0.0;
        }
        material.forward(points, &[], &mut self.ctx);
        let k = material.n_output();
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
            sum += to_f64(metal * (T::ONE - metal));
            d[METALLIC] = scale * (T::ONE - of::<T>(2.0) * metal);
        }
        // only the network's gradient is kept: the hash table's backward is
        // skipped
        self.network.clear();
        self.network.resize(material.mlp.n_params(), T::ZERO);
        material.backward_network(&mut self.ctx, &self.d_out, &mut self.network);
        let last = *material.mlp.layers().last().expect("an MLP has layers");
        let row = last.weight_offset + METALLIC * last.n_in;
        let bias = last.bias_offset + METALLIC;
        for i in (row..row + last.n_in).chain([bias]) {
            grads.mlp[i] += self.network[i];
        }
        sum / m as f64
    }
}
