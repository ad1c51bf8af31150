//! The training benchmark (`wildlight bench train`): the rays a training
//! step gets through per second, and where a step's time goes.
//!
//! Each repetition builds a fresh trainer on the capture, trains a warm-up
//! (the first steps differ: the occupancy grid is still full, the
//! coarse-to-fine schedule has few levels on), then times a fixed number of
//! steps. The report holds the median over the repetitions of the rays per
//! second and of each phase's mean time per step.

use crate::config::TrainConfig;
use crate::rays::TrainingRays;
use crate::trainer::{StepTimes, Trainer};
use std::time::Instant;

/// What to time.
#[derive(Clone, Copy, Debug)]
pub struct TrainBench {
    /// Steps trained before the timing starts.
    pub warmup: u64,
    /// Steps timed.
    pub steps: u64,
    /// Repetitions (each from a fresh trainer).
    pub reps: usize,
}

impl Default for TrainBench {
    /// 100 warm-up steps, 500 timed, 3 repetitions.
    fn default() -> Self {
        TrainBench {
            warmup: 100,
            steps: 500,
            reps: 3,
        }
    }
}

/// One repetition's timing.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TrainBenchRep {
    /// Rays per second over the timed steps (batch rays × steps / wall time).
    pub rays_per_s: f64,
    /// Wall time of the timed steps.
    pub seconds: f64,
    /// Mean time per timed step of each phase (milliseconds).
    pub phase_ms: StepTimes,
    /// Mean object samples per ray over the timed steps.
    pub samples_per_ray: f64,
}

/// The benchmark's result.
#[derive(Clone, Debug, serde::Serialize)]
pub struct TrainBenchReport {
    /// Rayon threads.
    pub threads: usize,
    /// Rays per step.
    pub batch_rays: usize,
    /// Warm-up steps.
    pub warmup: u64,
    /// Timed steps.
    pub steps: u64,
    /// Whether the rays ignore masks (the background is modelled).
    pub maskless: bool,
    /// Median over the repetitions of the rays per second.
    pub rays_per_s: f64,
    /// Median over the repetitions of each phase's mean time per step (ms).
    pub phase_ms: StepTimes,
    /// Median of the mean samples per ray.
    pub samples_per_ray: f64,
    /// Every repetition, in order.
    pub reps: Vec<TrainBenchRep>,
}

/// Runs the benchmark: `bench.reps` fresh trainers of `config`, each on
/// the rays `rays()` gives (the same every time).
pub fn bench_train(
    config: &TrainConfig,
    rays: impl Fn() -> TrainingRays,
    bench: &TrainBench,
) -> anyhow::Result<TrainBenchReport> {
    anyhow::ensure!(
        bench.steps > 0 && bench.reps > 0,
        "the training benchmark needs at least one timed step and one repetition"
    );
    let mut config = config.clone();
    // The schedules see a run of exactly these steps.
    config.iters = bench.warmup + bench.steps;
    config.output.preview_every = 0;
    let mut reps = Vec::with_capacity(bench.reps);
    let mut maskless = false;
    for _ in 0..bench.reps {
        let rays = rays();
        maskless = !rays.has_masks;
        let mut trainer = Trainer::new(config.clone(), rays)?;
        for _ in 0..bench.warmup {
            trainer.step();
        }
        let mut sum = StepTimes::default();
        let mut samples = 0usize;
        let start = Instant::now();
        for _ in 0..bench.steps {
            let st = trainer.step();
            add_times(&mut sum, &st.phase_ms);
            samples += st.samples;
        }
        let seconds = start.elapsed().as_secs_f64();
        let n = bench.steps as f64;
        reps.push(TrainBenchRep {
            rays_per_s: (config.batch_rays as f64 * n) / seconds,
            seconds,
            phase_ms: scale_times(&sum, 1.0 / n),
            samples_per_ray: samples as f64 / (n * config.batch_rays as f64),
        });
    }
    let median_of = |f: &dyn Fn(&TrainBenchRep) -> f64| median(reps.iter().map(f).collect());
    let phase_ms = StepTimes {
        setup: median_of(&|r| r.phase_ms.setup),
        forward: median_of(&|r| r.phase_ms.forward),
        backward: median_of(&|r| r.phase_ms.backward),
        priors: median_of(&|r| r.phase_ms.priors),
        hull: median_of(&|r| r.phase_ms.hull),
        update: median_of(&|r| r.phase_ms.update),
        background: median_of(&|r| r.phase_ms.background),
    };
    Ok(TrainBenchReport {
        threads: rayon::current_num_threads(),
        batch_rays: config.batch_rays,
        warmup: bench.warmup,
        steps: bench.steps,
        maskless,
        rays_per_s: median_of(&|r| r.rays_per_s),
        phase_ms,
        samples_per_ray: median_of(&|r| r.samples_per_ray),
        reps,
    })
}

fn add_times(sum: &mut StepTimes, t: &StepTimes) {
    sum.setup += t.setup;
    sum.forward += t.forward;
    sum.backward += t.backward;
    sum.priors += t.priors;
    sum.hull += t.hull;
    sum.update += t.update;
    sum.background += t.background;
}

fn scale_times(t: &StepTimes, k: f64) -> StepTimes {
    StepTimes {
        setup: t.setup * k,
        forward: t.forward * k,
        backward: t.backward * k,
        priors: t.priors * k,
        hull: t.hull * k,
        update: t.update * k,
        background: t.background * k,
    }
}

/// The median (the mean of the middle two for an even count).
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn medians() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(median(vec![]).is_nan());
    }
}
