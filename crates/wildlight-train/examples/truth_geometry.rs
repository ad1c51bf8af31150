//! A geometry (and material) oracle for experiments on synthetic captures:
//! a new run folder whose SDF is fitted to the built-in scene's true signed
//! distance before step 0, so that `wildlight train --out RUN --resume --iters ITERS` (or
//! `--time-budget`) trains the rest of the model (materials, ambient light,
//! the NeuS sharpness and the flash gain) on top of the right shape. With
//! the SDF's learning rates at zero (`optim.grid_lr_factors.sdf = 0`,
//! `optim.mlp_lr_factors.sdf = 0`) the shape, and the geometry features the
//! ambient network reads, stay fixed, and the run's scores show what the
//! right shape alone gives; with them left on, the run shows whether
//! training keeps a shape it did not have to find. Either way `optim.c2f_start_levels`
//! should be the SDF's level count, or the coarse-to-fine schedule hides the
//! fitted fine levels at the start.
//!
//! The fit: the SDF's distance output regresses the true distance (squared
//! error, Adam, cosine-decayed learning rate) at points drawn once — 30 %
//! uniform in [−0.9, 0.9]³, 70 % projected onto the true surface and moved
//! off it along the true normal by a triangular offset of half-width 0.002
//! or 0.02. The scene's mesh in the capture (surface nets at the synthesizer's
//! `--mesh-resolution`, shaded with interpolated vertex normals) differs from
//! this distance function within a mesh cell, most at creases. After the
//! fit the example prints the SDF's error near the surface and the angle
//! between its finite-difference normals (tetrahedral, at steps of ¼ to 4
//! cells of the finest level) and the true normals at surface points.
//!
//! With `MATERIALS` = 1 the material field is fitted too: Θ regresses the
//! scene's true parameters (squared error, targets clamped to [0.01, 0.99]
//! where the sigmoid cannot reach 0 or 1) at the pool's points near the
//! surface. With the material learning rates at zero as well, training then
//! learns the ambient light, s and γ alone on the true shape and materials;
//! with them on, it shows whether training keeps materials it did not have
//! to find.
//!
//! ```sh
//! cargo run --release -p wildlight-train --example truth_geometry -- \
//!     kettle CAPTURE CONFIG.toml RUN [ITERS [SEED [FIT_STEPS [MATERIALS]]]]
//! wildlight train --out RUN --resume --iters ITERS
//! ```

use anyhow::{Context, Result, bail};
use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;
use std::path::Path;
use wildlight_fields::{
    Adam, AdamConfig, FdScheme, FieldContext, FieldGrads, NeuralField, NormalContext, NormalMethod,
    SdfField,
};
use wildlight_material::{PARAM_COUNT, PARAM_NAMES};
use wildlight_synth::scenes::BuiltinScene;
use wildlight_train::config::TrainConfig;
use wildlight_train::rays::TrainingRays;
use wildlight_train::run::{CHECKPOINT_FILE, MaskMode, load_capture, write_run_files};
use wildlight_train::trainer::Trainer;

/// Fitting points drawn once.
const POOL: usize = 1 << 21;
/// Points per fitting step.
const BATCH: usize = 1 << 15;

fn main() -> Result<()> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    if a.len() < 4 {
        bail!(
            "usage: truth_geometry SCENE CAPTURE CONFIG.toml RUN [ITERS [SEED [FIT_STEPS [MATERIALS]]]]"
        );
    }
    let scene = BuiltinScene::from_name(&a[0]).with_context(|| format!("no scene {}", a[0]))?;
    let (capture, config_path, run) = (Path::new(&a[1]), Path::new(&a[2]), Path::new(&a[3]));
    let arg = |i: usize, default: u64| -> Result<u64> {
        a.get(i).map_or(Ok(default), |s| {
            s.parse().with_context(|| format!("bad number {s}"))
        })
    };
    let mut config = TrainConfig::load(config_path)?;
    config.iters = arg(4, config.iters)?;
    config.seed = arg(5, config.seed)?;
    let fit_steps = arg(6, 3000)? as usize;
    let fit_materials = arg(7, 0)? != 0;
    config.validate().map_err(anyhow::Error::msg)?;
    if config.optim.c2f_start_levels < config.model.sdf.levels {
        eprintln!(
            "warning: optim.c2f_start_levels = {} < model.sdf.levels = {}: the fitted SDF's \
             finest levels stay off until the coarse-to-fine schedule reaches them",
            config.optim.c2f_start_levels, config.model.sdf.levels
        );
    }
    if run.join(CHECKPOINT_FILE).exists() {
        bail!("{} already holds a run", run.display());
    }
    let (dataset, _) = load_capture(capture)?;
    let mut trainer = Trainer::new(config.clone(), TrainingRays::new(&dataset))?;

    let pool = fitting_points(scene);
    let sdf = &mut trainer.model.sdf;
    let active = sdf.field.active_levels;
    sdf.field.active_levels = sdf.field.grid.config().n_levels;
    fit(sdf, &pool, fit_steps);
    report(sdf, scene, &pool);
    sdf.field.active_levels = active;
    if fit_materials {
        let material = &mut trainer.model.material;
        let levels = material.active_levels;
        material.active_levels = material.grid.levels().len();
        fit_material(material, scene, &pool, fit_steps);
        material.active_levels = levels;
    }
    trainer.refresh_grid();

    write_run_files(run, &config, capture, MaskMode::Used)?;
    trainer.save_checkpoint(&run.join(CHECKPOINT_FILE))?;
    println!("wrote {} (step 0, the true SDF)", run.display());
    Ok(())
}

/// Points and their true distances (see the module docs).
fn fitting_points(scene: BuiltinScene) -> Vec<([f32; 3], f32)> {
    (0..POOL)
        .into_par_iter()
        .map(|i| {
            let mut rng = Pcg64::seed_from_u64(i as u64);
            let mut p = DVec3::new(
                rng.random_range(-0.9..0.9),
                rng.random_range(-0.9..0.9),
                rng.random_range(-0.9..0.9),
            );
            if i % 10 >= 3 {
                for _ in 0..4 {
                    p -= scene.normal(p) * scene.distance(p);
                }
                let width = if i % 2 == 0 { 0.002 } else { 0.02 };
                let t: f64 = rng.random_range(-1.0..1.0) + rng.random_range(-1.0..1.0);
                p += scene.normal(p) * t * width;
            }
            (p.as_vec3().to_array(), scene.distance(p) as f32)
        })
        .collect()
}

/// Adam on a field's grid (learning rate 0.01) and network (0.001) with a
/// cosine decay to 5 % over the fit.
struct Fitter {
    adam: Adam<f32>,
    grid: usize,
    mlp: usize,
}

impl Fitter {
    fn new(field: &NeuralField<f32>) -> Fitter {
        let mut adam = Adam::<f32>::new();
        let lr = |lr: f64| AdamConfig {
            lr,
            ..Default::default()
        };
        let grid = adam.add_group("grid", field.grid.params.len(), lr(0.01));
        let mlp = adam.add_group("mlp", field.mlp.params.len(), lr(0.001));
        Fitter { adam, grid, mlp }
    }

    fn step(
        &mut self,
        field: &mut NeuralField<f32>,
        grads: &FieldGrads<f32>,
        step: usize,
        steps: usize,
    ) {
        let cosine = 0.5 * (1.0 + (std::f64::consts::PI * step as f64 / steps as f64).cos());
        let factor = 0.05 + 0.95 * cosine;
        self.adam
            .step(self.grid, &mut field.grid.params, &grads.grid, factor);
        self.adam
            .step(self.mlp, &mut field.mlp.params, &grads.mlp, factor);
    }
}

/// A fitting batch: `BATCH` entries of `items` drawn with replacement, as
/// their indices and their points.
fn draw<T>(rng: &mut Pcg64, items: &[([f32; 3], T)]) -> (Vec<usize>, Vec<[f32; 3]>) {
    let idx: Vec<usize> = (0..BATCH)
        .map(|_| rng.random_range(0..items.len()))
        .collect();
    let x = idx.iter().map(|&i| items[i].0).collect();
    (idx, x)
}

/// Regresses the SDF's distance output on the pool's true distances.
fn fit(sdf: &mut SdfField<f32>, pool: &[([f32; 3], f32)], steps: usize) {
    let mut fitter = Fitter::new(&sdf.field);
    let mut grads = sdf.new_grads();
    let mut ctx = FieldContext::new();
    let stride = sdf.n_output();
    let mut rng = Pcg64::seed_from_u64(5);
    for step in 0..steps {
        let (idx, x) = draw(&mut rng, pool);
        sdf.forward(&x, &mut ctx);
        let mut d_out = vec![0.0f32; BATCH * stride];
        let mut sq = 0.0f64;
        for (j, &i) in idx.iter().enumerate() {
            let e = ctx.output()[j * stride] - pool[i].1;
            sq += f64::from(e * e);
            d_out[j * stride] = 2.0 * e / BATCH as f32;
        }
        grads.zero();
        sdf.backward(&mut ctx, &d_out, &mut grads, None);
        fitter.step(&mut sdf.field, &grads, step, steps);
        if step % 500 == 0 || step + 1 == steps {
            println!(
                "fit step {step}: rms error {:.5}",
                (sq / BATCH as f64).sqrt()
            );
        }
    }
}

/// Regresses Θ on the scene's true material at the pool's points near the
/// surface, and prints the mean absolute error per parameter over the last
/// step's points.
fn fit_material(
    material: &mut NeuralField<f32>,
    scene: BuiltinScene,
    pool: &[([f32; 3], f32)],
    steps: usize,
) {
    let points: Vec<([f32; 3], [f32; PARAM_COUNT])> = pool
        .iter()
        .filter(|(_, d)| d.abs() < 0.02)
        .map(|&(p, _)| {
            let truth = scene.material(DVec3::from(p.map(f64::from)));
            (p, truth.to_array::<f32>().map(|v| v.clamp(0.01, 0.99)))
        })
        .collect();
    let mut fitter = Fitter::new(material);
    let mut grads = material.new_grads();
    let mut ctx = FieldContext::new();
    let mut rng = Pcg64::seed_from_u64(6);
    let mut abs = [0.0f64; PARAM_COUNT];
    for step in 0..steps {
        let (idx, x) = draw(&mut rng, &points);
        material.forward(&x, &[], &mut ctx);
        let mut d_theta = vec![0.0f32; BATCH * PARAM_COUNT];
        abs = [0.0; PARAM_COUNT];
        for (j, &i) in idx.iter().enumerate() {
            for k in 0..PARAM_COUNT {
                let e = ctx.output()[j * PARAM_COUNT + k] - points[i].1[k];
                abs[k] += f64::from(e.abs()) / BATCH as f64;
                d_theta[j * PARAM_COUNT + k] = 2.0 * e / BATCH as f32;
            }
        }
        grads.zero();
        material.backward(&mut ctx, &d_theta, &mut grads, None, None);
        fitter.step(material, &grads, step, steps);
    }
    let names = PARAM_NAMES.iter().zip(abs);
    let listed: Vec<String> = names.map(|(n, e)| format!("{n} {e:.4}")).collect();
    println!("fitted material, mean |error|: {}", listed.join(", "));
}

/// Prints the fitted SDF's error at pool points within 0.01 of the surface.
fn report(sdf: &SdfField<f32>, scene: BuiltinScene, pool: &[([f32; 3], f32)]) {
    let near: Vec<[f32; 3]> = pool
        .iter()
        .step_by(97)
        .filter(|(_, d)| d.abs() < 0.01)
        .map(|(p, _)| *p)
        .collect();
    let mut ctx = FieldContext::new();
    sdf.forward(&near, &mut ctx);
    let stride = sdf.n_output();
    let errors: Vec<f64> = near
        .iter()
        .enumerate()
        .map(|(j, p)| {
            let truth = scene.distance(DVec3::from(p.map(f64::from)));
            (f64::from(ctx.output()[j * stride]) - truth).abs()
        })
        .collect();
    let mean = errors.iter().sum::<f64>() / errors.len().max(1) as f64;
    let max = errors.iter().copied().fold(0.0, f64::max);
    println!(
        "fitted SDF within 0.01 of the surface: |error| mean {mean:.5}, max {max:.5} ({} points)",
        errors.len()
    );
    let surface: Vec<[f32; 3]> = near
        .iter()
        .filter(|p| scene.distance(DVec3::from(p.map(f64::from))).abs() < 0.001)
        .copied()
        .collect();
    let cell = sdf.field.cell_size(sdf.field.active_levels - 1);
    for factor in [0.25, 0.5, 1.0, 2.0, 4.0] {
        let mut nctx = NormalContext::new();
        let method = NormalMethod::FiniteDifference {
            scheme: FdScheme::Tetrahedral,
            step: cell * factor,
        };
        sdf.forward_with_normals(&surface, method, &mut nctx);
        let mut degrees: Vec<f64> = surface
            .iter()
            .zip(&nctx.gradient)
            .map(|(p, g)| {
                let truth = scene.normal(DVec3::from(p.map(f64::from)));
                let n = DVec3::from(g.map(f64::from)).normalize_or_zero();
                n.dot(truth).clamp(-1.0, 1.0).acos().to_degrees()
            })
            .collect();
        degrees.sort_by(f64::total_cmp);
        let q = |p: f64| degrees[((degrees.len() - 1) as f64 * p) as usize];
        println!(
            "normals at FD step {:.5} ({factor} cells), angle to the true normal: median {:.3}°, p90 {:.3}°, p99 {:.3}° ({} points)",
            cell * factor,
            q(0.5),
            q(0.9),
            q(0.99),
            degrees.len()
        );
    }
}
