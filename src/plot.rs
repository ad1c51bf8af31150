//! A small line-plot rasteriser for quick-look PNGs (BRDF lobes, training
//! curves): axes, a grid, tick labels in a built-in 3×5 pixel font, and
//! anti-aliasing-free polylines. Nothing here is precise typography; it
//! exists so that a user can see a curve without another tool.

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

/// Digits and the few symbols tick labels need, 3×5 pixels, row-major bits.
fn glyph(ch: char) -> Option<[u8; 5]> {
    Some(match ch {
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
        for (i, ch) in s.chars().enumerate() {
            if let Some(rows) = glyph(ch) {
                for (r, bits) in rows.iter().enumerate() {
                    for col in 0..3 {
                        if bits & (0b100 >> col) != 0 {
                            self.put(x + i as i64 * 4 + col, y + r as i64, c);
                        }
                    }
                }
            }
        }
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
        let tmp = path.with_extension("png.tmp");
        canvas
            .img
            .save_with_format(&tmp, image::ImageFormat::Png)
            .with_context(|| format!("cannot write {}", tmp.display()))?;
        std::fs::rename(&tmp, path)
            .with_context(|| format!("cannot move {} to {}", tmp.display(), path.display()))?;
        Ok(())
    }
}
