//! `ExportOptions::object_only` on a ball standing on a table: the table
//! goes, the ball stays, and the result is closer to the ball than the
//! export that keeps the table; a support plane known from elsewhere cuts
//! what the surface holds below it when the surface has no plane.

use glam::Vec3;
use wildlight_export::{
    AnalyticSource, AtlasOptions, ExportOptions, MarchingOptions, export_asset,
};
use wildlight_mesh::TriMesh;

const CENTER: Vec3 = Vec3::new(0.05, -0.05, 0.0);
const RADIUS: f32 = 0.35;
const TABLE_Y: f32 = -0.4;

/// The ball united with the half-space below the table top (solid table).
fn scene_sdf(p: Vec3) -> f32 {
    ((p - CENTER).length() - RADIUS).min(p.y - TABLE_Y)
}

fn options(object_only: bool) -> ExportOptions {
    ExportOptions {
        marching: MarchingOptions {
            resolution: 96,
            ..Default::default()
        },
        max_faces: 6000,
        atlas: AtlasOptions {
            texture_size: 256,
            ..Default::default()
        },
        object_only,
        world_units: false,
        progress: false,
        ..Default::default()
    }
}

/// Mean distance of the mesh's vertices to the ball's surface.
fn mean_distance_to_ball(mesh: &TriMesh) -> f32 {
    let sum: f32 = mesh
        .positions
        .iter()
        .map(|p| ((*p - CENTER).length() - RADIUS).abs())
        .sum();
    sum / mesh.positions.len() as f32
}

#[test]
fn the_table_is_cut_away_and_the_ball_kept() {
    let source = AnalyticSource::new(scene_sdf, |_| [0.5; 9]);
    let with_table = export_asset(&source, &options(false)).expect("export with the table");
    let object = export_asset(&source, &options(true)).expect("export of the object");

    let plane = object.report.support_plane.expect("the table is found");
    assert!(plane.0[1] > 0.999, "normal {:?}", plane.0);
    assert!((plane.1 - TABLE_Y).abs() < 0.01, "offset {}", plane.1);
    assert_eq!(object.report.support_source.as_deref(), Some("surface"));
    let [support, _outside, _fragments] = object.report.removed_area.unwrap();
    // The disc of table inside the sphere: π(1 − 0.4²) ≈ 2.64.
    assert!(support > 2.3, "support area removed {support}");

    // Nothing of the result lies on or below the table top.
    let raw = object.raw_mesh.positions.iter();
    for p in raw.chain(&object.asset.mesh.positions) {
        assert!(p.y > TABLE_Y + 0.005, "vertex {p} on the table");
    }
    // The ball is kept (its area, 4π·0.35² ≈ 1.54, less a small cap at the
    // cut), and the result lies on it.
    let ball_area = 4.0 * std::f64::consts::PI * (RADIUS as f64).powi(2);
    let kept = object.raw_mesh.total_area();
    assert!(
        kept > 0.9 * ball_area && kept < 1.02 * ball_area,
        "{kept} of {ball_area}"
    );
    let cell = 2.0 / 96.0;
    let d_object = mean_distance_to_ball(&object.raw_mesh);
    let d_table = mean_distance_to_ball(&with_table.raw_mesh);
    assert!(
        d_object < 0.05 * cell,
        "object-only mean distance {d_object}"
    );
    assert!(
        d_table > 10.0 * d_object,
        "with the table {d_table}, object only {d_object}"
    );
}

#[test]
fn an_object_without_a_table_is_left_whole() {
    let ball = |p: Vec3| (p - CENTER).length() - RADIUS;
    let source = AnalyticSource::new(ball, |_| [0.5; 9]);
    let plain = export_asset(&source, &options(false)).expect("export");
    let object = export_asset(&source, &options(true)).expect("export, object only");
    assert_eq!(object.report.support_plane, None);
    assert_eq!(
        object.raw_mesh.triangles.len(),
        plain.raw_mesh.triangles.len()
    );
}

/// A ball whose foot runs on below the table top as a column, with no table
/// in the field (what a run without masks leaves when the background holds
/// the table): the surface gives no plane, the known one cuts the column.
#[test]
fn a_known_support_plane_cuts_what_runs_on_below_it() {
    let column = |p: Vec3| {
        let radial = Vec3::new(p.x - CENTER.x, 0.0, p.z - CENTER.z).length() - 0.15;
        radial.max(p.y - CENTER.y)
    };
    let sdf = move |p: Vec3| ((p - CENTER).length() - RADIUS).min(column(p));
    let source = AnalyticSource::new(sdf, |_| [0.5; 9]);
    let searched = export_asset(&source, &options(true)).expect("export, object only");
    assert_eq!(searched.report.support_plane, None);
    assert!(
        searched
            .raw_mesh
            .positions
            .iter()
            .any(|p| p.y < TABLE_Y - 0.2)
    );
    let known = wildlight_mesh::SupportPlane {
        normal: Vec3::Y,
        offset: TABLE_Y,
    };
    let cut = export_asset(
        &source,
        &ExportOptions {
            known_support: Some(known),
            ..options(true)
        },
    )
    .expect("export with the known plane");
    assert_eq!(cut.report.support_plane, Some(([0.0, 1.0, 0.0], TABLE_Y)));
    assert_eq!(cut.report.support_source.as_deref(), Some("known"));
    for p in cut
        .raw_mesh
        .positions
        .iter()
        .chain(&cut.asset.mesh.positions)
    {
        assert!(
            p.y > TABLE_Y + 0.005,
            "vertex {p} on or below the table top"
        );
    }
    // The ball and the column's stub above the table are what is left.
    let ball_area = 4.0 * std::f64::consts::PI * (RADIUS as f64).powi(2);
    let kept = cut.raw_mesh.total_area();
    assert!(
        kept > 0.9 * ball_area && kept < 1.3 * ball_area,
        "{kept} of {ball_area}"
    );
}
