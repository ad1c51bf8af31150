//! A bounding volume hierarchy over the triangles of a mesh for ray casting
//! (closest hit for camera rays, any hit for shadow rays).
//!
//! Built top-down with a binned surface-area heuristic; nodes are stored
//! depth-first in one array (the left child follows its parent). Boxes and
//! triangles are single precision; [`Bvh::refine`] recomputes a hit in
//! double precision.

use glam::{DVec3, Vec3};

const BINS: usize = 12;
const LEAF_SIZE: usize = 4;

#[derive(Clone, Copy, Debug)]
struct Node {
    min: Vec3,
    max: Vec3,
    /// Leaf: first index into `order`; inner: index of the right child.
    offset: u32,
    /// Number of triangles in a leaf, 0 for an inner node.
    count: u32,
}

/// A ray–triangle hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit.
    pub t: f64,
    /// Index of the triangle in the mesh.
    pub triangle: u32,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f64,
    /// Barycentric weight of the triangle's third vertex.
    pub v: f64,
}

/// BVH over a triangle list.
#[derive(Clone, Debug)]
pub struct Bvh {
    nodes: Vec<Node>,
    order: Vec<u32>,
    /// Per triangle (in `order` order): vertex 0, edge 1, edge 2.
    tris: Vec<[Vec3; 3]>,
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
}

#[derive(Clone, Copy)]
struct Bounds {
    min: Vec3,
    max: Vec3,
}

impl Bounds {
    const EMPTY: Bounds = Bounds {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };
    fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    fn merge(&mut self, b: &Bounds) {
        self.min = self.min.min(b.min);
        self.max = self.max.max(b.max);
    }
    fn area(&self) -> f32 {
        let d = (self.max - self.min).max(Vec3::ZERO);
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }
}

impl Bvh {
    /// Builds the hierarchy for `triangles` over `positions`.
    pub fn new(positions: &[DVec3], triangles: &[[u32; 3]]) -> Bvh {
        let pf: Vec<Vec3> = positions.iter().map(|p| p.as_vec3()).collect();
        let mut boxes = Vec::with_capacity(triangles.len());
        let mut centroids = Vec::with_capacity(triangles.len());
        for t in triangles {
            let mut b = Bounds::EMPTY;
            for &v in t {
                b.grow(pf[v as usize]);
            }
            boxes.push(b);
            centroids.push(0.5 * (b.min + b.max));
        }
        let mut order: Vec<u32> = (0..triangles.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * triangles.len() / LEAF_SIZE + 1);
        if !triangles.is_empty() {
            build(
                &mut nodes,
                &mut order,
                0,
                triangles.len(),
                &boxes,
                &centroids,
            );
        }
        let tris = order
            .iter()
            .map(|&t| {
                let [a, b, c] = triangles[t as usize].map(|v| pf[v as usize]);
                [a, b - a, c - a]
            })
            .collect();
        Bvh {
            nodes,
            order,
            tris,
            positions: positions.to_vec(),
            triangles: triangles.to_vec(),
        }
    }

    /// The closest hit with t in (t_min, t_max).
    pub fn intersect(&self, origin: DVec3, dir: DVec3, t_min: f64, t_max: f64) -> Option<Hit> {
        let mut best: Option<(f32, usize, f32, f32)> = None;
        let mut t_best = t_max as f32;
        self.traverse(
            origin,
            dir,
            t_min as f32,
            &mut t_best,
            false,
            &mut |slot, t, u, v| {
                best = Some((t, slot, u, v));
            },
        );
        best.map(|(t, slot, u, v)| Hit {
            t: t as f64,
            triangle: self.order[slot],
            u: u as f64,
            v: v as f64,
        })
    }

    /// Whether anything is hit with t in (t_min, t_max).
    pub fn occluded(&self, origin: DVec3, dir: DVec3, t_min: f64, t_max: f64) -> bool {
        let mut hit = false;
        let mut t_best = t_max as f32;
        self.traverse(
            origin,
            dir,
            t_min as f32,
            &mut t_best,
            true,
            &mut |_, _, _, _| hit = true,
        );
        hit
    }

    /// Recomputes `hit` in double precision: the exact ray parameter and
    /// barycentrics of the ray's intersection with the hit triangle's plane.
    pub fn refine(&self, origin: DVec3, dir: DVec3, hit: Hit) -> Hit {
        let [a, b, c] = self.triangles[hit.triangle as usize].map(|v| self.positions[v as usize]);
        let e1 = b - a;
        let e2 = c - a;
        let pv = dir.cross(e2);
        let det = e1.dot(pv);
        if det.abs() < 1e-300 {
            return hit;
        }
        let inv = 1.0 / det;
        let s = origin - a;
        let u = s.dot(pv) * inv;
        let q = s.cross(e1);
        let v = dir.dot(q) * inv;
        let t = e2.dot(q) * inv;
        Hit {
            t,
            triangle: hit.triangle,
            u,
            v,
        }
    }

    fn traverse(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_min: f32,
        t_best: &mut f32,
        any: bool,
        on_hit: &mut impl FnMut(usize, f32, f32, f32),
    ) {
        if self.nodes.is_empty() {
            return;
        }
        let o = origin.as_vec3();
        let d = dir.as_vec3();
        let inv = Vec3::ONE / d;
        let mut stack = [0u32; 64];
        let mut sp = 0;
        let mut node = 0usize;
        loop {
            let n = &self.nodes[node];
            if n.count > 0 {
                let first = n.offset as usize;
                for slot in first..first + n.count as usize {
                    let [a, e1, e2] = self.tris[slot];
                    // Möller–Trumbore
                    let pv = d.cross(e2);
                    let det = e1.dot(pv);
                    if det.abs() < 1e-12 {
                        continue;
                    }
                    let id = 1.0 / det;
                    let s = o - a;
                    let u = s.dot(pv) * id;
                    if !(0.0..=1.0).contains(&u) {
                        continue;
                    }
                    let q = s.cross(e1);
                    let v = d.dot(q) * id;
                    if v < 0.0 || u + v > 1.0 {
                        continue;
                    }
                    let t = e2.dot(q) * id;
                    if t > t_min && t < *t_best {
                        *t_best = t;
                        on_hit(slot, t, u, v);
                        if any {
                            return;
                        }
                    }
                }
            } else {
                let left = node + 1;
                let right = n.offset as usize;
                let tl = self.slab(left, o, inv, t_min, *t_best);
                let tr = self.slab(right, o, inv, t_min, *t_best);
                match (tl, tr) {
                    (Some(a), Some(b)) => {
                        let (near, far) = if a <= b { (left, right) } else { (right, left) };
                        if sp < stack.len() {
                            stack[sp] = far as u32;
                            sp += 1;
                        }
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = left;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = right;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            if sp == 0 {
                return;
            }
            sp -= 1;
            node = stack[sp] as usize;
        }
    }

    #[inline]
    fn slab(&self, node: usize, o: Vec3, inv: Vec3, t_min: f32, t_max: f32) -> Option<f32> {
        let n = &self.nodes[node];
        let t0 = (n.min - o) * inv;
        let t1 = (n.max - o) * inv;
        let near = t0.min(t1).max_element().max(t_min);
        let far = t0.max(t1).min_element().min(t_max);
        // Pad for rounding so that rays grazing a box edge are not lost.
        (near <= far * 1.000_001).then_some(near)
    }
}

fn build(
    nodes: &mut Vec<Node>,
    order: &mut [u32],
    first: usize,
    count: usize,
    boxes: &[Bounds],
    centroids: &[Vec3],
) -> usize {
    let mut bounds = Bounds::EMPTY;
    let mut cb = Bounds::EMPTY;
    for &t in &order[first..first + count] {
        bounds.merge(&boxes[t as usize]);
        cb.grow(centroids[t as usize]);
    }
    let me = nodes.len();
    nodes.push(Node {
        min: bounds.min,
        max: bounds.max,
        offset: first as u32,
        count: count as u32,
    });
    if count <= LEAF_SIZE {
        return me;
    }
    // Binned SAH over the three axes.
    let extent = cb.max - cb.min;
    let mut best = (f32::INFINITY, 0usize, 0usize);
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        let scale = BINS as f32 / extent[axis];
        let mut bins = [(Bounds::EMPTY, 0usize); BINS];
        for &t in &order[first..first + count] {
            let b = (((centroids[t as usize][axis] - cb.min[axis]) * scale) as usize).min(BINS - 1);
            bins[b].0.merge(&boxes[t as usize]);
            bins[b].1 += 1;
        }
        let mut right_area = [0.0f32; BINS];
        let mut right_count = [0usize; BINS];
        let mut acc = Bounds::EMPTY;
        let mut n = 0;
        for i in (1..BINS).rev() {
            acc.merge(&bins[i].0);
            n += bins[i].1;
            right_area[i] = acc.area();
            right_count[i] = n;
        }
        let mut acc = Bounds::EMPTY;
        let mut n = 0;
        for i in 0..BINS - 1 {
            acc.merge(&bins[i].0);
            n += bins[i].1;
            let cost = acc.area() * n as f32 + right_area[i + 1] * right_count[i + 1] as f32;
            if n > 0 && right_count[i + 1] > 0 && cost < best.0 {
                best = (cost, axis, i + 1);
            }
        }
    }
    let mid = if best.0.is_finite() {
        let (axis, split) = (best.1, best.2);
        let scale = BINS as f32 / extent[axis];
        let slice = &mut order[first..first + count];
        let mut i = 0;
        for j in 0..slice.len() {
            let b = (((centroids[slice[j] as usize][axis] - cb.min[axis]) * scale) as usize)
                .min(BINS - 1);
            if b < split {
                slice.swap(i, j);
                i += 1;
            }
        }
        i
    } else {
        count / 2
    };
    let mid = if mid == 0 || mid == count {
        count / 2
    } else {
        mid
    };
    nodes[me].count = 0;
    build(nodes, order, first, mid, boxes, centroids);
    let right = build(nodes, order, first + mid, count - mid, boxes, centroids);
    nodes[me].offset = right as u32;
    me
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sphere_bvh() -> Bvh {
        let mesh = crate::test_sphere(0.5);
        let pos: Vec<DVec3> = mesh.positions.iter().map(|p| p.as_dvec3()).collect();
        Bvh::new(&pos, &mesh.triangles)
    }

    #[test]
    fn closest_hit_matches_brute_force_and_sphere() {
        let bvh = sphere_bvh();
        let mut hits = 0;
        for i in 0..400 {
            let a = i as f64 * 0.61;
            let b = i as f64 * 0.37;
            let origin = DVec3::new(2.0 * a.cos(), 0.7 * b.sin(), 2.0 * a.sin());
            let target = DVec3::new(0.3 * b.cos(), 0.3 * a.sin(), 0.2 * (a + b).cos());
            let dir = (target - origin).normalize();
            // brute force
            let mut brute = f64::INFINITY;
            for (ti, t) in bvh.triangles.iter().enumerate() {
                let _ = t;
                let h = bvh.refine(
                    origin,
                    dir,
                    Hit {
                        t: 0.0,
                        triangle: ti as u32,
                        u: 0.0,
                        v: 0.0,
                    },
                );
                if h.u >= 0.0 && h.v >= 0.0 && h.u + h.v <= 1.0 && h.t > 0.0 {
                    brute = brute.min(h.t);
                }
            }
            let hit = bvh
                .intersect(origin, dir, 0.0, f64::INFINITY)
                .expect("aimed at the sphere");
            hits += 1;
            assert!((hit.t - brute).abs() < 1e-5, "{} vs {brute}", hit.t);
            let p = origin + hit.t * dir;
            assert!((p.length() - 0.5).abs() < 3e-3);
            assert!(bvh.occluded(origin, dir, 0.0, 10.0));
            assert!(!bvh.occluded(origin, dir, 0.0, hit.t * 0.999));
        }
        assert_eq!(hits, 400);
        assert!(
            bvh.intersect(DVec3::new(0.0, 2.0, 0.0), DVec3::Y, 0.0, 10.0)
                .is_none()
        );
    }
}
