//! Quick-look PNGs without another tool: a small line-plot rasteriser (BRDF
//! lobes, training curves: axes, a grid, tick labels and anti-aliasing-free
//! polylines) and a labelled grid of image tiles (the demo's preview).
//! Text uses a built-in 3×5 pixel font (digits, capital letters and a few
//! symbols). Nothing here is precise typography. PNGs are written
//! atomically (temporary file, then rename).

use anyhow::Context;
use std::path::Path;

/// One curve: points in data coordinates and an RGB colour.
pub struct Series {
    /// (x, y) samples, drawn as a polyline in order.
    pub points: Vec<(f64, f64)>,
    /// Line colour.
    pub color: [u8; 3],
    /// Draw every other segment only (to tell overlaid curves apart).
    pub dashed: bool,
}

/// A plot: ranges, axis scaling and curves.
pub struct Plot {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// x range shown.
    pub x_range: (f64, f64),
    /// y range shown (positive when `log_y`).
    pub y_range: (f64, f64),
    /// Base-10 logarithmic y axis.
    pub log_y: bool,
    /// Distance between x grid lines in data units.
    pub x_tick: f64,
    /// The curves.
    pub series: Vec<Series>,
}

const MARGIN_LEFT: i64 = 44;
const MARGIN_BOTTOM: i64 = 20;
const MARGIN: i64 = 10;

/// Digits, capital letters and a few symbols, 3×5 pixels, row-major bits
/// (0b100 is the left column). `None` draws nothing (a space).
fn glyph(ch: char) -> Option<[u8; 5]> {
    Some(match ch {
        'A' => [0b010, 0b101, 0b111, 0b101, 0b101],
        'B' => [0b110, 0b101, 0b110, 0b101, 0b110],
        'C' => [0b011, 0b100, 0b100, 0b100, 0b011],
        'D' => [0b110, 0b101, 0b101, 0b101, 0b110],
        'E' => [0b111, 0b100, 0b110, 0b100, 0b111],
        'F' => [0b111, 0b100, 0b110, 0b100, 0b100],
        'G' => [0b011, 0b100, 0b101, 0b101, 0b011],
        'H' => [0b101, 0b101, 0b111, 0b101, 0b101],
        'I' => [0b111, 0b010, 0b010, 0b010, 0b111],
        'J' => [0b001, 0b001, 0b001, 0b101, 0b010],
        'K' => [0b101, 0b101, 0b110, 0b101, 0b101],
        'L' => [0b100, 0b100, 0b100, 0b100, 0b111],
        'M' => [0b101, 0b111, 0b111, 0b101, 0b101],
        'N' => [0b110, 0b101, 0b101, 0b101, 0b101],
        'O' => [0b010, 0b101, 0b101, 0b101, 0b010],
        'P' => [0b110, 0b101, 0b110, 0b100, 0b100],
        'Q' => [0b010, 0b101, 0b101, 0b110, 0b011],
        'R' => [0b110, 0b101, 0b110, 0b101, 0b101],
        'S' => [0b011, 0b100, 0b010, 0b001, 0b110],
        'T' => [0b111, 0b010, 0b010, 0b010, 0b010],
        'U' => [0b101, 0b101, 0b101, 0b101, 0b111],
        'V' => [0b101, 0b101, 0b101, 0b101, 0b010],
        'W' => [0b101, 0b101, 0b111, 0b111, 0b101],
        'X' => [0b101, 0b101, 0b010, 0b101, 0b101],
        'Y' => [0b101, 0b101, 0b010, 0b010, 0b010],
        'Z' => [0b111, 0b001, 0b010, 0b100, 0b111],
        '/' => [0b001, 0b001, 0b010, 0b100, 0b100],
        ':' => [0b000, 0b010, 0b000, 0b010, 0b000],
        '0' => [0b111, 0b101, 0b101, 0b101, 0b111],
        '1' => [0b010, 0b110, 0b010, 0b010, 0b111],
        '2' => [0b111, 0b001, 0b111, 0b100, 0b111],
        '3' => [0b111, 0b001, 0b111, 0b001, 0b111],
        '4' => [0b101, 0b101, 0b111, 0b001, 0b001],
        '5' => [0b111, 0b100, 0b111, 0b001, 0b111],
        '6' => [0b111, 0b100, 0b111, 0b101, 0b111],
        '7' => [0b111, 0b001, 0b010, 0b010, 0b010],
        '8' => [0b111, 0b101, 0b111, 0b101, 0b111],
        '9' => [0b111, 0b101, 0b111, 0b001, 0b111],
        '.' => [0b000, 0b000, 0b000, 0b000, 0b010],
        '-' => [0b000, 0b000, 0b111, 0b000, 0b000],
        'e' => [0b000, 0b111, 0b111, 0b100, 0b111],
        _ => return None,
    })
}

struct Canvas {
    img: image::RgbImage,
}

impl Canvas {
    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as u32) < self.img.width() && (y as u32) < self.img.height() {
            self.img.put_pixel(x as u32, y as u32, image::Rgb(c));
        }
    }

    fn line(&mut self, (x0, y0): (f64, f64), (x1, y1): (f64, f64), c: [u8; 3]) {
        let steps = ((x1 - x0).abs().max((y1 - y0).abs()).ceil() as i64).max(1);
        for s in 0..=steps {
            let t = s as f64 / steps as f64;
            let x = x0 + (x1 - x0) * t;
            let y = y0 + (y1 - y0) * t;
            // two pixels thick for visibility
            self.put(x.round() as i64, y.round() as i64, c);
            self.put(x.round() as i64, y.round() as i64 + 1, c);
        }
    }

    fn text(&mut self, x: i64, y: i64, s: &str, c: [u8; 3]) {
        self.text_scaled(x, y, s, 1, c);
    }

    /// Draws `s` with its top-left corner at (x, y), each font pixel a
    /// `scale`×`scale` block; characters advance by 4·`scale` pixels.
    fn text_scaled(&mut self, x: i64, y: i64, s: &str, scale: i64, c: [u8; 3]) {
        for (i, ch) in s.chars().enumerate() {
            let Some(rows) = glyph(ch) else { continue };
            for (r, bits) in rows.iter().enumerate() {
                for col in 0..3 {
                    if bits & (0b100 >> col) == 0 {
                        continue;
                    }
                    let px = x + (i as i64 * 4 + col) * scale;
                    let py = y + r as i64 * scale;
                    for dy in 0..scale {
                        for dx in 0..scale {
                            self.put(px + dx, py + dy, c);
                        }
                    }
                }
            }
        }
    }
}

/// Encodes `img` as PNG and writes it atomically (`name.tmp`, then rename).
pub fn write_png_atomically(path: &Path, img: &image::RgbImage) -> anyhow::Result<()> {
    use image::ImageEncoder;
    let mut encoded = Vec::new();
    image::codecs::png::PngEncoder::new(&mut encoded)
        .write_image(
            img.as_raw(),
            img.width(),
            img.height(),
            image::ExtendedColorType::Rgb8,
        )
        .with_context(|| format!("cannot encode {} as PNG", path.display()))?;
    wildlight_data::atomic::write_bytes_atomically(path, &encoded)
        .with_context(|| format!("cannot write {}", path.display()))
}

/// A labelled grid of equally sized image tiles: a label column on the
/// left (one label per row), a header band on top (one label per column),
/// and a gap after every tile. Fixed layout, in pixels:
/// width = [`ImageGrid::LABEL_WIDTH`] + columns · (tile width + [`ImageGrid::GAP`]),
/// height = [`ImageGrid::HEADER_HEIGHT`] + rows · (tile height + [`ImageGrid::GAP`]).
pub struct ImageGrid {
    /// Width of every tile in pixels.
    pub tile_width: u32,
    /// Height of every tile in pixels.
    pub tile_height: u32,
    /// One label per column (capital letters, digits, space, `/`, `:`, `.`, `-`).
    pub column_labels: Vec<String>,
    /// One label per row (same characters).
    pub row_labels: Vec<String>,
    /// `tiles[row][column]`, each `tile_width`×`tile_height`; `None` is
    /// drawn as a light grey tile with a diagonal cross (nothing to show).
    pub tiles: Vec<Vec<Option<image::RgbImage>>>,
}

impl ImageGrid {
    /// Width of the row-label column in pixels (11 characters at text scale 2).
    pub const LABEL_WIDTH: u32 = 96;
    /// Height of the column-label band in pixels.
    pub const HEADER_HEIGHT: u32 = 18;
    /// Space after every tile, to the right and below, in pixels.
    pub const GAP: u32 = 4;
    /// Font pixels are drawn as blocks of this many pixels.
    const TEXT_SCALE: i64 = 2;

    /// The (width, height) of the whole image.
    pub fn dimensions(&self) -> (u32, u32) {
        let cols = self.column_labels.len() as u32;
        let rows = self.row_labels.len() as u32;
        (
            Self::LABEL_WIDTH + cols * (self.tile_width + Self::GAP),
            Self::HEADER_HEIGHT + rows * (self.tile_height + Self::GAP),
        )
    }

    /// The top-left pixel of tile (row, column).
    pub fn tile_origin(&self, row: usize, column: usize) -> (u32, u32) {
        (
            Self::LABEL_WIDTH + column as u32 * (self.tile_width + Self::GAP),
            Self::HEADER_HEIGHT + row as u32 * (self.tile_height + Self::GAP),
        )
    }

    /// Draws the grid. Tiles of the wrong size are an error.
    pub fn to_image(&self) -> anyhow::Result<image::RgbImage> {
        let (width, height) = self.dimensions();
        let mut canvas = Canvas {
            img: image::RgbImage::from_pixel(width, height, image::Rgb([255, 255, 255])),
        };
        let ink = [40, 40, 40];
        let s = Self::TEXT_SCALE;
        for (c, label) in self.column_labels.iter().enumerate() {
            let (x, _) = self.tile_origin(0, c);
            canvas.text_scaled(x as i64, 4, label, s, ink);
        }
        for (r, label) in self.row_labels.iter().enumerate() {
            let (_, y) = self.tile_origin(r, 0);
            let y = y as i64 + self.tile_height as i64 / 2 - 5 * s / 2;
            canvas.text_scaled(4, y, label, s, ink);
        }
        for (r, row) in self.tiles.iter().enumerate().take(self.row_labels.len()) {
            for (c, tile) in row.iter().enumerate().take(self.column_labels.len()) {
                let (x0, y0) = self.tile_origin(r, c);
                match tile {
                    Some(t) => {
                        if t.dimensions() != (self.tile_width, self.tile_height) {
                            anyhow::bail!(
                                "preview tile ({r}, {c}) is {}×{}, expected {}×{}",
                                t.width(),
                                t.height(),
                                self.tile_width,
                                self.tile_height
                            );
                        }
                        image::imageops::replace(&mut canvas.img, t, x0 as i64, y0 as i64);
                    }
                    None => {
                        let (w, h) = (self.tile_width as i64, self.tile_height as i64);
                        for y in 0..h {
                            for x in 0..w {
                                canvas.put(x0 as i64 + x, y0 as i64 + y, [220, 220, 220]);
                            }
                        }
                        let (x0, y0) = (x0 as f64, y0 as f64);
                        let (x1, y1) = (x0 + (w - 1) as f64, y0 + (h - 2) as f64);
                        canvas.line((x0, y0), (x1, y1), [170, 170, 170]);
                        canvas.line((x0, y1), (x1, y0), [170, 170, 170]);
                    }
                }
            }
        }
        Ok(canvas.img)
    }

    /// Draws the grid and writes it as a PNG, atomically.
    pub fn write_png(&self, path: &Path) -> anyhow::Result<()> {
        write_png_atomically(path, &self.to_image()?)
    }
}

fn label(v: f64) -> String {
    if v != 0.0 && (v.abs() >= 1e4 || v.abs() < 1e-2) {
        format!("{v:.0e}")
    } else if v.fract() == 0.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
    }
}

impl Plot {
    /// Renders the plot and writes it as a PNG (atomically: temp file, then rename).
    pub fn write_png(&self, path: &Path) -> anyhow::Result<()> {
        let mut canvas = Canvas {
            img: image::RgbImage::from_pixel(self.width, self.height, image::Rgb([255, 255, 255])),
        };
        let (x0, x1) = self.x_range;
        let map_y = |y: f64| if self.log_y { y.max(1e-300).log10() } else { y };
        let (y0, y1) = (map_y(self.y_range.0), map_y(self.y_range.1));
        let left = MARGIN_LEFT as f64;
        let right = (self.width as i64 - MARGIN) as f64;
        let top = MARGIN as f64;
        let bottom = (self.height as i64 - MARGIN_BOTTOM) as f64;
        let px = |x: f64| left + (x - x0) / (x1 - x0) * (right - left);
        let py = |y: f64| bottom - (map_y(y) - y0) / (y1 - y0) * (bottom - top);
        let grid = [225, 225, 225];
        let ink = [60, 60, 60];
        // vertical grid lines and x labels
        let mut xt = (x0 / self.x_tick).ceil() * self.x_tick;
        while xt <= x1 + 1e-9 {
            let x = px(xt);
            canvas.line((x, top), (x, bottom), grid);
            canvas.text(x as i64 - 4, bottom as i64 + 6, &label(xt), ink);
            xt += self.x_tick;
        }
        // horizontal grid lines and y labels: decades on a log axis, 5 steps otherwise
        let y_ticks: Vec<f64> = if self.log_y {
            (y0.ceil() as i64..=y1.floor() as i64)
                .map(|e| 10f64.powi(e as i32))
                .collect()
        } else {
            (0..=5)
                .map(|i| self.y_range.0 + (self.y_range.1 - self.y_range.0) * i as f64 / 5.0)
                .collect()
        };
        for yt in y_ticks {
            let y = py(yt);
            canvas.line((left, y), (right, y), grid);
            canvas.text(2, y as i64 - 2, &label(yt), ink);
        }
        canvas.line((left, bottom), (right, bottom), ink);
        canvas.line((left, top), (left, bottom), ink);
        for s in &self.series {
            for (i, w) in s.points.windows(2).enumerate() {
                if s.dashed && i % 2 == 1 {
                    continue;
                }
                let a = (px(w[0].0), py(w[0].1).clamp(top - 1.0, bottom + 1.0));
                let b = (px(w[1].0), py(w[1].1).clamp(top - 1.0, bottom + 1.0));
                canvas.line(a, b, s.color);
            }
        }
        write_png_atomically(path, &canvas.img)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(tiles: Vec<Vec<Option<image::RgbImage>>>) -> ImageGrid {
        ImageGrid {
            tile_width: 10,
            tile_height: 6,
            column_labels: vec!["GT".into(), "OURS".into(), "X".into()],
            row_labels: vec!["FLASH".into(), "NO FLASH".into()],
            tiles,
        }
    }

    #[test]
    fn image_grid_places_tiles_and_labels() {
        let red = image::RgbImage::from_pixel(10, 6, image::Rgb([255, 0, 0]));
        let blue = image::RgbImage::from_pixel(10, 6, image::Rgb([0, 0, 255]));
        let g = grid(vec![
            vec![Some(red.clone()), None, Some(blue)],
            vec![Some(red), None, None],
        ]);
        // 96 + 3·(10 + 4) by 18 + 2·(6 + 4)
        assert_eq!(g.dimensions(), (138, 38));
        let img = g.to_image().unwrap();
        assert_eq!(img.dimensions(), (138, 38));
        assert_eq!(g.tile_origin(1, 2), (124, 28));
        // tile corners land where the layout says, gaps stay white
        assert_eq!(img.get_pixel(96, 18).0, [255, 0, 0]);
        assert_eq!(img.get_pixel(105, 23).0, [255, 0, 0]);
        assert_eq!(img.get_pixel(106, 18).0, [255, 255, 255]);
        assert_eq!(img.get_pixel(124, 18).0, [0, 0, 255]);
        assert_eq!(img.get_pixel(96, 28).0, [255, 0, 0]);
        // an empty tile is light grey, not white
        assert_ne!(img.get_pixel(113, 20).0, [255, 255, 255]);
        // "G" of the first column label: its top row is 0b011 at scale 2
        assert_eq!(img.get_pixel(96, 4).0, [255, 255, 255]);
        assert_eq!(img.get_pixel(98, 4).0, [40, 40, 40]);
        assert_eq!(img.get_pixel(101, 5).0, [40, 40, 40]);
        // the row labels are drawn in the label column
        let inked = (0..96u32)
            .flat_map(|x| (18..38u32).map(move |y| (x, y)))
            .filter(|&(x, y)| img.get_pixel(x, y).0 == [40, 40, 40])
            .count();
        assert!(inked > 40, "{inked} label pixels");
    }

    #[test]
    fn image_grid_rejects_a_tile_of_the_wrong_size() {
        let small = image::RgbImage::new(4, 4);
        let g = grid(vec![vec![Some(small), None, None], vec![None, None, None]]);
        let err = g.to_image().unwrap_err().to_string();
        assert!(err.contains("4×4"), "{err}");
    }

    #[test]
    fn png_written_atomically_reads_back() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("grid.png");
        let g = grid(vec![vec![None, None, None], vec![None, None, None]]);
        g.write_png(&path).unwrap();
        assert!(!dir.path().join("grid.png.tmp").exists());
        let back = image::open(&path).unwrap().to_rgb8();
        assert_eq!(back, g.to_image().unwrap());
    }
}
