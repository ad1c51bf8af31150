//! Training rays: every pixel of every image of a capture, drawn at random
//! across images each step (flash and no-flash mixed, SPEC §4), with its
//! observed colour, mask value and flash energy.
//!
//! A batch mixes three kinds of draws ([`RayShares`]): foreground pixels,
//! pixels of the silhouette band (within a few pixels of a mask edge, on
//! either side), and pixels drawn uniformly from whole images. The band is
//! where the mask loss has something to say: a notch the silhouette shows
//! where a groove crosses the outline is a few pixels out of 65,536, and a
//! uniform draw reaches each of them about once in a whole training run.
//! Flash images can be drawn more (or less) often than no-flash ones, in
//! every kind of draw ([`TrainingRays::set_flash_weight`]).

use rand::Rng;
use wildlight_data::{Camera, Dataset};

/// The pixels of a capture, ready to be drawn as rays.
pub struct TrainingRays {
    views: Vec<ViewRays>,
    /// (view, pixel index) of every foreground pixel.
    foreground: Vec<(u32, u32)>,
    /// (view, pixel index) of every pixel of the silhouette band (empty
    /// until [`TrainingRays::set_silhouette_band`]).
    silhouette: Vec<(u32, u32)>,
    /// Whether the capture has masks.
    pub has_masks: bool,
    /// Probability of keeping a drawn pixel, per view (none: every draw is
    /// kept; see [`TrainingRays::set_flash_weight`]).
    keep: Option<Vec<f64>>,
}

struct ViewRays {
    camera: Camera,
    width: u32,
    height: u32,
    pixels: Vec<f32>,
    mask: Option<Vec<bool>>,
    energy: [f32; 3],
    /// This image's saturation cap ([`wildlight_data::View::saturation`]).
    saturation: Option<f32>,
}

/// How a batch is split between the kinds of draws; what the shares leave
/// is drawn uniformly from all pixels of all views.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RayShares {
    /// Share of the rays drawn from mask foreground pixels.
    pub foreground: f64,
    /// Share of the rays drawn from the silhouette band.
    pub silhouette: f64,
}

/// Grows the set flags of a `width × height` image by `radius` pixels in
/// every direction (a square, Chebyshev-distance dilation; pixels outside
/// the image count as unset).
pub(crate) fn dilate(flags: &[bool], width: usize, height: usize, radius: usize) -> Vec<bool> {
    // Separable: a running window along the rows, then along the columns.
    let pass = |src: &[bool], len: usize, count: usize, at: &dyn Fn(usize, usize) -> usize| {
        let mut out = vec![false; src.len()];
        for line in 0..count {
            for i in 0..len {
                let (lo, hi) = (i.saturating_sub(radius), (i + radius).min(len - 1));
                out[at(line, i)] = (lo..=hi).any(|j| src[at(line, j)]);
            }
        }
        out
    };
    let rows = pass(flags, width, height, &|y, x| y * width + x);
    pass(&rows, height, width, &|x, y| y * width + x)
}

/// The pixels (row-major indices) within `band` pixels (Chebyshev
/// distance) of both a set and an unset pixel of `mask`: the outline of the
/// object, `band` pixels deep on either side.
pub fn silhouette_band(mask: &[bool], width: usize, height: usize, band: usize) -> Vec<u32> {
    let near_object = dilate(mask, width, height, band);
    let outside: Vec<bool> = mask.iter().map(|m| !m).collect();
    let near_background = dilate(&outside, width, height, band);
    (0..mask.len())
        .filter(|&p| near_object[p] && near_background[p])
        .map(|p| p as u32)
        .collect()
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
    /// Saturation cap of each ray's image (SPEC §4, §5; none: no cap).
    /// Images may each have their own: an import scales each photo by its
    /// exposure, which moves its clip level.
    pub saturation: Vec<Option<f32>>,
    /// (view, pixel index) each ray was drawn from.
    pub pixels: Vec<(u32, u32)>,
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

    fn push(&mut self, v: u32, view: &ViewRays, pixel: u32) {
        self.pixels.push((v, pixel));
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
        self.saturation.push(view.saturation);
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
                    saturation: view.saturation,
                }
            })
            .collect();
        Self {
            has_masks: views.iter().all(|v| v.mask.is_some()),
            views,
            foreground,
            silhouette: Vec::new(),
            keep: None,
        }
    }

    /// Forgets the capture's masks: every pixel then counts and is drawn
    /// uniformly, as in a capture without masks (`--masks ignore`).
    pub fn ignore_masks(&mut self) {
        for v in &mut self.views {
            v.mask = None;
        }
        self.foreground.clear();
        self.silhouette.clear();
        self.has_masks = false;
    }

    /// The camera of each view.
    pub fn cameras(&self) -> impl Iterator<Item = &Camera> {
        self.views.iter().map(|v| &v.camera)
    }

    /// Draws each pixel of a flash image `weight` times as often as a pixel
    /// of a no-flash image, in every kind of draw (a view is a flash view
    /// when its flash energy is non-zero). A drawn pixel is kept with
    /// probability `w_v / max w` and drawn again otherwise, so a weight of
    /// 1, or a capture with only one kind of view, leaves the draws (and
    /// the random numbers they use) exactly as they were.
    pub fn set_flash_weight(&mut self, weight: f64) {
        let weights: Vec<f64> = self
            .views
            .iter()
            .map(|v| {
                if v.energy.iter().any(|e| *e != 0.0) {
                    weight
                } else {
                    1.0
                }
            })
            .collect();
        let max = weights.iter().copied().fold(0.0, f64::max);
        self.keep = (weights.iter().any(|w| *w != max) && max > 0.0)
            .then(|| weights.iter().map(|w| w / max).collect());
    }

    /// Whether a pixel drawn from view `v` is kept (always, without view
    /// weights; no random number is used then).
    fn keep_draw(&self, rng: &mut impl Rng, v: u32) -> bool {
        match &self.keep {
            None => true,
            Some(keep) => rng.random::<f64>() < keep[v as usize],
        }
    }

    /// Repeats `draw` until [`Self::keep_draw`] keeps the view `view_of`
    /// gives for its result (the first draw, without view weights).
    fn draw_kept<R: Rng, X: Copy>(
        &self,
        rng: &mut R,
        draw: impl Fn(&mut R) -> X,
        view_of: impl Fn(X) -> u32,
    ) -> X {
        loop {
            let x = draw(rng);
            if self.keep_draw(rng, view_of(x)) {
                return x;
            }
        }
    }

    /// Collects the silhouette band: the pixels within `band` pixels of a
    /// mask edge, on either side, of every view with a mask (none when
    /// `band` is 0).
    pub fn set_silhouette_band(&mut self, band: u32) {
        self.silhouette.clear();
        if band == 0 {
            return;
        }
        for (v, view) in self.views.iter().enumerate() {
            if let Some(mask) = &view.mask {
                let (w, h) = (view.width as usize, view.height as usize);
                self.silhouette.extend(
                    silhouette_band(mask, w, h, band as usize)
                        .into_iter()
                        .map(|p| (v as u32, p)),
                );
            }
        }
    }

    /// The visual hull of the views' masks, each dilated by `dilation`
    /// pixels (`crate::visual_hull`); `None` when a view has no mask.
    pub fn visual_hull(&self, dilation: usize) -> Option<crate::visual_hull::VisualHull> {
        let masked: Option<Vec<(&wildlight_data::Camera, &[bool])>> = self
            .views
            .iter()
            .map(|v| v.mask.as_deref().map(|m| (&v.camera, m)))
            .collect();
        masked.map(|views| crate::visual_hull::VisualHull::new(views, dilation))
    }

    /// Number of silhouette-band pixels over all views.
    pub fn silhouette_pixels(&self) -> usize {
        self.silhouette.len()
    }

    /// Number of foreground pixels over all views.
    pub fn foreground_pixels(&self) -> usize {
        self.foreground.len()
    }

    /// Draws `n` rays: `shares.foreground` of them from foreground pixels,
    /// `shares.silhouette` from the silhouette band, the rest uniformly from
    /// all pixels of all views (a kind with no pixels gives its share to the
    /// uniform draws).
    pub fn draw(&self, rng: &mut impl Rng, n: usize, shares: RayShares, out: &mut RayBatch) {
        *out = RayBatch::default();
        let count = |available: bool, share: f64| {
            if available {
                ((n as f64) * share).round() as usize
            } else {
                0
            }
        };
        let n_fg = count(!self.foreground.is_empty(), shares.foreground).min(n);
        let n_band = count(!self.silhouette.is_empty(), shares.silhouette).min(n - n_fg);
        for (pixels, draws) in [(&self.foreground, n_fg), (&self.silhouette, n_band)] {
            for _ in 0..draws {
                let (v, p) = self.draw_kept(
                    rng,
                    |rng| pixels[rng.random_range(0..pixels.len())],
                    |(v, _)| v,
                );
                out.push(v, &self.views[v as usize], p);
            }
        }
        for _ in out.len()..n {
            let v = self.draw_kept(
                rng,
                |rng| rng.random_range(0..self.views.len()),
                |v| v as u32,
            );
            let view = &self.views[v];
            let p = rng.random_range(0..view.width * view.height);
            out.push(v as u32, view, p);
        }
    }

    /// Every pixel of view `v` (row-major), for rendering or evaluation.
    pub fn view_batch(&self, v: usize) -> RayBatch {
        let view = &self.views[v];
        let mut out = RayBatch::default();
        for p in 0..view.width * view.height {
            out.push(v as u32, view, p);
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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat4, DVec3};
    use rand::SeedableRng;
    use wildlight_data::camera::intrinsics_from_fov_x;

    /// A `w × h` mask set on the pixels where `inside(x, y)` holds.
    fn mask(w: usize, h: usize, inside: impl Fn(usize, usize) -> bool) -> Vec<bool> {
        (0..w * h).map(|p| inside(p % w, p / w)).collect()
    }

    #[test]
    fn the_band_is_the_outline_on_both_sides() {
        // A 3×3 object in the middle of a 7×7 image, band 1: its outer ring
        // (8 pixels) and the background ring around it (16 pixels), that is
        // the 5×5 square without its centre.
        let m = mask(7, 7, |x, y| (2..=4).contains(&x) && (2..=4).contains(&y));
        let band = silhouette_band(&m, 7, 7, 1);
        let want: Vec<u32> = (0..49u32)
            .filter(|p| {
                let (x, y) = (p % 7, p / 7);
                (1..=5).contains(&x) && (1..=5).contains(&y) && (x, y) != (3, 3)
            })
            .collect();
        assert_eq!(band, want);
        // Band 2 reaches the centre and the image's edge rows and columns.
        assert_eq!(silhouette_band(&m, 7, 7, 2).len(), 49);
        // No background anywhere (pixels outside the image do not count as
        // background), or no object: no outline.
        assert!(silhouette_band(&[true; 16], 4, 4, 1).is_empty());
        assert!(silhouette_band(&[false; 16], 4, 4, 1).is_empty());
    }

    /// A 16×16 view whose red channel is the pixel index, with a 6×6
    /// object in the middle, lit by a flash of `energy`.
    fn test_view(energy: [f32; 3]) -> ViewRays {
        let (w, h) = (16u32, 16u32);
        let camera = Camera::look_at(
            0,
            w,
            h,
            intrinsics_from_fov_x(w, h, 40.0),
            DVec3::new(0.0, 0.0, 3.0),
            DVec3::ZERO,
            DVec3::Y,
            DMat4::IDENTITY,
            [0.0; 3],
        )
        .unwrap();
        let mut pixels = vec![0.0; (w * h * 3) as usize];
        for p in 0..(w * h) as usize {
            pixels[3 * p] = p as f32;
        }
        ViewRays {
            camera,
            width: w,
            height: h,
            pixels,
            mask: Some(mask(16, 16, |x, y| {
                (5..11).contains(&x) && (5..11).contains(&y)
            })),
            energy,
            saturation: None,
        }
    }

    /// Training rays over `views`, with their foreground pixels listed.
    fn rays_of(views: Vec<ViewRays>) -> TrainingRays {
        let foreground = views
            .iter()
            .enumerate()
            .flat_map(|(v, view)| {
                let m = view.mask.as_ref().unwrap();
                (0..m.len() as u32)
                    .filter(|p| m[*p as usize])
                    .map(move |p| (v as u32, p))
            })
            .collect();
        TrainingRays {
            views,
            foreground,
            silhouette: Vec::new(),
            has_masks: true,
            keep: None,
        }
    }

    #[test]
    fn rays_carry_their_images_cap() {
        // Two views with their own caps (an import's exposure scaling).
        let (mut a, mut b) = (test_view([0.0; 3]), test_view([1.0; 3]));
        a.saturation = Some(0.5);
        b.saturation = None;
        let rays = rays_of(vec![a, b]);
        let (batch_a, batch_b) = (rays.view_batch(0), rays.view_batch(1));
        assert!(batch_a.saturation.iter().all(|c| *c == Some(0.5)));
        assert!(batch_b.saturation.iter().all(|c| c.is_none()));
        assert_eq!(batch_a.saturation.len(), batch_a.len());
    }

    #[test]
    fn draws_follow_the_shares() {
        // One 16×16 view whose red channel is the pixel index, with a 6×6
        // object in the middle.
        let mut rays = rays_of(vec![test_view([0.0; 3])]);
        let object = rays.views[0].mask.clone().unwrap();
        rays.set_silhouette_band(1);
        let band = silhouette_band(&object, 16, 16, 1);
        assert_eq!(rays.silhouette_pixels(), band.len());
        let shares = RayShares {
            foreground: 0.5,
            silhouette: 0.25,
        };
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let mut batch = RayBatch::default();
        rays.draw(&mut rng, 400, shares, &mut batch);
        assert_eq!(batch.len(), 400);
        let drawn: Vec<u32> = batch.target.iter().map(|t| t[0] as u32).collect();
        // The first 200 are foreground pixels, the next 100 band pixels.
        assert!(drawn[..200].iter().all(|p| object[*p as usize]));
        assert!(drawn[200..300].iter().all(|p| band.contains(p)));
        // The band's draws land on both sides of the outline.
        let inside = drawn[200..300]
            .iter()
            .filter(|p| object[**p as usize])
            .count();
        assert!((20..80).contains(&inside), "{inside} of 100 inside");
        // The last 100 are uniform: some land far from the object.
        let far = drawn[300..]
            .iter()
            .filter(|p| !object[**p as usize] && !band.contains(p))
            .count();
        assert!(far > 40, "{far} of 100 far from the object");

        // Without a band, its share goes to the uniform draws, and the
        // draws are those of a batch that never asked for a band.
        rays.set_silhouette_band(0);
        let mut again = RayBatch::default();
        rays.draw(
            &mut rand_pcg::Pcg64::seed_from_u64(7),
            400,
            shares,
            &mut again,
        );
        let mut plain = RayBatch::default();
        let no_band = RayShares {
            foreground: 0.5,
            ..RayShares::default()
        };
        rays.draw(
            &mut rand_pcg::Pcg64::seed_from_u64(7),
            400,
            no_band,
            &mut plain,
        );
        assert_eq!(again.target, plain.target);

        // Each ray remembers the pixel it came from.
        assert!(
            again
                .pixels
                .iter()
                .zip(&again.target)
                .all(|((v, p), t)| *v == 0 && *p == t[0] as u32)
        );
    }

    #[test]
    fn flash_views_are_drawn_by_their_weight() {
        // Two views alike but for the flash: view 1 has it.
        let mut rays = rays_of(vec![test_view([0.0; 3]), test_view([1.0; 3])]);
        let shares = RayShares {
            foreground: 0.5,
            silhouette: 0.0,
        };
        let draw = |rays: &TrainingRays| {
            let mut batch = RayBatch::default();
            rays.draw(
                &mut rand_pcg::Pcg64::seed_from_u64(11),
                4000,
                shares,
                &mut batch,
            );
            batch
        };
        let flash_share = |b: &RayBatch, range: std::ops::Range<usize>| {
            let n = range.len() as f64;
            b.pixels[range].iter().filter(|(v, _)| *v == 1).count() as f64 / n
        };
        let plain = draw(&rays);
        // Weight 1 changes nothing, random numbers included.
        rays.set_flash_weight(1.0);
        assert!(rays.keep.is_none());
        assert_eq!(draw(&rays).pixels, plain.pixels);
        let even = flash_share(&plain, 0..4000);
        assert!((even - 0.5).abs() < 0.03, "{even}");
        // Weight 3: three flash draws for each no-flash one, in the
        // foreground draws and in the uniform ones alike.
        rays.set_flash_weight(3.0);
        let heavy = draw(&rays);
        assert_eq!(heavy.len(), 4000);
        for half in [0..2000, 2000..4000] {
            let share = flash_share(&heavy, half.clone());
            assert!((share - 0.75).abs() < 0.03, "{half:?}: {share}");
        }
        assert!(
            heavy.pixels[..2000]
                .iter()
                .all(|(v, p)| rays.views[*v as usize].mask.as_ref().unwrap()[*p as usize])
        );
        // Below 1 the flash views are drawn less.
        rays.set_flash_weight(0.25);
        let light = flash_share(&draw(&rays), 0..4000);
        assert!((light - 0.2).abs() < 0.03, "{light}");
        // A capture of flash views only: nothing to weigh.
        let mut flash_only = rays_of(vec![test_view([1.0; 3]), test_view([2.0; 3])]);
        flash_only.set_flash_weight(3.0);
        assert!(flash_only.keep.is_none());
    }
}
