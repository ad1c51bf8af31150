//! Profiling helper: wall time per value of the hidden activations' slice
//! kernels (`Activation::forward_in_place`) on 2^14 values, one thread.
//!
//! `RAYON_NUM_THREADS=1 cargo run --release -p wildlight-fields --example activation_timing`

use wildlight_fields::Activation;

fn main() {
    let n = 1 << 14;
    let reps = 1000;
    let cases = [
        (Activation::Softplus { beta: 100.0 }, 0.05f32),
        (Activation::Softplus { beta: 100.0 }, 0.3),
        (Activation::Relu, 1.0),
        (Activation::Sigmoid, 1.0),
    ];
    for (act, scale) in cases {
        // Inputs spread evenly over [−scale, scale].
        let base: Vec<f32> = (0..n)
            .map(|i| (((i * 7919) % 2001) as f32 / 1000.0 - 1.0) * scale)
            .collect();
        let mut buf = base.clone();
        let start = std::time::Instant::now();
        for _ in 0..reps {
            buf.copy_from_slice(&base);
            act.forward_in_place(&mut buf);
        }
        let ns = start.elapsed().as_secs_f64() / (reps * n) as f64 * 1e9;
        println!(
            "{act:?}, inputs in ±{scale}: {ns:.2} ns per value (checksum {})",
            buf.iter().sum::<f32>()
        );
    }
}
