//! Encoding baked textures as 8-bit PNG maps (and decoding them back).
//!
//! Maps written for the OBJ/MTL export (one file each, greyscale unless
//! noted): `base_color.png` (RGB, sRGB-encoded), `roughness.png`,
//! `metallic.png`, `specular.png` (the dielectric weight sp),
//! `clearcoat.png`, `clearcoat_gloss.png`, `subsurface.png` and
//! `normal.png` (RGB, tangent space, n·½ + ½, green = up in the image).
//!
//! Maps packed for glTF (SPEC §9), embedded in the `.glb`:
//! - base colour: RGB sRGB;
//! - metallicRoughness: R = subsurface (ignored by glTF; read back by
//!   wildlight), G = roughness, B = metallic;
//! - clearcoat: R = clearcoat (KHR_materials_clearcoat `clearcoatTexture`),
//!   G = clearcoat roughness √r_c with r_c = 0.1 − 0.099·g (appendix eq. 15;
//!   `clearcoatRoughnessTexture`), B = clearcoat gloss g (wildlight only);
//! - specular: RGB = white, A = sp (KHR_materials_specular `specularTexture`);
//! - normal: as `normal.png`.

use std::path::Path;

use glam::Vec3;
use image::ImageEncoder;
use wildlight_data::png_io::{linear_to_srgb, srgb_to_linear};
use wildlight_material::{
    BASE_COLOR, CLEARCOAT, CLEARCOAT_GLOSS, DIELECTRIC, METALLIC, ROUGHNESS, SUBSURFACE,
};

use crate::ExportError;
use crate::bake::{MaterialTextures, NORMAL, TEXEL_CHANNELS};

/// One 8-bit map to encode: a name (file stem) and how to fill a pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapKind {
    /// RGB sRGB base colour.
    BaseColor,
    /// Greyscale value of one material parameter (index into the 9).
    Scalar(usize),
    /// RGB tangent-space normal.
    Normal,
    /// glTF metallicRoughness pack (R subsurface, G roughness, B metallic).
    MetallicRoughness,
    /// glTF clearcoat pack (R clearcoat, G √r_c, B gloss).
    Clearcoat,
    /// glTF specular pack (RGBA, A = dielectric).
    Specular,
}

/// The OBJ maps: (file name, kind).
pub const OBJ_MAPS: [(&str, MapKind); 8] = [
    ("base_color.png", MapKind::BaseColor),
    ("roughness.png", MapKind::Scalar(ROUGHNESS)),
    ("metallic.png", MapKind::Scalar(METALLIC)),
    ("specular.png", MapKind::Scalar(DIELECTRIC)),
    ("clearcoat.png", MapKind::Scalar(CLEARCOAT)),
    ("clearcoat_gloss.png", MapKind::Scalar(CLEARCOAT_GLOSS)),
    ("subsurface.png", MapKind::Scalar(SUBSURFACE)),
    ("normal.png", MapKind::Normal),
];

/// Clearcoat roughness in glTF's convention: √r_c, with r_c = 0.1 − 0.099·g
/// the clearcoat alpha of appendix eq. 15 (SPEC §9).
pub fn clearcoat_roughness(gloss: f32) -> f32 {
    (0.1 - 0.099 * gloss).max(0.0).sqrt()
}

/// Quantizes a value in [0, 1] to 8 bits.
pub fn to_u8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

fn channels(kind: MapKind) -> usize {
    match kind {
        MapKind::Scalar(_) => 1,
        MapKind::Specular => 4,
        _ => 3,
    }
}

fn pixel(kind: MapKind, t: &[f32; TEXEL_CHANNELS], out: &mut [u8]) {
    match kind {
        MapKind::BaseColor => {
            for c in 0..3 {
                out[c] = to_u8(linear_to_srgb(t[BASE_COLOR + c].clamp(0.0, 1.0)));
            }
        }
        MapKind::Scalar(i) => out[0] = to_u8(t[i]),
        MapKind::Normal => {
            for c in 0..3 {
                out[c] = to_u8(t[NORMAL + c] * 0.5 + 0.5);
            }
        }
        MapKind::MetallicRoughness => {
            out[0] = to_u8(t[SUBSURFACE]);
            out[1] = to_u8(t[ROUGHNESS]);
            out[2] = to_u8(t[METALLIC]);
        }
        MapKind::Clearcoat => {
            out[0] = to_u8(t[CLEARCOAT]);
            out[1] = to_u8(clearcoat_roughness(t[CLEARCOAT_GLOSS]));
            out[2] = to_u8(t[CLEARCOAT_GLOSS]);
        }
        MapKind::Specular => {
            out[..3].fill(255);
            out[3] = to_u8(t[DIELECTRIC]);
        }
    }
}

/// Encodes one map of `textures` as PNG bytes.
pub fn encode_png(textures: &MaterialTextures, kind: MapKind) -> Result<Vec<u8>, ExportError> {
    let c = channels(kind);
    let mut raw = vec![0u8; textures.texels.len() * c];
    for (t, out) in textures.texels.iter().zip(raw.chunks_exact_mut(c)) {
        pixel(kind, t, out);
    }
    let color = match c {
        1 => image::ExtendedColorType::L8,
        3 => image::ExtendedColorType::Rgb8,
        _ => image::ExtendedColorType::Rgba8,
    };
    let mut bytes = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut bytes,
        image::codecs::png::CompressionType::Fast,
        image::codecs::png::FilterType::Adaptive,
    )
    .write_image(&raw, textures.width, textures.height, color)
    .map_err(|e| ExportError::Image {
        path: format!("<{kind:?} map>").into(),
        message: e.to_string(),
    })?;
    Ok(bytes)
}

/// A decoded 8-bit image: width, height and RGBA pixels.
pub(crate) struct Rgba8 {
    pub width: u32,
    pub height: u32,
    pub data: Vec<u8>,
}

/// Decodes PNG bytes to RGBA8; `what` names the image in errors.
pub(crate) fn decode_png(bytes: &[u8], what: &Path) -> Result<Rgba8, ExportError> {
    let img = image::load_from_memory_with_format(bytes, image::ImageFormat::Png).map_err(|e| {
        ExportError::Image {
            path: what.to_path_buf(),
            message: e.to_string(),
        }
    })?;
    let rgba = img.to_rgba8();
    Ok(Rgba8 {
        width: rgba.width(),
        height: rgba.height(),
        data: rgba.into_raw(),
    })
}

/// Rebuilds linear texel values from the glTF packs (base colour,
/// metallicRoughness, clearcoat, specular, normal), all the same size.
pub(crate) fn texels_from_gltf_maps(
    maps: [&Rgba8; 5],
    what: &Path,
) -> Result<MaterialTextures, ExportError> {
    let [base, mr, cc, spec, normal] = maps;
    for m in &maps[1..] {
        if (m.width, m.height) != (base.width, base.height) {
            return Err(ExportError::bad_asset(
                what,
                format!(
                    "texture sizes differ ({}x{} vs {}x{})",
                    m.width, m.height, base.width, base.height
                ),
            ));
        }
    }
    let n = (base.width * base.height) as usize;
    let f = |v: u8| v as f32 / 255.0;
    let texels = (0..n)
        .map(|i| {
            let px = |m: &Rgba8, c: usize| m.data[i * 4 + c];
            let mut t = [0.0f32; TEXEL_CHANNELS];
            for c in 0..3 {
                t[BASE_COLOR + c] = srgb_to_linear(f(px(base, c)));
            }
            t[SUBSURFACE] = f(px(mr, 0));
            t[ROUGHNESS] = f(px(mr, 1));
            t[METALLIC] = f(px(mr, 2));
            t[CLEARCOAT] = f(px(cc, 0));
            t[CLEARCOAT_GLOSS] = f(px(cc, 2));
            t[DIELECTRIC] = f(px(spec, 3));
            let nrm = Vec3::new(
                f(px(normal, 0)) * 2.0 - 1.0,
                f(px(normal, 1)) * 2.0 - 1.0,
                f(px(normal, 2)) * 2.0 - 1.0,
            )
            .normalize_or(Vec3::Z);
            t[NORMAL..].copy_from_slice(&nrm.to_array());
            t
        })
        .collect();
    Ok(MaterialTextures {
        width: base.width,
        height: base.height,
        texels,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use wildlight_material::PARAM_COUNT;

    #[test]
    fn gltf_packs_round_trip_within_quantization() {
        let texel = |i: usize| {
            let mut t = [0.0f32; TEXEL_CHANNELS];
            for (k, v) in t.iter_mut().take(PARAM_COUNT).enumerate() {
                *v = ((i * 7 + k * 13) % 97) as f32 / 96.0;
            }
            let n = Vec3::new(0.3, -0.2 + i as f32 * 0.01, 0.9).normalize();
            t[NORMAL..].copy_from_slice(&n.to_array());
            t
        };
        let tex = MaterialTextures {
            width: 4,
            height: 3,
            texels: (0..12).map(texel).collect(),
        };
        let kinds = [
            MapKind::BaseColor,
            MapKind::MetallicRoughness,
            MapKind::Clearcoat,
            MapKind::Specular,
            MapKind::Normal,
        ];
        let decoded: Vec<Rgba8> = kinds
            .iter()
            .map(|k| decode_png(&encode_png(&tex, *k).unwrap(), Path::new("x")).unwrap())
            .collect();
        let back = texels_from_gltf_maps(
            [
                &decoded[0],
                &decoded[1],
                &decoded[2],
                &decoded[3],
                &decoded[4],
            ],
            Path::new("x"),
        )
        .unwrap();
        for (a, b) in tex.texels.iter().zip(&back.texels) {
            for k in 0..TEXEL_CHANNELS {
                // sRGB 8-bit steps are at most ~0.013 in linear near 1.
                let tol = if k < 3 { 0.01 } else { 0.5 / 255.0 + 1e-3 }
                    + if k >= NORMAL { 0.01 } else { 0.0 };
                assert!(
                    (a[k] - b[k]).abs() <= tol,
                    "channel {k}: {} vs {}",
                    a[k],
                    b[k]
                );
            }
        }
        // The glTF clearcoat roughness channel holds √(0.1 − 0.099 g).
        let g = tex.texels[5][CLEARCOAT_GLOSS];
        let expect = to_u8(clearcoat_roughness(g));
        assert_eq!(decoded[2].data[5 * 4 + 1], expect);
        assert!((clearcoat_roughness(1.0) - 0.001f32.sqrt()).abs() < 1e-6);
    }
}
