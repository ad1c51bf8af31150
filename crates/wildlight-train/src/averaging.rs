//! Tail averaging of the parameters (Polyak–Ruppert): the mean of the
//! model's parameters over the last part of a run, taken every few steps.
//!
//! Late in a run the learning rate is small but the rays of each step are a
//! new random draw, so the parameters keep jittering around the optimum the
//! whole capture defines; their mean over the tail is closer to it than any
//! one step's values. Training continues on the live parameters; the
//! average is what a finished run renders and exports
//! ([`crate::inference::TrainedRun`]). Both are in the checkpoint, so a
//! resumed run continues the average exactly.

use crate::model::Model;
use rayon::prelude::*;

/// Every parameter array of a model, in a fixed order (the scalars last).
fn arrays(model: &Model) -> Vec<&[f32]> {
    let mut out: Vec<&[f32]> = vec![
        &model.sdf.field.grid.params,
        &model.sdf.field.mlp.params,
        &model.material.grid.params,
        &model.material.mlp.params,
        &model.ambient.grid.params,
        &model.ambient.mlp.params,
    ];
    if let Some(room) = &model.room {
        out.push(&room.grid.params);
        out.push(&room.mlp.params);
    }
    if let Some(bg) = &model.background {
        out.push(&bg.grid.params);
        out.push(&bg.mlp.params);
    }
    out
}

/// [`arrays`], writable.
fn arrays_mut(model: &mut Model) -> Vec<&mut [f32]> {
    let mut out: Vec<&mut [f32]> = vec![
        &mut model.sdf.field.grid.params,
        &mut model.sdf.field.mlp.params,
        &mut model.material.grid.params,
        &mut model.material.mlp.params,
        &mut model.ambient.grid.params,
        &mut model.ambient.mlp.params,
    ];
    if let Some(room) = &mut model.room {
        out.push(&mut room.grid.params);
        out.push(&mut room.mlp.params);
    }
    if let Some(bg) = &mut model.background {
        out.push(&mut bg.grid.params);
        out.push(&mut bg.mlp.params);
    }
    out
}

/// The running mean of a model's parameters.
#[derive(Clone, Debug)]
pub struct ParameterAverage {
    /// The mean so far (its parameters; its settings are the model's).
    pub model: Model,
    /// How many parameter sets the mean holds (0: none yet).
    pub count: u64,
}

impl ParameterAverage {
    /// An empty average shaped like `model`.
    pub fn new(model: &Model) -> Self {
        Self {
            model: model.clone(),
            count: 0,
        }
    }

    /// Adds `model`'s current parameters: mean += (θ − mean) / count; the
    /// first set is copied as it is (so the mean never depends on what the
    /// empty average held, and a resumed run matches a straight one).
    pub fn add(&mut self, model: &Model) {
        if self.count == 0 {
            self.model.clone_from(model);
            self.count = 1;
            return;
        }
        self.count += 1;
        let k = 1.0 / self.count as f32;
        for (mean, live) in arrays_mut(&mut self.model).into_iter().zip(arrays(model)) {
            mean.par_chunks_mut(4096)
                .zip(live.par_chunks(4096))
                .for_each(|(m, l)| {
                    for (m, l) in m.iter_mut().zip(l) {
                        *m += (l - *m) * k;
                    }
                });
        }
        let mean = &mut self.model;
        mean.sharpness += (model.sharpness - mean.sharpness) * k;
        mean.log_gain += (model.log_gain - mean.log_gain) * k;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::{FieldSize, ModelConfig};

    fn tiny(levels: usize) -> FieldSize {
        FieldSize {
            levels,
            features_per_level: 2,
            log2_table_size: 6,
            base_resolution: 2,
            finest_resolution: 8,
            hidden: vec![4],
            interpolation: Default::default(),
        }
    }

    #[test]
    fn the_average_is_the_mean_of_what_was_added() {
        let config = ModelConfig {
            sdf: tiny(3),
            geometry_features: 3,
            material: tiny(2),
            ambient: tiny(2),
            ambient_room: FieldSize {
                hidden: vec![],
                ..tiny(2)
            },
            ..ModelConfig::default()
        };
        let model = Model::new(&config, 3).unwrap();
        let mut avg = ParameterAverage::new(&model);
        assert_eq!(avg.count, 0);
        // the three fields and the room, each a table and a network
        assert_eq!(arrays(&model).len(), 8);
        // Three parameter sets: θ, θ + 1 and θ + 5 (every array and the
        // scalars), whose mean is θ + 2.
        let shifted = |by: f32| {
            let mut m = model.clone();
            for a in arrays_mut(&mut m) {
                a.iter_mut().for_each(|v| *v += by);
            }
            m.sharpness += by;
            m.log_gain += by;
            m
        };
        for by in [0.0, 1.0, 5.0] {
            avg.add(&shifted(by));
        }
        assert_eq!(avg.count, 3);
        let want = shifted(2.0);
        for (a, w) in arrays(&avg.model).into_iter().zip(arrays(&want)) {
            assert_eq!(a.len(), w.len());
            assert!(a.iter().zip(w).all(|(a, w)| (a - w).abs() < 1e-5));
        }
        assert!((avg.model.sharpness - want.sharpness).abs() < 1e-5);
        assert!((avg.model.log_gain - want.log_gain).abs() < 1e-5);
    }
}
