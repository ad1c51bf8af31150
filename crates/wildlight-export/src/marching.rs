//! Marching cubes of the SDF's zero level set inside the unit sphere,
//! evaluated slab by slab in a narrow band, giving an indexed (welded by
//! construction), closed, outward-oriented mesh in the normalized frame.
//!
//! Why not the `mcubes` crate: it needs the whole N³ volume in one `Vec`
//! (no chunking), emits an unindexed triangle soup that must be welded
//! afterwards, and allocates per cube. Here every grid edge gets exactly one
//! vertex (shared through per-plane edge tables), so no welding tolerance is
//! needed, and the SDF is only evaluated in blocks near the surface.
//!
//! The triangle table is derived, not typed in: for each of the 256 sign
//! configurations the crossing segments on the 6 cube faces are linked into
//! closed loops, each fanned into triangles. On a face with 4 crossings the
//! negative (inside) corners are kept apart; the rule depends only on the
//! face, so neighbouring cubes agree and the surface is watertight.
//! Triangles are counter-clockwise seen from the positive (outside) side, so
//! face normals point outwards (along +∇φ).

use std::sync::OnceLock;

use glam::{DVec3, Vec3};
use indicatif::ProgressBar;
use wildlight_mesh::TriMesh;

use crate::ExportError;
use crate::source::{FieldSource, bounded_sdf, par_eval};

/// Settings of the surface extraction.
#[derive(Clone, Debug, PartialEq)]
pub struct MarchingOptions {
    /// Cells per axis of the grid over [−1, 1]³ (default 512).
    pub resolution: u32,
    /// Cells per axis of a narrow-band block (default 4).
    pub block: u32,
    /// A block is skipped when its 8 corners share one sign and all have
    /// |φ| > `band_margin` × the block diagonal (an SDF with |∇φ| ≤
    /// `band_margin` cannot cross it). `0` or less evaluates every block.
    /// Default 1.5.
    pub band_margin: f32,
}

impl Default for MarchingOptions {
    fn default() -> Self {
        MarchingOptions {
            resolution: 512,
            block: 4,
            band_margin: 1.5,
        }
    }
}

/// Statistics of one extraction.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MarchingStats {
    /// SDF evaluations (coarse + fine).
    pub evaluations: u64,
    /// Blocks evaluated at full resolution.
    pub active_blocks: u64,
    /// All blocks.
    pub total_blocks: u64,
}

/// The 8 corners of a cell: corner `c` sits at offset (c & 1, c >> 1 & 1, c >> 2 & 1).
fn corner_offset(c: usize) -> [usize; 3] {
    [c & 1, (c >> 1) & 1, (c >> 2) & 1]
}

/// The 12 cell edges as (start corner, axis); the end corner is start | (1 << axis).
fn cell_edges() -> [(usize, usize); 12] {
    let mut edges = [(0, 0); 12];
    let mut n = 0;
    for axis in 0..3 {
        for c in 0..8 {
            if c & (1 << axis) == 0 {
                edges[n] = (c, axis);
                n += 1;
            }
        }
    }
    edges
}

/// The edge id (index into [`cell_edges`]) joining corners `a` and `b`.
fn edge_between(a: usize, b: usize) -> usize {
    let axis = (a ^ b).trailing_zeros() as usize;
    let start = a.min(b);
    cell_edges()
        .iter()
        .position(|&(c, ax)| c == start && ax == axis)
        .unwrap_or(0)
}

/// Triangles (as cell edge ids) for each of the 256 inside/outside corner
/// configurations (bit c set = corner c is inside, φ < 0).
fn triangle_table() -> &'static [Vec<[u8; 3]>] {
    static TABLE: OnceLock<Vec<Vec<[u8; 3]>>> = OnceLock::new();
    TABLE.get_or_init(|| (0..256).map(triangles_for_case).collect())
}

fn triangles_for_case(case: usize) -> Vec<[u8; 3]> {
    let inside = |c: usize| case & (1 << c) != 0;
    // successor[e] = the edge the surface loop goes to after crossing edge e.
    let mut successor = [usize::MAX; 12];
    for axis in 0..3 {
        for side in 0..2 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let at = |du: usize, dv: usize| (side << axis) | (du << u) | (dv << v);
            // Counter-clockwise around +axis; reversed on the −axis face so
            // that every cycle is counter-clockwise seen from outside the cell.
            let mut cycle = [at(0, 0), at(1, 0), at(1, 1), at(0, 1)];
            if side == 0 {
                cycle.reverse();
            }
            // Crossings in cycle order: (edge, true if going inside → outside).
            let crossings: Vec<(usize, bool)> = (0..4)
                .filter_map(|j| {
                    let (from, to) = (cycle[j], cycle[(j + 1) % 4]);
                    (inside(from) != inside(to)).then(|| (edge_between(from, to), inside(from)))
                })
                .collect();
            let k = crossings.len();
            for (i, &(edge, neg_to_pos)) in crossings.iter().enumerate() {
                if neg_to_pos {
                    continue;
                }
                // From an outside → inside crossing to the next inside → outside one.
                if let Some(&(next, _)) = (1..k)
                    .map(|d| &crossings[(i + d) % k])
                    .find(|(_, n2p)| *n2p)
                {
                    successor[edge] = next;
                }
            }
        }
    }
    let mut triangles = Vec::new();
    let mut visited = [false; 12];
    for start in 0..12 {
        if successor[start] == usize::MAX || visited[start] {
            continue;
        }
        let mut lp = Vec::new();
        let mut e = start;
        while !visited[e] {
            visited[e] = true;
            lp.push(e as u8);
            e = successor[e];
        }
        for i in 1..lp.len().saturating_sub(1) {
            triangles.push([lp[0], lp[i], lp[i + 1]]);
        }
    }
    triangles
}

/// Grid geometry: `n` cells per axis over [−1, 1]³.
struct Grid {
    n: usize,
}

impl Grid {
    fn coord(&self, i: usize) -> f64 {
        -1.0 + 2.0 * i as f64 / self.n as f64
    }
    fn point(&self, i: usize, j: usize, k: usize) -> [f32; 3] {
        [
            self.coord(i) as f32,
            self.coord(j) as f32,
            self.coord(k) as f32,
        ]
    }
}

/// Extracts the zero level set of `source`'s SDF, restricted to the unit
/// sphere (max(φ, |p| − 1)), as a closed mesh in the normalized frame.
/// `progress` advances by one per slab of blocks (its length is set here).
pub fn extract_surface<S: FieldSource + ?Sized>(
    source: &S,
    options: &MarchingOptions,
    progress: &ProgressBar,
) -> Result<(TriMesh, MarchingStats), ExportError> {
    if options.resolution < 2 || options.resolution > 4096 {
        return Err(ExportError::InvalidOption {
            name: "resolution",
            problem: format!("{} is outside 2..=4096", options.resolution),
        });
    }
    if options.block == 0 {
        return Err(ExportError::InvalidOption {
            name: "block",
            problem: "must be at least 1".into(),
        });
    }
    let n = options.resolution as usize;
    let b = (options.block as usize).min(n);
    let nb = n.div_ceil(b);
    let grid = Grid { n };
    let h = 2.0 / n as f32;
    let mut stats = MarchingStats {
        total_blocks: (nb * nb * nb) as u64,
        ..Default::default()
    };
    let eval = |points: &[[f32; 3]]| -> Vec<f32> {
        par_eval(points, |p, o: &mut [f32]| {
            source.sdf(p, o);
            for (v, q) in o.iter_mut().zip(p) {
                *v = bounded_sdf(*v, *q);
            }
        })
    };

    // Coarse pass: block corners.
    let cb = nb + 1;
    let block_corner = |i: usize| (i * b).min(n);
    let dense = options.band_margin <= 0.0;
    let active: Vec<bool> = if dense {
        vec![true; nb * nb * nb]
    } else {
        let mut coarse_points = Vec::with_capacity(cb * cb * cb);
        for k in 0..cb {
            for j in 0..cb {
                for i in 0..cb {
                    coarse_points.push(grid.point(
                        block_corner(i),
                        block_corner(j),
                        block_corner(k),
                    ));
                }
            }
        }
        let coarse = eval(&coarse_points);
        stats.evaluations += coarse.len() as u64;
        let threshold = options.band_margin * (b as f32 * h) * 3f32.sqrt();
        let mut active = vec![false; nb * nb * nb];
        for bz in 0..nb {
            for by in 0..nb {
                for bx in 0..nb {
                    let vals: Vec<f32> = (0..8)
                        .map(|c| {
                            let [dx, dy, dz] = corner_offset(c);
                            coarse[(bx + dx) + (by + dy) * cb + (bz + dz) * cb * cb]
                        })
                        .collect();
                    let any_neg = vals.iter().any(|v| *v < 0.0);
                    let any_pos = vals.iter().any(|v| *v >= 0.0);
                    let near = vals.iter().any(|v| v.abs() <= threshold);
                    active[bx + by * nb + bz * nb * nb] = (any_neg && any_pos) || near;
                }
            }
        }
        active
    };
    stats.active_blocks = active.iter().filter(|a| **a).count() as u64;

    let np = n + 1;
    let plane = np * np;
    let mut positions: Vec<Vec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    // Vertex ids of x- and y-edges on the lower/upper plane of the current
    // cell layer, and of z-edges between them (u32::MAX = none yet).
    let mut ex_lo = vec![u32::MAX; plane];
    let mut ey_lo = vec![u32::MAX; plane];
    let mut ex_hi = vec![u32::MAX; plane];
    let mut ey_hi = vec![u32::MAX; plane];
    let mut ez = vec![u32::MAX; plane];
    let edges = cell_edges();
    let table = triangle_table();
    progress.set_length(nb as u64);

    for bz in 0..nb {
        let z0 = bz * b;
        let z1 = (z0 + b).min(n);
        let planes = z1 - z0 + 1;
        let mut slab = vec![f32::NAN; planes * plane];
        let layer_blocks: Vec<(usize, usize)> = (0..nb * nb)
            .filter(|&i| active[i + bz * nb * nb])
            .map(|i| (i % nb, i / nb))
            .collect();
        // Gather the grid points of the active blocks of this slab.
        let mut wanted: Vec<usize> = Vec::new();
        for &(bx, by) in &layer_blocks {
            let (x0, x1) = (bx * b, ((bx + 1) * b).min(n));
            let (y0, y1) = (by * b, ((by + 1) * b).min(n));
            for kz in 0..planes {
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        let idx = kz * plane + y * np + x;
                        if slab[idx].is_nan() {
                            slab[idx] = f32::INFINITY;
                            wanted.push(idx);
                        }
                    }
                }
            }
        }
        let points: Vec<[f32; 3]> = wanted
            .iter()
            .map(|&idx| {
                let (kz, rest) = (idx / plane, idx % plane);
                grid.point(rest % np, rest / np, z0 + kz)
            })
            .collect();
        let values = eval(&points);
        stats.evaluations += values.len() as u64;
        for (&idx, &v) in wanted.iter().zip(&values) {
            slab[idx] = v;
        }

        for z in z0..z1 {
            let kz = z - z0;
            for &(bx, by) in &layer_blocks {
                let (x0, x1) = (bx * b, ((bx + 1) * b).min(n));
                let (y0, y1) = (by * b, ((by + 1) * b).min(n));
                for y in y0..y1 {
                    for x in x0..x1 {
                        let value_at = |c: usize| {
                            let [dx, dy, dz] = corner_offset(c);
                            slab[(kz + dz) * plane + (y + dy) * np + (x + dx)]
                        };
                        let mut case = 0usize;
                        let mut vals = [0f32; 8];
                        for (c, v) in vals.iter_mut().enumerate() {
                            *v = value_at(c);
                            if *v < 0.0 {
                                case |= 1 << c;
                            }
                        }
                        if case == 0 || case == 255 {
                            continue;
                        }
                        let mut vid = [u32::MAX; 12];
                        for tri in &table[case] {
                            let mut ids = [0u32; 3];
                            for (slot, &e) in ids.iter_mut().zip(tri) {
                                let e = e as usize;
                                if vid[e] == u32::MAX {
                                    let (c0, axis) = edges[e];
                                    let [dx, dy, dz] = corner_offset(c0);
                                    let (gx, gy) = (x + dx, y + dy);
                                    let table_slot = match (axis, dz) {
                                        (0, 0) => &mut ex_lo[gx + gy * np],
                                        (0, _) => &mut ex_hi[gx + gy * np],
                                        (1, 0) => &mut ey_lo[gx + gy * np],
                                        (1, _) => &mut ey_hi[gx + gy * np],
                                        _ => &mut ez[gx + gy * np],
                                    };
                                    if *table_slot == u32::MAX {
                                        let (v0, v1) =
                                            (vals[c0] as f64, vals[c0 | (1 << axis)] as f64);
                                        let t = (v0 / (v0 - v1)).clamp(0.0, 1.0);
                                        let mut p = DVec3::new(
                                            grid.coord(gx),
                                            grid.coord(gy),
                                            grid.coord(z + dz),
                                        );
                                        p[axis] += t * 2.0 / n as f64;
                                        *table_slot = positions.len() as u32;
                                        positions.push(p.as_vec3());
                                    }
                                    vid[e] = *table_slot;
                                }
                                *slot = vid[e];
                            }
                            triangles.push(ids);
                        }
                    }
                }
            }
            std::mem::swap(&mut ex_lo, &mut ex_hi);
            std::mem::swap(&mut ey_lo, &mut ey_hi);
            ex_hi.fill(u32::MAX);
            ey_hi.fill(u32::MAX);
            ez.fill(u32::MAX);
        }
        progress.inc(1);
    }
    if triangles.is_empty() {
        return Err(ExportError::EmptySurface {
            resolution: options.resolution,
        });
    }
    let mut mesh = TriMesh::new(positions, triangles);
    // Vertices exactly on a grid corner (φ = 0 there) can make zero-area
    // triangles; drop them.
    mesh.triangles
        .retain(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
    Ok((mesh, stats))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::source::AnalyticSource;
    use std::collections::HashMap;

    fn sphere(radius: f32) -> impl FieldSource {
        AnalyticSource::new(move |p: Vec3| p.length() - radius, |_| [0.5; 9])
    }

    /// Every directed edge appears once and its reverse once: closed and
    /// consistently oriented.
    fn assert_closed_oriented(mesh: &TriMesh) {
        let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
        for t in &mesh.triangles {
            for k in 0..3 {
                *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        for (&(a, b), &count) in &directed {
            assert_eq!(count, 1, "directed edge {a}->{b} used {count} times");
            assert_eq!(directed.get(&(b, a)), Some(&1), "edge {a}->{b} has no twin");
        }
    }

    fn euler_characteristic(mesh: &TriMesh) -> i64 {
        let mut undirected = std::collections::HashSet::new();
        for t in &mesh.triangles {
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                undirected.insert((a.min(b), a.max(b)));
            }
        }
        mesh.positions.len() as i64 - undirected.len() as i64 + mesh.triangles.len() as i64
    }

    #[test]
    fn every_case_gives_triangles_facing_away_from_the_inside_corners() {
        // Per case, the area-weighted normal of the triangles (edge
        // midpoints as vertices) points from the inside corners towards the
        // outside ones.
        let edges = cell_edges();
        let mid = |e: u8| {
            let (c, axis) = edges[e as usize];
            let mut p = Vec3::from_array(corner_offset(c).map(|v| v as f32));
            p[axis] += 0.5;
            p
        };
        let corner = |c: usize| Vec3::from_array(corner_offset(c).map(|v| v as f32));
        for case in 1..255usize {
            let tris = triangles_for_case(case);
            assert!(!tris.is_empty(), "case {case} has no triangles");
            let (mut inside, mut outside) = (Vec3::ZERO, Vec3::ZERO);
            let count_in = case.count_ones() as f32;
            for c in 0..8 {
                if case & (1 << c) != 0 {
                    inside += corner(c) / count_in;
                } else {
                    outside += corner(c) / (8.0 - count_in);
                }
            }
            let total: Vec3 = tris
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(mid);
                    (b - a).cross(c - a)
                })
                .sum();
            let axis = outside - inside;
            if axis.length() > 1e-6 {
                assert!(total.dot(axis) > 0.0, "case {case}: {tris:?}");
            }
        }
    }

    #[test]
    fn sphere_is_closed_outward_and_on_the_surface() {
        let source = sphere(0.6);
        let options = MarchingOptions {
            resolution: 64,
            block: 4,
            ..Default::default()
        };
        let (mesh, stats) = extract_surface(&source, &options, &ProgressBar::hidden()).unwrap();
        assert_closed_oriented(&mesh);
        assert_eq!(euler_characteristic(&mesh), 2);
        for (t, n) in mesh.face_normals().iter().enumerate() {
            let [a, b, c] = mesh.triangle_corners(t);
            assert!(
                n.dot((a + b + c) / 3.0) > 0.0,
                "triangle {t} points inwards"
            );
        }
        for p in &mesh.positions {
            assert!(
                (p.length() - 0.6).abs() < 2e-3,
                "vertex at radius {}",
                p.length()
            );
        }
        // Area of the sphere within 1 % (faceting makes it slightly smaller).
        let area = mesh.total_area();
        let exact = 4.0 * std::f64::consts::PI * 0.36;
        assert!(
            (area - exact).abs() / exact < 0.01,
            "area {area} vs {exact}"
        );
        assert!(stats.active_blocks < stats.total_blocks);
    }

    #[test]
    fn narrow_band_equals_dense_extraction() {
        let torus = AnalyticSource::new(
            |p: Vec3| {
                let q = glam::Vec2::new(p.truncate().length() - 0.55, p.z);
                q.length() - 0.22
            },
            |_| [0.5; 9],
        );
        let banded = MarchingOptions {
            resolution: 40,
            block: 4,
            band_margin: 1.5,
        };
        let dense = MarchingOptions {
            band_margin: 0.0,
            ..banded.clone()
        };
        let (a, sa) = extract_surface(&torus, &banded, &ProgressBar::hidden()).unwrap();
        let (d, sd) = extract_surface(&torus, &dense, &ProgressBar::hidden()).unwrap();
        assert_eq!(a.triangles.len(), d.triangles.len());
        assert!((a.total_area() - d.total_area()).abs() < 1e-9);
        assert!(sa.evaluations < sd.evaluations, "{sa:?} vs {sd:?}");
        assert_closed_oriented(&a);
        assert_eq!(euler_characteristic(&a), 0);
    }

    #[test]
    fn surface_is_clipped_to_the_unit_sphere() {
        // A half-space crosses the unit sphere: the result is a closed cap.
        let half = AnalyticSource::new(|p: Vec3| p.z - 0.2, |_| [0.5; 9]);
        let options = MarchingOptions {
            resolution: 32,
            ..Default::default()
        };
        let (mesh, _) = extract_surface(&half, &options, &ProgressBar::hidden()).unwrap();
        assert_closed_oriented(&mesh);
        assert!(
            mesh.positions
                .iter()
                .all(|p| p.length() < 1.0 + 1e-4 && p.z < 0.2 + 1e-5)
        );
    }

    #[test]
    fn empty_field_is_an_error() {
        let nothing = AnalyticSource::new(|_p: Vec3| 1.0, |_| [0.5; 9]);
        let options = MarchingOptions {
            resolution: 16,
            ..Default::default()
        };
        let err = extract_surface(&nothing, &options, &ProgressBar::hidden()).unwrap_err();
        assert!(err.to_string().contains("no zero level set"), "{err}");
    }
}
