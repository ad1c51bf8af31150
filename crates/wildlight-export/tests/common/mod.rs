//! A small analytic scene shared by the integration tests: a torus with a
//! procedural material, cameras around it, and one export of it.
#![allow(dead_code)]

use std::sync::OnceLock;

use glam::{DVec3, Mat4, Vec2, Vec3};
use wildlight_data::Camera;
use wildlight_data::camera::intrinsics_from_fov_x;
use wildlight_export::{
    AnalyticSource, AtlasOptions, ExportOptions, Exported, FieldSource, MarchingOptions,
    export_asset,
};

pub const MAJOR: f32 = 0.5;
pub const MINOR: f32 = 0.22;

/// Exact torus SDF (normalized frame).
pub fn torus_sdf(p: Vec3) -> f32 {
    Vec2::new(p.truncate().length() - MAJOR, p.z).length() - MINOR
}

/// Exact gradient of [`torus_sdf`].
pub fn torus_gradient(p: Vec3) -> Vec3 {
    let r = p.truncate().length().max(1e-9);
    let ring = Vec3::new(p.x / r * MAJOR, p.y / r * MAJOR, 0.0);
    (p - ring).normalize_or_zero()
}

/// A smooth procedural material with every parameter in use.
pub fn material(p: Vec3) -> [f32; 9] {
    let s = |x: f32| 0.5 + 0.5 * x.sin();
    [
        0.15 + 0.6 * s(3.0 * p.x),
        0.2 + 0.5 * s(2.0 * p.y + 1.0),
        0.25 + 0.4 * s(2.5 * p.z - 0.5),
        0.35 + 0.4 * s(2.0 * p.x + 1.5 * p.y),
        0.3 + 0.5 * s(1.5 * p.y),
        0.2 * s(2.0 * p.z),
        0.25 * s(1.7 * p.x + 0.3),
        0.3 + 0.4 * s(2.2 * p.y - p.z),
        0.3 * s(1.3 * p.x - 2.0 * p.z),
    ]
}

pub fn source() -> impl FieldSource {
    AnalyticSource::new(torus_sdf, material).with_gradient(torus_gradient)
}

/// World = 2.5 · normalized + (0.3, −0.2, 1.0).
pub fn scale_mat() -> Mat4 {
    Mat4::from_translation(Vec3::new(0.3, -0.2, 1.0)) * Mat4::from_scale(Vec3::splat(2.5))
}

pub fn options() -> ExportOptions {
    ExportOptions {
        marching: MarchingOptions {
            resolution: 96,
            ..Default::default()
        },
        max_faces: 8000,
        atlas: AtlasOptions {
            texture_size: 512,
            ..Default::default()
        },
        scale_mat: scale_mat(),
        progress: false,
        ..Default::default()
    }
}

/// The torus exported once for all tests of a test binary.
pub fn exported() -> &'static Exported {
    static EXPORT: OnceLock<Exported> = OnceLock::new();
    EXPORT.get_or_init(|| export_asset(&source(), &options()).expect("export"))
}

/// Flash cameras on a ring around the object (world units), 64×64 pixels.
pub fn cameras() -> Vec<Camera> {
    let sm = scale_mat().as_dmat4();
    let center = sm.transform_point3(DVec3::ZERO);
    let k = intrinsics_from_fov_x(64, 64, 40.0);
    [(0.0f64, 0.9f64), (2.1, 0.4), (4.0, -0.6)]
        .iter()
        .enumerate()
        .map(|(i, &(azimuth, elevation))| {
            let dir = DVec3::new(
                azimuth.cos() * elevation.cos(),
                azimuth.sin() * elevation.cos(),
                elevation.sin(),
            );
            let eye = center + dir * 2.5 * 3.0;
            Camera::look_at(i, 64, 64, k, eye, center, DVec3::Z, sm, [3.0, 2.5, 2.0]).unwrap()
        })
        .collect()
}
