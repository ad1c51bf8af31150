//! Throughput benchmark of the SDF field (used by `wildlight bench fields`).
//!
//! Points are realistic ray samples: rays from cameras on a sphere of radius
//! 2.5 aimed near the origin, each with 64 samples along its chord of the unit
//! sphere — 16 stratified over the chord and 48 clustered (Gaussian, σ = 0.02)
//! around the ray's hit of a sphere of radius 0.5 — in ray order.

use crate::hash_grid::BlockLayout;
use crate::hash_grid::HashGridConfig;
use crate::mlp::{CHUNK_ROWS, Mlp, MlpChunk, MlpScratch};
use crate::neural_field::FieldContext;
use crate::sdf_field::{FdScheme, NormalContext, NormalMethod, SdfField, SdfFieldConfig};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;

/// What to measure.
#[derive(Clone, Debug, Serialize)]
pub struct BenchConfig {
    /// The field measured.
    pub field: SdfFieldConfig,
    /// Points per batch.
    pub batch: usize,
    /// Timed repetitions (the median is reported).
    pub reps: usize,
    /// Seed of the points and the field.
    pub seed: u64,
}

impl Default for BenchConfig {
    /// The configuration of issue 5: 16 levels × 2 features, 2^19 entries, one 64-wide hidden layer; 2^18 points.
    fn default() -> Self {
        BenchConfig {
            field: SdfFieldConfig {
                grid: HashGridConfig::default(),
                ..SdfFieldConfig::default()
            },
            batch: 1 << 18,
            reps: 7,
            seed: 1,
        }
    }
}

/// Measured medians.
#[derive(Clone, Debug, Serialize)]
pub struct BenchReport {
    /// The configuration.
    pub config: BenchConfig,
    /// rayon threads.
    pub threads: usize,
    /// Forward (SDF + features) points per second.
    pub fwd_points_per_s: f64,
    /// Forward + backward (incl. zeroing the gradients) points per second.
    pub fwd_bwd_points_per_s: f64,
    /// Forward + backward with tetrahedral FD normals (5 evaluations per point), main points per second.
    pub fwd_bwd_normals_points_per_s: f64,
    /// Forward + backward with the analytic gradient
    /// ([`SdfField::forward_with_gradient_batched`]), points per second.
    pub fwd_bwd_analytic_points_per_s: f64,
    /// Forward points per second of process CPU time (all threads together):
    /// a figure less sensitive to other processes on a shared machine.
    pub fwd_points_per_cpu_s: f64,
    /// Forward + backward points per second of process CPU time.
    pub fwd_bwd_points_per_cpu_s: f64,
    /// Component timings below are medians of wall time per batch.
    /// Encoding forward alone, seconds per batch.
    pub encoding_fwd_s: f64,
    /// MLP forward alone, seconds per batch.
    pub mlp_fwd_s: f64,
    /// Encoding backward (table gradients) alone, seconds per batch.
    pub encoding_bwd_s: f64,
    /// Encoding backward with the alternative per-thread-buffer scheme
    /// (one table-sized buffer per thread, zeroed and reduced every call).
    pub encoding_bwd_per_thread_buffers_s: f64,
    /// MLP backward alone, seconds per batch.
    pub mlp_bwd_s: f64,
    /// Process CPU seconds per batch (all threads) of the encoding forward,
    /// MLP forward, encoding backward and MLP backward: less sensitive to
    /// other processes than the wall times above.
    pub component_cpu_s: [f64; 4],
    /// Share of encoding time in (encoding + MLP), forward + backward.
    pub encoding_share: f64,
    /// Share of MLP time in (encoding + MLP), forward + backward.
    pub mlp_share: f64,
}

/// Realistic ray samples (see module docs), `n` points.
pub fn ray_samples(n: usize, seed: u64) -> Vec<[f32; 3]> {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(seed);
    let per_ray = 64;
    let mut pts = Vec::with_capacity(n);
    while pts.len() < n {
        // camera on a sphere of radius 2.5, looking at a point near the origin
        let z: f64 = rng.random_range(-1.0..1.0);
        let phi: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let r = (1.0 - z * z).sqrt();
        let o = [2.5 * r * phi.cos(), 2.5 * r * phi.sin(), 2.5 * z];
        let target = [
            rng.random_range(-0.4..0.4),
            rng.random_range(-0.4..0.4),
            rng.random_range(-0.4..0.4),
        ];
        let mut d = [target[0] - o[0], target[1] - o[1], target[2] - o[2]];
        let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        d.iter_mut().for_each(|v| *v /= len);
        let chord = |radius: f64| {
            let b = o[0] * d[0] + o[1] * d[1] + o[2] * d[2];
            let c = o[0] * o[0] + o[1] * o[1] + o[2] * o[2] - radius * radius;
            let disc = b * b - c;
            (disc >= 0.0).then(|| (-b - disc.sqrt(), -b + disc.sqrt()))
        };
        let Some((near, far)) = chord(1.0) else {
            continue;
        };
        let hit = chord(0.5).map(|(t, _)| t).unwrap_or(0.5 * (near + far));
        let mut ts: Vec<f64> = (0..16)
            .map(|i| near + (far - near) * (i as f64 + rng.random::<f64>()) / 16.0)
            .collect();
        for _ in 16..per_ray {
            let g = crate::mlp::normal(&mut rng);
            ts.push((hit + 0.02 * g).clamp(near, far));
        }
        ts.sort_by(f64::total_cmp);
        for t in ts {
            if pts.len() < n {
                pts.push([
                    (o[0] + t * d[0]) as f32,
                    (o[1] + t * d[1]) as f32,
                    (o[2] + t * d[2]) as f32,
                ]);
            }
        }
    }
    pts
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// CPU time consumed by the whole process (all threads), in seconds.
fn process_cpu_time() -> f64 {
    #[cfg(target_os = "linux")]
    {
        let mut ts = libc::timespec {
            tv_sec: 0,
            tv_nsec: 0,
        };
        // SAFETY: clock_gettime writes into the valid timespec.
        if unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) } == 0 {
            return ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9;
        }
    }
    0.0
}

/// Median wall time and median process CPU time of `reps` runs (after one warm-up run).
fn time<F: FnMut()>(reps: usize, mut f: F) -> (f64, f64) {
    f(); // warm-up
    let (wall, cpu): (Vec<f64>, Vec<f64>) = (0..reps.max(1))
        .map(|_| {
            let c = process_cpu_time();
            let t = Instant::now();
            f();
            (t.elapsed().as_secs_f64(), process_cpu_time() - c)
        })
        .unzip();
    (median(wall), median(cpu))
}

/// Runs the benchmark on the current rayon pool.
pub fn run(config: &BenchConfig) -> Result<BenchReport, crate::FieldError> {
    let field = SdfField::<f32>::new(&config.field, config.seed)?;
    let n = config.batch;
    let x = ray_samples(n, config.seed);
    let n_out = field.n_output();
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(config.seed + 7);
    let d_out: Vec<f32> = (0..n * n_out)
        .map(|_| rng.random_range(-1.0..1.0))
        .collect();
    let mut ctx = FieldContext::new();
    let mut grads = field.new_grads();

    let t_fwd = time(config.reps, || field.forward(&x, &mut ctx));
    let t_fwd_bwd = time(config.reps, || {
        grads.zero();
        field.forward(&x, &mut ctx);
        field.backward(&mut ctx, &d_out, &mut grads, None);
    });

    let nn = n / 5;
    let xn = &x[..nn];
    let mut nctx = NormalContext::new();
    let d_sdf: Vec<f32> = d_out[..nn].to_vec();
    let d_feat: Vec<f32> = d_out[..nn * config.field.n_features].to_vec();
    let d_grad: Vec<[f32; 3]> = (0..nn)
        .map(|i| [d_out[i], d_out[i + 1], d_out[i + 2]])
        .collect();
    let mut with_normals = |method: NormalMethod| {
        time(config.reps, || {
            grads.zero();
            field.forward_with_normals(xn, method, &mut nctx);
            field.backward_with_normals(&mut nctx, &d_sdf, &d_feat, &d_grad, &mut grads);
        })
    };
    let t_normals = with_normals(NormalMethod::FiniteDifference {
        scheme: FdScheme::Tetrahedral,
        step: 1e-3,
    });
    let t_analytic = with_normals(NormalMethod::Analytic);

    // Component timings, on the buffers the field uses: column-major chunk
    // inputs, the encoding level-major over the whole batch.
    let grid = &field.field.grid;
    let n_enc = grid.n_outputs();
    let unit: Vec<[f32; 3]> = x.iter().map(|p| p.map(|v| (v + 1.0) * 0.5)).collect();
    let mlp: &Mlp<f32> = &field.field.mlp;
    let n_in = mlp.config().n_input;
    let enc_col = field.field.encoding_column();
    let mut chunks: Vec<MlpChunk<f32>> = (0..n.div_ceil(CHUNK_ROWS))
        .map(|c| {
            let mut ch = MlpChunk::default();
            mlp.prepare_chunk(&mut ch, CHUNK_ROWS.min(n - c * CHUNK_ROWS));
            ch
        })
        .collect();
    let layout = BlockLayout::column_major(CHUNK_ROWS);
    let levels = grid.config().n_levels;
    let (t_enc_fwd, t_enc_fwd_cpu) = time(config.reps, || {
        let mut outs: Vec<&mut [f32]> = chunks.iter_mut().map(|c| c.input.as_mut_slice()).collect();
        grid.encode_blocks(&unit, &mut outs, layout, enc_col, levels);
    });
    let d_enc: Vec<Vec<f32>> = chunks
        .iter()
        .enumerate()
        .map(|(c, ch)| {
            (0..ch.input.len())
                .map(|i| d_out[(c * CHUNK_ROWS * n_in + i) % d_out.len()])
                .collect()
        })
        .collect();
    let blocks: Vec<&[f32]> = d_enc.iter().map(|v| v.as_slice()).collect();
    let mut g_grid = crate::memory::huge_vec::<f32>(grid.n_params());
    let (t_enc_bwd, t_enc_bwd_cpu) = time(config.reps, || {
        g_grid.fill(0.0);
        grid.backward_params_blocks(&unit, &blocks, layout, enc_col, levels, &mut g_grid);
    });
    let d_rows: Vec<f32> = (0..n * n_enc).map(|i| d_out[i % d_out.len()]).collect();
    let row_blocks: Vec<&[f32]> = d_rows.chunks(CHUNK_ROWS * n_enc).collect();
    let mut scratch = Vec::new();
    let threads = rayon::current_num_threads();
    let (t_enc_bwd_bufs, _) = time(config.reps, || {
        g_grid.fill(0.0);
        grid.backward_params_per_part_buffers(
            &unit,
            &row_blocks,
            CHUNK_ROWS,
            n_enc,
            0,
            levels,
            threads,
            &mut scratch,
            &mut g_grid,
        );
    });
    drop(scratch);
    let (t_mlp_fwd, t_mlp_fwd_cpu) = time(config.reps, || {
        chunks.par_iter_mut().for_each(|ch| mlp.forward_chunk(ch));
    });
    let mut g_mlp = vec![0.0f32; mlp.n_params()];
    let n_out = mlp.config().n_output;
    let (t_mlp_bwd, t_mlp_bwd_cpu) = time(config.reps, || {
        chunks
            .par_iter_mut()
            .zip(d_out.par_chunks(CHUNK_ROWS * n_out))
            .for_each_init(MlpScratch::default, |sc, (ch, d)| {
                mlp.backward_chunk(ch, d, sc)
            });
        Mlp::reduce_chunk_grads(&chunks, &mut g_mlp);
    });

    let enc_t = t_enc_fwd + t_enc_bwd;
    let mlp_t = t_mlp_fwd + t_mlp_bwd;
    Ok(BenchReport {
        config: config.clone(),
        threads: rayon::current_num_threads(),
        fwd_points_per_s: n as f64 / t_fwd.0,
        fwd_bwd_points_per_s: n as f64 / t_fwd_bwd.0,
        fwd_bwd_normals_points_per_s: nn as f64 / t_normals.0,
        fwd_bwd_analytic_points_per_s: nn as f64 / t_analytic.0,
        fwd_points_per_cpu_s: n as f64 / t_fwd.1,
        fwd_bwd_points_per_cpu_s: n as f64 / t_fwd_bwd.1,
        encoding_fwd_s: t_enc_fwd,
        mlp_fwd_s: t_mlp_fwd,
        encoding_bwd_s: t_enc_bwd,
        encoding_bwd_per_thread_buffers_s: t_enc_bwd_bufs,
        mlp_bwd_s: t_mlp_bwd,
        component_cpu_s: [t_enc_fwd_cpu, t_mlp_fwd_cpu, t_enc_bwd_cpu, t_mlp_bwd_cpu],
        encoding_share: enc_t / (enc_t + mlp_t),
        mlp_share: mlp_t / (enc_t + mlp_t),
    })
}
