//! The surface an object stands on, as the background of a run without
//! masks shows it.
//!
//! A run without masks (SPEC §6) leaves most of the table to the
//! background field: the SDF holds the object and at most a ragged patch of
//! table, too little for the export to find the plane on the surface
//! ([`wildlight_mesh::TriMesh::object_only`]), and the object's walls may
//! run on below the table top where no camera could see them. The table
//! beyond the unit sphere is in the background field, though: along the
//! rays that miss the object, the depth at which the background's weights
//! pile up lands on the table top around the object. A plane fitted to
//! those points (RANSAC), with the cameras on one side and the region's
//! centre above it within the sphere, is the support.

use crate::inference::TrainedRun;
use crate::pipeline::{PassSettings, RayInputs};
use glam::Vec3;
use wildlight_data::Camera;
use wildlight_mesh::{SupportPlane, fit_plane};

/// Settings of [`TrainedRun::support_from_background`].
#[derive(Clone, Copy, Debug)]
pub struct BackgroundSupportSearch {
    /// Most cameras looked through (evenly spread over the capture).
    pub max_cameras: usize,
    /// Rays per camera along the image's longer side (a grid).
    pub rays_across: u32,
    /// Rays whose object opacity Σw exceeds this see the object, not the
    /// background, and are left out.
    pub max_object_opacity: f32,
    /// Only background points within this distance of the centre (unit
    /// sphere radii) are fitted: the surroundings of the object, where the
    /// table is, not the walls.
    pub max_radius: f32,
    /// Inlier distance of the plane fit (normalized units).
    pub tolerance: f32,
    /// Smallest share of the points the plane must hold.
    pub min_inlier_fraction: f32,
    /// Smallest share of the cameras that must lie on the plane's side.
    pub min_camera_fraction: f32,
    /// The depth of a ray's background: where its background weights reach
    /// this share of their sum. The background's density is a soft layer
    /// that starts at the table top and spreads behind it, so the median
    /// (0.5) lies below the table: by 0.028 and 0.037 radii on a synthetic
    /// table scene and a Mitsuba capture, against 0.007 and 0.010 at 0.4.
    pub depth_fraction: f64,
    /// Background samples per ray: finer than training's (32), for the
    /// depth, since the field is continuous.
    pub samples: usize,
}

impl Default for BackgroundSupportSearch {
    fn default() -> Self {
        BackgroundSupportSearch {
            max_cameras: 48,
            rays_across: 48,
            max_object_opacity: 0.2,
            max_radius: 3.0,
            tolerance: 0.03,
            min_inlier_fraction: 0.3,
            min_camera_fraction: 0.95,
            depth_fraction: 0.4,
            samples: 128,
        }
    }
}

/// A support plane found in the background, with what it rests on.
#[derive(Clone, Copy, Debug)]
pub struct BackgroundSupport {
    /// The plane (normalized frame), its normal towards the cameras.
    pub plane: SupportPlane,
    /// Background points fitted (those near the sphere).
    pub points: usize,
    /// Of them, on the plane.
    pub inliers: usize,
}

impl TrainedRun {
    /// The plane the object stands on, from the background field's depth
    /// along rays of `cameras` that miss the object (see the module docs
    /// and [`support_from_points`]), or `None`: a run with masks (no
    /// background) or no plane found.
    pub fn support_from_background(
        &mut self,
        cameras: &[Camera],
        search: &BackgroundSupportSearch,
    ) -> Option<BackgroundSupport> {
        self.model.background.as_ref()?;
        let settings = PassSettings::rendering(self.normal_method());
        let trained_settings = self.pipeline.background_settings;
        self.pipeline.background_settings.samples = search.samples.max(1);
        let step = (cameras.len() as f64 / search.max_cameras.max(1) as f64).max(1.0);
        let mut points = Vec::new();
        let mut centres = Vec::new();
        let (mut origins, mut dirs) = (Vec::new(), Vec::new());
        let mut k = 0.0f64;
        while (k as usize) < cameras.len() {
            let camera = &cameras[k as usize];
            k += step;
            centres.push(camera.ray(0.0, 0.0).origin.as_vec3());
            let spacing = camera.width.max(camera.height) as f64 / search.rays_across.max(1) as f64;
            origins.clear();
            dirs.clear();
            let mut y = 0.5 * spacing;
            while y < camera.height as f64 {
                let mut x = 0.5 * spacing;
                while x < camera.width as f64 {
                    let ray = camera.ray(x - 0.5, y - 0.5);
                    origins.push(ray.origin.as_vec3().to_array());
                    dirs.push(ray.dir.as_vec3().normalize().to_array());
                    x += spacing;
                }
                y += spacing;
            }
            let energy = vec![[0.0f32; 3]; origins.len()];
            let rays = RayInputs {
                origins: &origins,
                dirs: &dirs,
                energy: &energy,
            };
            self.pipeline
                .forward(&self.model, &self.grid, &rays, &[], &settings);
            let depth = self
                .pipeline
                .background
                .depth_quantile(search.depth_fraction);
            let acc = self.pipeline.acc_weight();
            for (r, t) in depth.iter().enumerate() {
                if let Some(t) = t
                    && acc[r] <= search.max_object_opacity
                {
                    points
                        .push(Vec3::from_array(origins[r]) + *t as f32 * Vec3::from_array(dirs[r]));
                }
            }
        }
        self.pipeline.background_settings = trained_settings;
        support_from_points(&points, &centres, search)
    }
}

/// The support plane among `points` (what the background shows, normalized
/// frame) seen from cameras at `centres`: the plane (RANSAC) through the
/// most of the points between the unit sphere and
/// [`BackgroundSupportSearch::max_radius`], provided that it holds at least
/// [`BackgroundSupportSearch::min_inlier_fraction`] of them (and 50), that
/// the cameras look from one side of it
/// ([`BackgroundSupportSearch::min_camera_fraction`]), and that the centre
/// lies above it within the sphere (else there is nothing to cut). Its
/// normal points towards the cameras.
pub fn support_from_points(
    points: &[Vec3],
    centres: &[Vec3],
    search: &BackgroundSupportSearch,
) -> Option<BackgroundSupport> {
    let near: Vec<Vec3> = points
        .iter()
        .copied()
        .filter(|p| {
            let r = p.length();
            r > 1.0 && r <= search.max_radius
        })
        .collect();
    let (plane, inliers) = fit_plane(&near, search.tolerance, 400, 0)?;
    if (inliers.len() as f32) < search.min_inlier_fraction * near.len() as f32
        || inliers.len() < 50
        || centres.is_empty()
    {
        return None;
    }
    let above = centres.iter().filter(|c| plane.height(**c) > 0.0).count();
    let plane = if above * 2 >= centres.len() {
        plane
    } else {
        SupportPlane {
            normal: -plane.normal,
            offset: -plane.offset,
        }
    };
    let on_side = above.max(centres.len() - above);
    if (on_side as f32) < search.min_camera_fraction * centres.len() as f32 {
        return None;
    }
    let h = plane.height(Vec3::ZERO);
    if h.is_nan() || h <= 0.0 || h >= 1.0 {
        return None;
    }
    Some(BackgroundSupport {
        plane,
        points: near.len(),
        inliers: inliers.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// What a background shows around an object on a table at y = −0.4:
    /// 600 table points between radius 1 and 3 (noise ±0.01), 300 of walls
    /// and clutter, 100 far away; and a ring of cameras above the table.
    fn scene(table: f32) -> (Vec<Vec3>, Vec<Vec3>) {
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(11);
        let mut points = Vec::new();
        while points.len() < 600 {
            let (x, z) = (rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0));
            let p = Vec3::new(x, table + rng.random_range(-0.01..0.01), z);
            if p.length() > 1.0 && p.length() < 3.0 {
                points.push(p);
            }
        }
        for _ in 0..300 {
            let d = Vec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-0.2..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize_or(Vec3::X);
            points.push(d * rng.random_range(1.0..3.0));
        }
        for _ in 0..100 {
            points.push(Vec3::new(0.0, 5.0, rng.random_range(20.0..40.0)));
        }
        let cameras = (0..12)
            .map(|i| {
                let a = i as f32 * std::f32::consts::TAU / 12.0;
                Vec3::new(2.5 * a.cos(), 0.3 + 0.1 * (i % 3) as f32, 2.5 * a.sin())
            })
            .collect();
        (points, cameras)
    }

    #[test]
    fn the_table_among_the_background_points_is_the_support() {
        let (points, cameras) = scene(-0.4);
        let found = support_from_points(&points, &cameras, &BackgroundSupportSearch::default())
            .expect("the table");
        assert!(found.plane.normal.dot(Vec3::Y) > 0.9999, "{found:?}");
        assert!((found.plane.offset + 0.4).abs() < 0.003, "{found:?}");
        // The far points are not fitted; the table's are the inliers.
        assert_eq!(found.points, 900);
        assert!((600..660).contains(&found.inliers), "{found:?}");
    }

    #[test]
    fn no_support_without_a_plane_below_the_centre_the_cameras_look_down_on() {
        let search = BackgroundSupportSearch::default();
        // The "table" above the centre: the object cannot stand on it.
        let (points, cameras) = scene(0.2);
        assert!(support_from_points(&points, &cameras, &search).is_none());
        // A floor below the sphere: nothing inside to cut.
        let (points, cameras) = scene(-1.2);
        assert!(support_from_points(&points, &cameras, &search).is_none());
        // Cameras on both sides of it (half of them under the table).
        let (points, mut cameras) = scene(-0.4);
        for c in cameras.iter_mut().step_by(2) {
            c.y = -1.0;
        }
        assert!(support_from_points(&points, &cameras, &search).is_none());
        // No cameras, or no points.
        let (points, _) = scene(-0.4);
        assert!(support_from_points(&points, &[], &search).is_none());
        assert!(support_from_points(&[], &[Vec3::Y], &search).is_none());
    }
}
