//! A triangle mesh ready for ray casting: its BVH, shading normals and
//! face normals, the first surface point along a camera ray and shadow
//! rays.

use glam::DVec3;
use wildlight_mesh::TriMesh;

use crate::bvh::Bvh;

/// A mesh ready for ray casting (normalized frame).
#[derive(Clone, Debug)]
pub struct Scene {
    bvh: Bvh,
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    face_normals: Vec<DVec3>,
}

/// A camera ray's hit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    /// Ray parameter (normalized-frame distance, the ray direction is unit).
    pub t: f64,
    /// Hit position (normalized frame).
    pub position: DVec3,
    /// Unit shading normal (interpolated vertex normals), facing the ray
    /// origin's side, leaning towards the face normal where the
    /// interpolated one turns away from the viewer (see `facing_viewer`).
    pub normal: DVec3,
    /// Unit face normal, facing the ray origin.
    pub geometric_normal: DVec3,
}

impl Scene {
    /// Prepares `mesh` (normalized frame). Vertex normals are taken from
    /// the mesh when present, else averaged from the faces.
    pub fn new(mesh: &TriMesh) -> Scene {
        let positions: Vec<DVec3> = mesh.positions.iter().map(|p| p.as_dvec3()).collect();
        let normals = match &mesh.normals {
            Some(n) if n.len() == positions.len() => n.clone(),
            _ => mesh.vertex_normals_from_faces(),
        };
        let normals = normals
            .iter()
            .map(|n| n.as_dvec3().try_normalize().unwrap_or(DVec3::Z))
            .collect();
        let face_normals = mesh
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| positions[v as usize]);
                (b - a).cross(c - a).try_normalize().unwrap_or(DVec3::Z)
            })
            .collect();
        let bvh = Bvh::new(&positions, &mesh.triangles);
        Scene {
            bvh,
            positions,
            normals,
            triangles: mesh.triangles.clone(),
            face_normals,
        }
    }

    /// The bounding volume hierarchy over the mesh's triangles (indexed as
    /// the mesh's), for renderers that interpolate their own attributes.
    pub fn bvh(&self) -> &Bvh {
        &self.bvh
    }

    /// The first surface point along the ray (unit `dir`), if any.
    pub fn trace(&self, origin: DVec3, dir: DVec3) -> Option<SurfacePoint> {
        let hit = self.bvh.intersect(origin, dir, 0.0, f64::INFINITY)?;
        let hit = self.bvh.refine(origin, dir, hit);
        let tri = self.triangles[hit.triangle as usize];
        let [a, b, c] = tri.map(|v| self.positions[v as usize]);
        let w0 = 1.0 - hit.u - hit.v;
        let position = a * w0 + b * hit.u + c * hit.v;
        let [na, nb, nc] = tri.map(|v| self.normals[v as usize]);
        let mut normal = (na * w0 + nb * hit.u + nc * hit.v)
            .try_normalize()
            .unwrap_or(self.face_normals[hit.triangle as usize]);
        let mut geometric_normal = self.face_normals[hit.triangle as usize];
        if geometric_normal.dot(dir) > 0.0 {
            // seen from behind (open or inconsistently oriented mesh)
            geometric_normal = -geometric_normal;
            normal = -normal;
        }
        Some(SurfacePoint {
            t: hit.t,
            position,
            normal: facing_viewer(normal, geometric_normal, -dir),
            geometric_normal,
        })
    }

    /// Whether the ray from `origin` along unit `dir` hits anything with
    /// t < `t_max`.
    pub fn occluded(&self, origin: DVec3, dir: DVec3, t_max: f64) -> bool {
        self.bvh.occluded(origin, dir, 0.0, t_max)
    }
}

/// Below this cosine between the interpolated normal and the direction to
/// the viewer, the shading normal leans towards the face normal.
const GRAZING_COSINE: f64 = 0.1;

/// The shading normal at a visible point: the interpolated vertex normal
/// `shading`, except where it turns away from the viewer `v` (unit).
///
/// Interpolated normals are smooth across a crease that the triangles
/// themselves turn sharply at (the kettle's lid groove, where the handle
/// meets the body), so a triangle beside the crease that faces the camera
/// can carry a shading normal that faces away from it; the BRDF is then
/// zero for every light, and the pixel is exactly black in both the
/// ambient and the flash image: no real surface looks like that, and no
/// reconstruction whose normals are its own geometry's can fit it. Where
/// c = n_s·v is below [`GRAZING_COSINE`] the normal is blended towards the
/// face normal `geometric` (which faces the viewer, since the ray hit its
/// front): normalize(w n_s + (1 − w) n_g) with w = max(c, 0) / [`GRAZING_COSINE`],
/// continuous in c, and equal to n_s on any surface whose triangles agree
/// with their vertex normals, as they do on a smooth part seen at a grazing
/// angle.
fn facing_viewer(shading: DVec3, geometric: DVec3, v: DVec3) -> DVec3 {
    let c = shading.dot(v);
    if c >= GRAZING_COSINE {
        return shading;
    }
    let w = (c / GRAZING_COSINE).clamp(0.0, 1.0);
    (shading * w + geometric * (1.0 - w))
        .try_normalize()
        .unwrap_or(geometric)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A shading normal that faces away from the viewer gives way to the
    /// face normal; the blend is continuous at both ends of the grazing
    /// band and leaves normals that face the viewer alone.
    #[test]
    fn shading_normals_never_face_away_from_the_viewer() {
        let v = DVec3::Z;
        let geometric = DVec3::new(0.6, 0.0, 0.8);
        let at = |c: f64| {
            let s = (1.0 - c * c).sqrt();
            facing_viewer(DVec3::new(-s, 0.0, c), geometric, v)
        };
        assert_eq!(at(0.5), DVec3::new(-(0.75f64).sqrt(), 0.0, 0.5));
        assert_eq!(at(-0.3), geometric);
        assert_eq!(at(0.0), geometric);
        // continuous at the top of the band, facing the viewer inside it
        assert!((at(GRAZING_COSINE - 1e-9) - at(GRAZING_COSINE)).length() < 1e-6);
        for k in 0..=20 {
            let n = at(-0.1 + 0.01 * k as f64);
            assert!((n.length() - 1.0).abs() < 1e-12 && n.dot(v) > 0.0, "{n}");
        }
    }
}
