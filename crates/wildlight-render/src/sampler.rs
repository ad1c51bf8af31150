//! Ray samplers: the fast one (occupancy grid + hierarchical refinement) and
//! a dense uniform reference.
//!
//! Both produce, per ray, contiguous *sections* [t_a, t_b] of the ray with a
//! sample at each section's midpoint t = (t_a + t_b)/2 and length δ = t_b − t_a
//! (the layout the NeuS weights of [`crate::neus`] expect, whose φ⁻/φ⁺ are the
//! SDF estimates at the section ends). Rays are clipped to the bounding
//! sphere (SPEC §5: near/far = the chord of the unit sphere, near ≥ 0).
//!
//! The fast sampler works in two stages, so that the caller evaluates the
//! SDF in batches with whatever field it has:
//!
//! 1. [`Sampler::coarse`]: the ray's sampled intervals from the occupancy
//!    grid (runs of surface cells; marching stops at the first inside cell)
//!    are cut into coarse sections of about `cell/coarse_steps_per_cell`
//!    (longer if the ray would exceed `max_coarse`). Returns the section
//!    boundaries; the caller evaluates φ there.
//! 2. [`Sampler::refine`]: NeuS-style coarse weights from the boundary SDF
//!    values (section ends estimated from the mid value and the steeper of
//!    this and the previous section's slope, as NeuS's up-sampling does),
//!    early termination once the coarse transmittance falls below
//!    `min_transmittance`, coarse sections whose SDF is provably far from
//!    the surface (s·φ > `skip_tail` over the whole section, with |∇φ| ≤ L)
//!    left out, then `n_fine` importance samples by inverse CDF
//!    of the coarse weights. The fine points split the coarse sections;
//!    every piece becomes one output section.
//!
//! The stretches without sections are where the NeuS alpha is negligible
//! (outside the grid's band, or s·φ > `skip_tail` by the Lipschitz bound),
//! so leaving them out changes the transmittance by a negligible factor.
//! Everywhere else the sections tile the ray without gaps, so the product
//! of (1 − alpha) telescopes as in dense sampling and the fast sampler is
//! unbiased up to quadrature error (tested against the dense sampler).

use rayon::prelude::*;

use crate::error::{RenderError, check};
use crate::neus::ALPHA_EPS;
use crate::occupancy::OccupancyGrid;
use crate::packing::{RAY_CHUNK, ray_count};
use crate::real::sigmoid;

/// Camera rays (unit directions) in the normalized frame.
#[derive(Clone, Copy, Debug)]
pub struct Rays<'a> {
    /// Ray origins o.
    pub origins: &'a [[f32; 3]],
    /// Unit ray directions d.
    pub dirs: &'a [[f32; 3]],
}

impl Rays<'_> {
    /// Number of rays.
    pub fn len(&self) -> usize {
        self.origins.len()
    }

    /// Whether there are no rays.
    pub fn is_empty(&self) -> bool {
        self.origins.is_empty()
    }
}

/// The chord [near, far] of ray o + t·d (|d| = 1) through the sphere of
/// radius `radius` around the origin, near clipped at 0 (SPEC §5); `None`
/// when the ray misses it.
#[inline]
pub fn sphere_chord(o: [f32; 3], d: [f32; 3], radius: f32) -> Option<[f32; 2]> {
    let b = o[0] * d[0] + o[1] * d[1] + o[2] * d[2];
    let c = o[0] * o[0] + o[1] * o[1] + o[2] * o[2] - radius * radius;
    let disc = b * b - c;
    if disc <= 0.0 {
        return None;
    }
    let root = disc.sqrt();
    let near = (-b - root).max(0.0);
    let far = -b + root;
    (far > near).then_some([near, far])
}

/// Point o + t·d.
#[inline(always)]
pub fn point_at(o: [f32; 3], d: [f32; 3], t: f32) -> [f32; 3] {
    [o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]]
}

/// Final samples of a batch of rays, packed as in [`crate::packing`].
#[derive(Clone, Debug, Default)]
pub struct RaySamples {
    /// Ray offsets (rays + 1 entries).
    pub offsets: Vec<u32>,
    /// Distance of each sample (its section's midpoint) along its ray.
    pub t: Vec<f32>,
    /// Length δ of each sample's section.
    pub delta: Vec<f32>,
    /// Position o + t·d of each sample.
    pub positions: Vec<[f32; 3]>,
}

impl RaySamples {
    /// Number of samples.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether there are no samples.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    fn clear(&mut self) {
        self.offsets.clear();
        self.offsets.push(0);
        self.t.clear();
        self.delta.clear();
        self.positions.clear();
    }
}

/// Coarse section boundaries of a batch of rays (stage 1 of the fast sampler).
#[derive(Clone, Debug, Default)]
pub struct CoarseSamples {
    /// Ray offsets into the boundary arrays (rays + 1 entries).
    pub offsets: Vec<u32>,
    /// Distance of each boundary along its ray (increasing per ray).
    pub t: Vec<f32>,
    /// Whether a section starts at this boundary (false at the end of an interval).
    pub opens_section: Vec<bool>,
    /// Position of each boundary: evaluate the SDF here.
    pub positions: Vec<[f32; 3]>,
}

impl CoarseSamples {
    fn clear(&mut self) {
        self.offsets.clear();
        self.offsets.push(0);
        self.t.clear();
        self.opens_section.clear();
        self.positions.clear();
    }
}

/// Settings of the fast sampler.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SamplerSettings {
    /// Radius of the bounding sphere (1 in the normalized frame; at most 1,
    /// the occupancy grid covers [−1, 1]³).
    pub bound_radius: f32,
    /// Coarse sections per grid cell length.
    pub coarse_steps_per_cell: f32,
    /// Most coarse sections per ray, plus one per sampled interval shorter
    /// than a coarse step (the final sections are at most that + `n_fine`).
    pub max_coarse: usize,
    /// Importance samples per ray.
    pub n_fine: usize,
    /// Coarse sections after the coarse transmittance falls below this are dropped.
    pub min_transmittance: f32,
    /// Assumed bound L on |∇φ|, for the lower bound of φ over a section.
    pub lipschitz: f32,
    /// Coarse sections where s·φ > `skip_tail` everywhere (by the bound) are
    /// left out of the final samples (NeuS alpha < ≈ e^(−skip_tail) there);
    /// 0 keeps every section.
    pub skip_tail: f32,
}

impl Default for SamplerSettings {
    fn default() -> Self {
        Self {
            bound_radius: 1.0,
            coarse_steps_per_cell: 2.0,
            max_coarse: 64,
            n_fine: 16,
            min_transmittance: 1e-4,
            lipschitz: 1.5,
            skip_tail: 10.0,
        }
    }
}

/// Per-chunk output buffers, kept between calls.
#[derive(Clone, Debug, Default)]
struct ChunkBuffers {
    counts: Vec<u32>,
    t: Vec<f32>,
    flags: Vec<bool>,
    delta: Vec<f32>,
}

/// The fast sampler (module docs). Keeps its work buffers between calls.
#[derive(Clone, Debug)]
pub struct Sampler {
    settings: SamplerSettings,
    chunks: Vec<ChunkBuffers>,
}

/// splitmix64: a well-mixed 64-bit hash for per-ray jitter that does not
/// depend on the thread schedule.
#[inline]
fn splitmix64(mut x: u64) -> u64 {
    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^ (x >> 31)
}

impl Sampler {
    /// A sampler with the given settings.
    pub fn new(settings: SamplerSettings) -> Result<Self, RenderError> {
        check(
            settings.bound_radius > 0.0 && settings.bound_radius <= 1.0,
            "bound_radius",
            settings.bound_radius,
            "must be in (0, 1]: the occupancy grid covers the unit sphere's cube",
        )?;
        check(
            settings.coarse_steps_per_cell.is_finite() && settings.coarse_steps_per_cell > 0.0,
            "coarse_steps_per_cell",
            settings.coarse_steps_per_cell,
            "must be finite and > 0",
        )?;
        check(
            settings.max_coarse >= 1,
            "max_coarse",
            settings.max_coarse,
            "must be ≥ 1",
        )?;
        check(
            (0.0..1.0).contains(&settings.min_transmittance),
            "min_transmittance",
            settings.min_transmittance,
            "must be in [0, 1)",
        )?;
        check(
            settings.lipschitz.is_finite() && settings.lipschitz >= 1.0,
            "lipschitz",
            settings.lipschitz,
            "must be finite and ≥ 1",
        )?;
        check(
            settings.skip_tail.is_finite() && settings.skip_tail >= 0.0,
            "skip_tail",
            settings.skip_tail,
            "must be finite and ≥ 0",
        )?;
        Ok(Self {
            settings,
            chunks: Vec::new(),
        })
    }

    /// The settings.
    pub fn settings(&self) -> &SamplerSettings {
        &self.settings
    }

    fn prepare_chunks(&mut self, n_rays: usize) {
        let n_chunks = n_rays.div_ceil(RAY_CHUNK);
        self.chunks.resize_with(n_chunks, ChunkBuffers::default);
        for c in &mut self.chunks {
            c.counts.clear();
            c.t.clear();
            c.flags.clear();
            c.delta.clear();
        }
    }

    /// Stage 1: coarse section boundaries of every ray from the grid.
    pub fn coarse(&mut self, grid: &OccupancyGrid, rays: &Rays<'_>, out: &mut CoarseSamples) {
        assert_eq!(
            rays.origins.len(),
            rays.dirs.len(),
            "Sampler::coarse: ray arrays"
        );
        let n_rays = rays.len();
        self.prepare_chunks(n_rays);
        let st = self.settings;
        let base_step = grid.cell_size() / st.coarse_steps_per_cell;
        self.chunks
            .par_iter_mut()
            .enumerate()
            .for_each(|(ci, buf)| {
                let mut intervals: Vec<[f32; 2]> = Vec::new();
                for ray in ci * RAY_CHUNK..((ci + 1) * RAY_CHUNK).min(n_rays) {
                    let (o, d) = (rays.origins[ray], rays.dirs[ray]);
                    let before = buf.t.len();
                    if let Some([near, far]) = sphere_chord(o, d, st.bound_radius) {
                        intervals.clear();
                        grid.sampled_intervals(o, d, near, far, &mut intervals);
                        let total: f32 = intervals.iter().map(|iv| iv[1] - iv[0]).sum();
                        let step = base_step.max(total / st.max_coarse as f32);
                        for iv in &intervals {
                            let len = iv[1] - iv[0];
                            // floor keeps Σn ≤ max_coarse (+1 per interval shorter than a step).
                            let n = ((len / step) as usize).max(1); // truncation = floor (len ≥ 0)
                            for j in 0..n {
                                buf.t.push(iv[0] + len * j as f32 / n as f32);
                                buf.flags.push(true);
                            }
                            buf.t.push(iv[1]);
                            buf.flags.push(false);
                        }
                    }
                    buf.counts.push((buf.t.len() - before) as u32);
                }
            });
        out.clear();
        for buf in &self.chunks {
            for &c in &buf.counts {
                let last = *out.offsets.last().unwrap_or(&0);
                out.offsets.push(last + c);
            }
            out.t.extend_from_slice(&buf.t);
            out.opens_section.extend_from_slice(&buf.flags);
        }
        out.positions.reserve(out.t.len());
        for ray in 0..n_rays {
            let (o, d) = (rays.origins[ray], rays.dirs[ray]);
            for k in out.offsets[ray] as usize..out.offsets[ray + 1] as usize {
                out.positions.push(point_at(o, d, out.t[k]));
            }
        }
    }

    /// Stage 2: final sections from the coarse boundaries and the SDF values
    /// `coarse_sdf` at them (module docs). `s` is the NeuS sharpness used for
    /// the coarse weights (the current one). With `jitter_seed`, the fine
    /// samples are stratified-random per ray (deterministic in the seed and
    /// the ray index); without, they sit at the strata centres.
    pub fn refine(
        &mut self,
        rays: &Rays<'_>,
        coarse: &CoarseSamples,
        coarse_sdf: &[f32],
        s: f32,
        jitter_seed: Option<u64>,
        out: &mut RaySamples,
    ) {
        let n_rays = rays.len();
        assert_eq!(
            ray_count(&coarse.offsets),
            n_rays,
            "Sampler::refine: ray count"
        );
        assert_eq!(
            coarse_sdf.len(),
            coarse.t.len(),
            "Sampler::refine: coarse SDF length"
        );
        self.prepare_chunks(n_rays);
        let st = self.settings;
        self.chunks
            .par_iter_mut()
            .enumerate()
            .for_each(|(ci, buf)| {
                // Per-section scratch: start, end, coarse weight.
                let mut sections: Vec<(f32, f32, f32)> = Vec::new();
                let mut fine: Vec<f32> = Vec::new();
                for ray in ci * RAY_CHUNK..((ci + 1) * RAY_CHUNK).min(n_rays) {
                    let range = coarse.offsets[ray] as usize..coarse.offsets[ray + 1] as usize;
                    let before = buf.t.len();
                    sections.clear();
                    // Coarse NeuS weights (NeuS up-sampling).
                    let mut trans = 1.0f32;
                    let mut prev_slope = 0.0f32;
                    for k in range.clone() {
                        if !coarse.opens_section[k] {
                            prev_slope = 0.0;
                            continue;
                        }
                        if trans < st.min_transmittance {
                            break;
                        }
                        let (t0, t1) = (coarse.t[k], coarse.t[k + 1]);
                        let (f0, f1) = (coarse_sdf[k], coarse_sdf[k + 1]);
                        let len = t1 - t0;
                        let slope = (f1 - f0) / (len + 1e-5);
                        let cos = slope.min(prev_slope).clamp(-1e3, 0.0);
                        prev_slope = slope;
                        let mid = 0.5 * (f0 + f1);
                        let p = sigmoid(s * (mid - cos * len * 0.5));
                        let n = sigmoid(s * (mid + cos * len * 0.5));
                        let eps = ALPHA_EPS as f32;
                        let alpha = ((p - n + eps) / (p + eps)).clamp(0.0, 1.0);
                        let alpha = if alpha.is_finite() { alpha } else { 1.0 };
                        // Lower bound of φ over the section (|∇φ| ≤ L): where
                        // s·φ exceeds the tail everywhere, NeuS alpha is
                        // negligible and the section is left out.
                        let phi_lo = 0.5 * (f0 + f1 - st.lipschitz * len);
                        let skip = st.skip_tail > 0.0 && s * phi_lo > st.skip_tail;
                        if !skip {
                            sections.push((t0, t1, trans * alpha + 1e-5));
                        }
                        trans *= 1.0 - alpha;
                    }
                    // Inverse-CDF importance samples (increasing in t).
                    fine.clear();
                    let total: f32 = sections.iter().map(|x| x.2).sum();
                    if st.n_fine > 0 && !sections.is_empty() {
                        let mut j = 0usize;
                        let mut cdf_lo = 0.0f32;
                        for i in 0..st.n_fine {
                            let xi = match jitter_seed {
                                Some(seed) => {
                                    let h = splitmix64(
                                        seed ^ splitmix64(((ray as u64) << 20) | i as u64),
                                    );
                                    (h >> 40) as f32 / (1u64 << 24) as f32
                                }
                                None => 0.5,
                            };
                            let u = (i as f32 + xi) / st.n_fine as f32 * total;
                            while j + 1 < sections.len() && cdf_lo + sections[j].2 < u {
                                cdf_lo += sections[j].2;
                                j += 1;
                            }
                            let (t0, t1, w) = sections[j];
                            let frac = ((u - cdf_lo) / w).clamp(0.0, 1.0);
                            fine.push(t0 + frac * (t1 - t0));
                        }
                    }
                    // Split the coarse sections at the fine points.
                    let mut fi = 0usize;
                    for &(t0, t_end, _) in &sections {
                        let mut a = t0;
                        while fi < fine.len() && fine[fi] <= t_end {
                            let b = fine[fi].max(a);
                            if b > a {
                                buf.t.push(0.5 * (a + b));
                                buf.delta.push(b - a);
                                a = b;
                            }
                            fi += 1;
                        }
                        if t_end > a {
                            buf.t.push(0.5 * (a + t_end));
                            buf.delta.push(t_end - a);
                        }
                    }
                    buf.counts.push((buf.t.len() - before) as u32);
                }
            });
        out.clear();
        for buf in &self.chunks {
            for &c in &buf.counts {
                let last = *out.offsets.last().unwrap_or(&0);
                out.offsets.push(last + c);
            }
            out.t.extend_from_slice(&buf.t);
            out.delta.extend_from_slice(&buf.delta);
        }
        fill_positions(rays, out);
    }

    /// Both stages with an SDF closure (`sdf_fn(points, values)`), using
    /// `coarse` as scratch for the coarse boundaries.
    #[allow(clippy::too_many_arguments)]
    pub fn sample<F>(
        &mut self,
        grid: &OccupancyGrid,
        rays: &Rays<'_>,
        sdf_fn: F,
        s: f32,
        jitter_seed: Option<u64>,
        coarse: &mut CoarseSamples,
        out: &mut RaySamples,
    ) where
        F: FnOnce(&[[f32; 3]], &mut [f32]),
    {
        self.coarse(grid, rays, coarse);
        let mut sdf = vec![0.0f32; coarse.t.len()];
        sdf_fn(&coarse.positions, &mut sdf);
        self.refine(rays, coarse, &sdf, s, jitter_seed, out);
    }
}

fn fill_positions(rays: &Rays<'_>, out: &mut RaySamples) {
    out.positions.clear();
    out.positions.reserve(out.t.len());
    for ray in 0..rays.len() {
        let (o, d) = (rays.origins[ray], rays.dirs[ray]);
        for k in out.offsets[ray] as usize..out.offsets[ray + 1] as usize {
            out.positions.push(point_at(o, d, out.t[k]));
        }
    }
}

/// The dense reference sampler: `n` equal sections over each ray's chord
/// of the sphere of radius `radius` (no skipping, no refinement).
pub fn dense_samples(rays: &Rays<'_>, n: usize, radius: f32, out: &mut RaySamples) {
    out.clear();
    for ray in 0..rays.len() {
        if let Some([near, far]) = sphere_chord(rays.origins[ray], rays.dirs[ray], radius) {
            let delta = (far - near) / n as f32;
            for j in 0..n {
                out.t.push(near + (j as f32 + 0.5) * delta);
                out.delta.push(delta);
            }
        }
        out.offsets.push(out.t.len() as u32);
    }
    fill_positions(rays, out);
}
