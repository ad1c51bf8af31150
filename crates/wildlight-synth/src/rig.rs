//! The camera rig of a synthetic capture: views on a ring of orbits
//! around the object, a world frame that differs from the normalized one
//! (so `scale_mat` is not the identity), and the flash on a chosen
//! fraction of the views.

use glam::{DMat4, DVec3, DVec4};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use wildlight_data::Camera;
use wildlight_data::camera::intrinsics_from_fov_x;

use crate::error::SynthError;

/// Options of the camera rig.
#[derive(Clone, Debug, PartialEq)]
pub struct RigOptions {
    /// Number of training views.
    pub views: usize,
    /// Number of held-out views (`val/`), at azimuths between the training ones.
    pub val_views: usize,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Horizontal field of view in degrees.
    pub fov_deg: f64,
    /// Distance of the cameras from the object centre, normalized units.
    pub distance: f64,
    /// Lowest camera elevation above the horizontal plane, degrees.
    pub elevation_min_deg: f64,
    /// Highest camera elevation, degrees.
    pub elevation_max_deg: f64,
    /// Random perturbation of the poses in [0, 1]: azimuth by up to half
    /// the spacing, elevation by up to a tenth of the range, distance by up
    /// to 10 %, the look-at point by up to 0.05.
    pub jitter: f64,
    /// x_world = world_scale · x_normalized + world_offset.
    pub world_scale: f64,
    /// See `world_scale`.
    pub world_offset: [f64; 3],
    /// Fraction of views with the flash on (each split separately).
    pub flash_fraction: f64,
    /// Flash RGB energy in normalized units before exposure.
    pub flash_energy: [f64; 3],
    /// Exposure multiplier applied to all light (the recorded
    /// `light_energy` includes it).
    pub exposure: f64,
    /// Random seed.
    pub seed: u64,
}

impl Default for RigOptions {
    fn default() -> Self {
        RigOptions {
            views: 64,
            val_views: 8,
            width: 256,
            height: 256,
            fov_deg: 40.0,
            distance: 2.6,
            elevation_min_deg: -10.0,
            elevation_max_deg: 60.0,
            jitter: 0.5,
            world_scale: 2.5,
            world_offset: [0.4, -0.3, 1.2],
            flash_fraction: 0.5,
            flash_energy: [10.0, 10.0, 10.0],
            exposure: 1.0,
            seed: 0,
        }
    }
}

/// Which part of the dataset a view belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Split {
    /// Training views (the dataset folder).
    Train,
    /// Held-out views (`val/`).
    Val,
}

/// One view of the capture.
#[derive(Clone, Debug, PartialEq)]
pub struct RigView {
    /// The camera; its index is the file number within its split.
    pub camera: Camera,
    /// The split.
    pub split: Split,
    /// Position in the whole capture (training views first), used to seed
    /// the per-pixel random numbers.
    pub global_index: usize,
}

impl RigOptions {
    /// Checks the options.
    pub fn validate(&self) -> Result<(), SynthError> {
        let bad = |what: &str, problem: String| {
            Err(SynthError::InvalidOption {
                what: what.into(),
                problem,
            })
        };
        if self.views == 0 {
            return bad("--views", "at least one view is needed".into());
        }
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return bad(
                "image size",
                format!(
                    "{}x{} (each side must be 1..=16384)",
                    self.width, self.height
                ),
            );
        }
        if !(self.fov_deg > 1.0 && self.fov_deg < 170.0) {
            return bad(
                "--fov",
                format!("{} degrees (must be in (1, 170))", self.fov_deg),
            );
        }
        if !(self.distance > 1.05) || !self.distance.is_finite() {
            return bad(
                "--distance",
                format!(
                    "{} (cameras must be outside the unit sphere: > 1.05)",
                    self.distance
                ),
            );
        }
        let (lo, hi) = (self.elevation_min_deg, self.elevation_max_deg);
        if !(lo >= -89.0 && hi <= 89.0 && lo <= hi) {
            return bad(
                "elevation range",
                format!("[{lo}, {hi}] (need −89 ≤ min ≤ max ≤ 89)"),
            );
        }
        if !(0.0..=1.0).contains(&self.jitter) {
            return bad("--jitter", format!("{} (must be in [0, 1])", self.jitter));
        }
        if !(self.world_scale > 0.0 && self.world_scale.is_finite())
            || self.world_offset.iter().any(|v| !v.is_finite())
        {
            return bad(
                "world transform",
                format!("scale {} offset {:?}", self.world_scale, self.world_offset),
            );
        }
        if !(0.0..=1.0).contains(&self.flash_fraction) {
            return bad(
                "--flash-fraction",
                format!("{} (must be in [0, 1])", self.flash_fraction),
            );
        }
        if self
            .flash_energy
            .iter()
            .any(|e| !(*e >= 0.0 && e.is_finite()))
        {
            return bad(
                "--flash-power",
                format!("{:?} (must be ≥ 0)", self.flash_energy),
            );
        }
        if !(self.exposure > 0.0 && self.exposure.is_finite()) {
            return bad("--exposure", format!("{} (must be > 0)", self.exposure));
        }
        Ok(())
    }

    /// scale_mat: x_world = scale_mat · x_normalized.
    pub fn scale_mat(&self) -> DMat4 {
        let s = self.world_scale;
        let o = self.world_offset;
        DMat4::from_cols(
            DVec4::new(s, 0.0, 0.0, 0.0),
            DVec4::new(0.0, s, 0.0, 0.0),
            DVec4::new(0.0, 0.0, s, 0.0),
            DVec4::new(o[0], o[1], o[2], 1.0),
        )
    }

    /// The recorded flash energy of a flash view: energy × exposure.
    pub fn light_energy(&self) -> [f64; 3] {
        self.flash_energy.map(|e| e * self.exposure)
    }

    /// Builds all views: training views first (indices 0..views), then the
    /// held-out ones (indices 0..val_views within `val/`).
    pub fn build(&self) -> Result<Vec<RigView>, SynthError> {
        self.validate()?;
        let mut rng = Pcg64::seed_from_u64(self.seed ^ 0x5157_4E54_4845_5349);
        let k = intrinsics_from_fov_x(self.width, self.height, self.fov_deg);
        let scale_mat = self.scale_mat();
        let mut out = Vec::new();
        for (split, count, phase) in [
            (Split::Train, self.views, 0.0),
            (Split::Val, self.val_views, 0.5),
        ] {
            let flash_count = (self.flash_fraction * count as f64).round() as usize;
            let mut flash: Vec<bool> = (0..count).map(|i| i < flash_count).collect();
            flash.shuffle(&mut rng);
            let golden = 0.618_033_988_749_894_9;
            for (i, &flash_on) in flash.iter().enumerate() {
                let jit = |rng: &mut Pcg64| self.jitter * (rng.random::<f64>() - 0.5);
                let az = 2.0
                    * std::f64::consts::PI
                    * ((i as f64 + phase + jit(&mut rng)) / count as f64);
                // elevations follow a low-discrepancy sequence over the range
                let t = ((i as f64 + phase) * golden + 0.25 * phase).fract();
                let span = self.elevation_max_deg - self.elevation_min_deg;
                let el = (self.elevation_min_deg + span * t + 0.2 * span * jit(&mut rng))
                    .clamp(self.elevation_min_deg, self.elevation_max_deg)
                    .to_radians();
                let dist = self.distance * (1.0 + 0.2 * jit(&mut rng)).max(1.05 / self.distance);
                let eye = dist * DVec3::new(el.cos() * az.sin(), el.sin(), el.cos() * az.cos());
                let target = 0.1
                    * self.jitter
                    * DVec3::new(
                        rng.random::<f64>() - 0.5,
                        rng.random::<f64>() - 0.5,
                        rng.random::<f64>() - 0.5,
                    );
                let to_world = |p: DVec3| scale_mat.transform_point3(p);
                let energy = if flash_on {
                    self.light_energy()
                } else {
                    [0.0; 3]
                };
                let camera = Camera::look_at(
                    i,
                    self.width,
                    self.height,
                    k,
                    to_world(eye),
                    to_world(target),
                    DVec3::Y,
                    scale_mat,
                    energy,
                )?;
                out.push(RigView {
                    camera,
                    split,
                    global_index: out.len(),
                });
            }
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_surround_the_object_and_flash_fraction_holds() {
        let opts = RigOptions {
            views: 20,
            val_views: 4,
            flash_fraction: 0.3,
            ..RigOptions::default()
        };
        let views = opts.build().unwrap();
        assert_eq!(views.len(), 24);
        let train: Vec<_> = views.iter().filter(|v| v.split == Split::Train).collect();
        assert_eq!(train.iter().filter(|v| v.camera.flash()).count(), 6);
        let val: Vec<_> = views.iter().filter(|v| v.split == Split::Val).collect();
        assert_eq!(val.len(), 4);
        for v in &views {
            let c = v.camera.center;
            assert!(c.length() > 1.05, "camera inside the unit sphere");
            // looks roughly at the centre: the origin projects near the image centre
            let uv = v.camera.project(DVec3::ZERO).unwrap();
            assert!(
                (uv.x - 127.5).abs() < 30.0 && (uv.y - 127.5).abs() < 30.0,
                "{uv:?}"
            );
            assert!(v.camera.scale_mat != DMat4::IDENTITY);
        }
        // azimuths cover the circle: mean direction is near zero
        let mean: DVec3 = train
            .iter()
            .map(|v| DVec3::new(v.camera.center.x, 0.0, v.camera.center.z).normalize())
            .sum();
        assert!(mean.length() / 20.0 < 0.2);
        assert!(opts.build().unwrap() == views, "deterministic");
    }

    #[test]
    fn bad_options_are_named() {
        let e = RigOptions {
            flash_fraction: 1.5,
            ..RigOptions::default()
        }
        .build()
        .unwrap_err();
        assert!(e.to_string().contains("--flash-fraction"));
        let e = RigOptions {
            distance: 0.5,
            ..RigOptions::default()
        }
        .build()
        .unwrap_err();
        assert!(e.to_string().contains("--distance"));
    }
}
