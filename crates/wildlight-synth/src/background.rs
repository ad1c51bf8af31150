//! What the photos of a synthetic capture show behind the object
//! (`wildlight synth --background room|table|none`).
//!
//! - **room** (the default, and what every capture written before this
//!   option shows): a pixel whose ray misses the object sees the
//!   environment map that lights the object, in the ray's direction.
//! - **table**: as room, plus a large textured table top that the object
//!   stands on: the horizontal plane (+y is up in the scenes, the
//!   environment map and the rig) through the object's lowest point, a disc
//!   of radius [`TABLE_RADIUS`] about the point below the object's centre,
//!   a Lambertian surface with a checker of two wood-like albedos
//!   ([`Table`]). The table is lit by the environment (the object shadows
//!   it; [`TableLight`]) and by the flash (SPEC §2, the same
//!   inverse-square law as the object), and it hides the lower environment
//!   from the object. Light is direct only, as on the object: the table
//!   does not light the object by reflection.
//! - **none**: black: a pixel whose ray misses the object is 0.
//!
//! Masks, the ground-truth meshes and the material maps are the object's
//! alone whatever the background; `gt/background.json`
//! ([`BackgroundInfo`]) records the background of a table or none capture
//! (a capture without it shows the room).

use std::path::Path;

use glam::DVec3;
use rand::Rng;
use rand_pcg::Pcg32;
use serde::{Deserialize, Serialize};
use wildlight_mesh::TriMesh;
use wildlight_pathtrace::{EnvMap, Occluder, Scene};

use crate::error::SynthError;
use crate::rig::{RigOptions, RigView};

/// Format tag of `gt/background.json`.
pub const BACKGROUND_FORMAT: &str = "wildlight-synth-background";

/// Name of the background record in a capture's `gt/` folder.
pub const BACKGROUND_FILE: &str = "background.json";

/// Radius of the table disc, normalized units (about 37 radii of an object
/// of radius 0.8): it crosses the unit sphere, and from the default rig's
/// cameras (0.6 to 2.7 above the kettle's table) its edge lies 1° to 5°
/// below the horizon.
pub const TABLE_RADIUS: f64 = 30.0;

/// Side of a checker square of the table, normalized units.
pub const TABLE_CELL: f64 = 0.25;

/// The two base colours (linear RGB) of the table's checker: light and dark wood.
pub const TABLE_ALBEDOS: [[f64; 3]; 2] = [[0.58, 0.42, 0.26], [0.26, 0.16, 0.09]];

/// Number of environment samples in the pool of a [`TableLight`].
pub const TABLE_LIGHT_POOL: usize = 1 << 16;

/// With a table, the lowest camera elevation is raised to this (degrees), so
/// that every camera looks from above the table.
pub const TABLE_MIN_ELEVATION_DEG: f64 = 5.0;

/// With a table, every camera centre must lie at least this far above the
/// table's plane (normalized units).
pub const TABLE_CAMERA_CLEARANCE: f64 = 0.05;

/// The kinds of background.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BackgroundKind {
    /// The environment map, seen where a ray misses the object (the default).
    #[default]
    Room,
    /// The room, and a textured table top the object stands on.
    Table,
    /// Black.
    None,
}

impl BackgroundKind {
    /// Every kind, the default first.
    pub const ALL: [BackgroundKind; 3] = [
        BackgroundKind::Room,
        BackgroundKind::Table,
        BackgroundKind::None,
    ];

    /// The kind's name on the command line and in `gt/background.json`.
    pub fn name(self) -> &'static str {
        match self {
            BackgroundKind::Room => "room",
            BackgroundKind::Table => "table",
            BackgroundKind::None => "none",
        }
    }

    /// Looks a kind up by name.
    pub fn from_name(name: &str) -> Option<BackgroundKind> {
        BackgroundKind::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The camera rig this background needs: with a table, the lowest
    /// elevation is raised to [`TABLE_MIN_ELEVATION_DEG`] (an error if the
    /// whole range lies below it); otherwise `rig` unchanged.
    pub fn rig(self, rig: &RigOptions) -> Result<RigOptions, SynthError> {
        let mut rig = rig.clone();
        if self == BackgroundKind::Table {
            if !(rig.elevation_max_deg >= TABLE_MIN_ELEVATION_DEG) {
                return Err(SynthError::InvalidOption {
                    what: "--elevation-max".into(),
                    problem: format!(
                        "{}° with --background table: the cameras must look from above the \
                         table, at elevations ≥ {TABLE_MIN_ELEVATION_DEG}°",
                        rig.elevation_max_deg
                    ),
                });
            }
            rig.elevation_min_deg = rig.elevation_min_deg.max(TABLE_MIN_ELEVATION_DEG);
        }
        Ok(rig)
    }
}

/// The table top of [`BackgroundKind::Table`], in the normalized frame:
/// the disc y = `height`, x² + z² ≤ `radius`², a Lambertian reflector
/// (BRDF albedo/π) with a checker texture.
///
/// It is Lambertian, rather than a rough SPEC §3 material, so that the
/// light it reflects does not depend on the view and its shading costs a
/// shadow test per sample ([`TableLight`]); for the flash (l = v) it is
/// the SPEC §3 model with roughness 0.25 and every other parameter 0
/// (eq. 4: 2r − 0.5 = 0).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Table {
    /// Height of the plane (y; +y is up).
    pub height: f64,
    /// Radius of the disc about (0, height, 0).
    pub radius: f64,
    /// Side of a checker square.
    pub cell: f64,
    /// Linear albedos of the two kinds of squares.
    pub albedos: [[f64; 3]; 2],
}

impl Table {
    /// The table under `mesh` (normalized frame): its plane touches the
    /// mesh's lowest point. None for a mesh without vertices.
    pub fn under(mesh: &TriMesh) -> Option<Table> {
        let height = mesh.positions.iter().map(|p| p.y as f64).reduce(f64::min)?;
        Some(Table {
            height,
            radius: TABLE_RADIUS,
            cell: TABLE_CELL,
            albedos: TABLE_ALBEDOS,
        })
    }

    /// The ray parameter t ∈ (0, `t_max`) where the ray from `origin` along
    /// unit `dir` crosses the disc (from either side), if it does.
    pub fn intersect(&self, origin: DVec3, dir: DVec3, t_max: f64) -> Option<f64> {
        if dir.y == 0.0 {
            return None;
        }
        let t = (self.height - origin.y) / dir.y;
        if !(t > 0.0 && t < t_max) {
            return None;
        }
        let p = origin + t * dir;
        (p.x * p.x + p.z * p.z <= self.radius * self.radius).then_some(t)
    }

    /// The linear albedo at the table point `p`, averaged over a box
    /// of `footprint` = (width along x, width along z) about it: the
    /// checker box-filtered exactly (the filter and the checker are both
    /// separable), so that a pixel shows the mean of the squares it
    /// covers instead of aliasing towards the horizon.
    pub fn albedo(&self, p: DVec3, footprint: [f64; 2]) -> [f64; 3] {
        // the box-filtered square wave of period 2 (values ±1) at u, box width w
        let wave = |u: f64, w: f64| {
            let w = w.max(1e-6);
            let tri = |s: f64| ((s * 0.5).rem_euclid(1.0) - 0.5).abs();
            (2.0 * (tri(u - 0.5 * w) - tri(u + 0.5 * w)) / w).clamp(-1.0, 1.0)
        };
        let sx = wave(p.x / self.cell, footprint[0] / self.cell);
        let sz = wave(p.z / self.cell, footprint[1] / self.cell);
        let dark = 0.5 - 0.5 * sx * sz;
        let [a, b] = self.albedos;
        [0, 1, 2].map(|c| a[c] + (b[c] - a[c]) * dark)
    }

    /// Height of `p` above the table's plane.
    pub fn height_above(&self, p: DVec3) -> f64 {
        p.y - self.height
    }
}

/// The environment light that reaches the table, with the object's shadows.
///
/// The table is flat and the environment infinitely far, so every table
/// point faces the same sky: the irradiance without the object,
/// E₀ = ∫ L(l) max(0, l_y) dω, is one number (RGB) per capture, and the
/// object only takes light away. E₀ is the mean of the weights
/// w_k = L(l_k) max(0, l_k,y) / pdf(l_k) of a fixed pool of
/// [`TABLE_LIGHT_POOL`] importance-sampled environment directions l_k
/// (drawn at the points of the R2 low-discrepancy sequence, so that any run
/// of consecutive ones is stratified). At a table point p, a run of
/// `count` consecutive pool samples from a random start gives the
/// irradiance as the unblocked fraction of their weight (per channel),
/// E(p) ≈ E₀ · Σ w_k [l_k not blocked at p] / Σ w_k: a ratio estimator,
/// consistent (its bias falls as 1/count), never negative, and exactly E₀,
/// without noise, far from the object where nothing is blocked. A
/// Lambertian table reflects L = albedo/π · E(p) towards every viewer.
/// Only the directions within the cone from p around the object's
/// bounding sphere are traced.
#[derive(Clone, Debug)]
pub struct TableLight {
    irradiance: DVec3,
    samples: Vec<(DVec3, DVec3)>,
    centre: DVec3,
    radius: f64,
}

impl TableLight {
    /// The pool of `env`'s samples and the irradiance E₀ of an upward
    /// plane, for an object inside the sphere of `radius` about `centre`.
    pub fn new(env: &EnvMap, centre: DVec3, radius: f64) -> TableLight {
        // R2: the additive recurrence of the plastic number
        let g = 1.324_717_957_244_746_f64;
        let (a1, a2) = (1.0 / g, 1.0 / (g * g));
        let samples: Vec<(DVec3, DVec3)> = (0..TABLE_LIGHT_POOL)
            .map(|k| {
                let u1 = (0.5 + a1 * k as f64).fract();
                let u2 = (0.5 + a2 * k as f64).fract();
                let (l, pdf) = env.sample(u1, u2);
                let w = if l.y > 0.0 && pdf > 0.0 {
                    env.radiance(l) * (l.y / pdf)
                } else {
                    DVec3::ZERO
                };
                (l, w)
            })
            .collect();
        let irradiance = samples.iter().map(|s| s.1).sum::<DVec3>() / TABLE_LIGHT_POOL as f64;
        TableLight {
            irradiance,
            samples,
            centre,
            radius,
        }
    }

    /// E₀: the irradiance of an upward plane that nothing shadows.
    pub fn unshadowed(&self) -> DVec3 {
        self.irradiance
    }

    /// The irradiance E(p) at the table point `p` (on the upper side),
    /// shadowed by `object` (inside the sphere given to [`TableLight::new`]),
    /// from `count` pool samples (at most the pool).
    pub fn irradiance(&self, p: DVec3, object: &Scene, count: usize, rng: &mut Pcg32) -> DVec3 {
        let n = self.samples.len();
        let count = count.clamp(1, n);
        let start = rng.random_range(0..n);
        let origin = p + DVec3::Y * (2e-4 * (1.0 + p.length()));
        // the cone of directions from the origin that meet the bounding sphere
        let to = self.centre - origin;
        let d2 = to.length_squared();
        let r2 = self.radius * self.radius;
        let (axis, cos_min) = if d2 > r2 {
            let d = d2.sqrt();
            (to / d, (1.0 - r2 / d2).sqrt())
        } else {
            (DVec3::Y, -1.0) // inside the sphere: every direction
        };
        let (mut open, mut all) = (DVec3::ZERO, DVec3::ZERO);
        for j in 0..count {
            let (l, w) = self.samples[(start + j) % n];
            if w == DVec3::ZERO {
                continue;
            }
            all += w;
            if l.dot(axis) < cos_min || !object.occluded(origin, l, f64::INFINITY) {
                open += w;
            }
        }
        if open == all {
            return self.irradiance;
        }
        // all > 0 here: some weight was blocked
        let fraction = DVec3::select(all.cmpgt(DVec3::ZERO), open / all, DVec3::ONE);
        self.irradiance * fraction
    }
}

/// The object and the table it stands on, as one [`Occluder`] for the
/// shadow rays of the object's shading.
pub struct OnTable<'a> {
    /// The object.
    pub scene: &'a Scene,
    /// The table.
    pub table: &'a Table,
}

impl Occluder for OnTable<'_> {
    fn occluded(&self, origin: DVec3, dir: DVec3, t_max: f64) -> bool {
        self.table.intersect(origin, dir, t_max).is_some()
            || self.scene.occluded(origin, dir, t_max)
    }
}

/// The background a capture is rendered with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Background {
    /// See [`BackgroundKind::Room`].
    Room,
    /// See [`BackgroundKind::Table`].
    Table(Table),
    /// See [`BackgroundKind::None`].
    None,
}

impl Background {
    /// The background of `kind` behind `mesh` (normalized frame).
    pub fn new(kind: BackgroundKind, mesh: &TriMesh) -> Result<Background, SynthError> {
        Ok(match kind {
            BackgroundKind::Room => Background::Room,
            BackgroundKind::None => Background::None,
            BackgroundKind::Table => {
                Background::Table(Table::under(mesh).ok_or_else(|| SynthError::InvalidOption {
                    what: "--background table".into(),
                    problem: "the object has no vertices to stand on".into(),
                })?)
            }
        })
    }

    /// Its kind.
    pub fn kind(&self) -> BackgroundKind {
        match self {
            Background::Room => BackgroundKind::Room,
            Background::Table(_) => BackgroundKind::Table,
            Background::None => BackgroundKind::None,
        }
    }

    /// The table, if there is one.
    pub fn table(&self) -> Option<&Table> {
        match self {
            Background::Table(t) => Some(t),
            _ => None,
        }
    }

    /// Checks that every camera lies at least [`TABLE_CAMERA_CLEARANCE`]
    /// above the table (if any), so that no camera sees the table from
    /// below or the object through it: the object lies above the plane, and
    /// a segment between two points above a plane does not cross it.
    pub fn check_cameras(&self, views: &[RigView]) -> Result<(), SynthError> {
        let Some(table) = self.table() else {
            return Ok(());
        };
        for view in views {
            let above = table.height_above(view.camera.center);
            if !(above >= TABLE_CAMERA_CLEARANCE) {
                return Err(SynthError::InvalidOption {
                    what: "camera rig".into(),
                    problem: format!(
                        "with --background table every camera must lie at least \
                         {TABLE_CAMERA_CLEARANCE} above the table, but view {} ({:?}) lies {above:.3} \
                         above it (raise --elevation-min or --distance)",
                        view.global_index, view.split
                    ),
                });
            }
        }
        Ok(())
    }
}

/// The table of a capture in both frames, as `gt/background.json` records
/// it. Its plane is `normal · x = offset` in each frame (the same normal in
/// both: scale_mat scales and translates without rotating).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TableInfo {
    /// Unit normal of the plane, pointing up towards the object (+y).
    pub normal: [f64; 3],
    /// Offset of the plane in the normalized frame.
    pub offset_normalized: f64,
    /// Offset of the plane in the world frame.
    pub offset_world: f64,
    /// Centre of the disc, normalized frame.
    pub centre_normalized: [f64; 3],
    /// Centre of the disc, world frame.
    pub centre_world: [f64; 3],
    /// Radius of the disc, normalized units.
    pub radius_normalized: f64,
    /// Radius of the disc, world units.
    pub radius_world: f64,
    /// The table as rendered (normalized frame: plane height, radius,
    /// checker cell, albedos of its Lambertian checker).
    pub table: Table,
}

/// The content of `gt/background.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BackgroundInfo {
    /// Always [`BACKGROUND_FORMAT`].
    pub format: String,
    /// Format version (1).
    pub version: u32,
    /// The kind of background.
    pub kind: BackgroundKind,
    /// The table, for [`BackgroundKind::Table`].
    pub table: Option<TableInfo>,
}

impl BackgroundInfo {
    /// The record of `background` in a capture whose normalized frame maps
    /// to the world by x_world = `world_scale` · x + `world_offset`.
    pub fn new(background: &Background, world_scale: f64, world_offset: [f64; 3]) -> Self {
        let table = background.table().map(|t| {
            let centre = DVec3::new(0.0, t.height, 0.0);
            let centre_world = centre * world_scale + DVec3::from(world_offset);
            TableInfo {
                normal: [0.0, 1.0, 0.0],
                offset_normalized: t.height,
                offset_world: centre_world.y,
                centre_normalized: centre.to_array(),
                centre_world: centre_world.to_array(),
                radius_normalized: t.radius,
                radius_world: t.radius * world_scale,
                table: *t,
            }
        });
        BackgroundInfo {
            format: BACKGROUND_FORMAT.into(),
            version: 1,
            kind: background.kind(),
            table,
        }
    }

    /// The background of the capture in `dir`: its `gt/background.json`,
    /// or the room where there is none (captures written before the
    /// option, and room captures, have none).
    pub fn load(dir: &Path) -> Result<BackgroundInfo, SynthError> {
        let path = dir.join("gt").join(BACKGROUND_FILE);
        if !path.exists() {
            return Ok(BackgroundInfo::new(&Background::Room, 1.0, [0.0; 3]));
        }
        let err = |problem: String| SynthError::InvalidOption {
            what: path.display().to_string(),
            problem,
        };
        let text = std::fs::read_to_string(&path).map_err(|e| SynthError::Io {
            path: path.clone(),
            action: "reading",
            source: e,
        })?;
        let info: BackgroundInfo = serde_json::from_str(&text).map_err(|e| err(e.to_string()))?;
        if info.format != BACKGROUND_FORMAT || info.version != 1 {
            return Err(err(format!(
                "format '{}' version {}, expected '{BACKGROUND_FORMAT}' version 1",
                info.format, info.version
            )));
        }
        if (info.kind == BackgroundKind::Table) != info.table.is_some() {
            return Err(err("a table record goes with kind \"table\" only".into()));
        }
        Ok(info)
    }

    /// Writes `DIR/gt/background.json` atomically (pretty JSON).
    pub fn save(&self, dir: &Path) -> Result<(), SynthError> {
        let path = dir.join("gt").join(BACKGROUND_FILE);
        let text = serde_json::to_string_pretty(self).map_err(|e| SynthError::InvalidOption {
            what: path.display().to_string(),
            problem: e.to_string(),
        })?;
        wildlight_data::atomic::write_bytes_atomically(&path, text.as_bytes())?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table() -> Table {
        Table {
            height: -0.5,
            radius: 10.0,
            cell: 0.25,
            albedos: TABLE_ALBEDOS,
        }
    }

    #[test]
    fn rays_cross_the_disc_from_either_side_within_its_radius() {
        let t = table();
        let down = DVec3::new(0.0, -1.0, 0.0);
        assert_eq!(
            t.intersect(DVec3::new(1.0, 1.5, 2.0), down, 10.0),
            Some(2.0)
        );
        assert_eq!(t.intersect(DVec3::new(1.0, 1.5, 2.0), down, 2.0), None);
        assert_eq!(
            t.intersect(DVec3::new(1.0, -1.5, 2.0), -down, 10.0),
            Some(1.0)
        );
        assert_eq!(t.intersect(DVec3::new(1.0, 1.5, 2.0), -down, 10.0), None);
        assert_eq!(t.intersect(DVec3::new(0.0, 1.5, 0.0), DVec3::X, 10.0), None);
        // outside the disc
        assert_eq!(t.intersect(DVec3::new(11.0, 1.5, 0.0), down, 10.0), None);
    }

    #[test]
    fn checker_alternates_and_filters_to_the_mean() {
        let t = table();
        let at = |x: f64, z: f64, w: f64| t.albedo(DVec3::new(x, -0.5, z), [w, w]);
        let (a, b) = (TABLE_ALBEDOS[0], TABLE_ALBEDOS[1]);
        // unfiltered: squares of side 0.25 alternate, both ways
        let close = |u: [f64; 3], v: [f64; 3]| (0..3).all(|c| (u[c] - v[c]).abs() < 1e-9);
        assert!(close(at(0.1, 0.1, 0.0), a) || close(at(0.1, 0.1, 0.0), b));
        let first = at(0.1, 0.1, 0.0);
        let other = if close(first, a) { b } else { a };
        assert!(close(at(0.35, 0.1, 0.0), other));
        assert!(close(at(0.1, 0.35, 0.0), other));
        assert!(close(at(0.35, 0.35, 0.0), first));
        assert!(close(at(-0.15, 0.1, 0.0), other));
        // a footprint of whole periods averages the two
        let mean = [0, 1, 2].map(|c| 0.5 * (a[c] + b[c]));
        assert!(close(at(0.1, 0.13, 1.0), mean));
        assert!(close(at(3.3, -7.1, 2.0), mean));
        // a small footprint inside a square leaves it alone
        assert!(close(at(0.1, 0.1, 0.05), first));
        // continuous in the footprint across a square's edge
        let e0 = at(0.25 - 1e-7, 0.1, 0.02);
        let e1 = at(0.25 + 1e-7, 0.1, 0.02);
        assert!((e0[0] - e1[0]).abs() < 1e-4, "{e0:?} {e1:?}");
        assert!((e0[0] - mean[0]).abs() < 1e-4, "{e0:?}");
    }

    #[test]
    fn the_table_rig_keeps_cameras_above_the_table() {
        let rig = RigOptions::default();
        assert_eq!(BackgroundKind::Room.rig(&rig).unwrap(), rig);
        let raised = BackgroundKind::Table.rig(&rig).unwrap();
        assert_eq!(raised.elevation_min_deg, TABLE_MIN_ELEVATION_DEG);
        assert_eq!(raised.elevation_max_deg, rig.elevation_max_deg);
        // a rig entirely below the table is refused
        let below = RigOptions {
            elevation_min_deg: -60.0,
            elevation_max_deg: -20.0,
            ..RigOptions::default()
        };
        let e = BackgroundKind::Table.rig(&below).unwrap_err();
        assert!(e.to_string().contains("--elevation-max"), "{e}");
        assert!(BackgroundKind::Room.rig(&below).is_ok());
        // and the cameras of such a rig would be refused by the check too
        let views = below.build().unwrap();
        let bg = Background::Table(table());
        assert!(bg.check_cameras(&views).is_err());
        assert!(Background::Room.check_cameras(&views).is_ok());
        let views = raised.build().unwrap();
        bg.check_cameras(&views).unwrap();
        for v in &views {
            assert!(v.camera.center.y > TABLE_CAMERA_CLEARANCE);
        }
    }

    /// Under a uniform sky of radiance 1 an upward plane receives π; a
    /// point far from the object keeps it all, noise-free; a point under a
    /// wide object is in its shadow; the estimate is deterministic.
    #[test]
    fn table_light_is_the_sky_minus_the_object_shadow() {
        let env = EnvMap::from_texels(64, 32, vec![[1.0; 3]; 64 * 32]).unwrap();
        let light = TableLight::new(&env, DVec3::new(0.0, 1.0, 0.0), 1.5);
        let e0 = light.unshadowed();
        assert!(
            (e0.x - std::f64::consts::PI).abs() < 0.01 * std::f64::consts::PI,
            "{e0}"
        );
        // a flat square roof of half-side 1 at height 1 above the plane y = 0
        let roof = TriMesh::new(
            vec![
                [-1.0, 1.0, -1.0].into(),
                [1.0, 1.0, -1.0].into(),
                [1.0, 1.0, 1.0].into(),
                [-1.0, 1.0, 1.0].into(),
            ],
            vec![[0, 1, 2], [0, 2, 3]],
        );
        let scene = Scene::new(&roof);
        let mut rng = wildlight_pathtrace::pixel_rng(1, 0, 0, 0);
        let far = light.irradiance(DVec3::new(50.0, 0.0, 0.0), &scene, 64, &mut rng);
        assert_eq!(far, e0);
        // under its centre the roof blocks ∫ cos dω over its solid angle:
        // for a roof element dA at (x, 1, z), cos at both ends is 1/d, so
        // cos dω = dA / d⁴ with d² = x² + 1 + z² (a quadrature)
        let p = DVec3::ZERO;
        let mut blocked = 0.0;
        let m = 400;
        for i in 0..m {
            for j in 0..m {
                let x = -1.0 + 2.0 * (i as f64 + 0.5) / m as f64;
                let z = -1.0 + 2.0 * (j as f64 + 0.5) / m as f64;
                let d2 = x * x + 1.0 + z * z;
                // dω cos = (area cos_at_roof / d²) cos = dA / d⁴
                blocked += (2.0 / m as f64).powi(2) / (d2 * d2);
            }
        }
        let expected = std::f64::consts::PI - blocked;
        let mut mean = 0.0;
        for k in 0..200 {
            let mut rng = wildlight_pathtrace::pixel_rng(2, 0, k, 0);
            mean += light.irradiance(p, &scene, 256, &mut rng).x / 200.0;
        }
        assert!(
            (mean - expected).abs() < 0.02 * std::f64::consts::PI,
            "{mean} vs {expected}"
        );
        assert!(mean < 0.5 * e0.x, "{mean}");
        let mut a = wildlight_pathtrace::pixel_rng(3, 0, 7, 0);
        let mut b = wildlight_pathtrace::pixel_rng(3, 0, 7, 0);
        assert_eq!(
            light.irradiance(p, &scene, 64, &mut a),
            light.irradiance(p, &scene, 64, &mut b)
        );
    }

    #[test]
    fn names_round_trip() {
        for k in BackgroundKind::ALL {
            assert_eq!(BackgroundKind::from_name(k.name()), Some(k));
        }
        assert_eq!(BackgroundKind::default(), BackgroundKind::Room);
    }
}
