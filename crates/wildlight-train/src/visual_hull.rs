//! The visual hull of a capture with masks, and a prior that keeps the SDF
//! positive outside it.
//!
//! A mask says which pixels see the object. A point that some view projects
//! onto one of its background pixels is therefore outside the object,
//! whatever the other views say: the object lies inside the intersection of
//! the masks' cones (the visual hull). Masks of real captures are a pixel or
//! two off at the outline, so the hull is built from masks dilated by
//! `loss.visual_hull_dilation` pixels: a point outside that hull lies at
//! least about that many pixels' width from the true surface.
//!
//! The hull prior: the SDF φ must be positive there. Late in a long run the
//! SDF can grow a pocket of φ < 0 away from the object (a floater: on the
//! default capture, seed 2, a blob 0.1 wide beside the knob appeared between
//! 20 and 30 minutes, in front of the background in most views). The mask
//! loss can remove it only through the few rays per step that are drawn off
//! the object and happen to cross it. The prior draws points where floaters
//! can be, in the cells of the occupancy grid that are not empty and whose
//! centre lies outside the hull, keeps the points outside the hull, and adds
//!
//! L_hull = λ · (1/n) Σ_j max(0, δ − φ(p_j)),
//!
//! with the margin δ = [`HULL_MARGIN`] (normalized units). A true surface is
//! farther than δ from any point outside the dilated hull (a pixel at the
//! default capture's object distance is about 0.003 wide), so it costs
//! nothing where the geometry is right; where φ < δ the gradient −λ/n
//! raises φ at the point. Only the SDF field receives the gradient. The
//! prior is the project's addition to SPEC §4; its weight is
//! `loss.visual_hull`.

use crate::float::{Float, of, to_f64};
use glam::DVec3;
use rand::Rng;
use wildlight_data::Camera;
use wildlight_fields::{FieldContext, FieldGrads, SdfField};
use wildlight_render::OccupancyGrid;

/// The margin δ of the hull prior: φ below it outside the hull costs.
pub const HULL_MARGIN: f64 = 0.002;

/// One view of the hull: its camera and its background pixels.
struct HullView {
    camera: Camera,
    /// Pixels outside the dilated mask (row-major).
    background: Vec<bool>,
}

/// The visual hull of a set of masked views.
pub struct VisualHull {
    views: Vec<HullView>,
}

impl VisualHull {
    /// The hull of `views` (camera, mask as row-major `width × height`
    /// flags), each mask dilated by `dilation` pixels.
    pub fn new<'a>(
        views: impl IntoIterator<Item = (&'a Camera, &'a [bool])>,
        dilation: usize,
    ) -> Self {
        let views = views
            .into_iter()
            .map(|(camera, mask)| {
                let (w, h) = (camera.width as usize, camera.height as usize);
                assert_eq!(
                    mask.len(),
                    w * h,
                    "visual hull: mask of camera {}",
                    camera.index
                );
                let grown = crate::rays::dilate(mask, w, h, dilation);
                HullView {
                    camera: camera.clone(),
                    background: grown.iter().map(|on| !on).collect(),
                }
            })
            .collect();
        Self { views }
    }

    /// Number of views.
    pub fn len(&self) -> usize {
        self.views.len()
    }

    /// Whether the hull has no view (every point is then inside).
    pub fn is_empty(&self) -> bool {
        self.views.is_empty()
    }

    /// Whether some view sees the normalized-frame point `p` over one of
    /// its (dilated) background pixels; pixel centres are at integers.
    pub fn outside(&self, p: [f64; 3]) -> bool {
        let p = DVec3::from_array(p);
        self.views.iter().any(|v| {
            let Some(px) = v
                .camera
                .project(p)
                .filter(|px| v.camera.contains_pixel(*px))
            else {
                return false;
            };
            // the nearest pixel centre (a coordinate of −0.5 rounds to −1,
            // which the saturating conversion takes to 0)
            let (x, y) = (px.x.round() as usize, px.y.round() as usize);
            let w = v.camera.width as usize;
            v.background[y.min(v.camera.height as usize - 1) * w + x.min(w - 1)]
        })
    }
}

/// The penalty of the hull prior at points already known to lie outside
/// the hull, with its gradient (generic, so that it is checked in f64).
#[derive(Default)]
pub struct HullPenalty<T> {
    ctx: FieldContext<T>,
    d_out: Vec<T>,
}

impl<T: Float + Default> HullPenalty<T> {
    /// Evaluates λ · (1/n) Σ max(0, δ − φ(p_j)) at `points` (δ = `margin`,
    /// λ = `weight`) and ADDS its gradient with respect to the SDF field's
    /// parameters into `grads`. Returns the unweighted mean.
    pub fn forward_backward(
        &mut self,
        sdf: &SdfField<T>,
        points: &[[T; 3]],
        margin: T,
        weight: T,
        grads: &mut FieldGrads<T>,
    ) -> f64 {
        let n = points.len();
        if n == 0 {
            return 0.0;
        }
        sdf.forward(points, &mut self.ctx);
        let k = sdf.n_output();
        let scale = weight / of(n as f64);
        self.d_out.clear();
        self.d_out.resize(n * k, T::ZERO);
        let mut sum = 0.0f64;
        let mut active = false;
        for (row, d) in self
            .ctx
            .output()
            .chunks_exact(k)
            .zip(self.d_out.chunks_exact_mut(k))
        {
            let shortfall = margin - row[0];
            if shortfall > T::ZERO {
                sum += to_f64(shortfall);
                d[0] = T::ZERO - scale;
                active = true;
            }
        }
        if active {
            sdf.backward(&mut self.ctx, &self.d_out, grads, None);
        }
        sum / n as f64
    }
}

/// The hull prior during training: the hull, the grid cells where its
/// points are drawn, and the penalty's buffers.
pub struct HullPrior {
    hull: VisualHull,
    /// Non-empty occupancy cells whose centre is outside the hull.
    cells: Vec<u32>,
    cell_size: f32,
    points: Vec<[f32; 3]>,
    penalty: HullPenalty<f32>,
}

impl HullPrior {
    /// A prior over `hull`; no cells until [`HullPrior::update_cells`].
    pub fn new(hull: VisualHull) -> Self {
        Self {
            hull,
            cells: Vec::new(),
            cell_size: 0.0,
            points: Vec::new(),
            penalty: HullPenalty::default(),
        }
    }

    /// Number of cells the points are drawn from.
    pub fn cell_count(&self) -> usize {
        self.cells.len()
    }

    /// Re-selects the cells to draw from after `grid` was refreshed (or
    /// restored): the cells whose last measured centre value is at most the
    /// grid's band for an infinite sharpness (inside the object, or near
    /// enough to its surface to hold part of it; the band of a finite
    /// sharpness only adds NeuS's tail) and whose centre is outside the
    /// hull. The choice depends on the measured values alone, so a resumed
    /// run draws from the same cells.
    pub fn update_cells(&mut self, grid: &OccupancyGrid) {
        let near = grid.band(f32::INFINITY);
        self.cell_size = grid.cell_size();
        self.cells.clear();
        for (i, &phi) in grid.sdf_values().iter().enumerate() {
            if phi <= near && self.hull.outside(grid.cell_center(i).map(f64::from)) {
                self.cells.push(i as u32);
            }
        }
    }

    /// Draws `n` points uniformly in random selected cells, keeps those
    /// outside the hull, and evaluates λ · L_hull there (λ = `weight`),
    /// adding its gradient into `grads`. Returns the unweighted mean over
    /// the kept points (0 when there are none).
    pub fn forward_backward(
        &mut self,
        sdf: &SdfField<f32>,
        grid: &OccupancyGrid,
        rng: &mut impl Rng,
        n: usize,
        weight: f32,
        grads: &mut FieldGrads<f32>,
    ) -> f64 {
        self.points.clear();
        if self.cells.is_empty() {
            return 0.0;
        }
        let half = 0.5 * self.cell_size;
        for _ in 0..n {
            let cell = self.cells[rng.random_range(0..self.cells.len())] as usize;
            let c = grid.cell_center(cell);
            let p = c.map(|v| v + rng.random_range(-half..half));
            if self.hull.outside(p.map(f64::from)) {
                self.points.push(p);
            }
        }
        self.penalty
            .forward_backward(sdf, &self.points, HULL_MARGIN as f32, weight, grads)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat4;
    use wildlight_data::camera::intrinsics_from_fov_x;
    use wildlight_render::{OccupancySettings, RefreshMode};

    /// Radius of the test object, a sphere at the origin.
    const RADIUS: f64 = 0.4;

    /// Six 64×64 cameras on the axes at distance 3 (45° field of view, so
    /// a pixel is about 0.019 units wide at the origin), with the sphere's
    /// exact masks (pixel centres).
    fn sphere_views() -> Vec<(Camera, Vec<bool>)> {
        let k = intrinsics_from_fov_x(64, 64, 45.0);
        let eyes = [
            DVec3::X,
            -DVec3::X,
            DVec3::Y,
            -DVec3::Y,
            DVec3::Z,
            -DVec3::Z,
        ];
        eyes.iter()
            .enumerate()
            .map(|(i, &e)| {
                let up = if e.y.abs() > 0.5 { DVec3::Z } else { DVec3::Y };
                let camera = Camera::look_at(
                    i,
                    64,
                    64,
                    k,
                    3.0 * e,
                    DVec3::ZERO,
                    up,
                    DMat4::IDENTITY,
                    [0.0; 3],
                )
                .unwrap();
                let mask = (0..64 * 64)
                    .map(|p| {
                        let ray = camera.ray((p % 64) as f64, (p / 64) as f64);
                        // distance of the line from the centre
                        ray.origin.cross(ray.dir).length() / ray.dir.length() < RADIUS
                    })
                    .collect();
                (camera, mask)
            })
            .collect()
    }

    fn hull(dilation: usize) -> VisualHull {
        let views = sphere_views();
        VisualHull::new(views.iter().map(|(c, m)| (c, m.as_slice())), dilation)
    }

    #[test]
    fn points_seen_over_background_are_outside() {
        let h = hull(0);
        assert_eq!(h.len(), 6);
        for p in [[0.0, 0.0, 0.0], [0.3, 0.0, 0.1], [0.0, -0.38, 0.0]] {
            assert!(!h.outside(p), "{p:?} is in the sphere");
        }
        // Outside the sphere but inside every cone (the hull of six axis
        // views is the intersection of three cylinders).
        assert!(!h.outside([0.27, 0.27, 0.0]));
        for p in [
            [0.6, 0.0, 0.0],
            [0.0, 0.0, -0.9],
            [0.35, 0.35, 0.0],
            [2.0, 2.0, 2.0],
        ] {
            assert!(h.outside(p), "{p:?} is seen over background");
        }
    }

    #[test]
    fn dilation_keeps_points_near_the_outline_inside() {
        // 0.03 beyond the sphere: outside the exact hull, inside the hull
        // of masks grown by 3 pixels (about 0.06 at the origin).
        let p = [RADIUS + 0.03, 0.0, 0.0];
        assert!(hull(0).outside(p));
        assert!(!hull(3).outside(p));
        assert!(hull(3).outside([RADIUS + 0.15, 0.0, 0.0]));
    }

    #[test]
    fn cells_are_chosen_where_a_floater_is() {
        let h = hull(2);
        let floater = [0.0f32, 0.0, 0.75];
        let sdf = |p: [f32; 3]| {
            let r = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() - RADIUS as f32;
            let d = [p[0] - floater[0], p[1] - floater[1], p[2] - floater[2]];
            r.min((d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() - 0.1)
        };
        let mut grid = OccupancyGrid::new(OccupancySettings {
            resolution: 32,
            ..OccupancySettings::default()
        })
        .unwrap();
        grid.refresh(
            |pts: &[[f32; 3]], out: &mut [f32]| {
                for (o, p) in out.iter_mut().zip(pts) {
                    *o = sdf(*p);
                }
            },
            100.0,
            RefreshMode::Full,
        );
        let mut prior = HullPrior::new(h);
        prior.update_cells(&grid);
        assert!(prior.cell_count() > 0);
        let mut floater_inside = 0;
        for &i in &prior.cells {
            let c = grid.cell_center(i as usize);
            let phi = sdf(c);
            // never a cell inside the object; cells inside the floater all
            // lie near it
            let r = c.iter().map(|v| v * v).sum::<f32>().sqrt();
            assert!(r > RADIUS as f32, "cell {c:?} is inside the object");
            if phi < 0.0 {
                let d: f32 = (0..3)
                    .map(|a| (c[a] - floater[a]).powi(2))
                    .sum::<f32>()
                    .sqrt();
                assert!(d < 0.1, "{c:?}");
                floater_inside += 1;
            }
        }
        // every cell centre inside the floater is chosen (4/3 π 0.1³ / 0.0625³ ≈ 17)
        let all_inside = (0..32usize.pow(3))
            .filter(|&i| {
                let c = grid.cell_center(i);
                sdf(c) < 0.0 && (c.iter().map(|v| v * v).sum::<f32>().sqrt() > 0.5)
            })
            .count();
        assert!(all_inside > 5, "{all_inside}");
        assert_eq!(floater_inside, all_inside);
    }
}
