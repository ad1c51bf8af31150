//! PLY reading and writing on hand-written files and on the Mitsuba torus.

use glam::{Vec2, Vec3};
use std::path::Path;
use wildlight_mesh::{MeshError, TriMesh, ply};

const ASCII_QUAD: &str = "ply
format ascii 1.0
comment a unit quad with colours and one extra element
element vertex 4
property double x
property double y
property double z
property uchar red
property uchar green
property uchar blue
element face 1
property list uchar int vertex_indices
element edge 1
property int vertex1
property int vertex2
end_header
0 0 0 255 0 0
1 0 0 0 255 0
1 1 0 0 0 255
0 1 0 51 102 153
4 0 1 2 3
0 1
";

#[test]
fn ascii_quad_is_fan_triangulated_with_colours() {
    let m = ply::parse_ply(ASCII_QUAD.as_bytes(), Path::new("quad.ply")).unwrap();
    assert_eq!(m.positions.len(), 4);
    assert_eq!(m.positions[2], Vec3::new(1.0, 1.0, 0.0));
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    let colors = m.colors.as_ref().unwrap();
    assert_eq!(colors[0], Vec3::X);
    assert!((colors[3] - Vec3::new(0.2, 0.4, 0.6)).abs().max_element() < 1e-6);
    assert!(m.normals.is_none() && m.uvs.is_none());
    assert!((m.total_area() - 1.0).abs() < 1e-12);
}

/// Builds a binary PLY by hand: two vertices-with-normals-and-uv layouts.
fn binary_triangle(big_endian: bool) -> Vec<u8> {
    let format = if big_endian {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let header = format!(
        "ply\nformat {format} 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
         property float z\nproperty double nx\nproperty double ny\nproperty double nz\n\
         property float s\nproperty float t\nelement face 1\n\
         property list uchar uint vertex_indices\nproperty int extra\nend_header\n"
    );
    let mut out = header.into_bytes();
    let f32b = |v: f32| {
        if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let f64b = |v: f64| {
        if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let u32b = |v: u32| {
        if big_endian {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        }
    };
    let verts = [[0.0f32, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 2.0, 0.0]];
    for (i, p) in verts.iter().enumerate() {
        for c in p {
            out.extend_from_slice(&f32b(*c));
        }
        for c in [0.0, 0.0, 1.0] {
            out.extend_from_slice(&f64b(c));
        }
        out.extend_from_slice(&f32b(i as f32 * 0.25));
        out.extend_from_slice(&f32b(0.5));
    }
    out.push(3);
    for i in [0u32, 1, 2] {
        out.extend_from_slice(&u32b(i));
    }
    out.extend_from_slice(&u32b(7));
    out
}

#[test]
fn binary_little_and_big_endian_agree() {
    for big in [false, true] {
        let m = ply::parse_ply(&binary_triangle(big), Path::new("t.ply")).unwrap();
        assert_eq!(
            m.positions[1],
            Vec3::new(2.0, 0.0, 0.0),
            "big endian: {big}"
        );
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        assert_eq!(m.normals.as_ref().unwrap()[2], Vec3::Z);
        assert_eq!(m.uvs.as_ref().unwrap()[2], Vec2::new(0.5, 0.5));
        assert_eq!(m.total_area(), 2.0);
    }
}

#[test]
fn truncated_binary_body_names_file_and_element() {
    let mut bytes = binary_triangle(false);
    bytes.truncate(bytes.len() - 6);
    let err = ply::parse_ply(&bytes, Path::new("cut.ply")).unwrap_err();
    let text = err.to_string();
    assert!(
        text.contains("cut.ply") && text.contains("face 0"),
        "{text}"
    );
}

#[test]
fn ascii_errors_name_the_line() {
    let bad = ASCII_QUAD.replace("1 1 0 0 0 255", "1 oops 0 0 0 255");
    let err = ply::parse_ply(bad.as_bytes(), Path::new("bad.ply")).unwrap_err();
    match &err {
        MeshError::Line { line, .. } => assert_eq!(*line, 19, "{err}"),
        other => panic!("expected a line error, got {other}"),
    }
    assert!(
        err.to_string().contains("bad.ply: line 19: `oops`"),
        "{err}"
    );

    let out_of_range = ASCII_QUAD.replace("4 0 1 2 3", "3 0 1 9");
    let err = ply::parse_ply(out_of_range.as_bytes(), Path::new("r.ply")).unwrap_err();
    assert!(err.to_string().contains("vertex 9"), "{err}");

    let bad_header = ASCII_QUAD.replace("property double y", "property quad y");
    let err = ply::parse_ply(bad_header.as_bytes(), Path::new("h.ply")).unwrap_err();
    assert!(err.to_string().contains("h.ply: line 6:"), "{err}");

    let err = ply::parse_ply(b"obj\n", Path::new("n.ply")).unwrap_err();
    assert!(err.to_string().contains("not a PLY file"), "{err}");
}

#[test]
fn binary_write_read_round_trip_is_exact() {
    let mut m = ply::parse_ply(&binary_triangle(false), Path::new("t.ply")).unwrap();
    m.colors = Some(vec![Vec3::new(1.0, 0.0, 0.2), Vec3::ONE, Vec3::ZERO]);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out.ply");
    m.write(&path).unwrap();
    assert!(!dir.path().join("out.ply.tmp").exists());
    let back = TriMesh::read(&path).unwrap();
    assert_eq!(back.positions, m.positions);
    assert_eq!(back.triangles, m.triangles);
    assert_eq!(back.normals, m.normals);
    assert_eq!(back.uvs, m.uvs);
    // Colours go through 8 bits: 0.2 → 51/255 exactly.
    assert_eq!(back.colors.unwrap()[0], Vec3::new(1.0, 0.0, 51.0 / 255.0));
}

#[test]
fn writing_into_a_missing_folder_fails_with_the_path() {
    let m = TriMesh::new(vec![Vec3::ZERO, Vec3::X, Vec3::Y], vec![[0, 1, 2]]);
    let err = m.write("/nonexistent-folder/x.ply").unwrap_err();
    assert!(
        err.to_string().contains("/nonexistent-folder/x.ply"),
        "{err}"
    );
    let err = m.write("x.stl").unwrap_err();
    assert!(matches!(err, MeshError::UnknownFormat { .. }));
}

#[test]
fn mitsuba_torus_matches_numpy_reference() {
    // Reference values computed once with numpy from the same file
    // (structured dtype read of the binary body, f64 cross products).
    let m = TriMesh::read(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/fixtures/torus_gt_mesh.ply"
    ))
    .unwrap();
    assert_eq!(m.positions.len(), 8192);
    assert_eq!(m.triangles.len(), 16384);
    assert!((m.total_area() - 0.2984565895859285).abs() < 1e-6);
    let b = m.bounding_box().unwrap();
    assert!(
        (b.min - Vec3::new(-0.07864498, -0.165, -0.10889301))
            .abs()
            .max_element()
            < 1e-7
    );
    assert!(
        (b.max - Vec3::new(0.31864497, 0.085, 0.24889302))
            .abs()
            .max_element()
            < 1e-7
    );
    assert_eq!(m.positions[0], Vec3::new(0.31864497, -0.04, 0.07));
    let c0 = m.colors.as_ref().unwrap()[0];
    assert_eq!(c0, Vec3::new(26.0, 77.0, 40.0) / 255.0);
    // A closed torus is one component, and welding exact duplicates changes nothing.
    assert_eq!(m.triangle_components().1, 1);
    assert_eq!(m.welded(0.0).triangles.len(), 16384);
}
