//! Wavefront OBJ reading and writing.
//!
//! Reading understands `v x y z [r g b]` (the optional vertex colour
//! extension is used when every `v` line has it), `vt u v`, `vn x y z` and
//! `f` lines with corners written `v`, `v/vt`, `v//vn` or `v/vt/vn`,
//! including negative (relative) indices. Polygons are fan-triangulated.
//! Other statements (`o`, `g`, `s`, `usemtl`, `mtllib`, `l`, `p`, ...) are
//! ignored.
//!
//! When faces use texture coordinates or normals, every distinct
//! (position, texcoord, normal) corner becomes one vertex of the
//! [`TriMesh`]; corners without a texcoord (normal) get zero. Otherwise the
//! vertices are the `v` lines in file order.
//!
//! Writing produces `v`, optional `vt` and `vn` lines (one per vertex) and
//! faces in the matching `a/b/c` form.

use crate::{MeshError, TriMesh};
use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::io::Write;
use std::path::Path;
use wildlight_data::atomic::write_io_atomically;

/// Reads an OBJ file.
pub fn read_obj(path: &Path) -> Result<TriMesh, MeshError> {
    let bytes = std::fs::read(path).map_err(|e| MeshError::io(path, e))?;
    let text = String::from_utf8_lossy(&bytes);
    parse_obj(&text, path)
}

/// One face corner: indices (0-based) into positions, texcoords, normals.
type Corner = (u32, Option<u32>, Option<u32>);

/// Parses OBJ text; `path` only names the source in error messages.
pub fn parse_obj(text: &str, path: &Path) -> Result<TriMesh, MeshError> {
    let mut positions = Vec::new();
    let mut colors = Vec::new();
    let mut all_have_color = true;
    let mut texcoords = Vec::new();
    let mut normals = Vec::new();
    let mut faces: Vec<[Corner; 3]> = Vec::new();
    let mut corners: Vec<Corner> = Vec::new();

    for (i, raw) in text.lines().enumerate() {
        let line_no = i + 1;
        let err = |m: String| MeshError::line(path, line_no, m);
        let line = raw.split('#').next().unwrap_or("");
        let mut words = line.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        let numbers = |words: std::str::SplitWhitespace| -> Result<Vec<f32>, MeshError> {
            words
                .map(|w| {
                    w.parse::<f32>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .ok_or_else(|| err(format!("`{w}` is not a finite number")))
                })
                .collect()
        };
        match keyword {
            "v" => {
                let v = numbers(words)?;
                if v.len() < 3 {
                    return Err(err(format!("`v` needs 3 coordinates, found {}", v.len())));
                }
                positions.push(Vec3::new(v[0], v[1], v[2]));
                if v.len() >= 6 {
                    colors.push(Vec3::new(v[3], v[4], v[5]));
                } else {
                    all_have_color = false;
                }
            }
            "vt" => {
                let v = numbers(words)?;
                if v.is_empty() {
                    return Err(err("`vt` needs at least 1 coordinate".into()));
                }
                texcoords.push(Vec2::new(v[0], v.get(1).copied().unwrap_or(0.0)));
            }
            "vn" => {
                let v = numbers(words)?;
                if v.len() < 3 {
                    return Err(err(format!("`vn` needs 3 components, found {}", v.len())));
                }
                normals.push(Vec3::new(v[0], v[1], v[2]));
            }
            "f" => {
                corners.clear();
                for word in words {
                    let mut parts = word.split('/');
                    let resolve = |part: Option<&str>, count: usize, what: &str| {
                        resolve_index(part, count)
                            .map_err(|m| err(format!("corner `{word}`: {what} {m}")))
                    };
                    let v = resolve(parts.next(), positions.len(), "position")?
                        .ok_or_else(|| err(format!("corner `{word}` has no position index")))?;
                    let t = resolve(parts.next(), texcoords.len(), "texcoord")?;
                    let n = resolve(parts.next(), normals.len(), "normal")?;
                    if parts.next().is_some() {
                        return Err(err(format!("corner `{word}` has more than 3 indices")));
                    }
                    corners.push((v, t, n));
                }
                if corners.len() < 3 {
                    return Err(err(format!(
                        "face has {} corners (at least 3 needed)",
                        corners.len()
                    )));
                }
                // Fan triangulation of a polygon (c0, c1, ..., ck).
                for k in 1..corners.len() - 1 {
                    faces.push([corners[0], corners[k], corners[k + 1]]);
                }
            }
            _ => {}
        }
    }

    let colors = (all_have_color && !positions.is_empty()).then_some(colors);
    let uses_tex = faces.iter().flatten().any(|c| c.1.is_some());
    let uses_normals = faces.iter().flatten().any(|c| c.2.is_some());
    if !uses_tex && !uses_normals {
        let triangles = faces.iter().map(|f| f.map(|c| c.0)).collect();
        return Ok(TriMesh {
            positions,
            triangles,
            normals: None,
            colors,
            uvs: None,
        });
    }

    // One vertex per distinct corner triple.
    let mut index_of: HashMap<Corner, u32> = HashMap::new();
    let mut mesh = TriMesh {
        normals: uses_normals.then(Vec::new),
        colors: colors.as_ref().map(|_| Vec::new()),
        uvs: uses_tex.then(Vec::new),
        ..TriMesh::default()
    };
    for face in &faces {
        let mut tri = [0u32; 3];
        for (slot, corner) in tri.iter_mut().zip(face) {
            *slot = *index_of.entry(*corner).or_insert_with(|| {
                let (v, t, n) = *corner;
                mesh.positions.push(positions[v as usize]);
                if let (Some(out), Some(c)) = (&mut mesh.colors, &colors) {
                    out.push(c[v as usize]);
                }
                if let Some(out) = &mut mesh.uvs {
                    out.push(t.map_or(Vec2::ZERO, |t| texcoords[t as usize]));
                }
                if let Some(out) = &mut mesh.normals {
                    out.push(n.map_or(Vec3::ZERO, |n| normals[n as usize]));
                }
                (mesh.positions.len() - 1) as u32
            });
        }
        mesh.triangles.push(tri);
    }
    Ok(mesh)
}

/// Turns a 1-based (or negative, relative) OBJ index into a 0-based one.
/// An empty or absent part means "no index".
fn resolve_index(part: Option<&str>, count: usize) -> Result<Option<u32>, String> {
    let Some(part) = part.filter(|p| !p.is_empty()) else {
        return Ok(None);
    };
    let i: i64 = part
        .parse()
        .map_err(|_| format!("index `{part}` is not an integer"))?;
    let resolved = if i > 0 { i - 1 } else { count as i64 + i };
    if i == 0 || resolved < 0 || resolved >= count as i64 {
        return Err(format!(
            "index {i} is out of range ({count} defined so far)"
        ));
    }
    Ok(Some(resolved as u32))
}

/// Writes `mesh` as OBJ, atomically. Colours, when present, are written as
/// the `v x y z r g b` extension.
pub fn write_obj(mesh: &TriMesh, path: &Path) -> Result<(), MeshError> {
    mesh.validate(path)?;
    write_io_atomically(path, |w| {
        writeln!(w, "# wildlight-mesh")?;
        for (i, p) in mesh.positions.iter().enumerate() {
            match &mesh.colors {
                Some(c) => {
                    let c = c[i];
                    writeln!(w, "v {} {} {} {} {} {}", p.x, p.y, p.z, c.x, c.y, c.z)?
                }
                None => writeln!(w, "v {} {} {}", p.x, p.y, p.z)?,
            }
        }
        if let Some(uvs) = &mesh.uvs {
            for t in uvs {
                writeln!(w, "vt {} {}", t.x, t.y)?;
            }
        }
        if let Some(normals) = &mesh.normals {
            for n in normals {
                writeln!(w, "vn {} {} {}", n.x, n.y, n.z)?;
            }
        }
        for tri in &mesh.triangles {
            let [a, b, c] = tri.map(|v| v + 1);
            match (mesh.uvs.is_some(), mesh.normals.is_some()) {
                (false, false) => writeln!(w, "f {a} {b} {c}")?,
                (true, false) => writeln!(w, "f {a}/{a} {b}/{b} {c}/{c}")?,
                (false, true) => writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?,
                (true, true) => writeln!(w, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}")?,
            }
        }
        Ok(())
    })?;
    Ok(())
}
