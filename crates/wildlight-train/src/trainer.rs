//! The optimisation: one [`Trainer::step`] draws a batch of rays across all
//! images, renders it, evaluates the losses of SPEC §4 and updates every
//! parameter with Adam. Deterministic for a seed and a thread count: each
//! step's random numbers come from (seed, step) alone, so a resumed run
//! continues exactly.

use crate::averaging::ParameterAverage;
use crate::config::TrainConfig;
use crate::loss::{colour_l1, mask_bce, psnr};
use crate::metallic_prior::BinaryMetallic;
use crate::model::{Model, ModelGrads};
use crate::normal_smoothness::{self, NormalSmoothness};
use crate::pipeline::{PassSettings, Pipeline, RayInputs, SurfacePoints, eval_sdf};
use crate::rays::{RayBatch, RayShares, TrainingRays};
use crate::smoothness::MaterialSmoothness;
use crate::visual_hull::HullPrior;
use anyhow::Context;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::path::Path;
use std::time::Instant;
use wildlight_fields::{
    Adam, AdamConfig, Checkpoint, CheckpointWriter, Checkpointable, Decay, FieldContext,
    LrSchedule, NeuralField, NormalMethod,
};
use wildlight_render::{OccupancyGrid, OccupancySnapshot, RefreshMode, Sampler, cos_anneal_ratio};

/// What one step measured.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct StepStats {
    /// Step index (0-based) that was taken.
    pub step: u64,
    /// Weighted total loss.
    pub loss: f64,
    /// L1 colour loss.
    pub color: f64,
    /// Mask cross-entropy.
    pub mask: f64,
    /// Eikonal residual.
    pub eikonal: f64,
    /// The material smoothness prior's mean Σ_i δ_i over its pairs
    /// (`crate::smoothness`; 0 when the prior is off).
    pub smoothness: f64,
    /// The normal smoothness prior's mean pseudo-Huber difference over its
    /// pairs (`crate::normal_smoothness`; 0 when the prior is off).
    pub normal_smoothness: f64,
    /// The binary-metallic prior's mean m (1 − m) over the surface points
    /// (`crate::metallic_prior`; 0 when the prior is off).
    pub binary_metallic: f64,
    /// The visual-hull prior's mean max(0, δ − φ) over its points outside
    /// the hull (`crate::visual_hull`; 0 when the prior is off).
    pub visual_hull: f64,
    /// PSNR of the batch's counted foreground channels (dB, peak 1).
    pub psnr: f64,
    /// NeuS sharpness s.
    pub s: f64,
    /// Flash gain γ.
    pub gamma: f64,
    /// Learning-rate factor used.
    pub lr_factor: f64,
    /// Samples along the batch's rays.
    pub samples: usize,
    /// Occupied fraction of the occupancy grid.
    pub occupied: f64,
    /// Whether the update was skipped (non-finite loss or gradient).
    pub skipped: bool,
    /// Wall time of the step's parts.
    pub phase_ms: StepTimes,
}

/// Wall time of the parts of one step, in milliseconds (`metrics.jsonl`'s
/// `phase_ms`): where the step's time goes, measured on every step.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct StepTimes {
    /// Schedules, the occupancy grid's refresh or reclassification, the
    /// ray draw and the eikonal points.
    pub setup: f64,
    /// The pipeline's forward pass (sampler, fields, compositing).
    pub forward: f64,
    /// The losses and the pipeline's backward pass (gradients zeroed first).
    pub backward: f64,
    /// The material, normal and metallic priors over the surface points.
    pub priors: f64,
    /// The visual-hull prior.
    pub hull: f64,
    /// The finiteness check and the Adam update of every group.
    pub update: f64,
    /// Of `forward` and `backward`: the background's part (a run without
    /// masks, SPEC §6; 0 with masks).
    pub background: f64,
}

/// Milliseconds from `start` to `end`.
fn ms(start: Instant, end: Instant) -> f64 {
    (end - start).as_secs_f64() * 1e3
}

/// Adam group indices.
struct Groups {
    sdf_grid: usize,
    sdf_mlp: usize,
    mat_grid: usize,
    mat_mlp: usize,
    amb_grid: usize,
    amb_mlp: usize,
    sharpness: usize,
    gain: usize,
    /// The room's grid and MLP, when the model has one.
    room: Option<(usize, usize)>,
    /// The background's grid and MLP, when the model has one.
    background: Option<(usize, usize)>,
}

/// The state of a training run.
pub struct Trainer {
    /// The configuration.
    pub config: TrainConfig,
    /// The model being trained.
    pub model: Model,
    /// Steps taken so far.
    pub step: u64,
    /// Multiplier of every learning rate, halved after each skipped step.
    pub lr_scale: f64,
    /// Skipped (non-finite) steps so far.
    pub skipped_steps: u64,
    /// The occupancy grid.
    pub grid: OccupancyGrid,
    /// The ray renderer's buffers.
    pub pipeline: Pipeline,
    smoothness: MaterialSmoothness<f32>,
    normal_smoothness: NormalSmoothness<f32>,
    binary_metallic: BinaryMetallic<f32>,
    /// The visual-hull prior (`None` when off or without masks).
    hull_prior: Option<HullPrior>,
    rays: TrainingRays,
    adam: Adam<f32>,
    groups: Groups,
    grads: ModelGrads,
    sdf_ctx: FieldContext<f32>,
    batch: RayBatch,
    d_colour: Vec<[f32; 3]>,
    d_acc: Vec<f32>,
    schedule: LrSchedule,
    /// The mean of the parameters over the run's last part (`None` when
    /// `optim.average_from` is 1).
    average: Option<ParameterAverage>,
}

fn mix(seed: u64, step: u64, stream: u64) -> u64 {
    let mut x = seed
        ^ step.wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

impl Trainer {
    /// A new run on the capture's rays: with masks when the rays have them,
    /// else without, the model then with a background field (SPEC §6).
    pub fn new(config: TrainConfig, mut rays: TrainingRays) -> anyhow::Result<Self> {
        config.validate().map_err(anyhow::Error::msg)?;
        rays.set_silhouette_band(if config.silhouette_fraction > 0.0 {
            config.silhouette_band
        } else {
            0
        });
        rays.set_flash_weight(config.flash_view_weight);
        let model = if rays.has_masks {
            Model::new(&config.model, config.seed)?
        } else {
            Model::with_background(&config.model, config.seed)?
        };
        let mut adam = Adam::new();
        let o = &config.optim;
        let (gf, mf) = (&o.grid_lr_factors, &o.mlp_lr_factors);
        // A field's hash table and MLP, each at its learning rate times the
        // field's factor.
        let add_field =
            |adam: &mut Adam<f32>, name: &str, field: &NeuralField<f32>, gk: f64, mk: f64| {
                let cfg = |lr: f64| AdamConfig {
                    lr,
                    eps: 1e-15,
                    ..AdamConfig::default()
                };
                (
                    adam.add_group(
                        &format!("{name}.grid"),
                        field.grid.params.len(),
                        cfg(o.lr_grid * gk),
                    ),
                    adam.add_group(
                        &format!("{name}.mlp"),
                        field.mlp.params.len(),
                        cfg(o.lr_mlp * mk),
                    ),
                )
            };
        let (sdf_grid, sdf_mlp) = add_field(&mut adam, "sdf", &model.sdf.field, gf.sdf, mf.sdf);
        let (mat_grid, mat_mlp) = add_field(
            &mut adam,
            "material",
            &model.material,
            gf.material,
            mf.material,
        );
        let (amb_grid, amb_mlp) =
            add_field(&mut adam, "ambient", &model.ambient, gf.ambient, mf.ambient);
        let mut groups = Groups {
            sdf_grid,
            sdf_mlp,
            mat_grid,
            mat_mlp,
            amb_grid,
            amb_mlp,
            sharpness: adam.add_group(
                "sharpness",
                1,
                AdamConfig {
                    lr: o.lr_sharpness,
                    ..AdamConfig::default()
                },
            ),
            gain: adam.add_group(
                "gain",
                1,
                AdamConfig {
                    lr: o.lr_gain,
                    ..AdamConfig::default()
                },
            ),
            room: None,
            background: None,
        };
        if let Some(f) = &model.room {
            groups.room = Some(add_field(&mut adam, ROOM, f, gf.ambient, mf.ambient));
        }
        if let Some(f) = &model.background {
            // at the ambient field's learning rates
            groups.background = Some(add_field(&mut adam, BACKGROUND, f, gf.ambient, mf.ambient));
        }
        let grid = OccupancyGrid::new(config.sampling.occupancy())?;
        let sampler = Sampler::new(config.sampling.sampler())?;
        let schedule = LrSchedule {
            warmup_steps: o.warmup_steps,
            warmup_start_factor: 0.01,
            decay: Decay::Cosine {
                total_steps: config.iters,
                final_factor: o.lr_factor_final,
            },
        };
        let grads = model.new_grads();
        let hull_prior = if config.loss.visual_hull > 0.0 {
            rays.visual_hull(config.loss.visual_hull_dilation as usize)
                .map(HullPrior::new)
        } else {
            None
        };
        let average = (config.optim.average_from < 1.0).then(|| ParameterAverage::new(&model));
        let mut pipeline = Pipeline::new(sampler);
        pipeline.background_settings = config.sampling.background();
        let mut t = Self {
            average,
            model,
            step: 0,
            lr_scale: 1.0,
            skipped_steps: 0,
            grid,
            pipeline,
            smoothness: MaterialSmoothness::default(),
            normal_smoothness: NormalSmoothness::default(),
            binary_metallic: BinaryMetallic::default(),
            hull_prior,
            rays,
            adam,
            groups,
            grads,
            sdf_ctx: FieldContext::new(),
            batch: RayBatch::default(),
            d_colour: Vec::new(),
            d_acc: Vec::new(),
            schedule,
            config,
        };
        t.apply_step_schedule();
        t.refresh_grid();
        Ok(t)
    }

    /// `share` × the planned steps, rounded up.
    fn share_of_planned_steps(&self, share: f64) -> u64 {
        (share * self.planned_total_steps() as f64).ceil() as u64
    }

    /// The factor on the flash photos' ambient gradient at `step`:
    /// `model.ambient_flash_gradient_late` from
    /// `model.ambient_flash_gradient_late_from` × the planned steps (rounded
    /// up) on, 1 before.
    pub fn ambient_flash_gradient(&self, step: u64) -> f64 {
        let model = &self.config.model;
        if step >= self.share_of_planned_steps(model.ambient_flash_gradient_late_from) {
            model.ambient_flash_gradient_late
        } else {
            1.0
        }
    }

    /// The first step whose parameters enter the average:
    /// `optim.average_from` × the planned steps, rounded up.
    pub fn average_start_step(&self) -> u64 {
        self.share_of_planned_steps(self.config.optim.average_from)
    }

    /// The mean of the parameters so far (`None` when averaging is off).
    pub fn average(&self) -> Option<&ParameterAverage> {
        self.average.as_ref()
    }

    /// Adds the parameters just updated at `step` to the average, from
    /// [`Self::average_start_step`] on, every `optim.average_every` steps.
    /// An average begun before the start (the plan grew: a run resumed with
    /// more `--iters`, or a time budget's pace rose) is dropped and begins
    /// again at the new start.
    fn add_to_average(&mut self, step: u64) {
        let start = self.average_start_step();
        let every = self.config.optim.average_every;
        let Some(avg) = &mut self.average else {
            return;
        };
        if step < start {
            avg.count = 0;
        } else if (step - start).is_multiple_of(every) {
            avg.add(&self.model);
        }
    }

    /// The steps on which the binary-metallic prior pushes:
    /// `loss.binary_metallic_from` to `loss.binary_metallic_until` × the
    /// planned steps, each rounded up (empty when the prior is off).
    pub fn binary_metallic_steps(&self) -> std::ops::Range<u64> {
        let loss = &self.config.loss;
        if loss.binary_metallic <= 0.0 {
            return 0..0;
        }
        self.share_of_planned_steps(loss.binary_metallic_from)
            ..self.share_of_planned_steps(loss.binary_metallic_until)
    }

    /// The learning rate's schedule with factor 1 through the warm-up,
    /// falling along its cosine to `final_factor` at the planned last step:
    /// the annealing of the priors' weight and offset.
    fn prior_anneal(&self, final_factor: f64) -> LrSchedule {
        LrSchedule {
            warmup_steps: self.schedule.warmup_steps,
            warmup_start_factor: 1.0,
            decay: Decay::Cosine {
                total_steps: self.planned_total_steps(),
                final_factor,
            },
        }
    }

    /// The material smoothness prior's weight at `step`: λ ·
    /// (f + (1 − f) · ½ (1 + cos π a)), where f is
    /// `loss.material_smoothness_final` and a the fraction of the learning
    /// rate's decay done by `step` (0 during the warm-up, 1 from the
    /// planned last step on). λ throughout when f = 1.
    pub fn material_smoothness_weight(&self, step: u64) -> f64 {
        let loss = &self.config.loss;
        loss.material_smoothness
            * self.smoothness_factor()
            * self
                .prior_anneal(loss.material_smoothness_final)
                .factor(step)
    }

    /// The factor on the smoothness priors: 1 with masks,
    /// `loss.smoothness_without_masks` without.
    fn smoothness_factor(&self) -> f64 {
        if self.rays.has_masks {
            1.0
        } else {
            self.config.loss.smoothness_without_masks
        }
    }

    /// The normal smoothness prior's weight at `step`: as
    /// [`Self::material_smoothness_weight`], with `loss.normal_smoothness`
    /// and `loss.normal_smoothness_final`.
    pub fn normal_smoothness_weight(&self, step: u64) -> f64 {
        let loss = &self.config.loss;
        loss.normal_smoothness
            * self.smoothness_factor()
            * self.prior_anneal(loss.normal_smoothness_final).factor(step)
    }

    /// Sets the step at which the learning rate reaches its final factor
    /// (the cosine decay's length), e.g. from the steps a time budget is
    /// expected to allow. It never exceeds the configured `iters`.
    pub fn plan_total_steps(&mut self, total: u64) {
        let total = total.clamp(1, self.config.iters);
        if let Decay::Cosine { total_steps, .. } = &mut self.schedule.decay {
            *total_steps = total;
        }
    }

    /// Sets the steps the run trains to (`iters`), keeping the planned
    /// steps within them.
    pub fn set_iters(&mut self, iters: u64) {
        self.config.iters = iters.max(1);
        self.plan_total_steps(self.planned_total_steps());
    }

    /// The step at which the learning rate reaches its final factor.
    pub fn planned_total_steps(&self) -> u64 {
        match self.schedule.decay {
            Decay::Cosine { total_steps, .. } => total_steps,
            _ => self.config.iters,
        }
    }

    /// The training rays.
    pub fn rays(&self) -> &TrainingRays {
        &self.rays
    }

    /// Activates hash levels for the current step (coarse-to-fine).
    fn apply_step_schedule(&mut self) {
        let o = &self.config.optim;
        let levels = if o.c2f_start_levels == 0 {
            usize::MAX
        } else {
            o.c2f_start_levels + (self.step / o.c2f_steps_per_level.max(1)) as usize
        };
        self.model.set_active_levels(levels, levels);
    }

    /// How the model's normals are computed now.
    pub fn normal_method(&self) -> NormalMethod {
        self.model.normal_method()
    }

    /// Re-measures the occupancy grid from the current SDF.
    pub fn refresh_grid(&mut self) {
        let s = self.model.s();
        let model = &self.model;
        let ctx = &mut self.sdf_ctx;
        self.grid.refresh(
            |pts: &[[f32; 3]], out: &mut [f32]| eval_sdf(model, pts, out, ctx),
            s,
            RefreshMode::Full,
        );
        if let Some(prior) = &mut self.hull_prior {
            prior.update_cells(&self.grid);
        }
    }

    /// Takes one optimisation step.
    pub fn step(&mut self) -> StepStats {
        let step = self.step;
        let t_start = Instant::now();
        self.apply_step_schedule();
        if step.is_multiple_of(self.config.sampling.grid_refresh_every) {
            self.refresh_grid();
        } else {
            self.grid.reclassify(self.model.s());
        }
        let cfg = &self.config;
        let mut rng = Pcg64::seed_from_u64(mix(cfg.seed, step, 1));
        let shares = RayShares {
            foreground: cfg.foreground_fraction,
            silhouette: cfg.silhouette_fraction,
        };
        self.rays
            .draw(&mut rng, cfg.batch_rays, shares, &mut self.batch);
        let eik: Vec<[f32; 3]> = (0..cfg.eikonal_points)
            .map(|_| {
                loop {
                    let p: [f32; 3] = [
                        rng.random_range(-1.2..1.2),
                        rng.random_range(-1.2..1.2),
                        rng.random_range(-1.2..1.2),
                    ];
                    if p[0] * p[0] + p[1] * p[1] + p[2] * p[2] <= 1.44 {
                        break p;
                    }
                }
            })
            .collect();
        let settings = PassSettings {
            normals: self.normal_method(),
            cos_anneal_ratio: cos_anneal_ratio(step, self.config.optim.cos_anneal_steps),
            jitter_seed: Some(mix(self.config.seed, step, 2)),
            for_backward: true,
            alpha_eps: wildlight_render::neus::ALPHA_EPS,
            ambient_flash_gradient: self.ambient_flash_gradient(step),
        };
        let rays = RayInputs {
            origins: &self.batch.origins,
            dirs: &self.batch.dirs,
            energy: &self.batch.energy,
        };
        let t_forward = Instant::now();
        self.pipeline
            .forward(&self.model, &self.grid, &rays, &eik, &settings);
        let t_backward = Instant::now();

        // Losses (SPEC §4).
        let cfg = &self.config;
        let n = self.batch.len();
        self.d_colour.resize(n, [0.0; 3]);
        self.d_acc.resize(n, 0.0);
        let has_masks = self.rays.has_masks;
        let counts: Vec<bool> = self.batch.mask.iter().map(|m| *m > 0.5).collect();
        let (color, _, mse) = colour_l1(
            &self.pipeline.colour,
            &self.batch.target,
            &counts,
            &self.batch.saturation,
            cfg.loss.color as f32,
            &mut self.d_colour,
        );
        let mask = if has_masks {
            mask_bce(
                self.pipeline.acc_weight(),
                &self.batch.mask,
                cfg.loss.mask as f32,
                &mut self.d_acc,
            )
        } else {
            self.d_acc.fill(0.0);
            0.0
        };
        let eikonal = self.pipeline.eikonal;

        self.grads.zero();
        self.pipeline.backward(
            &self.model,
            &rays,
            &self.d_colour,
            &self.d_acc,
            cfg.loss.eikonal as f32,
            &settings,
            &mut self.grads,
        );
        let t_priors = Instant::now();
        let (smoothness, normal_smoothness, binary_metallic) =
            self.surface_priors(&mut rng, settings.normals, step);
        let t_hull = Instant::now();
        let visual_hull = match &mut self.hull_prior {
            Some(prior) => prior.forward_backward(
                &self.model.sdf,
                &self.grid,
                &mut rng,
                self.config.loss.visual_hull_points,
                self.config.loss.visual_hull as f32,
                &mut self.grads.sdf,
            ),
            None => 0.0,
        };
        let t_update = Instant::now();
        let cfg = &self.config;
        let loss = cfg.loss.color * color
            + cfg.loss.mask * mask
            + cfg.loss.eikonal * eikonal
            + self.material_smoothness_weight(step) * smoothness
            + self.normal_smoothness_weight(step) * normal_smoothness
            + cfg.loss.binary_metallic * binary_metallic
            + cfg.loss.visual_hull * visual_hull;
        let lr_factor = self.schedule.factor(step) * self.lr_scale;
        let skipped = !loss.is_finite() || !self.grads.all_finite();
        if skipped {
            // A non-finite step never reaches the parameters (or a checkpoint).
            self.lr_scale *= 0.5;
            self.skipped_steps += 1;
        } else {
            self.apply_adam(lr_factor);
            self.add_to_average(step);
        }
        self.step += 1;
        let t_end = Instant::now();
        let phase_ms = StepTimes {
            setup: ms(t_start, t_forward),
            forward: ms(t_forward, t_backward),
            backward: ms(t_backward, t_priors),
            priors: ms(t_priors, t_hull),
            hull: ms(t_hull, t_update),
            update: ms(t_update, t_end),
            background: 1e3 * self.pipeline.background.take_seconds(),
        };
        StepStats {
            step,
            loss,
            color,
            mask,
            eikonal,
            smoothness,
            normal_smoothness,
            binary_metallic,
            visual_hull,
            psnr: psnr(mse, 1.0),
            s: self.model.s() as f64,
            gamma: self.model.gamma() as f64,
            lr_factor,
            samples: self.pipeline.n_samples(),
            occupied: self.grid.occupied_fraction() as f64,
            skipped,
            phase_ms,
        }
    }

    /// The priors over the surface points of the last pass: the
    /// binary-metallic prior (crate::metallic_prior) at the points
    /// themselves on [`Self::binary_metallic_steps`], and the smoothness of
    /// the material field (crate::smoothness) and of the normals
    /// (crate::normal_smoothness), each point paired with a point offset
    /// uniformly within `loss.smoothness_radius` per axis; adds their
    /// gradients and returns their unweighted values (0 for a prior that is
    /// off, or not on at this step). The offsets are drawn only when a
    /// smoothness prior is on, so a run with both off draws the same random
    /// numbers as before they existed.
    fn surface_priors(
        &mut self,
        rng: &mut Pcg64,
        normal_method: NormalMethod,
        step: u64,
    ) -> (f64, f64, f64) {
        let loss = &self.config.loss;
        let factor = self.smoothness_factor();
        let material_on = loss.material_smoothness * factor > 0.0;
        let normal_on = loss.normal_smoothness * factor > 0.0;
        let smooth = material_on || normal_on;
        let binary_on = self.binary_metallic_steps().contains(&step);
        if !smooth && !binary_on {
            return (0.0, 0.0, 0.0);
        }
        let SurfacePoints { centres, normals } = self.pipeline.surface_points(0.5);
        let binary = if binary_on {
            self.binary_metallic.forward_backward(
                &self.model.material,
                &centres,
                loss.binary_metallic as f32,
                &mut self.grads.material,
            )
        } else {
            0.0
        };
        if !smooth {
            return (0.0, 0.0, binary);
        }
        let offsets = random_offsets(rng, centres.len(), loss.smoothness_radius);
        let material_weight = self.material_smoothness_weight(step) as f32;
        let normal_weight = self.normal_smoothness_weight(step) as f32;
        let material = if material_on {
            self.smoothness.forward_backward(
                &self.model.material,
                &centres,
                &offsets,
                material_weight,
                &mut self.grads.material,
            )
        } else {
            0.0
        };
        let normal = if normal_on {
            self.normal_smoothness.forward_backward(
                &self.model.sdf,
                &centres,
                &normal_smoothness::pair_offsets(&offsets, &normals),
                normal_method,
                normal_weight,
                &mut self.grads.sdf,
            )
        } else {
            0.0
        };
        (material, normal, binary)
    }

    fn apply_adam(&mut self, f: f64) {
        let (m, g, gr, a) = (&mut self.model, &self.grads, &self.groups, &mut self.adam);
        a.step(gr.sdf_grid, &mut m.sdf.field.grid.params, &g.sdf.grid, f);
        a.step(gr.sdf_mlp, &mut m.sdf.field.mlp.params, &g.sdf.mlp, f);
        a.step(
            gr.mat_grid,
            &mut m.material.grid.params,
            &g.material.grid,
            f,
        );
        a.step(gr.mat_mlp, &mut m.material.mlp.params, &g.material.mlp, f);
        a.step(gr.amb_grid, &mut m.ambient.grid.params, &g.ambient.grid, f);
        a.step(gr.amb_mlp, &mut m.ambient.mlp.params, &g.ambient.mlp, f);
        if let (Some((grid, mlp)), Some(room), Some(grads)) = (gr.room, &mut m.room, &g.room) {
            a.step(grid, &mut room.grid.params, &grads.grid, f);
            a.step(mlp, &mut room.mlp.params, &grads.mlp, f);
        }
        if let (Some((grid, mlp)), Some(bg), Some(grads)) =
            (gr.background, &mut m.background, &g.background)
        {
            a.step(grid, &mut bg.grid.params, &grads.grid, f);
            a.step(mlp, &mut bg.mlp.params, &grads.mlp, f);
        }
        let mut v = [m.sharpness];
        a.step(gr.sharpness, &mut v, &[g.sharpness], f);
        m.sharpness = v[0];
        let mut lg = [m.log_gain];
        a.step(gr.gain, &mut lg, &[g.log_gain], f);
        m.log_gain = lg[0];
    }

    /// Writes the model, the optimiser state and the step (atomically).
    pub fn save_checkpoint(&self, path: &Path) -> anyhow::Result<()> {
        anyhow::ensure!(
            self.model.all_finite(),
            "refusing to write a checkpoint with non-finite parameters"
        );
        let mut w = CheckpointWriter::new();
        save_model(&self.model, &mut w, "");
        if let Some(avg) = self.average.as_ref().filter(|a| a.count > 0) {
            save_model(&avg.model, &mut w, AVERAGE_PREFIX);
            w.set_metadata(AVERAGE_COUNT, &avg.count.to_string());
        }
        self.adam.save_to(&mut w, "adam");
        let grid = self.grid.snapshot();
        w.add("occupancy.sdf", &[grid.sdf.len()], &grid.sdf);
        w.set_metadata("occupancy.resolution", &grid.resolution.to_string());
        w.set_metadata("occupancy.band", &format!("{:e}", grid.band));
        w.set_metadata("occupancy.round", &grid.round.to_string());
        w.set_metadata("step", &self.step.to_string());
        w.set_metadata("lr_scale", &format!("{:e}", self.lr_scale));
        w.set_metadata("skipped_steps", &self.skipped_steps.to_string());
        w.set_metadata(
            "planned_total_steps",
            &self.planned_total_steps().to_string(),
        );
        w.save(path)
            .with_context(|| format!("cannot write the checkpoint {}", path.display()))
    }

    /// Restores the state written by [`Trainer::save_checkpoint`].
    pub fn load_checkpoint(&mut self, path: &Path) -> anyhow::Result<()> {
        let ck = Checkpoint::load(path)
            .with_context(|| format!("cannot read the checkpoint {}", path.display()))?;
        load_model(&mut self.model, &ck, "")?;
        if let Some(avg) = &mut self.average {
            // absent until the average holds a parameter set; an empty
            // average's values are never read (its first set is copied in)
            match ck.metadata(AVERAGE_COUNT) {
                Some(count) => {
                    avg.count = count.parse().context(AVERAGE_COUNT)?;
                    load_model(&mut avg.model, &ck, AVERAGE_PREFIX)?;
                }
                None => avg.count = 0,
            }
        }
        // The room's optimiser groups, under their name in the checkpoint.
        let room = room_name(&ck, "adam.");
        let groups: Vec<usize> = self
            .groups
            .room
            .into_iter()
            .flat_map(|(g, m)| [g, m])
            .collect();
        for (&g, part) in groups.iter().zip(["grid", "mlp"]) {
            self.adam.groups[g].name = format!("{room}.{part}");
        }
        let loaded = self
            .adam
            .load_from(&ck, "adam")
            .with_context(|| format!("{}: optimiser state", path.display()));
        for (&g, part) in groups.iter().zip(["grid", "mlp"]) {
            self.adam.groups[g].name = format!("{ROOM}.{part}");
        }
        loaded?;
        let meta = |key: &str| {
            ck.metadata(key)
                .with_context(|| format!("{}: missing metadata '{key}'", path.display()))
        };
        self.step = meta("step")?.parse().context("step")?;
        self.lr_scale = meta("lr_scale")?.parse().context("lr_scale")?;
        self.skipped_steps = meta("skipped_steps")?.parse().context("skipped_steps")?;
        // absent in checkpoints of older versions: keep the configured length
        if let Some(total) = ck.metadata("planned_total_steps") {
            self.plan_total_steps(total.parse().context("planned_total_steps")?);
        }
        self.apply_step_schedule();
        // The occupancy grid as it was (measured at the last refresh step,
        // from the field of that time), so that the run continues exactly.
        let resolution: usize = meta("occupancy.resolution")?
            .parse()
            .context("occupancy.resolution")?;
        let mut sdf = vec![0.0f32; resolution.pow(3)];
        ck.read_into("occupancy.sdf", &[sdf.len()], &mut sdf)
            .with_context(|| format!("{}: occupancy grid", path.display()))?;
        let snapshot = OccupancySnapshot {
            resolution,
            sdf,
            band: meta("occupancy.band")?.parse().context("occupancy.band")?,
            round: meta("occupancy.round")?
                .parse()
                .context("occupancy.round")?,
        };
        self.grid
            .restore(&snapshot)
            .with_context(|| format!("{}: occupancy grid", path.display()))?;
        if let Some(prior) = &mut self.hull_prior {
            prior.update_cells(&self.grid);
        }
        Ok(())
    }
}

/// Prefix of the averaged parameters' tensors in a checkpoint.
pub const AVERAGE_PREFIX: &str = "average.";
/// Checkpoint metadata: how many parameter sets the average holds.
pub const AVERAGE_COUNT: &str = "average.count";

/// The room's name in checkpoints: its tensors (`room.grid.table`, …) and
/// optimiser groups (`adam.room.grid.m`, …).
const ROOM: &str = "room";
/// The background field's name in checkpoints: its tensors
/// (`background.grid.table`, …) and optimiser groups.
const BACKGROUND: &str = "background";
/// The room's name in checkpoints written before issue 48 (it lived in the
/// model's `ambient_specular` slot).
const OLD_ROOM: &str = "ambient_specular";

/// The room's name in `ck` among the tensors whose names begin with
/// `prefix`: [`ROOM`], or [`OLD_ROOM`] in an older checkpoint.
fn room_name(ck: &Checkpoint, prefix: &str) -> &'static str {
    let has = |name: &str| {
        ck.contains(&format!("{prefix}{name}.grid.table"))
            || ck.contains(&format!("{prefix}{name}.grid.m"))
    };
    if !has(ROOM) && has(OLD_ROOM) {
        OLD_ROOM
    } else {
        ROOM
    }
}

/// Adds the model's parameters to a checkpoint, each tensor's name after
/// `prefix` ("" for the live model, [`AVERAGE_PREFIX`] for the average).
pub fn save_model(model: &Model, w: &mut CheckpointWriter, prefix: &str) {
    model.sdf.save_to(w, &format!("{prefix}sdf"));
    model.material.save_to(w, &format!("{prefix}material"));
    model.ambient.save_to(w, &format!("{prefix}ambient"));
    if let Some(f) = &model.room {
        f.save_to(w, &format!("{prefix}{ROOM}"));
    }
    if let Some(f) = &model.background {
        f.save_to(w, &format!("{prefix}{BACKGROUND}"));
    }
    w.add(
        &format!("{prefix}scalars"),
        &[2],
        &[model.sharpness, model.log_gain],
    );
}

/// Reads the model's parameters (those saved with `prefix`) from a
/// checkpoint; the room also under its name of older checkpoints.
pub fn load_model(model: &mut Model, ck: &Checkpoint, prefix: &str) -> anyhow::Result<()> {
    let p = ck.path().display().to_string();
    model
        .sdf
        .load_from(ck, &format!("{prefix}sdf"))
        .with_context(|| format!("{p}: {prefix}SDF field"))?;
    model
        .material
        .load_from(ck, &format!("{prefix}material"))
        .with_context(|| format!("{p}: {prefix}material field"))?;
    model
        .ambient
        .load_from(ck, &format!("{prefix}ambient"))
        .with_context(|| format!("{p}: {prefix}ambient field"))?;
    if let Some(f) = &mut model.room {
        let room = room_name(ck, prefix);
        f.load_from(ck, &format!("{prefix}{room}"))
            .with_context(|| format!("{p}: {prefix}room field"))?;
    }
    if let Some(f) = &mut model.background {
        f.load_from(ck, &format!("{prefix}{BACKGROUND}"))
            .with_context(|| format!("{p}: {prefix}background field"))?;
    }
    let mut s = [0.0f32; 2];
    ck.read_into(&format!("{prefix}scalars"), &[2], &mut s)
        .with_context(|| format!("{p}: {prefix}scalars"))?;
    model.sharpness = s[0];
    model.log_gain = s[1];
    anyhow::ensure!(
        model.all_finite(),
        "{p}: the checkpoint holds non-finite parameters"
    );
    Ok(())
}

/// `n` offsets with every coordinate uniform in ±`radius` (the smoothness
/// pairs' second points).
fn random_offsets(rng: &mut Pcg64, n: usize, radius: f64) -> Vec<[f32; 3]> {
    let r = radius as f32;
    (0..n)
        .map(|_| [0; 3].map(|_| rng.random_range(-r..=r)))
        .collect()
}
