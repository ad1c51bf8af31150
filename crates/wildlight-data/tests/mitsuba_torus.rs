//! The capture written by Mitsuba 3 (an independent NeuS-format writer):
//! the loader reports its cameras exactly as the writer's `meta.json` lists
//! them, and the ground-truth mesh projects into the masks.

use std::path::{Path, PathBuf};

use glam::DVec3;
use wildlight_data::{Dataset, LoadOptions};

fn torus() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/mitsuba-torus")
}

fn meta() -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(torus().join("meta.json")).unwrap()).unwrap()
}

fn vec3(v: &serde_json::Value) -> DVec3 {
    let a: Vec<f64> = serde_json::from_value(v.clone()).unwrap();
    DVec3::new(a[0], a[1], a[2])
}

/// Vertices and triangles of a binary little-endian PLY whose vertex
/// element starts with float x, y, z and whose faces are `list uchar int`
/// (the layout of `gt_mesh_normalized.ply`).
fn read_ply(path: &Path) -> (Vec<DVec3>, Vec<[usize; 3]>) {
    let bytes = std::fs::read(path).unwrap();
    let end = bytes
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = std::str::from_utf8(&bytes[..end]).unwrap();
    assert!(header.contains("format binary_little_endian 1.0"));
    assert!(header.contains("property list uchar int vertex_indices"));
    let (mut n_vertices, mut n_faces, mut stride) = (0usize, 0usize, 0usize);
    let mut in_vertex = false;
    for line in header.lines() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["element", "vertex", n] => {
                n_vertices = n.parse().unwrap();
                in_vertex = true;
            }
            ["element", "face", n] => {
                n_faces = n.parse().unwrap();
                in_vertex = false;
            }
            ["property", ty, _] if in_vertex => {
                stride += match *ty {
                    "float" | "float32" | "int" | "uint" => 4,
                    "uchar" | "uint8" | "char" => 1,
                    "double" => 8,
                    other => panic!("unexpected vertex property type {other}"),
                }
            }
            _ => {}
        }
    }
    let f = |o: usize| f32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()) as f64;
    let i = |o: usize| i32::from_le_bytes(bytes[o..o + 4].try_into().unwrap()) as usize;
    let vertices = (0..n_vertices)
        .map(|k| {
            let o = end + k * stride;
            DVec3::new(f(o), f(o + 4), f(o + 8))
        })
        .collect();
    let mut o = end + n_vertices * stride;
    let mut faces = Vec::with_capacity(n_faces);
    for _ in 0..n_faces {
        assert_eq!(bytes[o], 3, "triangles only");
        faces.push([i(o + 1), i(o + 5), i(o + 9)]);
        o += 13;
    }
    assert_eq!(o, bytes.len());
    (vertices, faces)
}

/// The mesh silhouette seen by `cam`: pixels whose centre, moved by
/// `shift` pixels, lies inside a projected triangle.
fn silhouette(
    cam: &wildlight_data::Camera,
    vertices: &[DVec3],
    faces: &[[usize; 3]],
    shift: f64,
) -> Vec<bool> {
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut out = vec![false; w * h];
    let projected: Vec<glam::DVec2> = vertices.iter().map(|v| cam.project(*v).unwrap()).collect();
    for face in faces {
        let [a, b, c] = face.map(|k| projected[k]);
        let area = (b - a).perp_dot(c - a);
        if area.abs() < 1e-12 {
            continue;
        }
        let lo = a.min(b).min(c).floor().max(glam::DVec2::ZERO);
        let hi = a
            .max(b)
            .max(c)
            .ceil()
            .min(glam::DVec2::new(w as f64 - 1.0, h as f64 - 1.0));
        for y in lo.y as usize..=hi.y as usize {
            for x in lo.x as usize..=hi.x as usize {
                let p = glam::DVec2::new(x as f64 + shift, y as f64 + shift);
                let e0 = (b - a).perp_dot(p - a) / area;
                let e1 = (c - b).perp_dot(p - b) / area;
                let e2 = (a - c).perp_dot(p - c) / area;
                if e0 >= 0.0 && e1 >= 0.0 && e2 >= 0.0 {
                    out[y * w + x] = true;
                }
            }
        }
    }
    out
}

fn iou(a: &[bool], b: &[bool]) -> f64 {
    let inter = a.iter().zip(b).filter(|(x, y)| **x && **y).count();
    let union = a.iter().zip(b).filter(|(x, y)| **x || **y).count();
    inter as f64 / union as f64
}

fn load() -> Dataset {
    Dataset::load(&torus(), &LoadOptions::default()).unwrap()
}

fn check_split(data: &Dataset, views: &serde_json::Value, light_energy: &[f64]) {
    let views = views.as_array().unwrap();
    assert_eq!(data.views.len(), views.len());
    for (view, m) in data.views.iter().zip(views) {
        let cam = &view.camera;
        assert_eq!(cam.index as u64, m["index"].as_u64().unwrap());
        let c = vec3(&m["C_normalized"]);
        assert!(
            cam.center.abs_diff_eq(c, 1e-5),
            "view {}: centre {:?} vs meta {c:?}",
            cam.index,
            cam.center
        );
        let cw = vec3(&m["C_world"]);
        assert!(
            cam.center_world().abs_diff_eq(cw, 1e-5),
            "view {}: world centre",
            cam.index
        );
        assert_eq!(cam.flash(), m["flash"].as_bool().unwrap());
        assert_eq!(cam.flash(), cam.index % 2 == 0, "flash on even views");
        let expected = if cam.flash() {
            light_energy.to_vec()
        } else {
            vec![0.0; 3]
        };
        for (a, b) in cam.light_energy.iter().zip(&expected) {
            // Stored as float32 in the npz.
            assert!(
                (a - b).abs() <= 1e-6 * b.abs().max(1.0),
                "view {}: light energy {a} vs {b}",
                cam.index
            );
        }
        // The camera looks at the writer's target: it projects near the principal point.
        let target = cam.to_normalized(vec3(&m["target_world"]));
        let px = cam.project(target).unwrap();
        assert!(
            (px.x - cam.cx()).abs() < 1e-4 && (px.y - cam.cy()).abs() < 1e-4,
            "view {}: {px:?}",
            cam.index
        );
        assert_eq!(
            view.mask.as_ref().unwrap().count() as u64,
            m["mask_pixels"].as_u64().unwrap()
        );
    }
}

#[test]
fn cameras_match_the_writers_meta() {
    let data = load();
    let meta = meta();
    assert_eq!((data.width(), data.height()), (96, 96));
    assert_eq!(data.saturation, None, "EXR data has no cap");
    let le: Vec<f64> = serde_json::from_value(meta["light_energy"].clone()).unwrap();
    check_split(&data, &meta["views"], &le);
    check_split(data.val.as_ref().unwrap(), &meta["val_views"], &le);
    // Intrinsics: 45° horizontal field of view over 96 pixels, pixel centres at integers.
    let f = 48.0 / 22.5f64.to_radians().tan();
    for v in &data.views {
        let c = &v.camera;
        assert!(
            (c.fx() - f).abs() < 1e-3 && (c.fy() - f).abs() < 1e-3,
            "fx {} vs {f}",
            c.fx()
        );
        assert!((c.cx() - 47.5).abs() < 1e-3 && (c.cy() - 47.5).abs() < 1e-3);
        assert!(c.skew().abs() < 1e-6);
    }
    // scale_mat as in meta.json.
    let s: Vec<Vec<f64>> = serde_json::from_value(meta["scale_mat"].clone()).unwrap();
    let rows = wildlight_data::npz::mat4_rows(&data.views[0].camera.scale_mat);
    for r in 0..4 {
        for c in 0..4 {
            assert!((rows[r][c] - s[r][c]).abs() < 1e-7);
        }
    }
}

#[test]
fn ground_truth_mesh_projects_into_the_masks() {
    let data = load();
    let (vertices, faces) = read_ply(&torus().join("gt_mesh_normalized.ply"));
    assert_eq!((vertices.len(), faces.len()), (8192, 16384));
    assert!(
        vertices.iter().all(|v| v.length() < 1.0),
        "object inside the unit sphere"
    );
    for split in [&data, data.val.as_deref().unwrap()] {
        for view in &split.views {
            let cam = &view.camera;
            let mask = view.mask.as_ref().unwrap();
            // Every vertex lands on the mask or next to it (silhouette pixels
            // less than half covered are background in the binary mask).
            let mut on_mask = 0;
            for v in &vertices {
                let p = cam.project(*v).expect("vertex in front of the camera");
                assert!(
                    cam.contains_pixel(p),
                    "view {}: vertex projects outside the image",
                    cam.index
                );
                let (x, y) = (p.x.round() as i64, p.y.round() as i64);
                let near = (-1..=1).any(|dy| {
                    (-1..=1).any(|dx| {
                        let (xx, yy) = (x + dx, y + dy);
                        (0..96).contains(&xx)
                            && (0..96).contains(&yy)
                            && mask.get(xx as u32, yy as u32)
                    })
                });
                assert!(
                    near,
                    "view {}: vertex {v:?} projects to {p:?}, away from the mask",
                    cam.index
                );
                on_mask += mask.get(x as u32, y as u32) as usize;
            }
            let fraction = on_mask as f64 / vertices.len() as f64;
            assert!(
                fraction > 0.9,
                "view {}: only {fraction} of the vertices land on a mask pixel",
                cam.index
            );
            // The rasterized silhouette matches the mask, and matches it
            // better than with pixel centres off by half a pixel.
            let exact = iou(&silhouette(cam, &vertices, &faces, 0.0), &mask.data);
            assert!(exact > 0.99, "view {}: silhouette IoU {exact}", cam.index);
            for shift in [0.5, -0.5] {
                let shifted = iou(&silhouette(cam, &vertices, &faces, shift), &mask.data);
                assert!(
                    shifted < exact - 0.02,
                    "view {}: IoU {exact} vs {shifted} shifted by {shift}",
                    cam.index
                );
            }
        }
    }
}

#[test]
fn rays_through_mask_pixels_meet_the_unit_sphere() {
    let data = load();
    for view in &data.views {
        let mask = view.mask.as_ref().unwrap();
        for y in 0..96 {
            for x in 0..96 {
                if mask.get(x, y) {
                    let ray = view.camera.ray(x as f64, y as f64);
                    let (near, far) = ray
                        .near_far_unit_sphere()
                        .expect("object pixels see the unit sphere");
                    assert!(near > 0.0 && far > near, "cameras are outside the sphere");
                }
            }
        }
    }
}

#[test]
fn images_are_read_by_channel_name() {
    // Mitsuba stores the channels as B, G, R; the reader looks them up by name.
    let ch = wildlight_data::exr_io::read_exr_channels(&torus().join("image/000.exr")).unwrap();
    let names: Vec<&str> = ch.channels.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(&names[..3], &["B", "G", "R"]);
    let data = load();
    let img = &data.views[0].image;
    let r = ch.channel("R").unwrap();
    let b = ch.channel("B").unwrap();
    for i in [0usize, 1000, 4700, 9215] {
        assert_eq!(img.data[3 * i], r[i]);
        assert_eq!(img.data[3 * i + 2], b[i]);
    }
    assert!(img.data.iter().all(|v| v.is_finite() && *v >= 0.0));
}
