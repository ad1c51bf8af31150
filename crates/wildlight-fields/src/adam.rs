//! Adam (Kingma & Ba 2015) with parameter groups, each with its own learning
//! rate, epsilon and betas, and its own first/second-moment state.
//!
//! Update of group `g` at its step `t` (1-based):
//! `m ← β1 m + (1−β1) g`, `v ← β2 v + (1−β2) g²`,
//! `p ← p − lr · (m / (1−β1^t)) / (sqrt(v / (1−β2^t)) + ε)`.
//! Element-wise and parallel over fixed chunks, hence deterministic.
//!
//! Moments smaller than [`MOMENT_FLOOR`] are stored as 0. A hash-table
//! entry that no training ray reaches any more keeps decaying its moments
//! (m by β1, v by β2 each step) until they pass through the subnormal
//! range, where every operation on them takes a microcode assist: late in
//! a run most entries are there, and on the 2-vCPU Xeon the Adam step
//! over the default model's 16.5 million entries grew from about 14 to
//! 45–55 ms (`examples/adam_timing`: 23 ms a step with normal moments, 1.5 s
//! with subnormal ones, one thread). Below the floor a moment moves its
//! parameter by less than `lr · 1e-30 / ε`, far below f32's resolution.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use wildlight_real::Real;

/// Hyper-parameters of one group.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdamConfig {
    /// Base learning rate (multiplied by the schedule factor at each step).
    pub lr: f64,
    /// First-moment decay.
    pub beta1: f64,
    /// Second-moment decay.
    pub beta2: f64,
    /// Denominator epsilon (Instant-NGP uses 1e-15 for hash tables).
    pub eps: f64,
}

impl Default for AdamConfig {
    /// lr 1e-3, betas (0.9, 0.99), eps 1e-15.
    fn default() -> Self {
        AdamConfig {
            lr: 1e-3,
            beta1: 0.9,
            beta2: 0.99,
            eps: 1e-15,
        }
    }
}

/// One parameter group's settings and state.
#[derive(Clone, Debug)]
pub struct AdamGroup<T> {
    /// Name (used in checkpoints).
    pub name: String,
    /// Hyper-parameters.
    pub config: AdamConfig,
    /// First moments.
    pub m: Vec<T>,
    /// Second moments.
    pub v: Vec<T>,
    /// Steps taken by this group.
    pub step: u64,
}

/// Adam over several parameter groups.
#[derive(Clone, Debug, Default)]
pub struct Adam<T> {
    /// The groups, in the order they were added.
    pub groups: Vec<AdamGroup<T>>,
}

const ADAM_CHUNK: usize = 1 << 14;

/// Moments of smaller magnitude are stored as 0 (see the module's notes),
/// well above f32's smallest normal value, 1.2e-38, and far below any
/// moment that moves a parameter.
pub const MOMENT_FLOOR: f64 = 1e-30;

/// `x`, or 0 when `|x| < floor`.
#[inline(always)]
fn flush<T: Real>(x: T, floor: T) -> T {
    if x.abs() < floor { T::ZERO } else { x }
}

impl<T: Real> Adam<T> {
    /// An optimiser with no groups.
    pub fn new() -> Self {
        Adam { groups: Vec::new() }
    }

    /// Adds a group of `len` parameters; returns its index.
    pub fn add_group(&mut self, name: &str, len: usize, config: AdamConfig) -> usize {
        self.groups.push(AdamGroup {
            name: name.to_string(),
            config,
            m: vec![T::ZERO; len],
            v: vec![T::ZERO; len],
            step: 0,
        });
        self.groups.len() - 1
    }

    /// One Adam step of group `group` with learning rate `config.lr · lr_factor`.
    pub fn step(&mut self, group: usize, params: &mut [T], grads: &[T], lr_factor: f64) {
        let g = &mut self.groups[group];
        assert_eq!(params.len(), g.m.len(), "adam: group '{}' size", g.name);
        assert_eq!(
            grads.len(),
            g.m.len(),
            "adam: group '{}' gradient size",
            g.name
        );
        g.step += 1;
        let c = g.config;
        let t = g.step as i32;
        let bc1 = 1.0 - c.beta1.powi(t);
        let bc2 = 1.0 - c.beta2.powi(t);
        let lr = T::from_f64(c.lr * lr_factor / bc1);
        let inv_sqrt_bc2 = T::from_f64(1.0 / bc2.sqrt());
        let b1 = T::from_f64(c.beta1);
        let b2 = T::from_f64(c.beta2);
        let ob1 = T::from_f64(1.0 - c.beta1);
        let ob2 = T::from_f64(1.0 - c.beta2);
        let eps = T::from_f64(c.eps);
        let floor = T::from_f64(MOMENT_FLOOR);
        params
            .par_chunks_mut(ADAM_CHUNK)
            .zip(grads.par_chunks(ADAM_CHUNK))
            .zip(g.m.par_chunks_mut(ADAM_CHUNK))
            .zip(g.v.par_chunks_mut(ADAM_CHUNK))
            .for_each(|(((p, gr), m), v)| {
                for i in 0..p.len() {
                    let gi = gr[i];
                    let mi = flush(b1 * m[i] + ob1 * gi, floor);
                    let vi = flush(b2 * v[i] + ob2 * gi * gi, floor);
                    m[i] = mi;
                    v[i] = vi;
                    // p -= lr/bc1 · m / (sqrt(v)/sqrt(bc2) + eps)
                    p[i] -= lr * mi / (vi.sqrt() * inv_sqrt_bc2 + eps);
                }
            });
    }
}

/// How the learning rate decays after the warm-up.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Decay {
    /// Factor 1.
    Constant,
    /// Cosine from 1 down to `final_factor` at `total_steps`.
    Cosine {
        /// Step at which the factor reaches `final_factor`.
        total_steps: u64,
        /// Factor at the end.
        final_factor: f64,
    },
    /// Geometric from 1 down to `final_factor` at `total_steps` (continues after).
    Exponential {
        /// Step at which the factor reaches `final_factor`.
        total_steps: u64,
        /// Factor at `total_steps`.
        final_factor: f64,
    },
}

/// Learning-rate schedule: linear warm-up then a decay; gives a factor for the base lr.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LrSchedule {
    /// Steps of linear warm-up (0: none).
    pub warmup_steps: u64,
    /// Factor at step 0 of the warm-up.
    pub warmup_start_factor: f64,
    /// Decay after the warm-up (its steps count from the end of the warm-up).
    pub decay: Decay,
}

impl LrSchedule {
    /// A constant factor of 1.
    pub fn constant() -> Self {
        LrSchedule {
            warmup_steps: 0,
            warmup_start_factor: 1.0,
            decay: Decay::Constant,
        }
    }

    /// The factor at (0-based) step `step`.
    pub fn factor(&self, step: u64) -> f64 {
        if step < self.warmup_steps {
            let a = step as f64 / self.warmup_steps as f64;
            return self.warmup_start_factor + (1.0 - self.warmup_start_factor) * a;
        }
        let s = (step - self.warmup_steps) as f64;
        match self.decay {
            Decay::Constant => 1.0,
            Decay::Cosine {
                total_steps,
                final_factor,
            } => {
                let span = total_steps.saturating_sub(self.warmup_steps).max(1) as f64;
                let a = (s / span).min(1.0);
                final_factor + (1.0 - final_factor) * 0.5 * (1.0 + (std::f64::consts::PI * a).cos())
            }
            Decay::Exponential {
                total_steps,
                final_factor,
            } => {
                let span = total_steps.saturating_sub(self.warmup_steps).max(1) as f64;
                final_factor.powf(s / span)
            }
        }
    }
}
