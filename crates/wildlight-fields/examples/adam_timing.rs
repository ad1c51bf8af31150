//! Profiling helper: wall time of one Adam step (with ordinary moments, and
//! after they decayed into the subnormal range), one finiteness check and
//! one zeroing over a hash-table-sized group (16.5 million f32 values, as
//! the default model's tables), median of several repetitions.
//!
//! `cargo run --release -p wildlight-fields --example adam_timing`
//! (`RAYON_NUM_THREADS=1` for one thread).

use std::time::Instant;
use wildlight_fields::{Adam, AdamConfig, all_finite};

fn median_ms<F: FnMut()>(reps: usize, mut f: F) -> f64 {
    let mut times: Vec<f64> = (0..reps)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    times.sort_by(f64::total_cmp);
    times[reps / 2]
}

fn main() {
    let n = 16_500_000;
    let reps = 15;
    let mut params: Vec<f32> = (0..n).map(|i| ((i % 1000) as f32 - 500.0) * 1e-4).collect();
    // A tenth of the entries carry a gradient, as in a training step.
    let mut grads: Vec<f32> = (0..n)
        .map(|i| {
            if i % 10 == 0 {
                ((i % 77) as f32 - 38.0) * 1e-5
            } else {
                0.0
            }
        })
        .collect();
    let mut adam = Adam::new();
    let group = adam.add_group("grid", n, AdamConfig::default());
    let step = median_ms(reps, || adam.step(group, &mut params, &grads, 1.0));
    // The moments of entries that have had no gradient for many steps
    // decay into the subnormal range (m by 0.9 a step, v by 0.99).
    let g = &mut adam.groups[group];
    for (m, v) in g.m.iter_mut().zip(g.v.iter_mut()) {
        *m = 1e-39;
        *v = 1e-39;
    }
    // The first step flushes them to 0 (`adam::MOMENT_FLOOR`); the median
    // is that of the steps after it.
    let subnormal = median_ms(reps, || adam.step(group, &mut params, &grads, 1.0));
    println!("adam step after the moments decayed into the subnormal range: {subnormal:.2} ms");
    let check = median_ms(reps, || assert!(all_finite(&grads)));
    let zero = median_ms(reps, || grads.fill(0.0));
    println!(
        "{n} values, {} threads: adam step {step:.2} ms, finiteness check {check:.2} ms, zeroing {zero:.2} ms (checksum {})",
        rayon::current_num_threads(),
        params.iter().map(|&p| p as f64).sum::<f64>()
    );
}
