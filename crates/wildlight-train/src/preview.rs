//! Preview images written while training: for one view, side by side, the
//! photo, the rendering, the normals, the base colour, the flash-only and
//! the ambient-only images.

use anyhow::Context;
use std::path::Path;
use wildlight_data::View;
use wildlight_data::ViewMaps;

/// Linear → sRGB-encoded 8-bit, clamped.
pub fn srgb8(v: f32) -> u8 {
    let v = v.clamp(0.0, 1.0);
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// Composes the preview strip of `maps` next to the photo of `view`, and
/// writes it as PNG atomically.
pub fn write_preview(path: &Path, view: &View, maps: &ViewMaps) -> anyhow::Result<()> {
    let (w, h) = (maps.width, maps.height);
    let panels = 6u32;
    let mut img = image::RgbImage::new(w * panels, h);
    let (sx, sy) = (
        view.image.width as f32 / w as f32,
        view.image.height as f32 / h as f32,
    );
    for y in 0..h {
        for x in 0..w {
            let p = (y * w + x) as usize;
            let px = ((x as f32 + 0.5) * sx) as u32;
            let py = ((y as f32 + 0.5) * sy) as u32;
            let photo = view
                .image
                .get(px.min(view.image.width - 1), py.min(view.image.height - 1));
            let n = maps.normal[p];
            let normal = if n == [0.0; 3] {
                [0.0; 3]
            } else {
                [n[0] * 0.5 + 0.5, n[1] * 0.5 + 0.5, n[2] * 0.5 + 0.5]
            };
            let th = maps.params[p];
            let panels_rgb = [
                photo,
                maps.rgb[p],
                normal.map(|v| v * v), // shown linearly after sRGB encoding
                [th[0], th[1], th[2]],
                maps.flash[p],
                maps.ambient[p],
            ];
            for (i, c) in panels_rgb.iter().enumerate() {
                img.put_pixel(
                    i as u32 * w + x,
                    y,
                    image::Rgb([srgb8(c[0]), srgb8(c[1]), srgb8(c[2])]),
                );
            }
        }
    }
    let tmp = path.with_extension("png.tmp");
    img.save_with_format(&tmp, image::ImageFormat::Png)
        .with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path)
        .with_context(|| format!("cannot move {} to {}", tmp.display(), path.display()))
}
