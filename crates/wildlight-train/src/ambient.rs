//! The ambient term a_k of SPEC §2 at every sample of a pass, in either form
//! of [`AmbientModel`], with its backward pass.
//!
//! The inputs of the fields, per sample k of ray r (direction d_r, unit
//! normal n_k, ω = d_r or its mirror image d_r − 2(d_r·n_k)n_k, see
//! [`AmbientDirection`]):
//!
//! | form | `ambient` field | `ambient_specular` field |
//! | --- | --- | --- |
//! | [`AmbientModel::Neural`] | features, n, SH(ω), Θ | – |
//! | [`AmbientModel::DiffuseSpecular`] | features, n | SH(ω), roughness |
//! | [`AmbientModel::NeuralRoom`] | features, n, SH(ω), Θ, R(ω) | – (ω on its grid) |
//!
//! Both fields also encode the sample position on their own hash grids,
//! except the room R of [`AmbientModel::NeuralRoom`], whose grid encodes
//! ω itself and whose [`ROOM_FEATURES`] outputs are inputs of the
//! `ambient` field.

use crate::config::{AmbientDirection, AmbientModel, ROOM_FEATURES};
use crate::float::{Float, dot3, of};
use crate::model::Model;
use wildlight_fields::{FieldContext, FieldGrads, NeuralField};
use wildlight_material::{BASE_COLOR, CLEARCOAT, DIELECTRIC, METALLIC, PARAM_COUNT, ROUGHNESS};
use wildlight_render::{SH_DEG4_LEN, sh_deg4, sh_deg4_jacobian};

/// Columns of the `ambient_specular` field's extra input: SH(ω), roughness.
pub const SPECULAR_EXTRA_INPUTS: usize = SH_DEG4_LEN + 1;

/// Columns of the `ambient` field's extra input (beyond its own encoding)
/// for `geometry_features` features, in the given form.
pub fn ambient_extra_inputs(model: AmbientModel, geometry_features: usize) -> usize {
    match model {
        AmbientModel::Neural => geometry_features + 3 + SH_DEG4_LEN + PARAM_COUNT,
        AmbientModel::NeuralRoom => {
            geometry_features + 3 + SH_DEG4_LEN + PARAM_COUNT + ROOM_FEATURES
        }
        AmbientModel::DiffuseSpecular => geometry_features + 3,
    }
}

/// The tints of [`AmbientModel::DiffuseSpecular`] at one sample: the
/// diffuse albedo (1 − m)·base and the normal-incidence reflectance
/// F0 = m·base + 0.08·(1 − m)·sp + 0.25·F_c·cc of the specular lobes of
/// SPEC §3 (metal: Fresnel = base; dielectric: weight 0.08·(1 − m)·sp;
/// clearcoat: weight 0.25·cc, Fresnel F_c, appendix eq. 14).
#[inline]
fn tints<T: Float>(theta: &[T; PARAM_COUNT], clearcoat_fresnel: T) -> ([T; 3], [T; 3]) {
    let m = theta[METALLIC];
    let plain = of::<T>(0.08) * (T::ONE - m) * theta[DIELECTRIC]
        + of::<T>(0.25) * clearcoat_fresnel * theta[CLEARCOAT];
    let base = [0, 1, 2].map(|c| theta[BASE_COLOR + c]);
    (base.map(|b| (T::ONE - m) * b), base.map(|b| m * b + plain))
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
    /// The direction ω of every sample, when it varies per sample (the
    /// reflected direction) or the room reads it.
    dirs: Vec<[T; 3]>,
    /// ∂L/∂ω through the room's grid (empty without a room).
    d_room_dirs: Vec<[T; 3]>,
    room_ctx: FieldContext<T>,
    d_room_out: Vec<T>,
    extra: Vec<T>,
    ctx: FieldContext<T>,
    specular_extra: Vec<T>,
    specular_ctx: FieldContext<T>,
    d_out: Vec<T>,
    d_extra: Vec<T>,
    d_specular_out: Vec<T>,
    d_specular_extra: Vec<T>,
}

/// The `ambient_specular` field when the model's form uses it as the
/// mirrored room ([`AmbientModel::DiffuseSpecular`]; [`Model::new`] builds
/// it then).
fn specular_field<T: Float>(model: &Model<T>) -> Option<&NeuralField<T>> {
    match model.config.ambient_model {
        AmbientModel::Neural | AmbientModel::NeuralRoom => None,
        AmbientModel::DiffuseSpecular => Some(
            model
                .ambient_specular
                .as_ref()
                .expect("a diffuse-specular model has an ambient_specular field"),
        ),
    }
}

/// The reflected-direction field of [`AmbientModel::NeuralRoom`] (it lives
/// in the model's `ambient_specular` slot).
fn room_field<T: Float>(model: &Model<T>) -> Option<&NeuralField<T>> {
    match model.config.ambient_model {
        AmbientModel::NeuralRoom => Some(
            model
                .ambient_specular
                .as_ref()
                .expect("a neural-room model has its room field"),
        ),
        _ => None,
    }
}

/// The spherical harmonics of `d` with the bands from `bands` up held at
/// zero (bands 0..`bands` kept: their first `bands`² functions).
#[inline]
fn sh_bands<T: Float>(d: [T; 3], bands: usize) -> [T; SH_DEG4_LEN] {
    let mut sh = sh_deg4(d);
    sh[bands * bands..].fill(T::ZERO);
    sh
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
        let specular = specular_field(model);
        let split = specular.is_some();
        let reflected = config.ambient_direction == AmbientDirection::Reflected;
        let bands = config.ambient_sh_bands;
        let room = room_field(model);
        self.dirs.clear();
        if reflected || room.is_some() {
            for (ray, &d) in inputs.ray_dirs.iter().enumerate() {
                let ks = inputs.offsets[ray] as usize..inputs.offsets[ray + 1] as usize;
                self.dirs.extend(
                    inputs.normals[ks]
                        .iter()
                        .map(|nrm| if reflected { reflect(d, *nrm) } else { d }),
                );
            }
        }
        if let Some(room) = room {
            room.forward(&self.dirs, &[], &mut self.room_ctx);
        }
        self.extra.clear();
        self.extra
            .reserve(n * ambient_extra_inputs(config.ambient_model, nf));
        self.specular_extra.clear();
        if split {
            self.specular_extra.reserve(n * SPECULAR_EXTRA_INPUTS);
        }
        for (ray, &d) in inputs.ray_dirs.iter().enumerate() {
            let view_sh: Option<[T; SH_DEG4_LEN]> = (!reflected).then(|| sh_bands(d, bands));
            for k in inputs.offsets[ray] as usize..inputs.offsets[ray + 1] as usize {
                let nrm = inputs.normals[k];
                let sh = view_sh.unwrap_or_else(|| sh_bands(self.dirs[k], bands));
                self.extra
                    .extend_from_slice(&inputs.features[k * nf..(k + 1) * nf]);
                self.extra.extend_from_slice(&nrm);
                if split {
                    self.specular_extra.extend_from_slice(&sh);
                    self.specular_extra.push(inputs.theta[k][ROUGHNESS]);
                } else {
                    self.extra.extend_from_slice(&sh);
                    self.extra.extend_from_slice(&inputs.theta[k]);
                    if room.is_some() {
                        let r = ROOM_FEATURES;
                        self.extra
                            .extend_from_slice(&self.room_ctx.output()[k * r..(k + 1) * r]);
                    }
                }
            }
        }
        model
            .ambient
            .forward(inputs.positions, &self.extra, &mut self.ctx);
        out.clear();
        match specular {
            Some(specular) => {
                specular.forward(
                    inputs.positions,
                    &self.specular_extra,
                    &mut self.specular_ctx,
                );
                let fc = of::<T>(config.brdf.clearcoat_fresnel);
                let diffuse = self.ctx.output().chunks_exact(3);
                let mirrored = self.specular_ctx.output().chunks_exact(3);
                out.extend(inputs.theta.iter().zip(diffuse.zip(mirrored)).map(
                    |(theta, (e_d, e_s))| {
                        let (albedo, f0) = tints(theta, fc);
                        [0, 1, 2].map(|c| albedo[c] * e_d[c] + f0[c] * e_s[c])
                    },
                ));
            }
            None => {
                out.extend(
                    self.ctx
                        .output()
                        .chunks_exact(3)
                        .map(|r| [r[0], r[1], r[2]]),
                );
            }
        }
    }

    /// Backward pass of the last [`AmbientPass::forward`]: `d_ambient` is
    /// ∂L/∂a_k. Adds the fields' parameter gradients into `field_grads`
    /// (`ambient`) and `specular_grads` (`ambient_specular`, when the model
    /// has it) and the input gradients into `input_grads`.
    pub fn backward(
        &mut self,
        model: &Model<T>,
        inputs: &AmbientInputs<'_, T>,
        d_ambient: &[[T; 3]],
        field_grads: &mut FieldGrads<T>,
        specular_grads: Option<&mut FieldGrads<T>>,
        input_grads: AmbientInputGrads<'_, T>,
    ) {
        let config = &model.config;
        let nf = config.geometry_features;
        let n = inputs.positions.len();
        let ne = ambient_extra_inputs(config.ambient_model, nf);
        let specular = specular_field(model);
        let split = specular.is_some();
        let reflected = config.ambient_direction == AmbientDirection::Reflected;
        let trains_material = config.ambient_trains_material;
        self.d_extra.clear();
        self.d_extra.resize(n * ne, T::ZERO);
        self.d_room_dirs.clear();
        if let Some(specular) = specular {
            let specular_grads = specular_grads.expect("gradients for the ambient_specular field");
            // a = A ⊙ E_d + F0 ⊙ E_s: ∂L/∂E_d = A ⊙ ∂L/∂a, ∂L/∂E_s = F0 ⊙ ∂L/∂a,
            // and Θ through A and F0.
            let fc = of::<T>(config.brdf.clearcoat_fresnel);
            self.d_out.clear();
            self.d_specular_out.clear();
            let diffuse = self.ctx.output();
            let mirrored = self.specular_ctx.output();
            for k in 0..n {
                let theta = &inputs.theta[k];
                let g = d_ambient[k];
                let (albedo, f0) = tints(theta, fc);
                let e_d = &diffuse[3 * k..3 * k + 3];
                let e_s = &mirrored[3 * k..3 * k + 3];
                self.d_out.extend((0..3).map(|c| albedo[c] * g[c]));
                self.d_specular_out.extend((0..3).map(|c| f0[c] * g[c]));
                if trains_material {
                    let m = theta[METALLIC];
                    let dt = &mut input_grads.theta[k];
                    let (mut d_m, mut d_plain) = (T::ZERO, T::ZERO);
                    for c in 0..3 {
                        let b = theta[BASE_COLOR + c];
                        dt[BASE_COLOR + c] += g[c] * ((T::ONE - m) * e_d[c] + m * e_s[c]);
                        d_m += g[c] * (b * (e_s[c] - e_d[c]));
                        d_plain += g[c] * e_s[c];
                    }
                    // plain = 0.08·(1 − m)·sp + 0.25·F_c·cc
                    d_m -= d_plain * of::<T>(0.08) * theta[DIELECTRIC];
                    dt[METALLIC] += d_m;
                    dt[DIELECTRIC] += d_plain * of::<T>(0.08) * (T::ONE - m);
                    dt[CLEARCOAT] += d_plain * of::<T>(0.25) * fc;
                }
            }
            model.ambient.backward(
                &mut self.ctx,
                &self.d_out,
                field_grads,
                Some(&mut self.d_extra),
                None,
            );
            self.d_specular_extra.clear();
            self.d_specular_extra
                .resize(n * SPECULAR_EXTRA_INPUTS, T::ZERO);
            specular.backward(
                &mut self.specular_ctx,
                &self.d_specular_out,
                specular_grads,
                Some(&mut self.d_specular_extra),
                None,
            );
        } else {
            model.ambient.backward(
                &mut self.ctx,
                d_ambient.as_flattened(),
                field_grads,
                Some(&mut self.d_extra),
                None,
            );
            if let Some(room) = room_field(model) {
                // the room's outputs are the last ROOM_FEATURES columns
                let r = ROOM_FEATURES;
                self.d_room_out.clear();
                self.d_room_out
                    .extend(self.d_extra.chunks_exact(ne).flat_map(|row| &row[ne - r..]));
                self.d_room_dirs.resize(n, [T::ZERO; 3]);
                room.backward(
                    &mut self.room_ctx,
                    &self.d_room_out,
                    specular_grads.expect("gradients for the room field"),
                    None,
                    Some(&mut self.d_room_dirs),
                );
            }
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
                let (d_sh, d_theta): (&[T], Option<&[T]>) = if split {
                    let s = &self.d_specular_extra
                        [k * SPECULAR_EXTRA_INPUTS..(k + 1) * SPECULAR_EXTRA_INPUTS];
                    (&s[..SH_DEG4_LEN], None)
                } else {
                    (
                        &row[nf + 3..nf + 3 + SH_DEG4_LEN],
                        Some(&row[nf + 3 + SH_DEG4_LEN..]),
                    )
                };
                if reflected {
                    // ω = d − 2(d·n)n: ∂ω/∂n = −2 (n dᵀ + (d·n) I)
                    let nrm = inputs.normals[k];
                    // (the bands held at zero pass no gradient)
                    let jac = sh_deg4_jacobian(self.dirs[k]);
                    // ∂L/∂ω of the room's grid (zero without a room). Held
                    // back from the normals, the room gained nothing over the
                    // plain form (3,000 steps: 26.27 / 28.16 dB against
                    // 26.54 / 28.54 dB with it).
                    let mut d_r = self.d_room_dirs.get(k).copied().unwrap_or([T::ZERO; 3]);
                    let kept = config.ambient_sh_bands * config.ambient_sh_bands;
                    for (jrow, g) in jac.iter().zip(d_sh).take(kept) {
                        for a in 0..3 {
                            d_r[a] += *g * jrow[a];
                        }
                    }
                    let (dn_dot, d_dot_n) = (dot3(nrm, d_r), dot3(d, nrm));
                    for a in 0..3 {
                        dn[a] -= of::<T>(2.0) * (d[a] * dn_dot + d_dot_n * d_r[a]);
                    }
                }
                if trains_material {
                    let dt = &mut input_grads.theta[k];
                    match d_theta {
                        Some(d_theta) => {
                            for (a, b) in dt.iter_mut().zip(d_theta) {
                                *a += *b;
                            }
                        }
                        None => {
                            dt[ROUGHNESS] +=
                                self.d_specular_extra[k * SPECULAR_EXTRA_INPUTS + SH_DEG4_LEN];
                        }
                    }
                }
            }
        }
    }
}
