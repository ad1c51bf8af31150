//! UV atlas of the simplified mesh with `uvunwrap`, and MikkTSpace
//! tangents with `mikktspace`: the mesh a texture is baked for.

use std::collections::HashMap;

use glam::{Vec2, Vec3, Vec4};
use wildlight_mesh::TriMesh;

use crate::ExportError;

/// A triangle mesh ready for texturing: every vertex has a position, a unit
/// normal, a MikkTSpace tangent (xyz unit, w = ±1 bitangent sign) and a
/// texture coordinate (glTF convention: (0, 0) is the top-left corner of
/// the image, v grows downwards). Vertices are split along UV seams.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TexturedMesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit vertex normals.
    pub normals: Vec<Vec3>,
    /// Tangents; the bitangent is `w · normal × tangent.xyz` (glTF).
    pub tangents: Vec<Vec4>,
    /// Texture coordinates in [0, 1]².
    pub uvs: Vec<Vec2>,
    /// Counter-clockwise triangles (outward normals).
    pub triangles: Vec<[u32; 3]>,
}

/// Settings of the atlas.
#[derive(Clone, Debug, PartialEq)]
pub struct AtlasOptions {
    /// Width (and largest height) of the texture in texels (default 2048).
    pub texture_size: u32,
    /// Empty texels around each chart (default 4).
    pub padding: u32,
    /// Use uvunwrap's fast row packing instead of shape packing (default true:
    /// much faster on 100k+ faces, slightly less dense).
    pub fast_packing: bool,
}

impl Default for AtlasOptions {
    fn default() -> Self {
        AtlasOptions {
            texture_size: 2048,
            padding: 4,
            fast_packing: true,
        }
    }
}

/// The atlas size: always `texture_size` square (power-of-two sizes stay
/// power-of-two, so every engine can mip-map the maps).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtlasSize {
    /// Texture width in texels.
    pub width: u32,
    /// Texture height in texels.
    pub height: u32,
    /// Number of charts.
    pub charts: u32,
    /// Fraction of texels covered by charts.
    pub utilization: f32,
}

/// Unwraps `mesh` (which must carry unit vertex normals) into one atlas
/// page, splitting vertices along chart seams, then computes tangents.
pub fn unwrap(
    mesh: &TriMesh,
    options: &AtlasOptions,
) -> Result<(TexturedMesh, AtlasSize), ExportError> {
    if options.texture_size < 16 || options.texture_size > 16384 {
        return Err(ExportError::InvalidOption {
            name: "texture",
            problem: format!("{} is outside 16..=16384", options.texture_size),
        });
    }
    let normals = mesh
        .normals
        .clone()
        .unwrap_or_else(|| mesh.vertex_normals_from_faces());
    let positions: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
    let indices: Vec<u32> = mesh.triangles.iter().flatten().copied().collect();
    let input = uvunwrap::MeshInput::new(&positions, &indices);
    let unwrap_options = uvunwrap::Options {
        density: uvunwrap::Density::Auto {
            page_size: options.texture_size,
        },
        padding: options.padding,
        packing: if options.fast_packing {
            uvunwrap::Packing::Fast
        } else {
            uvunwrap::Packing::Shape
        },
        ..Default::default()
    };
    let atlas = uvunwrap::generate(&[input], &unwrap_options)
        .map_err(|e| ExportError::stage("UV unwrapping", e.to_string()))?;
    if atlas.page_count != 1 {
        return Err(ExportError::stage(
            "UV unwrapping",
            format!(
                "the charts need {} atlas pages; use a larger texture or fewer faces",
                atlas.page_count
            ),
        ));
    }
    let out = atlas
        .meshes
        .first()
        .ok_or_else(|| ExportError::stage("UV unwrapping", "no output mesh"))?;
    // uvunwrap crops its page to the rows it used (v grows with the row);
    // the texture stays square, its last rows left to the gutter dilation,
    // so v is rescaled from the cropped page to the full one.
    let rows_used = atlas.height as f32 / atlas.width as f32;
    let mut textured = TexturedMesh {
        positions: out
            .vertices
            .iter()
            .map(|v| mesh.positions[v.xref as usize])
            .collect(),
        normals: out
            .vertices
            .iter()
            .map(|v| normals[v.xref as usize].normalize_or(Vec3::Z))
            .collect(),
        tangents: Vec::new(),
        uvs: out
            .vertices
            .iter()
            .map(|v| Vec2::new(v.uv[0], v.uv[1] * rows_used))
            .collect(),
        triangles: out
            .indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
    };
    add_tangents(&mut textured)?;
    let size = AtlasSize {
        width: atlas.width,
        height: atlas.width,
        charts: atlas.chart_count,
        utilization: atlas.utilization * rows_used,
    };
    Ok((textured, size))
}

/// Geometry adaptor for mikktspace, collecting one tangent per corner.
struct MikkMesh<'a> {
    mesh: &'a TexturedMesh,
    corner_tangents: Vec<[f32; 4]>,
}

impl mikktspace::Geometry for MikkMesh<'_> {
    fn num_faces(&self) -> usize {
        self.mesh.triangles.len()
    }
    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }
    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.mesh.positions[self.mesh.triangles[face][vert] as usize].to_array()
    }
    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        self.mesh.normals[self.mesh.triangles[face][vert] as usize].to_array()
    }
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        // MikkTSpace in the OpenGL UV convention (v up), as Blender and the
        // glTF sample viewer do for glTF's top-left-origin UVs: the
        // bitangent then points up in the image (normal map green = up).
        let uv = self.mesh.uvs[self.mesh.triangles[face][vert] as usize];
        [uv.x, 1.0 - uv.y]
    }
    fn set_tangent_encoded(&mut self, tangent: [f32; 4], face: usize, vert: usize) {
        self.corner_tangents[face * 3 + vert] = tangent;
    }
}

/// Computes MikkTSpace tangents; a vertex whose corners get different
/// tangents is split so that each vertex has exactly one.
pub fn add_tangents(mesh: &mut TexturedMesh) -> Result<(), ExportError> {
    let mut mikk = MikkMesh {
        mesh,
        corner_tangents: vec![[1.0, 0.0, 0.0, 1.0]; mesh.triangles.len() * 3],
    };
    if !mikktspace::generate_tangents(&mut mikk) {
        return Err(ExportError::stage(
            "tangents",
            "mikktspace could not generate tangents",
        ));
    }
    let corner_tangents = mikk.corner_tangents;
    let mut key_to_vertex: HashMap<(u32, [u32; 4]), u32> = HashMap::new();
    let mut out = TexturedMesh::default();
    let mut triangles = Vec::with_capacity(mesh.triangles.len());
    for (f, tri) in mesh.triangles.iter().enumerate() {
        let mut new_tri = [0u32; 3];
        for k in 0..3 {
            let v = tri[k];
            let mut t = corner_tangents[f * 3 + k];
            if !t.iter().all(|x| x.is_finite()) {
                t = [1.0, 0.0, 0.0, 1.0];
            }
            let key = (v, t.map(f32::to_bits));
            new_tri[k] = *key_to_vertex.entry(key).or_insert_with(|| {
                let id = out.positions.len() as u32;
                out.positions.push(mesh.positions[v as usize]);
                out.normals.push(mesh.normals[v as usize]);
                out.uvs.push(mesh.uvs[v as usize]);
                let n = mesh.normals[v as usize];
                let xyz = Vec3::new(t[0], t[1], t[2]);
                // Orthonormal to the normal, unit length (glTF requires it).
                let xyz = (xyz - n * n.dot(xyz))
                    .try_normalize()
                    .unwrap_or_else(|| n.any_orthonormal_vector());
                out.tangents
                    .push(xyz.extend(if t[3] < 0.0 { -1.0 } else { 1.0 }));
                id
            });
        }
        triangles.push(new_tri);
    }
    out.triangles = triangles;
    *mesh = out;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn icosphere_unwraps_into_one_page_with_unit_tangents() {
        let mut sphere = wildlight_eval_free_icosphere();
        sphere.normals = Some(sphere.positions.iter().map(|p| p.normalize()).collect());
        let options = AtlasOptions {
            texture_size: 256,
            ..Default::default()
        };
        let (mesh, size) = unwrap(&sphere, &options).unwrap();
        assert_eq!(mesh.triangles.len(), sphere.triangles.len());
        assert!(mesh.positions.len() >= sphere.positions.len());
        assert_eq!((size.width, size.height), (256, 256), "square, as asked");
        assert!(size.utilization > 0.3, "{size:?}");
        for (t, n) in mesh.tangents.iter().zip(&mesh.normals) {
            assert!((t.truncate().length() - 1.0).abs() < 1e-4);
            assert!(t.truncate().dot(*n).abs() < 1e-4);
            assert!(t.w == 1.0 || t.w == -1.0);
        }
        for uv in &mesh.uvs {
            assert!((0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y));
        }
        // The tangent points along increasing u on each triangle.
        for tri in &mesh.triangles {
            let [a, b, c] = tri.map(|v| v as usize);
            let (e1, e2) = (
                mesh.positions[b] - mesh.positions[a],
                mesh.positions[c] - mesh.positions[a],
            );
            let (d1, d2) = (mesh.uvs[b] - mesh.uvs[a], mesh.uvs[c] - mesh.uvs[a]);
            let det = d1.x * d2.y - d1.y * d2.x;
            if det.abs() < 1e-9 {
                continue;
            }
            let dp_du = (e1 * d2.y - e2 * d1.y) / det;
            assert!(dp_du.dot(mesh.tangents[a].truncate()) > 0.0);
        }
    }

    /// An octahedron subdivided 4 times onto the unit sphere (no dependency
    /// on other crates' shapes).
    fn wildlight_eval_free_icosphere() -> TriMesh {
        let mut positions = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        let mut triangles: Vec<[u32; 3]> = vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ];
        for _ in 0..4 {
            let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
            let mut next = Vec::new();
            for t in &triangles {
                let mut m = [0u32; 3];
                for k in 0..3 {
                    let (a, b) = (t[k], t[(k + 1) % 3]);
                    m[k] = *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                        positions.push((positions[a as usize] + positions[b as usize]).normalize());
                        positions.len() as u32 - 1
                    });
                }
                next.extend([
                    [t[0], m[0], m[2]],
                    [m[0], t[1], m[1]],
                    [m[2], m[1], t[2]],
                    [m[0], m[1], m[2]],
                ]);
            }
            triangles = next;
        }
        TriMesh::new(positions, triangles)
    }
}
