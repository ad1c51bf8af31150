//! Throughput of sampling and compositing (`cargo bench -p wildlight-render`).
//!
//! An analytic torus SDF stands in for the field (its cost is excluded from
//! the kernel timings and reported on its own), so the numbers measure the
//! renderer alone. Thread count: `RAYON_NUM_THREADS`. Each figure is the
//! median of `BENCH_REPS` (default 15) runs on batches of `BENCH_RAYS`
//! (default 4096) rays.
#![allow(clippy::needless_range_loop)] // index-heavy test arithmetic over parallel arrays

use std::time::Instant;

use wildlight_material::BrdfSettings;
use wildlight_render::composite::{composite, composite_backward};
use wildlight_render::flash::{FlashCache, FlashInputs, flash_backward, flash_forward};
use wildlight_render::neus::{NeusInputs, NeusSettings, NeusWeights};
use wildlight_render::occupancy::{OccupancyGrid, OccupancySettings, RefreshMode};
use wildlight_render::sampler::{CoarseSamples, RaySamples, Rays, Sampler, SamplerSettings};

/// Torus SDF and gradient (major 0.5, minor 0.2, axis y).
fn torus(p: [f32; 3]) -> (f32, [f32; 3]) {
    let [x, y, z] = p;
    let rho = (x * x + z * z).sqrt().max(1e-12);
    let qx = rho - 0.5;
    let ql = (qx * qx + y * y).sqrt().max(1e-12);
    (ql - 0.2, [qx / ql * x / rho, y / ql, qx / ql * z / rho])
}

fn torus_batch(p: &[[f32; 3]], out: &mut [f32]) {
    for (o, &x) in out.iter_mut().zip(p) {
        *o = torus(x).0;
    }
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn time<F: FnMut()>(reps: usize, mut f: F) -> f64 {
    f(); // warm-up
    median(
        (0..reps)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .collect(),
    )
}

/// CPU time consumed by the whole process (all threads), in seconds.
fn process_cpu_time() -> f64 {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: clock_gettime writes into the valid timespec it is given.
    if unsafe { libc::clock_gettime(libc::CLOCK_PROCESS_CPUTIME_ID, &mut ts) } == 0 {
        ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
    } else {
        f64::NAN
    }
}

/// Median process CPU time (all threads) of `reps` runs after a warm-up:
/// unlike wall time, it does not count time the process waited while
/// preempted on a busy machine.
fn cpu_time<F: FnMut()>(reps: usize, mut f: F) -> f64 {
    f(); // warm-up
    median(
        (0..reps)
            .map(|_| {
                let c = process_cpu_time();
                f();
                process_cpu_time() - c
            })
            .collect(),
    )
}

fn main() {
    let env = |k: &str, d: usize| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    let reps = env("BENCH_REPS", 15);
    let n_rays = env("BENCH_RAYS", 4096);
    let threads = rayon::current_num_threads();
    // Random rays from cameras on a sphere of radius 2.5, aimed into the torus' bounding box.
    let mut state = 0x1234_5678_9abc_def0u64;
    let mut rnd = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    let mut origins = Vec::with_capacity(n_rays);
    let mut dirs = Vec::with_capacity(n_rays);
    for _ in 0..n_rays {
        let az = rnd() * std::f32::consts::TAU;
        let el = (rnd() - 0.5) * 1.2;
        let o = [
            2.5 * el.cos() * az.cos(),
            2.5 * el.sin(),
            2.5 * el.cos() * az.sin(),
        ];
        let aim = [
            (rnd() - 0.5) * 1.4,
            (rnd() - 0.5) * 0.4,
            (rnd() - 0.5) * 1.4,
        ];
        let d = [aim[0] - o[0], aim[1] - o[1], aim[2] - o[2]];
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        origins.push(o);
        dirs.push(d.map(|x| x / l));
    }
    let rays = Rays {
        origins: &origins,
        dirs: &dirs,
    };
    let s = 800.0f32;
    let v = s.ln() / 10.0;

    println!("render_throughput: {threads} thread(s), {n_rays} rays per batch, median of {reps}");
    for res in [64usize, 128] {
        let mut grid = OccupancyGrid::new(OccupancySettings {
            resolution: res,
            ..Default::default()
        })
        .unwrap();
        let t_full = time(reps.min(5), || {
            grid.refresh(torus_batch, s, RefreshMode::Full);
        });
        let t_part = time(reps.min(5), || {
            grid.refresh(torus_batch, s, RefreshMode::Partial { stride: 16 });
        });
        let n_full = grid.refresh(torus_batch, s, RefreshMode::Full);
        let n_part = grid.refresh(torus_batch, s, RefreshMode::Partial { stride: 16 });
        let t_sdf = time(reps.min(5), || {
            let pts: Vec<[f32; 3]> = (0..n_full).map(|i| grid.cell_center(i)).collect();
            let mut out = vec![0.0; n_full];
            torus_batch(&pts, &mut out);
        });
        println!(
            "grid {res}³: full refresh {:.1} ms ({n_full} cells, analytic SDF ≈ {:.1} ms of it), \
             partial (stride 16) {:.1} ms ({n_part} cells), occupied {:.1}%",
            t_full * 1e3,
            t_sdf * 1e3,
            t_part * 1e3,
            grid.occupied_fraction() * 100.0
        );
    }

    let mut grid = OccupancyGrid::new(OccupancySettings::default()).unwrap();
    grid.refresh(torus_batch, s, RefreshMode::Full);
    let mut sampler = Sampler::new(SamplerSettings::default()).unwrap();
    let mut coarse = CoarseSamples::default();
    let mut samples = RaySamples::default();
    let t_coarse = time(reps, || sampler.coarse(&grid, &rays, &mut coarse));
    let mut coarse_sdf = vec![0.0; coarse.t.len()];
    let t_coarse_sdf = time(reps, || torus_batch(&coarse.positions, &mut coarse_sdf));
    let t_refine = time(reps, || {
        sampler.refine(&rays, &coarse, &coarse_sdf, s, Some(1), &mut samples)
    });
    let n = samples.len();
    let hit_rays = (0..n_rays)
        .filter(|&r| samples.offsets[r + 1] > samples.offsets[r])
        .count();
    println!(
        "sampler (grid 128³, s = {s}): coarse {:.2} ms ({} boundaries), refine {:.2} ms → {n} samples \
         ({:.1} per ray with samples, {hit_rays} of {n_rays} rays); analytic SDF at coarse points {:.2} ms",
        t_coarse * 1e3,
        coarse.t.len(),
        t_refine * 1e3,
        n as f64 / hit_rays.max(1) as f64,
        t_coarse_sdf * 1e3
    );

    // Per-sample field values (analytic) for the kernels, in f32.
    let mut sdf = vec![0.0f32; n];
    let mut grad = vec![[0.0f32; 3]; n];
    for (k, p) in samples.positions.iter().enumerate() {
        let (f, g) = torus(*p);
        sdf[k] = f;
        grad[k] = g;
    }
    let params = vec![[0.6f32, 0.5, 0.4, 0.4, 0.5, 0.1, 0.2, 0.5, 0.3]; n];
    let energy = vec![[2.0f32; 3]; n_rays];
    let ambient = vec![[0.2f32; 3]; n];
    let settings = NeusSettings::default();
    let brdf = BrdfSettings::default();
    let ninp = NeusInputs {
        offsets: &samples.offsets,
        ray_dirs: &dirs,
        sdf: &sdf,
        sdf_grad: &grad,
        delta: &samples.delta,
    };
    let finp = FlashInputs {
        offsets: &samples.offsets,
        ray_dirs: &dirs,
        light_energy: &energy,
        t: &samples.t,
        sdf_grad: &grad,
        params: &params,
    };
    let mut w = NeusWeights::new();
    let mut flash = vec![[0.0f32; 3]; n];
    let mut c = vec![[0.0f32; 3]; n];
    let mut colour = vec![[0.0f32; 3]; n_rays];
    let t_neus = time(reps, || w.forward(&ninp, v, &settings));
    let t_flash_value = time(reps, || flash_forward(&finp, 0.0, &brdf, &mut flash, None));
    let mut cache = FlashCache::new();
    let t_flash = time(reps, || {
        flash_forward(&finp, 0.0, &brdf, &mut flash, Some(&mut cache))
    });
    for k in 0..n {
        c[k] = [
            ambient[k][0] + flash[k][0],
            ambient[k][1] + flash[k][1],
            ambient[k][2] + flash[k][2],
        ];
    }
    let t_comp = time(reps, || {
        composite(&samples.offsets, &w.weight, &c, &mut colour)
    });
    let d_colour = vec![[1.0f32, -0.5, 0.25]; n_rays];
    let d_acc = vec![0.1f32; n_rays];
    let mut d_w = vec![0.0f32; n];
    let mut d_c = vec![[0.0f32; 3]; n];
    let mut d_theta = vec![[0.0f32; 9]; n];
    let mut d_grad = vec![[0.0f32; 3]; n];
    let mut d_sdf = vec![0.0f32; n];
    let t_back = time(reps, || {
        d_w.fill(0.0);
        d_c.fill([0.0; 3]);
        d_theta.fill([0.0; 9]);
        d_grad.fill([0.0; 3]);
        d_sdf.fill(0.0);
        composite_backward(
            &samples.offsets,
            &w.weight,
            &c,
            &d_colour,
            &mut d_w,
            Some(&mut d_c),
        );
        flash_backward(
            &finp,
            0.0,
            &brdf,
            Some(&cache),
            &d_c,
            &mut d_theta,
            &mut d_grad,
        );
        w.backward(
            &ninp,
            v,
            &settings,
            &d_w,
            Some(&d_acc),
            &mut d_sdf,
            &mut d_grad,
        );
    });
    let ms = |t: f64| t * 1e3;
    let rate = |t: f64| n as f64 / t / 1e6;
    println!(
        "kernels on {n} samples: NeuS forward {:.2} ms ({:.1} M samples/s), flash forward value-only {:.2} ms, \
         with Jacobian cache {:.2} ms ({:.1} M/s), composite {:.2} ms ({:.1} M/s), \
         backward (composite + flash + NeuS) {:.2} ms ({:.1} M/s)",
        ms(t_neus),
        rate(t_neus),
        ms(t_flash_value),
        ms(t_flash),
        rate(t_flash),
        ms(t_comp),
        rate(t_comp),
        ms(t_back),
        rate(t_back)
    );
    let c_neus = cpu_time(reps, || w.forward(&ninp, v, &settings));
    let c_flash_value = cpu_time(reps, || flash_forward(&finp, 0.0, &brdf, &mut flash, None));
    let c_flash = cpu_time(reps, || {
        flash_forward(&finp, 0.0, &brdf, &mut flash, Some(&mut cache))
    });
    let c_flash_back = cpu_time(reps, || {
        d_theta.fill([0.0; 9]);
        d_grad.fill([0.0; 3]);
        flash_backward(
            &finp,
            0.0,
            &brdf,
            Some(&cache),
            &d_c,
            &mut d_theta,
            &mut d_grad,
        );
    });
    println!(
        "CPU time (all threads) per call: NeuS forward {:.2} ms, flash forward value-only {:.2} ms \
         ({:.0} ns/sample), with Jacobian cache {:.2} ms ({:.0} ns/sample), flash backward \
         (cached) {:.2} ms",
        ms(c_neus),
        ms(c_flash_value),
        c_flash_value / n as f64 * 1e9,
        ms(c_flash),
        c_flash / n as f64 * 1e9,
        ms(c_flash_back)
    );
    let total = t_coarse + t_refine + t_neus + t_flash + t_comp + t_back;
    println!(
        "total renderer time per batch (sampling + forward + backward, field excluded): {:.2} ms → \
         {:.0} k rays/s, {:.1} M samples/s",
        ms(total),
        n_rays as f64 / total / 1e3,
        n as f64 / total / 1e6
    );
}
