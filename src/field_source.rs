//! A trained run as the exporter's field source: the bridge between
//! `wildlight-train` (the model) and `wildlight-export` (which reads fields
//! through [`wildlight_export::FieldSource`]), so that neither crate
//! depends on the other.

use wildlight_fields::{FieldContext, NormalContext};
use wildlight_train::Model;
use wildlight_train::inference::TrainedRun;
use wildlight_train::pipeline::eval_sdf;

/// The trained fields as a source for `wildlight-export`: SDF, gradient
/// (the SDF field's own normals, computed as in training) and material.
pub struct ExportSource<'a> {
    model: &'a Model,
}

impl<'a> ExportSource<'a> {
    /// Wraps a trained run's model.
    pub fn new(run: &'a TrainedRun) -> Self {
        Self { model: &run.model }
    }
}

impl wildlight_export::FieldSource for ExportSource<'_> {
    fn sdf(&self, points: &[[f32; 3]], out: &mut [f32]) {
        let mut ctx = FieldContext::new();
        eval_sdf(self.model, points, out, &mut ctx);
    }

    fn material(&self, points: &[[f32; 3]], out: &mut [[f32; 9]]) {
        out.copy_from_slice(&self.model.material_at(points));
    }

    fn gradient(&self, points: &[[f32; 3]], out: &mut [[f32; 3]]) {
        let mut ctx = NormalContext::new();
        self.model
            .sdf
            .forward_with_normals(points, self.model.normal_method(), &mut ctx);
        out.copy_from_slice(&ctx.gradient);
    }

    fn gradient_step(&self) -> f32 {
        self.model.fd_step() as f32
    }
}
