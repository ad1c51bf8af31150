//! Training rays: every pixel of every image of a capture, drawn at random
//! across images each step (flash and no-flash mixed, SPEC §4), with its
//! observed colour, mask value and flash energy.

use rand::Rng;
use wildlight_data::{Camera, Dataset};

/// The pixels of a capture, ready to be drawn as rays.
pub struct TrainingRays {
    views: Vec<ViewRays>,
    /// (view, pixel index) of every foreground pixel.
    foreground: Vec<(u32, u32)>,
    /// Saturation cap of the capture.
    pub saturation: Option<f32>,
    /// Whether the capture has masks.
    pub has_masks: bool,
}

struct ViewRays {
    camera: Camera,
    width: u32,
    height: u32,
    pixels: Vec<f32>,
    mask: Option<Vec<bool>>,
    energy: [f32; 3],
}

/// A batch of rays with what was observed along them.
#[derive(Clone, Debug, Default)]
pub struct RayBatch {
    /// Camera centres (normalized frame).
    pub origins: Vec<[f32; 3]>,
    /// Unit directions.
    pub dirs: Vec<[f32; 3]>,
    /// Flash energy of each ray's image.
    pub energy: Vec<[f32; 3]>,
    /// Observed linear RGB.
    pub target: Vec<[f32; 3]>,
    /// Mask value (1 object, 0 background; 1 when there are no masks).
    pub mask: Vec<f32>,
}

impl RayBatch {
    /// Number of rays.
    pub fn len(&self) -> usize {
        self.dirs.len()
    }

    /// Whether the batch is empty.
    pub fn is_empty(&self) -> bool {
        self.dirs.is_empty()
    }

    fn push(&mut self, view: &ViewRays, pixel: u32) {
        let (x, y) = (pixel % view.width, pixel / view.width);
        let ray = view.camera.ray(x as f64, y as f64);
        self.origins.push(ray.origin.as_vec3().to_array());
        self.dirs.push(ray.dir.as_vec3().normalize().to_array());
        self.energy.push(view.energy);
        let i = pixel as usize * 3;
        self.target
            .push([view.pixels[i], view.pixels[i + 1], view.pixels[i + 2]]);
        self.mask.push(match &view.mask {
            Some(m) => f32::from(u8::from(m[pixel as usize])),
            None => 1.0,
        });
    }
}

impl TrainingRays {
    /// Collects the pixels of every view of `dataset`.
    pub fn new(dataset: &Dataset) -> Self {
        let mut foreground = Vec::new();
        let views: Vec<ViewRays> = dataset
            .views
            .iter()
            .enumerate()
            .map(|(v, view)| {
                let mask = view.mask.as_ref().map(|m| m.data.clone());
                if let Some(m) = &mask {
                    foreground.extend(
                        m.iter()
                            .enumerate()
                            .filter(|(_, on)| **on)
                            .map(|(p, _)| (v as u32, p as u32)),
                    );
                }
                ViewRays {
                    camera: view.camera.clone(),
                    width: view.image.width,
                    height: view.image.height,
                    pixels: view.image.data.clone(),
                    mask,
                    energy: view.camera.light_energy.map(|e| e as f32),
                }
            })
            .collect();
        Self {
            has_masks: views.iter().all(|v| v.mask.is_some()),
            views,
            foreground,
            saturation: dataset.saturation,
        }
    }

    /// Number of foreground pixels over all views.
    pub fn foreground_pixels(&self) -> usize {
        self.foreground.len()
    }

    /// Draws `n` rays: `fg_fraction` of them from foreground pixels, the
    /// rest uniformly from all pixels of all views.
    pub fn draw(&self, rng: &mut impl Rng, n: usize, fg_fraction: f64, out: &mut RayBatch) {
        *out = RayBatch::default();
        let n_fg = if self.foreground.is_empty() {
            0
        } else {
            ((n as f64) * fg_fraction).round() as usize
        };
        for _ in 0..n_fg {
            let (v, p) = self.foreground[rng.random_range(0..self.foreground.len())];
            out.push(&self.views[v as usize], p);
        }
        for _ in n_fg..n {
            let view = &self.views[rng.random_range(0..self.views.len())];
            let p = rng.random_range(0..view.width * view.height);
            out.push(view, p);
        }
    }

    /// Every pixel of view `v` (row-major), for rendering or evaluation.
    pub fn view_batch(&self, v: usize) -> RayBatch {
        let view = &self.views[v];
        let mut out = RayBatch::default();
        for p in 0..view.width * view.height {
            out.push(view, p);
        }
        out
    }

    /// Number of views.
    pub fn view_count(&self) -> usize {
        self.views.len()
    }

    /// Size of view `v`.
    pub fn view_size(&self, v: usize) -> (u32, u32) {
        (self.views[v].width, self.views[v].height)
    }
}
