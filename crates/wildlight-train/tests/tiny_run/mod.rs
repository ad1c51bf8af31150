//! The tiny synthetic captures and the small model the training tests share.
#![allow(dead_code)]

use std::path::Path;
use wildlight_data::{Dataset, LoadOptions};
use wildlight_synth::{RigOptions, SynthOptions, synthesize};
use wildlight_train::config::{FieldSize, TrainConfig};
use wildlight_train::pipeline::eval_sdf;
use wildlight_train::trainer::Trainer;

/// A synthetic kettle capture of `views` views at `size`², written to `dir` and loaded.
pub fn capture(dir: &Path, views: usize, size: u32) -> Dataset {
    synthesize(&SynthOptions {
        rig: RigOptions {
            views,
            val_views: 0,
            width: size,
            height: size,
            seed: 3,
            ..RigOptions::default()
        },
        spp: 4,
        val_spp: 4,
        mesh_resolution: 64,
        out: dir.to_path_buf(),
        progress: false,
        ..SynthOptions::default()
    })
    .expect("synthesis works");
    Dataset::load(dir, &LoadOptions::default()).expect("the capture loads")
}

/// A field of `levels` levels up to `finest`, a 2^`log2` table and these hidden layers.
pub fn small(levels: usize, log2: u32, finest: u32, hidden: Vec<usize>) -> FieldSize {
    FieldSize {
        levels,
        features_per_level: 2,
        log2_table_size: log2,
        base_resolution: 8,
        finest_resolution: finest,
        hidden,
        interpolation: Default::default(),
    }
}

/// The small model the training tests train for `iters` steps.
pub fn small_config(iters: u64) -> TrainConfig {
    let mut c = TrainConfig {
        iters,
        batch_rays: 512,
        eikonal_points: 128,
        ..TrainConfig::default()
    };
    c.model.sdf = small(8, 15, 128, vec![32]);
    c.model.material = small(6, 14, 64, vec![32]);
    c.model.ambient = small(4, 12, 32, vec![32]);
    c.model.ambient_room = small(3, 12, 32, vec![]);
    c.sampling.grid_resolution = 32;
    c.sampling.grid_refresh_every = 4;
    c.optim.warmup_steps = 10;
    c.optim.cos_anneal_steps = 50;
    c.optim.c2f_start_levels = 3;
    c.optim.c2f_steps_per_level = 20;
    c
}

/// Mean |φ| of the model at the ground-truth surface vertices: the distance
/// from the true surface to the learned zero level set (one side of eq. 16,
/// for a field that is close to a distance function).
pub fn mean_abs_sdf_at_gt(trainer: &Trainer, dir: &Path) -> f64 {
    let mesh = wildlight_mesh::TriMesh::read(dir.join("gt/mesh_normalized.ply")).unwrap();
    let pts: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
    let mut out = vec![0.0f32; pts.len()];
    let mut ctx = wildlight_fields::FieldContext::new();
    eval_sdf(&trainer.model, &pts, &mut out, &mut ctx);
    out.iter().map(|v| v.abs() as f64).sum::<f64>() / out.len() as f64
}
