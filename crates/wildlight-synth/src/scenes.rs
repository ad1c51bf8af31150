//! The built-in procedural scenes: a shape given as a signed distance
//! function and a spatially varying material given as a function of the
//! position, both in the normalized frame (object inside radius ≈ 0.8).
//!
//! The material functions are the ground truth of a capture: they can be
//! evaluated at any surface point, not only at the pixels of the images.
//! Each scene assigns a material to a point by the part of the object
//! nearest to it (the part whose distance function is smallest), then
//! applies that part's pattern.

use glam::DVec3;
use wildlight_material::Material;
use wildlight_pathtrace::hash64;

use crate::sdf::{
    capsule, cylinder_x, cylinder_z, round_box, smooth_intersect, smooth_subtract, smooth_union,
    sphere, torus_y, torus_z,
};

/// A built-in scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BuiltinScene {
    /// A glazed ceramic kettle with a brass handle and foot ring, a steel
    /// knob, a hollow spout and a lid groove: mostly smooth, coloured bands
    /// and dots, some metal and some gloss. The default.
    Kettle,
    /// A material test bench: a plinth with a roughness and specular
    /// gradient under a checker pattern, a rainbow clearcoated sphere, a
    /// metal cube with crossing tunnels, a thin gold ring and a thin
    /// subsurface fin. Sharp edges, thin parts and the whole parameter range.
    Sampler,
}

/// Names of the procedural materials that can be put on any mesh: the
/// scenes' own materials plus the generic `patches`.
pub const PROCEDURAL_MATERIALS: [&str; 3] = ["kettle", "sampler", "patches"];

impl BuiltinScene {
    /// Every built-in scene, the default first.
    pub const ALL: [BuiltinScene; 2] = [BuiltinScene::Kettle, BuiltinScene::Sampler];

    /// The scene's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            BuiltinScene::Kettle => "kettle",
            BuiltinScene::Sampler => "sampler",
        }
    }

    /// One line describing the scene.
    pub fn description(self) -> &'static str {
        match self {
            BuiltinScene::Kettle => {
                "glazed ceramic kettle with brass handle, steel knob, hollow spout (default; moderate)"
            }
            BuiltinScene::Sampler => {
                "material test bench: roughness/specular gradients, clearcoat, metal, thin ring and fin (hard)"
            }
        }
    }

    /// Looks a scene up by name.
    pub fn from_name(name: &str) -> Option<BuiltinScene> {
        BuiltinScene::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Signed distance to the scene's surface at `p` (normalized frame).
    pub fn distance(self, p: DVec3) -> f64 {
        match self {
            BuiltinScene::Kettle => kettle_distance(p),
            BuiltinScene::Sampler => sampler_distance(p),
        }
    }

    /// Unit outward normal of the distance function at `p` (central
    /// differences, step 1e-5; normalized frame).
    pub fn normal(self, p: DVec3) -> DVec3 {
        crate::sdf::gradient(&|q| self.distance(q), p, 1e-5).normalize_or_zero()
    }

    /// Ground-truth material at `p` (normalized frame).
    pub fn material(self, p: DVec3) -> Material {
        procedural_material(self.name(), p).unwrap_or_default()
    }
}

/// The procedural material `name` (one of [`PROCEDURAL_MATERIALS`]) at `p`;
/// `None` for an unknown name.
pub fn procedural_material(name: &str, p: DVec3) -> Option<Material> {
    match name {
        "kettle" => Some(kettle_material(p)),
        "sampler" => Some(sampler_material(p)),
        "patches" => Some(patches_material(p)),
        _ => None,
    }
}

// ---------------------------------------------------------------- kettle --

const KETTLE_BODY: usize = 0;
const KETTLE_FOOT: usize = 1;
const KETTLE_KNOB: usize = 2;
const KETTLE_SPOUT: usize = 3;
const KETTLE_HANDLE: usize = 4;

/// Distances to the kettle's parts before the spout is blended into the
/// body (see [`kettle_distance`]).
fn kettle_parts(p: DVec3) -> [f64; 5] {
    // Body: a sphere with a flat bottom and a groove around the lid.
    let body_sphere = sphere(p - DVec3::new(0.0, -0.06, 0.0), 0.42);
    let floor = -0.36 - p.y; // y ≥ −0.36
    let mut body = smooth_intersect(body_sphere, floor, 0.03);
    let groove = torus_y(p - DVec3::new(0.0, 0.24, 0.0), 0.275, 0.018);
    body = smooth_subtract(body, groove, 0.006);
    // Foot ring under the body.
    let foot = torus_y(p - DVec3::new(0.0, -0.36, 0.0), 0.26, 0.035);
    // Knob on a thin stem.
    let stem = capsule(
        p,
        DVec3::new(0.0, 0.3, 0.0),
        DVec3::new(0.0, 0.42, 0.0),
        0.025,
    );
    let knob = smooth_union(sphere(p - DVec3::new(0.0, 0.45, 0.0), 0.06), stem, 0.02);
    // Hollow spout.
    let a = DVec3::new(0.3, -0.08, 0.0);
    let b = DVec3::new(0.6, 0.2, 0.0);
    let outer = capsule(p, a, b, 0.06);
    let bore = capsule(p, a + 0.5 * (b - a), b + 0.3 * (b - a), 0.032);
    let spout = smooth_subtract(outer, bore, 0.008);
    // Handle: a thin torus in the xy plane, half inside the body.
    let handle = torus_z(p - DVec3::new(-0.42, 0.0, 0.0), 0.2, 0.033);
    [body, foot, knob, spout, handle]
}

/// The kettle: the union of its parts with the spout blended into the body.
fn kettle_distance(p: DVec3) -> f64 {
    let d = kettle_parts(p);
    smooth_union(d[KETTLE_BODY], d[KETTLE_SPOUT], 0.05)
        .min(d[KETTLE_FOOT])
        .min(d[KETTLE_KNOB])
        .min(d[KETTLE_HANDLE])
}

fn mix(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn kettle_material(p: DVec3) -> Material {
    let parts = kettle_parts(p);
    let part = nearest(&parts);
    match part {
        KETTLE_FOOT | KETTLE_HANDLE => Material {
            // brass
            base_color: [0.85, 0.6, 0.3],
            roughness: 0.3,
            metallic: 1.0,
            dielectric: 0.5,
            ..Material::default()
        },
        KETTLE_KNOB => Material {
            // polished steel
            base_color: [0.75, 0.75, 0.78],
            roughness: 0.18,
            metallic: 1.0,
            dielectric: 0.5,
            ..Material::default()
        },
        _ => {
            let cream = [0.78, 0.72, 0.58];
            let red = [0.62, 0.12, 0.07];
            let blue = [0.08, 0.2, 0.55];
            let green = [0.15, 0.45, 0.2];
            if p.y < -0.27 {
                // unglazed terracotta bottom
                return Material {
                    base_color: [0.5, 0.28, 0.18],
                    roughness: 0.85,
                    dielectric: 0.3,
                    subsurface: 0.1,
                    ..Material::default()
                };
            }
            let mut color = cream;
            // red band with soft edges
            let band = smoothstep(-0.1, -0.08, p.y) * (1.0 - smoothstep(0.0, 0.02, p.y));
            color = mix(color, red, band);
            // blue dots on the shoulder, 14 around, 2 rows
            let az = p.z.atan2(p.x);
            let cell_az = (az / (2.0 * std::f64::consts::PI) * 14.0).rem_euclid(1.0) - 0.5;
            for (row_y, shift) in [(0.1, 0.0), (0.17, 0.5)] {
                let da = ((cell_az + shift + 0.5).rem_euclid(1.0) - 0.5) * 0.6;
                let dy = (p.y - row_y) / 0.04;
                let d = (da * da / 0.04 + dy * dy).sqrt();
                color = mix(color, blue, 1.0 - smoothstep(0.8, 1.0, d));
            }
            if part == KETTLE_SPOUT {
                color = green;
            }
            Material {
                base_color: color,
                roughness: 0.4,
                clearcoat: 0.8,
                clearcoat_gloss: 0.8,
                dielectric: 0.5,
                subsurface: 0.2,
                metallic: 0.0,
            }
        }
    }
}

fn nearest(d: &[f64]) -> usize {
    let mut best = 0;
    for (i, v) in d.iter().enumerate() {
        if *v < d[best] {
            best = i;
        }
    }
    best
}

// --------------------------------------------------------------- sampler --

const SAMPLER_PLINTH: usize = 0;
const SAMPLER_SPHERE: usize = 1;
const SAMPLER_CUBE: usize = 2;
const SAMPLER_RING: usize = 3;
const SAMPLER_FIN: usize = 4;

fn sampler_parts(p: DVec3) -> [f64; 5] {
    let plinth = round_box(
        p - DVec3::new(0.0, -0.42, 0.0),
        DVec3::new(0.48, 0.08, 0.36),
        0.012,
    );
    let ball = sphere(p - DVec3::new(-0.24, -0.1, -0.1), 0.25);
    let cube_centre = DVec3::new(0.24, -0.16, 0.02);
    let q = p - cube_centre;
    let cube = round_box(q, DVec3::splat(0.18), 0.008);
    let tunnels = cylinder_x(q, 0.075).min(cylinder_z(q, 0.075));
    let cube = cube.max(-tunnels);
    let ring = torus_z(p - DVec3::new(0.24, 0.24, 0.02), 0.2, 0.028);
    let fin = round_box(
        p - DVec3::new(-0.2, -0.2, 0.26),
        DVec3::new(0.2, 0.14, 0.016),
        0.004,
    );
    [plinth, ball, cube, ring, fin]
}

fn sampler_distance(p: DVec3) -> f64 {
    sampler_parts(p)
        .iter()
        .fold(f64::INFINITY, |a, &b| a.min(b))
}

/// A fully saturated hue in [0, 1) as linear RGB.
fn hue(h: f64) -> [f64; 3] {
    let f = |n: f64| {
        let k = (n + h * 6.0).rem_euclid(6.0);
        1.0 - (k.min(4.0 - k).clamp(0.0, 1.0))
    };
    [f(5.0), f(3.0), f(1.0)]
}

fn sampler_material(p: DVec3) -> Material {
    let parts = sampler_parts(p);
    match nearest(&parts) {
        SAMPLER_PLINTH => {
            // checker of two dielectrics; roughness grows along x, specular along z
            let c = ((p.x / 0.12).floor() + (p.z / 0.12).floor()).rem_euclid(2.0);
            let color = if c < 0.5 {
                [0.7, 0.7, 0.68]
            } else {
                [0.12, 0.3, 0.5]
            };
            Material {
                base_color: color,
                roughness: (0.05 + 0.95 * (p.x + 0.48) / 0.96).clamp(0.0, 1.0),
                dielectric: ((p.z + 0.36) / 0.72).clamp(0.0, 1.0),
                ..Material::default()
            }
        }
        SAMPLER_SPHERE => {
            // hue by azimuth, clearcoat rises with height, subsurface on one side
            let q = p - DVec3::new(-0.24, -0.1, -0.1);
            let h = (q.z.atan2(q.x) / (2.0 * std::f64::consts::PI)).rem_euclid(1.0);
            let col = hue(h);
            Material {
                base_color: mix(col, [0.9, 0.9, 0.9], 0.25),
                roughness: 0.25,
                clearcoat: ((q.y + 0.25) / 0.5).clamp(0.0, 1.0),
                clearcoat_gloss: 0.9,
                subsurface: if q.x > 0.0 { 0.6 } else { 0.0 },
                dielectric: 0.5,
                metallic: 0.0,
            }
        }
        SAMPLER_CUBE => {
            // brushed steel with rougher horizontal stripes
            let stripe = ((p.y / 0.05).floor()).rem_euclid(2.0) < 0.5;
            Material {
                base_color: [0.6, 0.62, 0.65],
                roughness: if stripe { 0.12 } else { 0.45 },
                metallic: 1.0,
                dielectric: 0.5,
                ..Material::default()
            }
        }
        SAMPLER_RING => Material {
            base_color: [0.95, 0.72, 0.3],
            roughness: 0.2,
            metallic: 1.0,
            dielectric: 0.5,
            ..Material::default()
        },
        part => {
            debug_assert_eq!(part, SAMPLER_FIN);
            // waxy subsurface
            Material {
                base_color: [0.85, 0.8, 0.7],
                roughness: 0.7,
                subsurface: 1.0,
                dielectric: 0.4,
                ..Material::default()
            }
        }
    }
}

// --------------------------------------------------------------- patches --

/// Generic material for any mesh: space is cut into cubes of side 0.25 and
/// each cube gets its own material drawn from a hash of its index, about a
/// third of them metal, a third clearcoated.
fn patches_material(p: DVec3) -> Material {
    let c = (p / 0.25).floor();
    let key = (c.x as i64 as u64).wrapping_mul(73_856_093)
        ^ (c.y as i64 as u64).wrapping_mul(19_349_663)
        ^ (c.z as i64 as u64).wrapping_mul(83_492_791);
    let mut h = hash64(key);
    let mut next = || {
        h = hash64(h);
        (h >> 11) as f64 / (1u64 << 53) as f64
    };
    let color = mix(hue(next()), [0.8, 0.8, 0.8], 0.2 + 0.6 * next());
    let kind = next();
    let roughness = 0.08 + 0.9 * next();
    Material {
        base_color: color,
        roughness,
        metallic: if kind < 0.33 { 1.0 } else { 0.0 },
        clearcoat: if kind > 0.66 { 1.0 } else { 0.0 },
        clearcoat_gloss: next(),
        dielectric: next(),
        subsurface: 0.3 * next(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kettle_normal_points_out_of_the_knob_and_the_body() {
        let k = BuiltinScene::Kettle;
        // the knob's sphere (centre y 0.45, radius 0.06) tops the kettle
        let top = k.normal(DVec3::new(0.0, 0.51, 0.0));
        assert!((top - DVec3::Y).length() < 1e-6, "{top:?}");
        // the body's sphere (centre y −0.06, radius 0.42) on its equator, away
        // from the handle (−x) and the spout (+x)
        let side = k.normal(DVec3::new(0.0, -0.06, 0.42));
        assert!((side - DVec3::Z).length() < 1e-6, "{side:?}");
    }

    #[test]
    fn scenes_fit_inside_radius_point_eight_and_contain_the_origin_region() {
        // Sample a grid on the sphere of radius 0.82: every point is outside.
        for scene in BuiltinScene::ALL {
            for i in 0..40 {
                for j in 0..80 {
                    let t = std::f64::consts::PI * (i as f64 + 0.5) / 40.0;
                    let f = 2.0 * std::f64::consts::PI * j as f64 / 80.0;
                    let p = 0.82 * DVec3::new(t.sin() * f.cos(), t.cos(), t.sin() * f.sin());
                    assert!(scene.distance(p) > 0.0, "{} reaches {p:?}", scene.name());
                }
            }
        }
        assert!(BuiltinScene::Kettle.distance(DVec3::ZERO) < -0.2);
    }

    #[test]
    fn materials_are_in_range_and_vary() {
        for name in PROCEDURAL_MATERIALS {
            let mut metal = 0;
            let mut rough = (f64::INFINITY, f64::NEG_INFINITY);
            for i in 0..2000 {
                let u = hash64(i) as f64 / u64::MAX as f64;
                let v = hash64(i + 10_000) as f64 / u64::MAX as f64;
                let w = hash64(i + 20_000) as f64 / u64::MAX as f64;
                let p = DVec3::new(u, v, w) * 1.6 - DVec3::splat(0.8);
                let m = procedural_material(name, p).unwrap();
                assert!(m.out_of_range().is_none(), "{name} at {p:?}: {m:?}");
                metal += (m.metallic > 0.5) as usize;
                rough = (rough.0.min(m.roughness), rough.1.max(m.roughness));
            }
            assert!(metal > 0, "{name} has no metal");
            assert!(rough.1 - rough.0 > 0.4, "{name} roughness range {rough:?}");
        }
        assert!(procedural_material("nope", DVec3::ZERO).is_none());
    }

    #[test]
    fn names_round_trip_and_default_is_first() {
        assert_eq!(BuiltinScene::ALL[0], BuiltinScene::Kettle);
        for s in BuiltinScene::ALL {
            assert_eq!(BuiltinScene::from_name(s.name()), Some(s));
            assert!(PROCEDURAL_MATERIALS.contains(&s.name()));
        }
    }
}
