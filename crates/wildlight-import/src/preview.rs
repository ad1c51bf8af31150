//! `roi.png`: a few of the capture's images with the region of interest's
//! outline (yellow) and the sparse points each image observes (green
//! inside the sphere, red outside) drawn on, for checking the import at a glance.

use glam::{DMat3, DVec2, DVec3};
use wildlight_data::RgbImage;
use wildlight_data::png_io::linear_to_srgb;

use crate::roi::Roi;

/// One image to draw, with its camera (SPEC §5 convention, world units).
pub struct PreviewView<'a> {
    /// The linear image.
    pub image: &'a RgbImage,
    /// K with pixel centres at integer coordinates.
    pub k: DMat3,
    /// World → camera rotation.
    pub r: DMat3,
    /// World → camera translation.
    pub t: DVec3,
    /// The sparse points this image observes.
    pub points: Vec<DVec3>,
}

/// Width of one tile of the grid.
pub const TILE_WIDTH: u32 = 480;

fn project(view: &PreviewView<'_>, p: DVec3) -> Option<DVec2> {
    let c = view.r * p + view.t;
    if c.z <= 1e-9 {
        return None;
    }
    let q = view.k * (c / c.z);
    Some(DVec2::new(q.x, q.y))
}

struct Canvas {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
}

impl Canvas {
    fn put(&mut self, x: i64, y: i64, c: [u8; 3]) {
        if x >= 0 && y >= 0 && (x as u32) < self.width && (y as u32) < self.height {
            let i = 3 * (y as usize * self.width as usize + x as usize);
            self.rgb[i..i + 3].copy_from_slice(&c);
        }
    }

    fn dot(&mut self, p: DVec2, c: [u8; 3]) {
        let (x, y) = (p.x.round() as i64, p.y.round() as i64);
        for dy in 0..2 {
            for dx in 0..2 {
                self.put(x + dx, y + dy, c);
            }
        }
    }

    fn line(&mut self, a: DVec2, b: DVec2, c: [u8; 3]) {
        let n = ((b - a).abs().max_element().ceil() as usize).clamp(1, 4096);
        for k in 0..=n {
            let p = a.lerp(b, k as f64 / n as f64);
            self.dot(p, c);
        }
    }
}

/// Draws one tile: the image scaled to [`TILE_WIDTH`], the points and the
/// sphere's outline.
fn tile(view: &PreviewView<'_>, roi: &Roi) -> Canvas {
    let img = view.image;
    let s = TILE_WIDTH as f64 / img.width as f64;
    let width = TILE_WIDTH;
    let height = ((img.height as f64 * s).round() as u32).max(1);
    let mut canvas = Canvas {
        width,
        height,
        rgb: vec![0; (3 * width * height) as usize],
    };
    for y in 0..height {
        for x in 0..width {
            let sx = (((x as f64 + 0.5) / s) as u32).min(img.width - 1);
            let sy = (((y as f64 + 0.5) / s) as u32).min(img.height - 1);
            let v = img.get(sx, sy);
            canvas.put(
                x as i64,
                y as i64,
                v.map(|c| (linear_to_srgb(c.clamp(0.0, 1.0)) * 255.0).round() as u8),
            );
        }
    }
    let to_tile = |p: DVec2| (p + 0.5) * s - 0.5;
    for p in &view.points {
        if let Some(q) = project(view, *p) {
            let inside = (*p - roi.center).length() <= roi.radius;
            let colour = if inside { [40, 230, 60] } else { [235, 40, 40] };
            canvas.dot(to_tile(q), colour);
        }
    }
    // The outline: the circle where the cone from the camera touches the sphere.
    let eye = -(view.r.transpose() * view.t);
    let to_eye = eye - roi.center;
    let d = to_eye.length();
    if d > roi.radius {
        let axis = to_eye / d;
        let centre = roi.center + axis * (roi.radius * roi.radius / d);
        let rad = roi.radius * (1.0 - (roi.radius / d).powi(2)).sqrt();
        let u = axis.any_orthonormal_vector();
        let v = axis.cross(u);
        let mut prev: Option<DVec2> = None;
        for k in 0..=256 {
            let a = k as f64 / 256.0 * std::f64::consts::TAU;
            let p = centre + rad * (a.cos() * u + a.sin() * v);
            let q = project(view, p).map(to_tile);
            if let (Some(a), Some(b)) = (prev, q) {
                canvas.line(a, b, [255, 220, 0]);
            }
            prev = q;
        }
    }
    canvas
}

/// The grid of tiles (two columns) as an 8-bit RGB image.
pub fn render_preview(views: &[PreviewView<'_>], roi: &Roi) -> image::RgbImage {
    let tiles: Vec<Canvas> = views.iter().map(|v| tile(v, roi)).collect();
    let cols = tiles.len().clamp(1, 2) as u32;
    let rows = (tiles.len() as u32).div_ceil(cols).max(1);
    let th = tiles.iter().map(|t| t.height).max().unwrap_or(1);
    let mut out = image::RgbImage::new(cols * TILE_WIDTH, rows * th);
    for (i, t) in tiles.iter().enumerate() {
        let (ox, oy) = ((i as u32 % cols) * TILE_WIDTH, (i as u32 / cols) * th);
        for y in 0..t.height {
            for x in 0..t.width {
                let j = 3 * (y * t.width + x) as usize;
                out.put_pixel(
                    ox + x,
                    oy + y,
                    image::Rgb([t.rgb[j], t.rgb[j + 1], t.rgb[j + 2]]),
                );
            }
        }
    }
    out
}
