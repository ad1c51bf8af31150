//! One pass of the whole differentiable image formation (SPEC §2) over a
//! batch of rays, with its backward pass:
//!
//! ```text
//! rays → occupancy-grid sampler (coarse φ, refinement) → sample points
//!      → SDF field with its normals (analytic ∇φ, or finite differences)
//!      → NeuS weights w_k
//!      → material field Θ_k, ambient field a_k, flash term f_k
//!      → C = Σ w_k (a_k + f_k), Σ w_k
//!      [→ C += (1 − Σ w_k) B: the background of a run without masks,
//!         `crate::background`]
//! ```
//!
//! The backward pass takes ∂L/∂C and ∂L/∂(Σw) per ray (and the eikonal
//! weight) and accumulates the gradients of every model parameter.
//! Buffers are kept between calls; nothing is allocated per sample.

use crate::ambient::{AmbientInputGrads, AmbientInputs, AmbientPass};
use crate::background::BackgroundPass;
use crate::float::{Float, finite, norm3, of, safe_norm3, to_f64, unit3, unit3_backward};
use crate::model::{Model, ModelGrads};
use wildlight_fields::{FieldContext, NormalContext, NormalMethod};
use wildlight_material::PARAM_COUNT;
use wildlight_render::{
    BackgroundSettings, CoarseSamples, FlashCache, FlashInputs, NeusInputs, NeusSettings,
    NeusWeights, OccupancyGrid, RaySamples, Rays, Sampler, composite, composite_backward,
    flash_backward, flash_forward,
};

/// Radius of the ball in which the eikonal term applies (SPEC §4).
pub const EIKONAL_RADIUS: f64 = 1.2;

/// Samples along a batch of rays, packed by ray (see `wildlight_render::packing`).
#[derive(Clone, Debug, Default)]
pub struct Samples<T> {
    /// Ray `r` owns samples `offsets[r]..offsets[r + 1]`.
    pub offsets: Vec<u32>,
    /// Distance of each sample from the ray origin.
    pub t: Vec<T>,
    /// Length of each sample's section.
    pub delta: Vec<T>,
    /// Position of each sample.
    pub positions: Vec<[T; 3]>,
}

impl<T: Float> Samples<T> {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Copies the sampler's output.
    pub fn set_from(&mut self, s: &RaySamples) {
        let c = |v: f32| of::<T>(v as f64);
        self.offsets.clone_from(&s.offsets);
        self.t.clear();
        self.t.extend(s.t.iter().map(|&v| c(v)));
        self.delta.clear();
        self.delta.extend(s.delta.iter().map(|&v| c(v)));
        self.positions.clear();
        self.positions.extend(s.positions.iter().map(|p| p.map(c)));
    }
}

/// The rays of one pass (normalized frame) and the flash energy of each
/// ray's image.
#[derive(Clone, Copy, Debug)]
pub struct RayInputs<'a, T = f32> {
    /// Camera centres.
    pub origins: &'a [[T; 3]],
    /// Unit directions.
    pub dirs: &'a [[T; 3]],
    /// `light_energy` of each ray's image (zeros: flash off).
    pub energy: &'a [[T; 3]],
}

/// Per-pass settings that change during training.
#[derive(Clone, Copy, Debug)]
pub struct PassSettings {
    /// How the SDF normals are computed.
    pub normals: NormalMethod,
    /// NeuS cos-annealing ratio.
    pub cos_anneal_ratio: f64,
    /// Seed of the sampler's stratified jitter (`None`: strata centres).
    pub jitter_seed: Option<u64>,
    /// Whether a backward pass follows (keeps the BRDF Jacobians).
    pub for_backward: bool,
    /// The ε of the NeuS alpha (SPEC §2: 1e-5, [`wildlight_render::neus::ALPHA_EPS`]);
    /// comparisons between samplers set it to 0 (see [`NeusSettings::alpha_eps`]).
    pub alpha_eps: f64,
    /// The factor on the gradient the flash photos send to the ambient
    /// term, in [0, 1] (the trainer's schedule of
    /// `model.ambient_flash_gradient_late`; 1 leaves the gradient whole,
    /// and a pass without a backward ignores it).
    pub ambient_flash_gradient: f64,
}

impl PassSettings {
    /// The settings of a pass that renders a trained model: the normals'
    /// `normals`, no cos-annealing, strata centres, no backward.
    pub fn rendering(normals: NormalMethod) -> Self {
        PassSettings {
            normals,
            cos_anneal_ratio: 1.0,
            jitter_seed: None,
            for_backward: false,
            alpha_eps: wildlight_render::neus::ALPHA_EPS,
            ambient_flash_gradient: 1.0,
        }
    }
}

/// Buffers and results of a pass.
#[derive(Default)]
pub struct Pipeline<T = f32> {
    sampler: Option<Sampler>,
    coarse: CoarseSamples,
    raw_samples: RaySamples,
    /// The samples of the last pass.
    pub samples: Samples<T>,
    sdf_ctx: FieldContext<f32>,
    normal_ctx: NormalContext<T>,
    points: Vec<[T; 3]>,
    n_samples: usize,
    /// NeuS alphas, weights and Σw of the last pass.
    pub weights: NeusWeights<T>,
    material_ctx: FieldContext<T>,
    ambient_pass: AmbientPass<T>,
    flash_cache: FlashCache<T>,
    /// Material parameters at each sample.
    pub theta: Vec<[T; PARAM_COUNT]>,
    /// Unit normals at each sample.
    pub normals: Vec<[T; 3]>,
    /// Ambient radiance at each sample.
    pub ambient: Vec<[T; 3]>,
    /// Flash radiance at each sample.
    pub flash: Vec<[T; 3]>,
    sample_colour: Vec<[T; 3]>,
    /// Composited colour of each ray.
    pub colour: Vec<[T; 3]>,
    /// Mean eikonal residual (|∇φ| − 1)² over the points inside the ball.
    pub eikonal: f64,
    eikonal_count: usize,
    /// How the background is sampled (a model with a background field).
    pub background_settings: BackgroundSettings,
    /// The background of the last pass (empty for a model without one).
    pub background: BackgroundPass<T>,
    d_acc_total: Vec<T>,
    // backward buffers
    d_weight: Vec<T>,
    d_colour_sample: Vec<[T; 3]>,
    d_theta: Vec<[T; PARAM_COUNT]>,
    d_grad: Vec<[T; 3]>,
    d_sdf: Vec<T>,
    d_features: Vec<T>,
    d_normal: Vec<[T; 3]>,
}

/// Fills `out` with the SDF at `pts` (no normals, no gradients).
pub fn eval_sdf<T: Float>(
    model: &Model<T>,
    pts: &[[T; 3]],
    out: &mut [T],
    ctx: &mut FieldContext<T>,
) {
    model.sdf.forward(pts, ctx);
    let stride = model.sdf.n_output();
    for (o, row) in out.iter_mut().zip(ctx.output().chunks_exact(stride)) {
        *o = row[0];
    }
}

/// Where the rays of a pass meet the surface ([`Pipeline::surface_points`]).
#[derive(Clone, Debug, Default)]
pub struct SurfacePoints<T> {
    /// The expected hit points.
    pub centres: Vec<[T; 3]>,
    /// Their unit expected normals.
    pub normals: Vec<[T; 3]>,
}

impl Pipeline<f32> {
    /// An empty pipeline; `sampler` is the fast sampler to use.
    pub fn new(sampler: Sampler) -> Self {
        Self {
            sampler: Some(sampler),
            ..Self::default()
        }
    }

    /// Forward pass. `eikonal_points` are extra points (beyond the samples)
    /// where the SDF gradient is evaluated for the eikonal term.
    pub fn forward(
        &mut self,
        model: &Model,
        grid: &OccupancyGrid,
        rays: &RayInputs<'_>,
        eikonal_points: &[[f32; 3]],
        settings: &PassSettings,
    ) {
        let s = model.s();
        let render_rays = Rays {
            origins: rays.origins,
            dirs: rays.dirs,
        };
        let sampler = self
            .sampler
            .as_mut()
            .expect("pipeline built with a sampler");
        let sdf_ctx = &mut self.sdf_ctx;
        sampler.sample(
            grid,
            &render_rays,
            |pts: &[[f32; 3]], out: &mut [f32]| eval_sdf(model, pts, out, sdf_ctx),
            s,
            settings.jitter_seed,
            &mut self.coarse,
            &mut self.raw_samples,
        );
        self.samples.set_from(&self.raw_samples);
        self.forward_samples(model, rays, eikonal_points, settings);
    }
}

impl<T: Float + Default> Pipeline<T> {
    /// Number of samples of the last pass.
    pub fn n_samples(&self) -> usize {
        self.n_samples
    }

    /// Forward pass over samples already in `self.samples` (set by
    /// [`Pipeline::forward`] or by a caller, e.g. the dense reference sampler).
    pub fn forward_samples(
        &mut self,
        model: &Model<T>,
        rays: &RayInputs<'_, T>,
        eikonal_points: &[[T; 3]],
        settings: &PassSettings,
    ) {
        let n = self.samples.len();
        self.n_samples = n;
        let nf = model.config.geometry_features;
        let offsets = &self.samples.offsets;

        // SDF, features and ∇φ at the samples and the eikonal points.
        self.points.clear();
        self.points.extend_from_slice(&self.samples.positions);
        self.points.extend_from_slice(eikonal_points);
        model
            .sdf
            .forward_with_normals(&self.points, settings.normals, &mut self.normal_ctx);
        let ctx = &self.normal_ctx;

        // NeuS weights (SPEC §2).
        let neus = NeusSettings {
            cos_anneal_ratio: settings.cos_anneal_ratio,
            alpha_eps: settings.alpha_eps,
        };
        self.weights.forward(
            &neus_inputs(&self.samples, ctx, rays),
            model.sharpness,
            &neus,
        );

        // Material parameters Θ = sigmoid(outputs) (SPEC §3).
        model
            .material
            .forward(&self.samples.positions, &[], &mut self.material_ctx);
        self.theta.clear();
        self.theta.extend(
            self.material_ctx
                .output()
                .chunks_exact(PARAM_COUNT)
                .map(|r| <[T; PARAM_COUNT]>::try_from(r).expect("9 outputs")),
        );

        // Unit normals n = ∇φ/|∇φ| and the ambient term (crate::ambient).
        self.normals.clear();
        self.normals
            .extend(ctx.gradient[..n].iter().map(|&g| unit3(g).0));
        self.ambient_pass.forward(
            model,
            &ambient_inputs(&self.samples, ctx, rays, &self.normals, &self.theta, nf),
            &mut self.ambient,
        );

        // Flash term (SPEC §2).
        self.flash.clear();
        self.flash.resize(n, [T::ZERO; 3]);
        flash_forward(
            &flash_inputs(&self.samples, ctx, rays, &self.theta),
            model.log_gain,
            &model.config.brdf,
            &mut self.flash,
            if settings.for_backward {
                Some(&mut self.flash_cache)
            } else {
                None
            },
        );

        // C = Σ w_k (a_k + f_k).
        self.sample_colour.clear();
        self.sample_colour.extend(
            self.ambient
                .iter()
                .zip(&self.flash)
                .map(|(a, f)| [a[0] + f[0], a[1] + f[1], a[2] + f[2]]),
        );
        self.colour.clear();
        self.colour.resize(rays.dirs.len(), [T::ZERO; 3]);
        composite(
            offsets,
            &self.weights.weight,
            &self.sample_colour,
            &mut self.colour,
        );

        // The background behind the object (SPEC §6): C += (1 − Σw) B.
        match &model.background {
            Some(field) => self.background.forward(
                field,
                model.log_gain,
                rays.origins,
                rays.dirs,
                rays.energy,
                &self.background_settings,
                settings.jitter_seed,
                &self.weights.acc_weight,
                &mut self.colour,
            ),
            None => self.background.clear(),
        }

        // Eikonal residual over every point inside the ball (SPEC §4).
        let (mut sum, mut count) = (0.0f64, 0usize);
        for (p, g) in self.points.iter().zip(&ctx.gradient) {
            if in_eikonal_ball(p) {
                let len = to_f64(norm3(*g));
                sum += (len - 1.0) * (len - 1.0);
                count += 1;
            }
        }
        self.eikonal = if count > 0 { sum / count as f64 } else { 0.0 };
        self.eikonal_count = count;
    }

    /// Σw of each ray of the last pass.
    pub fn acc_weight(&self) -> &[T] {
        &self.weights.acc_weight
    }

    /// The expected hit point Σ w_k x_k / Σw of every ray of the last pass
    /// whose Σw is at least `min_acc` (rays that meet the surface), with
    /// the unit expected normal Σ w_k n_k / |Σ w_k n_k| (zero where that
    /// sum vanishes).
    pub fn surface_points(&self, min_acc: f64) -> SurfacePoints<T> {
        let offsets = &self.samples.offsets;
        let mut points = SurfacePoints::default();
        for r in 0..offsets.len().saturating_sub(1) {
            let acc = self.weights.acc_weight[r];
            if to_f64(acc) < min_acc {
                continue;
            }
            let (mut p, mut n) = ([T::ZERO; 3], [T::ZERO; 3]);
            for k in offsets[r] as usize..offsets[r + 1] as usize {
                let (w, x) = (self.weights.weight[k], self.samples.positions[k]);
                for a in 0..3 {
                    p[a] += w * x[a];
                    n[a] += w * self.normals[k][a];
                }
            }
            points.centres.push(p.map(|c| c / acc));
            points.normals.push(unit3(n).0);
        }
        points
    }

    /// Backward pass of the last forward pass: `d_colour` = ∂L/∂C and
    /// `d_acc` = ∂L/∂(Σw) per ray; `eikonal_weight` scales the eikonal term
    /// (whose value is [`Pipeline::eikonal`]). ADDS into `grads`.
    #[allow(clippy::too_many_arguments)]
    pub fn backward(
        &mut self,
        model: &Model<T>,
        rays: &RayInputs<'_, T>,
        d_colour: &[[T; 3]],
        d_acc: &[T],
        eikonal_weight: T,
        settings: &PassSettings,
        grads: &mut ModelGrads<T>,
    ) {
        let n = self.n_samples;
        let n_points = self.points.len();
        let nf = model.config.geometry_features;
        let offsets = &self.samples.offsets;
        let ctx = &self.normal_ctx;

        // The background: ∂L/∂(Σw) of its 1 − Σw joins the caller's.
        self.d_acc_total.clear();
        self.d_acc_total.extend_from_slice(d_acc);
        if let Some(field) = &model.background {
            grads.log_gain += self.background.backward(
                field,
                model.log_gain,
                rays.energy,
                &self.weights.acc_weight,
                d_colour,
                &mut self.d_acc_total,
                grads
                    .background
                    .as_mut()
                    .expect("gradients for the background field"),
            );
        }

        // C = Σ w_k c_k
        self.d_weight.clear();
        self.d_weight.resize(n, T::ZERO);
        self.d_colour_sample.clear();
        self.d_colour_sample.resize(n, [T::ZERO; 3]);
        composite_backward(
            offsets,
            &self.weights.weight,
            &self.sample_colour,
            d_colour,
            &mut self.d_weight,
            Some(&mut self.d_colour_sample),
        );

        // Flash term → Θ, ∇φ, g.
        self.d_theta.clear();
        self.d_theta.resize(n, [T::ZERO; PARAM_COUNT]);
        self.d_grad.clear();
        self.d_grad.resize(n_points, [T::ZERO; 3]);
        assert!(
            settings.for_backward,
            "Pipeline::backward after a forward pass without `for_backward`"
        );
        let d_log_gain = flash_backward(
            &flash_inputs(&self.samples, ctx, rays, &self.theta),
            model.log_gain,
            &model.config.brdf,
            Some(&self.flash_cache),
            &self.d_colour_sample,
            &mut self.d_theta,
            &mut self.d_grad[..n],
        );
        grads.log_gain += d_log_gain;

        // Ambient term → its fields, the features, n and Θ.
        self.d_features.clear();
        self.d_features.resize(n_points * nf, T::ZERO);
        self.d_normal.clear();
        self.d_normal.resize(n, [T::ZERO; 3]);
        // The flash photos' share of the ambient term's gradient, scaled (at
        // 0 their ambient term is a given). In place: the flash term has
        // taken its gradient above, and nothing reads ∂L/∂c_k after this.
        let flash_factor = settings.ambient_flash_gradient;
        if flash_factor != 1.0 {
            let factor = of::<T>(flash_factor);
            for (r, energy) in rays.energy.iter().enumerate() {
                if energy.iter().any(|e| *e != T::ZERO) {
                    let range = offsets[r] as usize..offsets[r + 1] as usize;
                    for d in &mut self.d_colour_sample[range] {
                        *d = d.map(|v| v * factor);
                    }
                }
            }
        }
        self.ambient_pass.backward(
            model,
            &ambient_inputs(&self.samples, ctx, rays, &self.normals, &self.theta, nf),
            &self.d_colour_sample,
            &mut grads.ambient,
            grads.room.as_mut(),
            AmbientInputGrads {
                features: &mut self.d_features,
                normals: &mut self.d_normal,
                theta: &mut self.d_theta,
            },
        );
        // n = ∇φ/|∇φ|: ∂L/∂∇φ = (∂L/∂n − n (n·∂L/∂n)) / |∇φ|
        for k in 0..n {
            let len = safe_norm3(ctx.gradient[k]);
            let d = unit3_backward(self.d_normal[k], self.normals[k], len);
            for (g, v) in self.d_grad[k].iter_mut().zip(d) {
                *g += v;
            }
        }

        // Material field.
        model.material.backward(
            &mut self.material_ctx,
            self.d_theta.as_flattened(),
            &mut grads.material,
            None,
            None,
        );

        // NeuS weights → φ, ∇φ, v.
        self.d_sdf.clear();
        self.d_sdf.resize(n_points, T::ZERO);
        let neus = NeusSettings {
            cos_anneal_ratio: settings.cos_anneal_ratio,
            alpha_eps: settings.alpha_eps,
        };
        let d_v = self.weights.backward(
            &neus_inputs(&self.samples, ctx, rays),
            model.sharpness,
            &neus,
            &self.d_weight,
            Some(&self.d_acc_total),
            &mut self.d_sdf[..n],
            &mut self.d_grad[..n],
        );
        grads.sharpness += d_v;

        // Eikonal: ∂/∂∇φ of w·mean((|∇φ| − 1)²) = w·2(|∇φ| − 1)·∇φ/|∇φ| / count.
        if self.eikonal_count > 0 && eikonal_weight != T::ZERO {
            let scale = eikonal_weight * of(2.0 / self.eikonal_count as f64);
            for ((p, g), dg) in self.points.iter().zip(&ctx.gradient).zip(&mut self.d_grad) {
                if in_eikonal_ball(p) {
                    let len = safe_norm3(*g);
                    let f = scale * (len - T::ONE) / len;
                    for a in 0..3 {
                        dg[a] += f * g[a];
                    }
                }
            }
        }

        // SDF field through its normals.
        model.sdf.backward_with_normals(
            &mut self.normal_ctx,
            &self.d_sdf,
            &self.d_features,
            &self.d_grad,
            &mut grads.sdf,
        );
    }
}

/// The NeuS kernel's view of a pass (the samples, not the eikonal points).
fn neus_inputs<'a, T: Float>(
    samples: &'a Samples<T>,
    ctx: &'a NormalContext<T>,
    rays: &RayInputs<'a, T>,
) -> NeusInputs<'a, T> {
    let n = samples.len();
    NeusInputs {
        offsets: &samples.offsets,
        ray_dirs: rays.dirs,
        sdf: &ctx.sdf[..n],
        sdf_grad: &ctx.gradient[..n],
        delta: &samples.delta,
    }
}

/// The ambient term's view of a pass.
fn ambient_inputs<'a, T: Float>(
    samples: &'a Samples<T>,
    ctx: &'a NormalContext<T>,
    rays: &RayInputs<'a, T>,
    normals: &'a [[T; 3]],
    theta: &'a [[T; PARAM_COUNT]],
    nf: usize,
) -> AmbientInputs<'a, T> {
    AmbientInputs {
        offsets: &samples.offsets,
        ray_dirs: rays.dirs,
        positions: &samples.positions,
        features: &ctx.features[..samples.len() * nf],
        normals,
        theta,
    }
}

/// The flash kernel's view of a pass.
fn flash_inputs<'a, T: Float>(
    samples: &'a Samples<T>,
    ctx: &'a NormalContext<T>,
    rays: &RayInputs<'a, T>,
    theta: &'a [[T; PARAM_COUNT]],
) -> FlashInputs<'a, T> {
    FlashInputs {
        offsets: &samples.offsets,
        ray_dirs: rays.dirs,
        light_energy: rays.energy,
        t: &samples.t,
        sdf_grad: &ctx.gradient[..samples.len()],
        params: theta,
    }
}

#[inline]
fn in_eikonal_ball<T: Float>(p: &[T; 3]) -> bool {
    to_f64(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) <= EIKONAL_RADIUS * EIKONAL_RADIUS
}

/// Whether every value of a slice of vectors is finite.
pub fn all_finite<T: Float, const C: usize>(v: &[[T; C]]) -> bool {
    v.iter().all(|x| x.iter().all(|c| finite(*c)))
}
