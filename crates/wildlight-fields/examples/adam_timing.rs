//! Profiling helper: wall time of one Adam step, one finiteness check and
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
    let (b1, b2, ob1, ob2, lr, k, eps) =
        (0.9f32, 0.99f32, 0.1f32, 0.01f32, 1e-3f32, 1.0f32, 1e-15f32);
    let mut m = vec![0f32; n];
    let mut v = vec![0f32; n];
    use rayon::prelude::*;
    let zipped = median_ms(reps, || {
        params
            .par_chunks_mut(1 << 14)
            .zip(grads.par_chunks(1 << 14))
            .zip(m.par_chunks_mut(1 << 14))
            .zip(v.par_chunks_mut(1 << 14))
            .for_each(|(((p, gr), m), v)| {
                for (((p, &gi), m), v) in p.iter_mut().zip(gr).zip(m.iter_mut()).zip(v.iter_mut()) {
                    let mi = b1 * *m + ob1 * gi;
                    let vi = b2 * *v + ob2 * gi * gi;
                    *m = mi;
                    *v = vi;
                    *p -= lr * mi / (vi.sqrt() * k + eps);
                }
            })
    });
    println!("zipped adam {zipped:.2} ms");
    let check = median_ms(reps, || assert!(all_finite(&grads)));
    let zero = median_ms(reps, || grads.fill(0.0));
    println!(
        "{n} values, {} threads: adam step {step:.2} ms, finiteness check {check:.2} ms, zeroing {zero:.2} ms (checksum {})",
        rayon::current_num_threads(),
        params.iter().map(|&p| p as f64).sum::<f64>()
    );
}
