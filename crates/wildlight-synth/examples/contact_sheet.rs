//! Tiles the images of a capture (or any folder of EXR files) into one
//! sRGB PNG for a quick look: `cargo run --example contact_sheet -- DIR/image sheet.png [columns]`.

use std::path::PathBuf;

use wildlight_data::RgbImage;
use wildlight_data::exr_io::read_exr_rgb;
use wildlight_data::png_io::write_png_srgb;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    anyhow::ensure!(
        args.len() >= 3,
        "usage: contact_sheet FOLDER OUT.png [columns]"
    );
    let mut files: Vec<PathBuf> = std::fs::read_dir(&args[1])?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "exr"))
        .collect();
    files.sort();
    anyhow::ensure!(!files.is_empty(), "no .exr files in {}", args[1]);
    let cols: usize = args.get(3).map(|c| c.parse()).transpose()?.unwrap_or(8);
    let images: Vec<RgbImage> = files
        .iter()
        .map(|f| read_exr_rgb(f))
        .collect::<Result<_, _>>()?;
    let (w, h) = (images[0].width, images[0].height);
    let rows = images.len().div_ceil(cols);
    let mut sheet = RgbImage::new(w * cols as u32, h * rows as u32);
    for (i, img) in images.iter().enumerate() {
        let (ox, oy) = ((i % cols) as u32 * w, (i / cols) as u32 * h);
        for y in 0..h.min(img.height) {
            for x in 0..w.min(img.width) {
                sheet.set(ox + x, oy + y, img.get(x, y).map(|v| v.clamp(0.0, 1.0)));
            }
        }
    }
    write_png_srgb(std::path::Path::new(&args[2]), &sheet)?;
    Ok(())
}
