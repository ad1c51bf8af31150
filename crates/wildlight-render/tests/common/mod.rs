//! Analytic fields and cameras shared by the integration tests.
#![allow(dead_code)]

use wildlight_render::occupancy::{OccupancyGrid, OccupancySettings};
use wildlight_render::sampler::{CoarseSamples, RaySamples, Rays, Sampler, SamplerSettings};

/// A torus around the y axis (major radius `major`, tube radius `minor`),
/// tilted by rotating the query point about the x axis by `tilt`.
#[derive(Clone, Copy, Debug)]
pub struct Torus {
    pub major: f64,
    pub minor: f64,
    pub tilt: f64,
}

impl Torus {
    pub fn standard() -> Self {
        Self {
            major: 0.5,
            minor: 0.2,
            tilt: 0.6,
        }
    }

    fn rotate(&self, p: [f64; 3]) -> [f64; 3] {
        let (s, c) = self.tilt.sin_cos();
        [p[0], c * p[1] - s * p[2], s * p[1] + c * p[2]]
    }

    fn rotate_back(&self, p: [f64; 3]) -> [f64; 3] {
        let (s, c) = self.tilt.sin_cos();
        [p[0], c * p[1] + s * p[2], -s * p[1] + c * p[2]]
    }

    /// φ and ∇φ (exact SDF, |∇φ| = 1).
    pub fn eval(&self, p: [f64; 3]) -> (f64, [f64; 3]) {
        let [x, y, z] = self.rotate(p);
        let rho = (x * x + z * z).sqrt().max(1e-12);
        let qx = rho - self.major;
        let ql = (qx * qx + y * y).sqrt().max(1e-12);
        let g = [qx / ql * x / rho, y / ql, qx / ql * z / rho];
        (ql - self.minor, self.rotate_back(g))
    }

    /// φ in f32 for a batch of points: the closure the occupancy grid and
    /// the sampler evaluate.
    pub fn batch_sdf(self) -> impl Fn(&[[f32; 3]], &mut [f32]) + Copy {
        move |p: &[[f32; 3]], out: &mut [f32]| {
            for (o, x) in out.iter_mut().zip(p) {
                *o = self.eval(x.map(f64::from)).0 as f32;
            }
        }
    }

    /// φ, ∇φ and [`colour`] at each of `positions`, in f64.
    pub fn fields_at(&self, positions: &[[f32; 3]]) -> (Vec<f64>, Vec<[f64; 3]>, Vec<[f64; 3]>) {
        let n = positions.len();
        let (mut sdf, mut grad, mut col) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        for p in positions {
            let p = p.map(f64::from);
            let (f, g) = self.eval(p);
            sdf.push(f);
            grad.push(g);
            col.push(colour(p));
        }
        (sdf, grad, col)
    }

    /// A point on the surface at angles (u around the axis, w around the tube).
    pub fn surface_point(&self, u: f64, w: f64) -> [f64; 3] {
        let rho = self.major + self.minor * w.cos();
        self.rotate_back([rho * u.cos(), self.minor * w.sin(), rho * u.sin()])
    }
}

/// A smooth colour function with values in [0.1, 0.9].
pub fn colour(p: [f64; 3]) -> [f64; 3] {
    [
        0.5 + 0.4 * (3.0 * p[0] + 1.0).sin(),
        0.5 + 0.4 * (2.0 * p[1] - 0.5).cos(),
        0.5 + 0.4 * (2.5 * p[2] + 2.0 * p[0]).sin(),
    ]
}

/// Pinhole camera at `eye` looking at the origin: rays through the centres
/// of a `w`×`h` image with the given half field of view.
pub fn camera_rays(
    eye: [f32; 3],
    w: usize,
    h: usize,
    half_fov: f32,
) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let norm = |v: [f32; 3]| {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|x| x / l)
    };
    let cross = |a: [f32; 3], b: [f32; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let fwd = norm(eye.map(|x| -x));
    let right = norm(cross(fwd, [0.0, 1.0, 0.0]));
    let up = cross(right, fwd);
    let tan = half_fov.tan();
    let mut origins = Vec::new();
    let mut dirs = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let u = ((x as f32 + 0.5) / w as f32 * 2.0 - 1.0) * tan;
            let v = ((y as f32 + 0.5) / h as f32 * 2.0 - 1.0) * tan;
            let d = norm([
                fwd[0] + u * right[0] - v * up[0],
                fwd[1] + u * right[1] - v * up[1],
                fwd[2] + u * right[2] - v * up[2],
            ]);
            origins.push(eye);
            dirs.push(d);
        }
    }
    (origins, dirs)
}

/// A small deterministic generator (xorshift64*) for test data.
pub struct TestRng(pub u64);

impl TestRng {
    pub fn next_f64(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next_f64()
    }
}

/// An occupancy grid of `resolution`³ cells, its other settings the defaults.
pub fn occupancy_grid(resolution: usize) -> OccupancyGrid {
    OccupancyGrid::new(OccupancySettings {
        resolution,
        ..Default::default()
    })
    .unwrap()
}

/// Runs `f` on a rayon pool of `threads` threads.
pub fn on_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// The samples of `rays` drawn by a fresh sampler with the default settings
/// from `grid`, the batch SDF `sdf` at sharpness `s` and the jitter seed
/// `jitter_seed` (`None`: no jitter).
pub fn fast_samples(
    grid: &OccupancyGrid,
    rays: &Rays<'_>,
    sdf: impl FnOnce(&[[f32; 3]], &mut [f32]),
    s: f32,
    jitter_seed: Option<u64>,
) -> RaySamples {
    let mut sampler = Sampler::new(SamplerSettings::default()).unwrap();
    let (mut coarse, mut samples) = (CoarseSamples::default(), RaySamples::default());
    sampler.sample(grid, rays, sdf, s, jitter_seed, &mut coarse, &mut samples);
    samples
}
