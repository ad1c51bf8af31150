//! Profiling helper: CPU time of the parts of the SDF MLP on 2^18 rows
//! (first layer, hidden activation, last layer; backward), one thread.

use wildlight_fields::dense::{linear_backward_params, linear_forward};
use wildlight_fields::{Activation, CHUNK_ROWS};

fn main() {
    let (n_in, h, n_out) = (35, 64, 16);
    let chunks = (1 << 18) / CHUNK_ROWS;
    let ld = CHUNK_ROWS;
    let input: Vec<f32> = (0..n_in * ld)
        .map(|i| ((i * 7919) % 1000) as f32 * 1e-3)
        .collect();
    let w0: Vec<f32> = (0..h * n_in)
        .map(|i| ((i * 31) % 17) as f32 * 0.01 - 0.08)
        .collect();
    let w1: Vec<f32> = (0..n_out * h)
        .map(|i| ((i * 13) % 11) as f32 * 0.01 - 0.05)
        .collect();
    let b0 = vec![0.01f32; h];
    let b1 = vec![0.02f32; n_out];
    let mut a0 = vec![0.0f32; h * ld];
    let mut a1 = vec![0.0f32; n_out * ld];
    let act = Activation::Softplus { beta: 100.0 };
    let mut gw0 = vec![0.0f32; h * n_in];
    let mut gb0 = vec![0.0f32; h];
    let mut d_in = vec![0.0f32; n_in * ld];
    let cpu = || {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime writes into the valid timespec.
        unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
        ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
    };
    let t = |name: &str, f: &mut dyn FnMut()| {
        let s = cpu();
        for _ in 0..chunks {
            f();
        }
        println!("{name}: {:.1} ms cpu", (cpu() - s) * 1e3);
    };
    for _ in 0..2 {
        t("layer0", &mut || {
            linear_forward(n_in, h, ld, ld, &w0, (n_in, 1), &b0, &input, &mut a0)
        });
        let mut rm = vec![0.0f32; ld * h];
        t("layer0 (matrixmultiply)", &mut || {
            wildlight_fields::real::gemm_strided(
                ld,
                n_in,
                h,
                1.0,
                &input,
                (1, ld),
                &w0,
                (1, n_in),
                0.0,
                &mut rm,
                (h, 1),
            )
        });
        t("softplus", &mut || act.forward_in_place(&mut a0));
        t("layer1", &mut || {
            linear_forward(h, n_out, ld, ld, &w1, (h, 1), &b1, &a0, &mut a1)
        });
        t("layer0 dW", &mut || {
            linear_backward_params(n_in, h, ld, ld, &a0, &input, &mut gw0, &mut gb0)
        });
        t("layer0 dW (matrixmultiply)", &mut || {
            wildlight_fields::real::gemm_strided(
                h,
                ld,
                n_in,
                1.0,
                &rm,
                (1, h),
                &input,
                (1, ld),
                1.0,
                &mut gw0,
                (n_in, 1),
            )
        });
        t("layer0 d_in", &mut || {
            linear_forward(h, n_in, ld, ld, &w0, (1, n_in), &[], &a0, &mut d_in)
        });
        t("softplus bwd", &mut || {
            act.backward_in_place(&a1[..ld * 16], &mut a0[..ld * 16])
        });
    }
    println!("{}", a1[5] + gw0[3] + d_in[7]);
}
