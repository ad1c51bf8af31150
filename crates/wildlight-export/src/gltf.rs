//! glTF 2.0 binary (.glb) writing and reading of a textured asset.
//!
//! The writer builds the JSON document, checks that `gltf-json` parses it
//! into its typed document model, and packs it with one binary buffer
//! holding the vertex data and the PNG maps (see [`crate::textures`] for
//! the channel layout, SPEC §9 for the material mapping). The reader
//! understands what the writer produces (one mesh, one primitive, one
//! material, embedded PNG images) and nothing more.

use std::path::Path;

use glam::{Vec2, Vec3, Vec4};
use serde_json::{Value, json};
use wildlight_data::atomic::write_bytes_atomically;

use crate::ExportError;
use crate::atlas::TexturedMesh;
use crate::bake::MaterialTextures;
use crate::textures::{MapKind, decode_png, encode_png, texels_from_gltf_maps};

/// A textured asset: mesh and linear texel values of all maps.
#[derive(Clone, Debug, PartialEq)]
pub struct Asset {
    /// The mesh (its own frame: world units by default).
    pub mesh: TexturedMesh,
    /// The maps.
    pub textures: MaterialTextures,
    /// The frame of the mesh's vertices, recorded in the .glb's
    /// `asset.extras.wildlight.frame` (None: not recorded).
    pub frame: Option<AssetFrame>,
}

/// The frame an asset's vertices are in (SPEC §5, §9).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AssetFrame {
    /// World units: x_world = scale_mat · x_normalized (the default export).
    World,
    /// The normalized frame (object inside the unit sphere).
    Normalized,
}

impl AssetFrame {
    /// The name written to the .glb.
    pub fn name(self) -> &'static str {
        match self {
            AssetFrame::World => "world",
            AssetFrame::Normalized => "normalized",
        }
    }
}

const GLB_MAGIC: u32 = 0x4654_6C67; // "glTF"
const CHUNK_JSON: u32 = 0x4E4F_534A; // "JSON"
const CHUNK_BIN: u32 = 0x004E_4942; // "BIN\0"

/// The maps embedded in the .glb, in texture-index order.
const GLTF_MAPS: [MapKind; 5] = [
    MapKind::BaseColor,
    MapKind::MetallicRoughness,
    MapKind::Clearcoat,
    MapKind::Specular,
    MapKind::Normal,
];

struct BinBuilder {
    bin: Vec<u8>,
    views: Vec<Value>,
}

impl BinBuilder {
    fn push(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut view = json!({
            "buffer": 0,
            "byteOffset": self.bin.len(),
            "byteLength": bytes.len(),
        });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(view);
        self.views.len() - 1
    }
}

fn f32_bytes(values: impl IntoIterator<Item = f32>) -> Vec<u8> {
    values.into_iter().flat_map(f32::to_le_bytes).collect()
}

/// Encodes `asset` as a .glb file's bytes.
pub fn encode_glb(asset: &Asset) -> Result<Vec<u8>, ExportError> {
    let mesh = &asset.mesh;
    let n = mesh.positions.len();
    const ARRAY_BUFFER: u32 = 34962;
    const ELEMENT_ARRAY_BUFFER: u32 = 34963;
    const FLOAT: u32 = 5126;
    const UNSIGNED_INT: u32 = 5125;
    let mut b = BinBuilder {
        bin: Vec::new(),
        views: Vec::new(),
    };
    let pos_view = b.push(
        &f32_bytes(mesh.positions.iter().flat_map(|p| p.to_array())),
        Some(ARRAY_BUFFER),
    );
    let nrm_view = b.push(
        &f32_bytes(mesh.normals.iter().flat_map(|p| p.to_array())),
        Some(ARRAY_BUFFER),
    );
    let tan_view = b.push(
        &f32_bytes(mesh.tangents.iter().flat_map(|p| p.to_array())),
        Some(ARRAY_BUFFER),
    );
    let uv_view = b.push(
        &f32_bytes(mesh.uvs.iter().flat_map(|p| p.to_array())),
        Some(ARRAY_BUFFER),
    );
    let idx: Vec<u8> = mesh
        .triangles
        .iter()
        .flatten()
        .flat_map(|i| i.to_le_bytes())
        .collect();
    let idx_view = b.push(&idx, Some(ELEMENT_ARRAY_BUFFER));
    let mut images = Vec::new();
    for kind in GLTF_MAPS {
        let png = encode_png(&asset.textures, kind)?;
        let view = b.push(&png, None);
        images.push(json!({"bufferView": view, "mimeType": "image/png"}));
    }
    let (lo, hi) = mesh.positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let accessor = |view: usize, ty: &str, count: usize, ctype: u32| json!({"bufferView": view, "componentType": ctype, "count": count, "type": ty});
    let mut position_accessor = accessor(pos_view, "VEC3", n, FLOAT);
    position_accessor["min"] = json!(lo.to_array());
    position_accessor["max"] = json!(hi.to_array());
    let tex = |i: usize| json!({"index": i});
    let mut asset_info = json!({"version": "2.0", "generator": "wildlight export"});
    if let Some(frame) = asset.frame {
        asset_info["extras"] = json!({"wildlight": {"frame": frame.name()}});
    }
    let doc = json!({
        "asset": asset_info,
        "extensionsUsed": ["KHR_materials_clearcoat", "KHR_materials_specular"],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "wildlight"}],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1, "TANGENT": 2, "TEXCOORD_0": 3},
            "indices": 4,
            "material": 0,
            "mode": 4
        }]}],
        "accessors": [
            position_accessor,
            accessor(nrm_view, "VEC3", n, FLOAT),
            accessor(tan_view, "VEC4", n, FLOAT),
            accessor(uv_view, "VEC2", n, FLOAT),
            accessor(idx_view, "SCALAR", mesh.triangles.len() * 3, UNSIGNED_INT),
        ],
        "materials": [{
            "name": "wildlight",
            "pbrMetallicRoughness": {
                "baseColorTexture": tex(0),
                "metallicRoughnessTexture": tex(1),
                "metallicFactor": 1.0,
                "roughnessFactor": 1.0
            },
            "normalTexture": tex(4),
            "extensions": {
                // SPEC §9: clearcoat factor, clearcoat roughness ≈ √r_c.
                "KHR_materials_clearcoat": {
                    "clearcoatFactor": 1.0,
                    "clearcoatTexture": tex(2),
                    "clearcoatRoughnessFactor": 1.0,
                    "clearcoatRoughnessTexture": tex(2)
                },
                // SPEC §9: F0 = 0.08·sp = 0.04 (glTF default) × 2 × sp.
                "KHR_materials_specular": {
                    "specularFactor": 1.0,
                    "specularTexture": tex(3),
                    "specularColorFactor": [2.0, 2.0, 2.0]
                }
            }
        }],
        "samplers": [{"magFilter": 9729, "minFilter": 9987, "wrapS": 33071, "wrapT": 33071}],
        "textures": (0..GLTF_MAPS.len()).map(|i| json!({"sampler": 0, "source": i})).collect::<Vec<_>>(),
        "images": images,
        "bufferViews": b.views,
        "buffers": [{"byteLength": b.bin.len()}],
    });
    // Type check with gltf-json's document model, then serialize it.
    let root: gltf_json::Root = serde_json::from_value(doc)
        .map_err(|e| ExportError::stage("glTF", format!("document does not parse: {e}")))?;
    let mut json_bytes = root
        .to_vec()
        .map_err(|e| ExportError::stage("glTF", e.to_string()))?;
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let mut bin = b.bin;
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(&GLB_MAGIC.to_le_bytes());
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_JSON.to_le_bytes());
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(&CHUNK_BIN.to_le_bytes());
    out.extend_from_slice(&bin);
    Ok(out)
}

/// Writes `asset` to `path` as a .glb, atomically.
pub fn write_glb(asset: &Asset, path: &Path) -> Result<(), ExportError> {
    let bytes = encode_glb(asset)?;
    write_bytes_atomically(path, &bytes)?;
    Ok(())
}

fn u32_at(bytes: &[u8], offset: usize) -> Option<u32> {
    bytes
        .get(offset..offset + 4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Reads a .glb written by [`write_glb`].
pub fn read_glb(path: &Path) -> Result<Asset, ExportError> {
    let bytes = std::fs::read(path).map_err(|e| ExportError::io(path, e))?;
    parse_glb(&bytes, path)
}

/// Parses .glb bytes; `path` names the file in errors.
pub fn parse_glb(bytes: &[u8], path: &Path) -> Result<Asset, ExportError> {
    let bad = |m: &str| ExportError::bad_asset(path, m);
    if u32_at(bytes, 0) != Some(GLB_MAGIC) {
        return Err(bad("not a binary glTF file (bad magic)"));
    }
    if u32_at(bytes, 4) != Some(2) {
        return Err(bad("unsupported glTF container version (expected 2)"));
    }
    let json_len = u32_at(bytes, 12).ok_or_else(|| bad("truncated header"))? as usize;
    if u32_at(bytes, 16) != Some(CHUNK_JSON) {
        return Err(bad("first chunk is not JSON"));
    }
    let json_bytes = bytes
        .get(20..20 + json_len)
        .ok_or_else(|| bad("truncated JSON chunk"))?;
    let bin_start = 20 + json_len;
    let bin_len = u32_at(bytes, bin_start).ok_or_else(|| bad("missing BIN chunk"))? as usize;
    if u32_at(bytes, bin_start + 4) != Some(CHUNK_BIN) {
        return Err(bad("second chunk is not BIN"));
    }
    let bin = bytes
        .get(bin_start + 8..bin_start + 8 + bin_len)
        .ok_or_else(|| bad("truncated BIN chunk"))?;
    gltf_json::Root::from_slice(json_bytes).map_err(|e| bad(&format!("invalid glTF JSON: {e}")))?;
    let doc: Value =
        serde_json::from_slice(json_bytes).map_err(|e| bad(&format!("invalid JSON: {e}")))?;

    let view_bytes = |view: &Value| -> Result<&[u8], ExportError> {
        let v =
            &doc["bufferViews"][view.as_u64().ok_or_else(|| bad("missing bufferView"))? as usize];
        let off = v["byteOffset"].as_u64().unwrap_or(0) as usize;
        let len = v["byteLength"]
            .as_u64()
            .ok_or_else(|| bad("bufferView without byteLength"))? as usize;
        if v.get("byteStride").is_some() {
            return Err(bad("interleaved buffer views are not supported"));
        }
        bin.get(off..off + len)
            .ok_or_else(|| bad("bufferView outside the buffer"))
    };
    let floats = |accessor: &Value, width: usize| -> Result<Vec<f32>, ExportError> {
        let a =
            &doc["accessors"][accessor.as_u64().ok_or_else(|| bad("missing accessor"))? as usize];
        if a["componentType"].as_u64() != Some(5126) {
            return Err(bad("vertex attribute is not float"));
        }
        let count = a["count"]
            .as_u64()
            .ok_or_else(|| bad("accessor without count"))? as usize;
        let data = view_bytes(&a["bufferView"])?;
        let off = a["byteOffset"].as_u64().unwrap_or(0) as usize;
        let data = data
            .get(off..off + count * width * 4)
            .ok_or_else(|| bad("accessor outside its bufferView"))?;
        Ok(data
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect())
    };
    let prim = &doc["meshes"][0]["primitives"][0];
    let attrs = &prim["attributes"];
    let positions: Vec<Vec3> = floats(&attrs["POSITION"], 3)?
        .chunks_exact(3)
        .map(Vec3::from_slice)
        .collect();
    let normals: Vec<Vec3> = floats(&attrs["NORMAL"], 3)?
        .chunks_exact(3)
        .map(Vec3::from_slice)
        .collect();
    let tangents: Vec<Vec4> = floats(&attrs["TANGENT"], 4)?
        .chunks_exact(4)
        .map(Vec4::from_slice)
        .collect();
    let uvs: Vec<Vec2> = floats(&attrs["TEXCOORD_0"], 2)?
        .chunks_exact(2)
        .map(Vec2::from_slice)
        .collect();
    let ia = &doc["accessors"][prim["indices"]
        .as_u64()
        .ok_or_else(|| bad("primitive without indices"))? as usize];
    let count = ia["count"]
        .as_u64()
        .ok_or_else(|| bad("index accessor without count"))? as usize;
    let data = view_bytes(&ia["bufferView"])?;
    let off = ia["byteOffset"].as_u64().unwrap_or(0) as usize;
    let indices: Vec<u32> = match ia["componentType"].as_u64() {
        Some(5125) => data
            .get(off..off + count * 4)
            .ok_or_else(|| bad("indices outside their bufferView"))?
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect(),
        Some(5123) => data
            .get(off..off + count * 2)
            .ok_or_else(|| bad("indices outside their bufferView"))?
            .chunks_exact(2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]) as u32)
            .collect(),
        _ => return Err(bad("unsupported index type")),
    };
    let n = positions.len();
    if normals.len() != n || tangents.len() != n || uvs.len() != n {
        return Err(bad("vertex attributes have different counts"));
    }
    if indices.iter().any(|&i| i as usize >= n) || !indices.len().is_multiple_of(3) {
        return Err(bad("index out of range or not a triangle list"));
    }
    let mat = &doc["materials"][prim["material"].as_u64().unwrap_or(0) as usize];
    let texture_image = |info: &Value| -> Result<crate::textures::Rgba8, ExportError> {
        let t = info["index"]
            .as_u64()
            .ok_or_else(|| bad("material texture without index"))? as usize;
        let src = doc["textures"][t]["source"]
            .as_u64()
            .ok_or_else(|| bad("texture without source"))? as usize;
        let png = view_bytes(&doc["images"][src]["bufferView"])?;
        decode_png(png, &path.join(format!("image {src}")))
    };
    let ext = &mat["extensions"];
    let maps = [
        texture_image(&mat["pbrMetallicRoughness"]["baseColorTexture"])?,
        texture_image(&mat["pbrMetallicRoughness"]["metallicRoughnessTexture"])?,
        texture_image(&ext["KHR_materials_clearcoat"]["clearcoatTexture"])?,
        texture_image(&ext["KHR_materials_specular"]["specularTexture"])?,
        texture_image(&mat["normalTexture"])?,
    ];
    let textures = texels_from_gltf_maps([&maps[0], &maps[1], &maps[2], &maps[3], &maps[4]], path)?;
    Ok(Asset {
        mesh: TexturedMesh {
            positions,
            normals,
            tangents,
            uvs,
            triangles: indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect(),
        },
        textures,
        frame: match doc["asset"]["extras"]["wildlight"]["frame"].as_str() {
            Some("world") => Some(AssetFrame::World),
            Some("normalized") => Some(AssetFrame::Normalized),
            _ => None,
        },
    })
}
