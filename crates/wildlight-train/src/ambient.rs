//! The ambient term a_k of SPEC §2 at every sample of a pass, in either form
//! of [`AmbientModel`], with its backward pass.
//!
//! The inputs, per sample k of ray r (direction d_r, unit normal n_k, and
//! ω = d_r − 2(d_r·n_k)n_k the view direction mirrored about the normal,
//! Ref-NeRF's parameterisation, along which reflections of the room vary
//! smoothly):
//!
//! | form | `ambient` field | room |
//! | --- | --- | --- |
//! | [`AmbientModel::Neural`] | features, n, SH(ω), Θ | – |
//! | [`AmbientModel::NeuralRoom`] | features, n, SH(ω), Θ, R(ω) | ω on its grid |
//!
//! The `ambient` field also encodes the sample position on its own hash
//! grid; the room R's grid encodes ω itself, and its [`ROOM_FEATURES`]
//! outputs are inputs of the `ambient` field.

use crate::config::{AmbientModel, ROOM_FEATURES};
use crate::float::{Float, dot3, of};
use crate::model::Model;
use wildlight_fields::{FieldContext, FieldGrads};
use wildlight_material::PARAM_COUNT;
use wildlight_render::{SH_DEG4_LEN, sh_deg4, sh_deg4_jacobian};

/// Columns of the `ambient` field's extra input (beyond its own encoding)
/// for `geometry_features` features, in the given form.
pub fn ambient_extra_inputs(model: AmbientModel, geometry_features: usize) -> usize {
    let named = geometry_features + 3 + SH_DEG4_LEN + PARAM_COUNT;
    match model {
        AmbientModel::Neural => named,
        AmbientModel::NeuralRoom => named + ROOM_FEATURES,
    }
}

/// What the ambient term reads at a pass's `n` samples.
#[derive(Clone, Copy, Debug)]
pub struct AmbientInputs<'a, T> {
    /// Ray `r` owns samples `offsets[r]..offsets[r + 1]`.
    pub offsets: &'a [u32],
    /// Unit direction of each ray.
    pub ray_dirs: &'a [[T; 3]],
    /// Sample positions.
    pub positions: &'a [[T; 3]],
    /// Geometry features, `geometry_features` per sample (at least `n` rows).
    pub features: &'a [T],
    /// Unit normals.
    pub normals: &'a [[T; 3]],
    /// Material parameters.
    pub theta: &'a [[T; PARAM_COUNT]],
}

/// The gradients the ambient term ADDS to its inputs.
#[derive(Debug)]
pub struct AmbientInputGrads<'a, T> {
    /// ∂L/∂features, `geometry_features` per sample.
    pub features: &'a mut [T],
    /// ∂L/∂n per sample (the caller maps it onto ∇φ).
    pub normals: &'a mut [[T; 3]],
    /// ∂L/∂Θ per sample.
    pub theta: &'a mut [[T; PARAM_COUNT]],
}

/// Buffers of the ambient term between its forward and backward pass.
#[derive(Default)]
pub struct AmbientPass<T> {
    /// The reflected direction ω of every sample.
    dirs: Vec<[T; 3]>,
    /// ∂L/∂ω through the room's grid (empty without a room).
    d_room_dirs: Vec<[T; 3]>,
    room_ctx: FieldContext<T>,
    d_room_out: Vec<T>,
    extra: Vec<T>,
    ctx: FieldContext<T>,
    d_extra: Vec<T>,
}

/// The mirror image of `d` about the unit normal `n`: d − 2(d·n)n.
#[inline]
fn reflect<T: Float>(d: [T; 3], n: [T; 3]) -> [T; 3] {
    let k = of::<T>(2.0) * dot3(d, n);
    [d[0] - k * n[0], d[1] - k * n[1], d[2] - k * n[2]]
}

impl<T: Float + Default> AmbientPass<T> {
    /// Evaluates a_k at every sample into `out`.
    pub fn forward(
        &mut self,
        model: &Model<T>,
        inputs: &AmbientInputs<'_, T>,
        out: &mut Vec<[T; 3]>,
    ) {
        let config = &model.config;
        let nf = config.geometry_features;
        let n = inputs.positions.len();
        self.dirs.clear();
        for (ray, &d) in inputs.ray_dirs.iter().enumerate() {
            let ks = inputs.offsets[ray] as usize..inputs.offsets[ray + 1] as usize;
            self.dirs
                .extend(inputs.normals[ks].iter().map(|nrm| reflect(d, *nrm)));
        }
        if let Some(room) = &model.room {
            room.forward(&self.dirs, &[], &mut self.room_ctx);
        }
        self.extra.clear();
        self.extra
            .reserve(n * ambient_extra_inputs(config.ambient_model, nf));
        for ray in 0..inputs.ray_dirs.len() {
            for k in inputs.offsets[ray] as usize..inputs.offsets[ray + 1] as usize {
                self.extra
                    .extend_from_slice(&inputs.features[k * nf..(k + 1) * nf]);
                self.extra.extend_from_slice(&inputs.normals[k]);
                self.extra.extend_from_slice(&sh_deg4(self.dirs[k]));
                self.extra.extend_from_slice(&inputs.theta[k]);
                if model.room.is_some() {
                    let r = ROOM_FEATURES;
                    self.extra
                        .extend_from_slice(&self.room_ctx.output()[k * r..(k + 1) * r]);
                }
            }
        }
        model
            .ambient
            .forward(inputs.positions, &self.extra, &mut self.ctx);
        out.clear();
        out.extend(
            self.ctx
                .output()
                .chunks_exact(3)
                .map(|r| [r[0], r[1], r[2]]),
        );
    }

    /// Backward pass of the last [`AmbientPass::forward`]: `d_ambient` is
    /// ∂L/∂a_k. Adds the fields' parameter gradients into `field_grads`
    /// (`ambient`) and `room_grads` (the room, when the model has one) and
    /// the input gradients into `input_grads`.
    pub fn backward(
        &mut self,
        model: &Model<T>,
        inputs: &AmbientInputs<'_, T>,
        d_ambient: &[[T; 3]],
        field_grads: &mut FieldGrads<T>,
        room_grads: Option<&mut FieldGrads<T>>,
        input_grads: AmbientInputGrads<'_, T>,
    ) {
        let config = &model.config;
        let nf = config.geometry_features;
        let n = inputs.positions.len();
        let ne = ambient_extra_inputs(config.ambient_model, nf);
        let trains_material = config.ambient_trains_material;
        self.d_extra.clear();
        self.d_extra.resize(n * ne, T::ZERO);
        self.d_room_dirs.clear();
        model.ambient.backward(
            &mut self.ctx,
            d_ambient.as_flattened(),
            field_grads,
            Some(&mut self.d_extra),
            None,
        );
        if let Some(room) = &model.room {
            // the room's outputs are the last ROOM_FEATURES columns
            let r = ROOM_FEATURES;
            self.d_room_out.clear();
            self.d_room_out
                .extend(self.d_extra.chunks_exact(ne).flat_map(|row| &row[ne - r..]));
            self.d_room_dirs.resize(n, [T::ZERO; 3]);
            room.backward(
                &mut self.room_ctx,
                &self.d_room_out,
                room_grads.expect("gradients for the room field"),
                None,
                Some(&mut self.d_room_dirs),
            );
        }
        for (ray, &d) in inputs.ray_dirs.iter().enumerate() {
            for k in inputs.offsets[ray] as usize..inputs.offsets[ray + 1] as usize {
                let row = &self.d_extra[k * ne..(k + 1) * ne];
                for (a, b) in input_grads.features[k * nf..(k + 1) * nf]
                    .iter_mut()
                    .zip(&row[..nf])
                {
                    *a += *b;
                }
                let dn = &mut input_grads.normals[k];
                for a in 0..3 {
                    dn[a] += row[nf + a];
                }
                let d_sh = &row[nf + 3..nf + 3 + SH_DEG4_LEN];
                // ω = d − 2(d·n)n: ∂ω/∂n = −2 (n dᵀ + (d·n) I)
                let nrm = inputs.normals[k];
                let jac = sh_deg4_jacobian(self.dirs[k]);
                // ∂L/∂ω of the room's grid (zero without a room). Held back
                // from the normals, the room gained nothing over the plain
                // form (3,000 steps: 26.27 / 28.16 dB against 26.54 / 28.54
                // dB with it).
                let mut d_r = self.d_room_dirs.get(k).copied().unwrap_or([T::ZERO; 3]);
                for (jrow, g) in jac.iter().zip(d_sh) {
                    for a in 0..3 {
                        d_r[a] += *g * jrow[a];
                    }
                }
                let (dn_dot, d_dot_n) = (dot3(nrm, d_r), dot3(d, nrm));
                for a in 0..3 {
                    dn[a] -= of::<T>(2.0) * (d[a] * dn_dot + d_dot_n * d_r[a]);
                }
                if trains_material {
                    let d_theta = &row[nf + 3 + SH_DEG4_LEN..];
                    for (a, b) in input_grads.theta[k].iter_mut().zip(d_theta) {
                        *a += *b;
                    }
                }
            }
        }
    }
}
