//! Baking the material field into textures: rasterise the atlas, find the
//! surface point of every texel, evaluate the material and the fine normal
//! there, then dilate into the gutters.

use glam::{Mat3, Mat4, Vec2, Vec3};
use indicatif::ProgressBar;
use rayon::prelude::*;
use wildlight_material::PARAM_COUNT;

use crate::atlas::TexturedMesh;
use crate::source::{FieldSource, MAX_BATCH};

/// Channels of a baked texel: the 9 material parameters (SPEC §3 order),
/// then the tangent-space normal (x, y, z, unit length).
pub const TEXEL_CHANNELS: usize = PARAM_COUNT + 3;
/// Index of the tangent-space normal's x in a texel.
pub const NORMAL: usize = PARAM_COUNT;

/// Linear texel values of all maps, row 0 at the top (v = 0).
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialTextures {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// `width × height` texels, row-major.
    pub texels: Vec<[f32; TEXEL_CHANNELS]>,
}

impl MaterialTextures {
    /// The texel at column `x`, row `y`.
    pub fn get(&self, x: u32, y: u32) -> &[f32; TEXEL_CHANNELS] {
        &self.texels[(y * self.width + x) as usize]
    }

    /// Bilinear sample at texture coordinate `uv` (texel centres at
    /// ((x + ½)/W, (y + ½)/H), clamped at the borders); the normal is
    /// re-normalized.
    pub fn sample(&self, uv: Vec2) -> [f32; TEXEL_CHANNELS] {
        let fx = (uv.x * self.width as f32 - 0.5).clamp(0.0, self.width as f32 - 1.0);
        let fy = (uv.y * self.height as f32 - 0.5).clamp(0.0, self.height as f32 - 1.0);
        let (x0, y0) = (fx.floor() as u32, fy.floor() as u32);
        let (x1, y1) = ((x0 + 1).min(self.width - 1), (y0 + 1).min(self.height - 1));
        let (tx, ty) = (fx - x0 as f32, fy - y0 as f32);
        let mut out = [0.0f32; TEXEL_CHANNELS];
        for (x, y, w) in [
            (x0, y0, (1.0 - tx) * (1.0 - ty)),
            (x1, y0, tx * (1.0 - ty)),
            (x0, y1, (1.0 - tx) * ty),
            (x1, y1, tx * ty),
        ] {
            for (o, v) in out.iter_mut().zip(self.get(x, y)) {
                *o += w * v;
            }
        }
        let n = Vec3::new(out[NORMAL], out[NORMAL + 1], out[NORMAL + 2]).normalize_or(Vec3::Z);
        out[NORMAL..].copy_from_slice(&n.to_array());
        out
    }
}

/// Settings of the bake.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeOptions {
    /// Newton steps p ← p − φ(p) ∇φ / |∇φ|² that move a texel's point on
    /// the simplified mesh onto the SDF's zero level set (default 1: the
    /// point starts within the simplification error of the surface).
    pub projection_iterations: u32,
    /// Largest distance one step may move (normalized units, default 0.02).
    pub max_step: f32,
    /// Take the fine normal from the gradient of the last projection step
    /// (evaluated before that step, at most one step length away) instead
    /// of evaluating the gradient again at the projected point (default
    /// true: one gradient per texel fewer; the step is ~the simplification
    /// error, far below what an 8-bit normal map resolves).
    pub reuse_projection_gradient: bool,
}

impl Default for BakeOptions {
    fn default() -> Self {
        BakeOptions {
            projection_iterations: 1,
            max_step: 0.02,
            reuse_projection_gradient: true,
        }
    }
}

/// Where one texel lies on the mesh: triangle and barycentric coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexelHit {
    /// Texel index (row-major).
    pub texel: u32,
    /// Triangle index.
    pub triangle: u32,
    /// Barycentric weights of the triangle's corners.
    pub bary: [f32; 3],
}

/// Finds, for every texel whose centre lies in a triangle of the atlas,
/// that triangle and the barycentric coordinates (a texel covered by two
/// triangles, on a shared edge, keeps the later one).
pub fn rasterize(mesh: &TexturedMesh, width: u32, height: u32) -> Vec<TexelHit> {
    let size = Vec2::new(width as f32, height as f32);
    let per_triangle: Vec<Vec<TexelHit>> = mesh
        .triangles
        .par_iter()
        .enumerate()
        .map(|(t, tri)| {
            let [a, b, c] = tri.map(|v| mesh.uvs[v as usize] * size);
            let det = (b - a).perp_dot(c - a);
            let mut hits = Vec::new();
            if det.abs() < 1e-12 {
                return hits;
            }
            let lo = a.min(b).min(c);
            let hi = a.max(b).max(c);
            let x0 = (lo.x - 0.5).ceil().max(0.0) as u32;
            let y0 = (lo.y - 0.5).ceil().max(0.0) as u32;
            let x1 = ((hi.x - 0.5).floor() as i64).min(width as i64 - 1);
            let y1 = ((hi.y - 0.5).floor() as i64).min(height as i64 - 1);
            let eps = -1e-5;
            for y in y0 as i64..=y1 {
                for x in x0 as i64..=x1 {
                    let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                    let wb = (p - a).perp_dot(c - a) / det;
                    let wc = (b - a).perp_dot(p - a) / det;
                    let wa = 1.0 - wb - wc;
                    if wa >= eps && wb >= eps && wc >= eps {
                        hits.push(TexelHit {
                            texel: (y as u32) * width + x as u32,
                            triangle: t as u32,
                            bary: [wa, wb, wc],
                        });
                    }
                }
            }
            hits
        })
        .collect();
    let mut owner = vec![u32::MAX; (width * height) as usize];
    let mut all: Vec<TexelHit> = per_triangle.into_iter().flatten().collect();
    for (i, h) in all.iter().enumerate() {
        owner[h.texel as usize] = i as u32;
    }
    let mut kept = Vec::with_capacity(all.len());
    for (i, h) in all.drain(..).enumerate() {
        if owner[h.texel as usize] == i as u32 {
            kept.push(h);
        }
    }
    kept
}

/// Bakes the material maps and the tangent-space normal map of `mesh`.
///
/// `mesh` is in the export frame; `to_normalized` maps its positions to the
/// normalized frame where `source` is evaluated. Each covered texel's point
/// is interpolated on its triangle, projected onto φ = 0 (Newton steps,
/// [`BakeOptions`]), and gets the material there and the SDF normal, which
/// is expressed in the texel's interpolated tangent frame (T, B = w·N×T,
/// N). Returns the textures (uncovered texels zero) and the coverage mask.
pub fn bake<S: FieldSource + ?Sized>(
    source: &S,
    mesh: &TexturedMesh,
    to_normalized: &Mat4,
    width: u32,
    height: u32,
    options: &BakeOptions,
    progress: &ProgressBar,
) -> (MaterialTextures, Vec<bool>) {
    let hits = rasterize(mesh, width, height);
    // Normals transform by the inverse transpose of the linear part.
    let normal_to_export = Mat3::from_mat4(*to_normalized).transpose();
    progress.set_length(hits.len() as u64);
    let results: Vec<(u32, [f32; TEXEL_CHANNELS])> = hits
        .par_chunks(MAX_BATCH)
        .flat_map_iter(|chunk| {
            let mut points: Vec<[f32; 3]> = chunk
                .iter()
                .map(|h| {
                    let tri = mesh.triangles[h.triangle as usize];
                    let p: Vec3 = (0..3)
                        .map(|k| mesh.positions[tri[k] as usize] * h.bary[k])
                        .sum();
                    to_normalized.transform_point3(p).to_array()
                })
                .collect();
            let mut phi = vec![0.0f32; points.len()];
            let mut grad = vec![[0.0f32; 3]; points.len()];
            for _ in 0..options.projection_iterations {
                source.sdf(&points, &mut phi);
                source.gradient(&points, &mut grad);
                for ((p, f), g) in points.iter_mut().zip(&phi).zip(&grad) {
                    let g = Vec3::from_array(*g);
                    let g2 = g.length_squared();
                    if g2 > 1e-12 && f.is_finite() {
                        let step = (g * (*f / g2)).clamp_length_max(options.max_step);
                        *p = (Vec3::from_array(*p) - step).to_array();
                    }
                }
            }
            let mut material = vec![[0.0f32; PARAM_COUNT]; points.len()];
            source.material(&points, &mut material);
            if options.projection_iterations == 0 || !options.reuse_projection_gradient {
                source.gradient(&points, &mut grad);
            }
            let out: Vec<(u32, [f32; TEXEL_CHANNELS])> = chunk
                .iter()
                .zip(material.iter().zip(&grad))
                .map(|(h, (m, g))| {
                    let tri = mesh.triangles[h.triangle as usize];
                    let mut n = Vec3::ZERO;
                    let mut t = Vec3::ZERO;
                    let mut w = 0.0;
                    for (&v, &weight) in tri.iter().zip(&h.bary) {
                        let v = v as usize;
                        n += mesh.normals[v] * weight;
                        t += mesh.tangents[v].truncate() * weight;
                        w += mesh.tangents[v].w * weight;
                    }
                    let fine = (normal_to_export * Vec3::from_array(*g)).normalize_or(n);
                    let local = to_tangent_space(fine, n, t, w);
                    let mut texel = [0.0f32; TEXEL_CHANNELS];
                    for (o, v) in texel.iter_mut().zip(m) {
                        *o = v.clamp(0.0, 1.0);
                    }
                    texel[NORMAL..].copy_from_slice(&local.to_array());
                    (h.texel, texel)
                })
                .collect();
            progress.inc(chunk.len() as u64);
            out
        })
        .collect();
    let mut textures = MaterialTextures {
        width,
        height,
        texels: vec![[0.0; TEXEL_CHANNELS]; (width * height) as usize],
    };
    let mut covered = vec![false; textures.texels.len()];
    for (i, texel) in results {
        textures.texels[i as usize] = texel;
        covered[i as usize] = true;
    }
    (textures, covered)
}

/// The shading frame of a point from interpolated normal `n`, tangent `t`
/// and bitangent sign `w` (glTF: B = w · N × T, after Gram–Schmidt).
pub fn tangent_frame(n: Vec3, t: Vec3, w: f32) -> (Vec3, Vec3, Vec3) {
    let n = n.normalize_or(Vec3::Z);
    let t = (t - n * n.dot(t))
        .try_normalize()
        .unwrap_or_else(|| n.any_orthonormal_vector());
    let b = n.cross(t) * if w < 0.0 { -1.0 } else { 1.0 };
    (t, b, n)
}

/// Expresses the unit vector `v` in the tangent frame of ([`tangent_frame`]).
pub fn to_tangent_space(v: Vec3, n: Vec3, t: Vec3, w: f32) -> Vec3 {
    let (t, b, n) = tangent_frame(n, t, w);
    Vec3::new(v.dot(t), v.dot(b), v.dot(n)).normalize_or(Vec3::Z)
}

/// The inverse of [`to_tangent_space`]: a tangent-space vector to the mesh frame.
pub fn from_tangent_space(local: Vec3, n: Vec3, t: Vec3, w: f32) -> Vec3 {
    let (t, b, n) = tangent_frame(n, t, w);
    (t * local.x + b * local.y + n * local.z).normalize_or(n)
}

/// Fills every uncovered texel, ring by ring outwards from the covered
/// ones, with the mean of its already-filled 8-neighbours, so that
/// bilinear filtering and mip-mapping near chart borders only mix values of
/// the nearby surface. Normals are re-normalized. With no covered texel at
/// all nothing changes.
pub fn dilate(textures: &mut MaterialTextures, covered: &[bool]) {
    let (w, h) = (textures.width as i64, textures.height as i64);
    let mut filled: Vec<bool> = covered.to_vec();
    let neighbours = |i: usize| {
        let (x, y) = (i as i64 % w, i as i64 / w);
        (-1..=1i64)
            .flat_map(move |dy| (-1..=1i64).map(move |dx| (x + dx, y + dy)))
            .filter(move |&(nx, ny)| (nx, ny) != (x, y) && nx >= 0 && ny >= 0 && nx < w && ny < h)
            .map(move |(nx, ny)| (ny * w + nx) as usize)
    };
    let mut ring: Vec<usize> = (0..filled.len())
        .filter(|&i| !filled[i] && neighbours(i).any(|j| filled[j]))
        .collect();
    let mut queued = vec![false; filled.len()];
    for &i in &ring {
        queued[i] = true;
    }
    while !ring.is_empty() {
        let values: Vec<[f32; TEXEL_CHANNELS]> = ring
            .par_iter()
            .map(|&i| {
                let mut sum = [0.0f32; TEXEL_CHANNELS];
                let mut count = 0.0f32;
                for j in neighbours(i).filter(|&j| filled[j]) {
                    for (s, v) in sum.iter_mut().zip(&textures.texels[j]) {
                        *s += v;
                    }
                    count += 1.0;
                }
                for s in &mut sum {
                    *s /= count;
                }
                let n =
                    Vec3::new(sum[NORMAL], sum[NORMAL + 1], sum[NORMAL + 2]).normalize_or(Vec3::Z);
                sum[NORMAL..].copy_from_slice(&n.to_array());
                sum
            })
            .collect();
        for (&i, v) in ring.iter().zip(values) {
            textures.texels[i] = v;
            filled[i] = true;
        }
        let mut next = Vec::new();
        for &i in &ring {
            for j in neighbours(i) {
                if !filled[j] && !queued[j] {
                    queued[j] = true;
                    next.push(j);
                }
            }
        }
        ring = next;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> TexturedMesh {
        // Two triangles covering the left half of the texture [0, 0.5] × [0, 1].
        TexturedMesh {
            positions: vec![
                Vec3::new(-0.5, -0.5, 0.0),
                Vec3::new(0.5, -0.5, 0.0),
                Vec3::new(0.5, 0.5, 0.0),
                Vec3::new(-0.5, 0.5, 0.0),
            ],
            normals: vec![Vec3::Z; 4],
            tangents: vec![Vec3::X.extend(1.0); 4],
            uvs: vec![
                Vec2::new(0.0, 1.0),
                Vec2::new(0.5, 1.0),
                Vec2::new(0.5, 0.0),
                Vec2::new(0.0, 0.0),
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
        }
    }

    #[test]
    fn rasterize_covers_each_texel_once() {
        let hits = rasterize(&quad(), 16, 8);
        // Texel centres with x + 0.5 ≤ 8: columns 0..8 (the centre 7.5 is inside).
        assert_eq!(hits.len(), 8 * 8);
        let mut seen = std::collections::HashSet::new();
        for h in &hits {
            assert!(seen.insert(h.texel));
            assert!(h.texel % 16 < 8);
            assert!((h.bary.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn tangent_space_round_trip() {
        let n = Vec3::new(0.2, 0.3, 0.9).normalize();
        let t = Vec3::new(1.0, 0.1, 0.0);
        let v = Vec3::new(-0.3, 0.5, 0.8).normalize();
        for w in [1.0, -1.0] {
            let local = to_tangent_space(v, n, t, w);
            assert!((from_tangent_space(local, n, t, w) - v).length() < 1e-5);
        }
        // The normal itself maps to +z.
        assert!((to_tangent_space(n, n, t, 1.0) - Vec3::Z).length() < 1e-5);
    }

    #[test]
    fn dilation_fills_all_texels_with_nearby_values() {
        let (w, h) = (12u32, 6u32);
        let mut tex = MaterialTextures {
            width: w,
            height: h,
            texels: vec![[0.0; TEXEL_CHANNELS]; (w * h) as usize],
        };
        let mut covered = vec![false; (w * h) as usize];
        // Two covered islands: value 0.2 at column 1, value 0.8 at column 10.
        for y in 0..h {
            for (x, v) in [(1u32, 0.2f32), (10, 0.8)] {
                let i = (y * w + x) as usize;
                tex.texels[i] = [v; TEXEL_CHANNELS];
                tex.texels[i][NORMAL..].copy_from_slice(&[0.0, 0.0, 1.0]);
                covered[i] = true;
            }
        }
        let before = tex.clone();
        dilate(&mut tex, &covered);
        for y in 0..h {
            for x in 0..w {
                let t = tex.get(x, y);
                assert!(t[0] > 0.0, "texel {x},{y} not filled");
                // Covered texels keep their value; gutters copy the nearest island.
                if x <= 4 {
                    assert!((t[0] - 0.2).abs() < 1e-6);
                } else if x >= 7 {
                    assert!((t[0] - 0.8).abs() < 1e-6);
                }
                assert!((t[NORMAL + 2] - 1.0).abs() < 1e-6);
            }
        }
        for (i, c) in covered.iter().enumerate() {
            if *c {
                assert_eq!(tex.texels[i], before.texels[i]);
            }
        }
    }
}
