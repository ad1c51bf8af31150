//! The material field Θ(x) (SPEC §3): the nine principled-BRDF parameters
//! at a point, each through a sigmoid.
//!
//! By default one hash grid and one network give all nine. Optionally
//! (`model.metallic_field`) metallic comes from a second, smaller field of
//! its own, and the first field's metallic output goes unused: a prior on
//! metallic alone (`crate::metallic_prior`) then moves only parameters
//! that read metallic, never base colour or roughness. With one field
//! every parameter shares the coarse hash levels and the hidden layer, so
//! pushing a partial metal (the kettle's terracotta) to a dielectric
//! darkened the metals beside it too (docs/benchmark-log.md, session 28).

use crate::float::Float;
use wildlight_fields::{FieldContext, FieldGrads, NeuralField};
use wildlight_material::{METALLIC, PARAM_COUNT};

/// The fields behind Θ.
#[derive(Clone, Debug)]
pub struct MaterialField<T> {
    /// The nine parameters (its metallic output unused when [`Self::metallic`]
    /// is set).
    pub params: NeuralField<T>,
    /// Metallic from a field of its own (one sigmoid output), if any.
    pub metallic: Option<NeuralField<T>>,
}

/// Gradients of a [`MaterialField`]'s parameters.
#[derive(Clone, Debug)]
pub struct MaterialGrads<T> {
    /// Of [`MaterialField::params`].
    pub params: FieldGrads<T>,
    /// Of [`MaterialField::metallic`], when there is one.
    pub metallic: Option<FieldGrads<T>>,
}

impl<T: Float> MaterialGrads<T> {
    /// Sets every gradient to zero.
    pub fn zero(&mut self) {
        self.params.zero();
        if let Some(g) = &mut self.metallic {
            g.zero();
        }
    }

    /// Whether every gradient is finite.
    pub fn all_finite(&self) -> bool {
        self.params.all_finite() && self.metallic.as_ref().is_none_or(FieldGrads::all_finite)
    }
}

/// Buffers of one forward and backward pass of a [`MaterialField`].
#[derive(Default)]
pub struct MaterialContext<T> {
    params: FieldContext<T>,
    metallic: FieldContext<T>,
    /// Θ, row-major (`n × 9`), when metallic comes from its own field.
    theta: Vec<T>,
    d_params: Vec<T>,
    d_metallic: Vec<T>,
    separate: bool,
}

impl<T: Float + Default> MaterialContext<T> {
    /// Empty buffers.
    pub fn new() -> Self {
        Self::default()
    }

    /// Θ of the last forward pass, row-major (`n × 9`).
    pub fn output(&self) -> &[T] {
        if self.separate {
            &self.theta
        } else {
            self.params.output()
        }
    }
}

impl<T: Float + Default> MaterialField<T> {
    /// Zeroed gradient buffers shaped like the parameters.
    pub fn new_grads(&self) -> MaterialGrads<T> {
        MaterialGrads {
            params: self.params.new_grads(),
            metallic: self.metallic.as_ref().map(NeuralField::new_grads),
        }
    }

    /// Θ at the points `x`, in `ctx.output()`.
    pub fn forward(&self, x: &[[T; 3]], ctx: &mut MaterialContext<T>) {
        self.params.forward(x, &[], &mut ctx.params);
        ctx.separate = self.metallic.is_some();
        if let Some(field) = &self.metallic {
            field.forward(x, &[], &mut ctx.metallic);
            ctx.theta.clear();
            ctx.theta.extend_from_slice(ctx.params.output());
            for (row, m) in ctx
                .theta
                .chunks_exact_mut(PARAM_COUNT)
                .zip(ctx.metallic.output())
            {
                row[METALLIC] = *m;
            }
        }
    }

    /// Backward pass after [`Self::forward`] with upstream gradients
    /// `d_theta` (`n × 9`); accumulates (`+=`) into `grads`.
    pub fn backward(
        &self,
        ctx: &mut MaterialContext<T>,
        d_theta: &[T],
        grads: &mut MaterialGrads<T>,
    ) {
        let Some(field) = &self.metallic else {
            self.params
                .backward(&mut ctx.params, d_theta, &mut grads.params, None, None);
            return;
        };
        ctx.d_params.clear();
        ctx.d_params.extend_from_slice(d_theta);
        ctx.d_metallic.clear();
        for row in ctx.d_params.chunks_exact_mut(PARAM_COUNT) {
            ctx.d_metallic.push(row[METALLIC]);
            row[METALLIC] = T::ZERO;
        }
        self.params.backward(
            &mut ctx.params,
            &ctx.d_params,
            &mut grads.params,
            None,
            None,
        );
        let g = grads
            .metallic
            .as_mut()
            .expect("gradients for the metallic field");
        field.backward(&mut ctx.metallic, &ctx.d_metallic, g, None, None);
    }

    /// The field whose output is metallic: [`Self::metallic`] when set,
    /// else [`Self::params`] (output [`METALLIC`]).
    pub fn metallic_source(&self) -> (&NeuralField<T>, usize) {
        match &self.metallic {
            Some(f) => (f, 0),
            None => (&self.params, METALLIC),
        }
    }

    /// Sets how many hash levels of the fields are active (coarse-to-fine).
    pub fn set_active_levels(&mut self, levels: usize) {
        self.params.active_levels = levels.min(self.params.grid.levels().len());
        if let Some(f) = &mut self.metallic {
            f.active_levels = levels.min(f.grid.levels().len());
        }
    }

    /// Whether every parameter is finite.
    pub fn all_finite(&self) -> bool {
        self.params.all_finite() && self.metallic.as_ref().is_none_or(NeuralField::all_finite)
    }
}
