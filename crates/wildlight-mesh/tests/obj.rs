//! OBJ reading and writing.

use glam::{Vec2, Vec3};
use std::path::Path;
use wildlight_mesh::{MeshError, TriMesh, obj};

#[test]
fn plain_obj_with_polygon_and_negative_indices() {
    let text = "# a unit square and a triangle\n\
                o thing\n\
                v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n\
                f 1 2 3 4\n\
                v 0 0 1\n\
                f -5 -4 -1\n";
    let m = obj::parse_obj(text, Path::new("a.obj")).unwrap();
    assert_eq!(m.positions.len(), 5);
    assert_eq!(m.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
    assert!(m.uvs.is_none() && m.normals.is_none() && m.colors.is_none());
    assert!((m.total_area() - 1.5).abs() < 1e-12);
}

#[test]
fn corner_forms_create_one_vertex_per_distinct_corner() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\
                vt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\n\
                vn 0 0 1\n\
                f 1/1/1 2/2/1 3/3/1\n\
                f 2/2/1 4/4/1 3/3/1\n\
                f 1//1 2//1 3//1\n\
                f 1/1 2/2 3/3\n";
    let m = obj::parse_obj(text, Path::new("b.obj")).unwrap();
    // Distinct corners: 4 full (v/vt/vn), 3 v//vn, 3 v/vt.
    assert_eq!(m.positions.len(), 10);
    assert_eq!(m.triangles.len(), 4);
    assert_eq!(m.triangles[0], [0, 1, 2]);
    assert_eq!(m.triangles[1], [1, 3, 2]);
    let uvs = m.uvs.as_ref().unwrap();
    assert_eq!(uvs[3], Vec2::new(1.0, 1.0));
    // The v//vn corners have no texcoord: zero.
    assert_eq!(uvs[4], Vec2::ZERO);
    let normals = m.normals.as_ref().unwrap();
    assert_eq!(normals[0], Vec3::Z);
    // The v/vt corners have no normal: zero.
    assert_eq!(normals[9], Vec3::ZERO);
}

#[test]
fn vertex_colours_extension_is_read() {
    let text = "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nf 1 2 3\n";
    let m = obj::parse_obj(text, Path::new("c.obj")).unwrap();
    assert_eq!(m.colors.unwrap()[2], Vec3::Z);
}

#[test]
fn errors_name_file_and_line() {
    let cases = [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", 4, "out of range"),
        ("v 0 0 0\nv 1 x 0\n", 2, "`x`"),
        ("v 0 0 0\nv 1 0 0\nf 1 2\n", 3, "2 corners"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n", 4, "index 0"),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/a 2 3\n",
            4,
            "not an integer",
        ),
        ("v 0 0\n", 1, "3 coordinates"),
    ];
    for (text, line, needle) in cases {
        let err = obj::parse_obj(text, Path::new("bad.obj")).unwrap_err();
        match &err {
            MeshError::Line { line: l, .. } => assert_eq!(*l, line, "{err}"),
            other => panic!("expected a line error, got {other}"),
        }
        let msg = err.to_string();
        assert!(msg.starts_with(&format!("bad.obj: line {line}:")), "{msg}");
        assert!(msg.contains(needle), "{msg} lacks {needle}");
    }
}

#[test]
fn write_read_round_trip_keeps_all_attributes() {
    let mut m = TriMesh::new(
        vec![
            Vec3::ZERO,
            Vec3::new(0.5, 0.0, 0.25),
            Vec3::new(0.0, 1.5, 0.0),
        ],
        vec![[0, 1, 2]],
    );
    m.uvs = Some(vec![Vec2::ZERO, Vec2::X, Vec2::new(0.125, 0.75)]);
    m.normals = Some(vec![Vec3::Z, Vec3::Y, Vec3::X]);
    m.colors = Some(vec![Vec3::splat(0.5), Vec3::ONE, Vec3::ZERO]);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.OBJ");
    m.write(&path).unwrap();
    let back = TriMesh::read(&path).unwrap();
    assert_eq!(back, m);
    // Without attributes the `f a b c` form is used and read back identically.
    let plain = TriMesh::new(m.positions.clone(), m.triangles.clone());
    plain.write(&path).unwrap();
    assert_eq!(TriMesh::read(&path).unwrap(), plain);
}

#[test]
fn missing_file_error_names_it() {
    let err = TriMesh::read("/definitely/not/here.obj").unwrap_err();
    assert!(
        err.to_string().starts_with("/definitely/not/here.obj:"),
        "{err}"
    );
}
