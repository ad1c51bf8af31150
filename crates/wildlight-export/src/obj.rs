//! OBJ + MTL + PNG export of a textured asset.
//!
//! The MTL uses the names WildLight users' tools read: `map_Kd` (base
//! colour, sRGB), and from the PBR extension of MTL `map_Pr` (roughness),
//! `map_Pm` (metallic), `map_Pc` (clearcoat) and `norm` (tangent-space
//! normal map). Blender's importer reads the normal map from `map_Bump`
//! instead, so the same file is also given there (`-bm 1`). Maps that MTL
//! has no keyword for (dielectric `specular.png` is also given as
//! `map_Ks`; `clearcoat_gloss.png`, `subsurface.png`) are written next to
//! it and listed in comments.

use std::fmt::Write as _;
use std::path::Path;

use wildlight_data::atomic::write_bytes_atomically;

use crate::ExportError;
use crate::gltf::Asset;
use crate::textures::{OBJ_MAPS, encode_png};

/// The MTL text referencing the [`OBJ_MAPS`] files.
pub fn mtl_text() -> String {
    [
        "# wildlight export: principled BRDF baked to textures (SPEC §9)",
        "# extra maps: clearcoat_gloss.png (clearcoat gloss g), subsurface.png (subsurface weight)",
        "newmtl wildlight",
        "Ka 0 0 0",
        "Kd 1 1 1",
        "Ks 1 1 1",
        "illum 2",
        "map_Kd base_color.png",
        "map_Ks specular.png",
        "Pr 1",
        "map_Pr roughness.png",
        "Pm 1",
        "map_Pm metallic.png",
        "Pc 1",
        "map_Pc clearcoat.png",
        "norm normal.png",
        "map_Bump -bm 1 normal.png",
        "",
    ]
    .join("\n")
}

/// The OBJ text of the mesh (`mtllib <mtl_name>`, v/vt/vn per vertex; vt is
/// written with v flipped, since OBJ's texture origin is the bottom left).
pub fn obj_text(asset: &Asset, mtl_name: &str) -> String {
    let m = &asset.mesh;
    let mut s = String::with_capacity(m.positions.len() * 100 + m.triangles.len() * 40);
    let _ = writeln!(s, "# wildlight export\nmtllib {mtl_name}\no wildlight");
    for p in &m.positions {
        let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
    }
    for uv in &m.uvs {
        let _ = writeln!(s, "vt {} {}", uv.x, 1.0 - uv.y);
    }
    for n in &m.normals {
        let _ = writeln!(s, "vn {} {} {}", n.x, n.y, n.z);
    }
    s.push_str("usemtl wildlight\n");
    for t in &m.triangles {
        let [a, b, c] = t.map(|v| v + 1);
        let _ = writeln!(s, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}");
    }
    s
}

/// Writes `dir/<stem>.obj`, `dir/<stem>.mtl` and the PNG maps, each atomically.
pub fn write_obj_bundle(asset: &Asset, dir: &Path, stem: &str) -> Result<(), ExportError> {
    let mtl_name = format!("{stem}.mtl");
    for (name, kind) in OBJ_MAPS {
        let png = encode_png(&asset.textures, kind)?;
        write_bytes_atomically(&dir.join(name), &png)?;
    }
    write_bytes_atomically(&dir.join(&mtl_name), mtl_text().as_bytes())?;
    write_bytes_atomically(
        &dir.join(format!("{stem}.obj")),
        obj_text(asset, &mtl_name).as_bytes(),
    )?;
    Ok(())
}
