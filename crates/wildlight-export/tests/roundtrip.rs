//! End-to-end checks of an export of an analytic torus: geometry, texel
//! values, dilation, the flash round trip, the eq. 16 round trip, rendering
//! an asset with every map and an environment light, files and the glTF
//! validator.

mod common;

use std::path::{Path, PathBuf};

use glam::{Mat3, Vec3};
use wildlight_eval::{SurfaceDistanceOptions, surface_distance};
use wildlight_export::bake::{NORMAL, rasterize, to_tangent_space};
use wildlight_export::{
    AssetTracer, FlashSettings, LightingSettings, MarchingOptions, ReferenceOptions, flash_psnr,
    flash_round_trip, level_set_reference, read_glb, render_source_flash, write_export,
};

fn written() -> (tempfile::TempDir, wildlight_export::ExportFiles) {
    let dir = tempfile::tempdir().unwrap();
    let files = write_export(common::exported(), dir.path()).unwrap();
    (dir, files)
}

/// A dense, accurate torus mesh in world units (reference for eq. 16).
fn reference_torus_world() -> wildlight_mesh::TriMesh {
    wildlight_eval::shapes::torus(common::MAJOR, common::MINOR, 600, 300, |_, _| 0.0)
        .transformed(&common::scale_mat())
}

#[test]
fn raw_mesh_lies_on_the_analytic_surface() {
    let e = common::exported();
    let to_normalized = common::scale_mat().inverse();
    let voxel = 2.0 / 96.0;
    let worst = e
        .raw_mesh
        .positions
        .iter()
        .map(|p| common::torus_sdf(to_normalized.transform_point3(*p)).abs())
        .fold(0.0f32, f32::max);
    // Linear interpolation of an exact SDF along grid edges: error ≪ a voxel.
    assert!(worst < 0.02 * voxel, "worst vertex |φ| = {worst}");
    let opts = SurfaceDistanceOptions {
        max_pairs: 40_000,
        ..Default::default()
    };
    let reference = reference_torus_world();
    let raw = surface_distance(&e.raw_mesh, &reference, &opts).unwrap();
    let simplified = wildlight_mesh::TriMesh::new(
        e.asset.mesh.positions.clone(),
        e.asset.mesh.triangles.clone(),
    );
    let coarse = surface_distance(&simplified, &reference, &opts).unwrap();
    println!(
        "eq. 16 (world units, scale 2.5): raw {:.3e}, simplified {:.3e}",
        raw.mean, coarse.mean
    );
    // World units: 2.5 × normalized. Faceting of a 96³ grid is ~1e-4 voxel².
    assert!(raw.mean < 2.5 * 1e-3, "raw mesh distance {}", raw.mean);
    assert!(
        coarse.mean < 2.5 * 3e-3,
        "simplified mesh distance {}",
        coarse.mean
    );
    assert!(e.asset.mesh.triangles.len() <= 8000);
    assert!(e.raw_mesh.triangles.len() > 8000);
}

#[test]
fn texels_hold_the_material_at_their_surface_point() {
    let (_dir, files) = written();
    let asset = read_glb(&files.glb).unwrap();
    let e = common::exported();
    let tex = &e.asset.textures;
    let to_normalized = common::scale_mat().inverse();
    let hits = rasterize(&e.asset.mesh, tex.width, tex.height);
    assert!(hits.len() > 50_000, "{} covered texels", hits.len());
    let mesh = &e.asset.mesh;
    let mut checked = 0;
    for h in hits.iter().step_by(97) {
        let tri = mesh.triangles[h.triangle as usize];
        let p: Vec3 = (0..3)
            .map(|k| mesh.positions[tri[k] as usize] * h.bary[k])
            .sum();
        // Project onto the exact torus (closest point) independently of the baker.
        let q = to_normalized.transform_point3(p);
        let g = common::torus_gradient(q);
        let surface = q - g * common::torus_sdf(q);
        let want = common::material(surface);
        let got = asset.textures.texels[h.texel as usize];
        for k in 0..9 {
            // 8-bit quantization (sRGB for the base colour) plus the baker's
            // Newton step.
            let tol = if k < 3 { 0.012 } else { 0.6 / 255.0 + 2e-3 };
            assert!(
                (got[k] - want[k]).abs() <= tol,
                "texel {} param {k}: {} vs {}",
                h.texel,
                got[k],
                want[k]
            );
        }
        // The normal map holds the exact normal in the texel's tangent frame.
        let mut n = Vec3::ZERO;
        let mut t = Vec3::ZERO;
        let mut w = 0.0;
        for (&v, &weight) in tri.iter().zip(&h.bary) {
            n += mesh.normals[v as usize] * weight;
            t += mesh.tangents[v as usize].truncate() * weight;
            w += mesh.tangents[v as usize].w * weight;
        }
        let world_normal = (Mat3::from_mat4(to_normalized).transpose() * g).normalize();
        let local = to_tangent_space(world_normal, n, t, w);
        let stored = Vec3::new(got[NORMAL], got[NORMAL + 1], got[NORMAL + 2]);
        assert!(
            (stored - local).length() < 0.015,
            "normal {stored} vs {local}"
        );
        checked += 1;
    }
    assert!(checked > 500);
}

#[test]
fn dilation_fills_every_gutter_texel_with_surface_values() {
    let e = common::exported();
    let tex = &e.asset.textures;
    let hits = rasterize(&e.asset.mesh, tex.width, tex.height);
    let mut covered = vec![false; tex.texels.len()];
    for h in &hits {
        covered[h.texel as usize] = true;
    }
    let gutter = covered.iter().filter(|c| !**c).count();
    assert!(gutter > 1000, "only {gutter} gutter texels");
    // The procedural base colour red channel lies in [0.15, 0.75]; an
    // unfilled texel would be 0.
    for (t, c) in tex.texels.iter().zip(&covered) {
        if !*c {
            assert!((0.149..=0.751).contains(&t[0]), "gutter texel red {}", t[0]);
            let n = Vec3::new(t[NORMAL], t[NORMAL + 1], t[NORMAL + 2]);
            assert!((n.length() - 1.0).abs() < 1e-4);
        }
    }
}

#[test]
fn flash_of_the_exported_asset_matches_the_source_at_30_db() {
    let (_dir, files) = written();
    let asset = read_glb(&files.glb).unwrap();
    let tracer = AssetTracer::new(&asset, common::scale_mat().inverse()).unwrap();
    // A gain ≠ 1 applies to both renderings.
    let settings = FlashSettings {
        gain: 1.7,
        ..FlashSettings::default()
    };
    let source = common::source();
    let cameras = common::cameras();
    let views = flash_round_trip(&tracer, &source, &cameras, &settings);
    assert_eq!(views.len(), cameras.len());
    for v in &views {
        println!(
            "view {}: flash PSNR {:.2} dB over {} pixels",
            v.index, v.psnr, v.surface_pixels
        );
        assert!(v.surface_pixels > 300, "view {}", v.index);
        assert!(v.psnr >= 30.0, "view {}: {} dB", v.index, v.psnr);
    }
    // The measure is sensitive: a 10 % error of the flash gain alone costs
    // several dB.
    let reference = render_source_flash(&source, &cameras[0], &settings);
    let brighter = FlashSettings {
        gain: 1.7 * 1.1,
        ..settings
    };
    let off = flash_psnr(&tracer.render_flash(&cameras[0], &brighter), &reference).unwrap();
    println!("view 0 with a 10 % gain error: {off:.2} dB");
    assert!(off < views[0].psnr - 3.0, "{off} vs {}", views[0].psnr);
}

#[test]
fn files_are_complete_and_no_temporary_file_is_left() {
    let (dir, files) = written();
    for name in [
        "model.glb",
        "model.obj",
        "model.mtl",
        "mesh_raw.ply",
        "base_color.png",
        "roughness.png",
        "metallic.png",
        "specular.png",
        "clearcoat.png",
        "clearcoat_gloss.png",
        "subsurface.png",
        "normal.png",
    ] {
        assert!(dir.path().join(name).is_file(), "{name} missing");
    }
    let leftovers: Vec<PathBuf> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
    let e = common::exported();
    let obj = wildlight_mesh::TriMesh::read(&files.obj).unwrap();
    assert_eq!(obj.triangles.len(), e.asset.mesh.triangles.len());
    let raw = wildlight_mesh::TriMesh::read(&files.raw_ply).unwrap();
    assert_eq!(raw.triangles.len(), e.raw_mesh.triangles.len());
    let mtl = std::fs::read_to_string(dir.path().join("model.mtl")).unwrap();
    for line in mtl
        .lines()
        .filter(|l| l.starts_with("map_") || l.starts_with("norm"))
    {
        let file = line.split_whitespace().last().unwrap();
        assert!(dir.path().join(file).is_file(), "{line}");
    }
    // The .glb reads back with the same mesh and its recorded frame.
    let asset = read_glb(&files.glb).unwrap();
    assert_eq!(asset.mesh, e.asset.mesh);
    assert_eq!(asset.frame, Some(wildlight_export::AssetFrame::World));
    assert_eq!(
        (asset.textures.width, asset.textures.height),
        (e.asset.textures.width, e.asset.textures.height)
    );
}

/// Where the Khronos validator (npm package `gltf-validator`) is, if anywhere.
fn validator_dir() -> Option<PathBuf> {
    if let Ok(dir) = std::env::var("GLTF_VALIDATOR") {
        return Some(PathBuf::from(dir));
    }
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../node_modules/gltf-validator");
    repo.join("package.json").is_file().then_some(repo)
}

#[test]
fn glb_passes_the_khronos_validator() {
    let Some(validator) = validator_dir() else {
        println!(
            "SKIPPED: gltf-validator not found (set GLTF_VALIDATOR or npm install --prefix <repo> gltf-validator)"
        );
        return;
    };
    if std::process::Command::new("node")
        .arg("--version")
        .output()
        .is_err()
    {
        println!("SKIPPED: node is not installed");
        return;
    }
    let (dir, files) = written();
    let script = dir.path().join("validate.js");
    std::fs::write(
        &script,
        r#"const fs = require('fs');
const validator = require(process.argv[2]);
const bytes = new Uint8Array(fs.readFileSync(process.argv[3]));
validator.validateBytes(bytes, {maxIssues: 50}).then((report) => {
  console.log(JSON.stringify(report.issues, null, 1));
  process.exit(report.issues.numErrors > 0 ? 1 : 0);
}, (err) => { console.error(err); process.exit(2); });
"#,
    )
    .unwrap();
    let out = std::process::Command::new("node")
        .arg(&script)
        .arg(validator.canonicalize().unwrap())
        .arg(&files.glb)
        .output()
        .unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    println!("{report}{}", String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "validator reported errors:\n{report}");
    assert!(report.contains("\"numErrors\": 0"), "{report}");
}

/// Amplitude of the ground truth's bumps (normalized units).
const BUMP: f32 = 0.02;

/// The "ground truth" of the eq. 16 check: the torus with bumps of
/// amplitude [`BUMP`] along its normal, dense, in world units.
fn bumpy_ground_truth_world() -> wildlight_mesh::TriMesh {
    wildlight_eval::shapes::torus(common::MAJOR, common::MINOR, 720, 360, |u, v| {
        BUMP * (3.0 * u).sin() * (2.0 * v).sin()
    })
    .transformed(&common::scale_mat())
}

#[test]
fn raw_mesh_scores_the_eq16_distance_of_the_level_set_within_one_percent() {
    let e = common::exported();
    let source = common::source();
    // The zero level set's reference: a 2× finer extraction, vertices
    // projected onto the level set.
    let options = ReferenceOptions {
        marching: MarchingOptions {
            resolution: 192,
            ..Default::default()
        },
        ..Default::default()
    };
    let (reference, stats) =
        level_set_reference(&source, &options, &indicatif::ProgressBar::hidden()).unwrap();
    assert!(stats.max_abs_sdf_after < 1e-5, "{stats:?}");
    assert!(stats.max_abs_sdf_after < 0.01 * stats.max_abs_sdf_before);
    let reference = reference.transformed(&common::scale_mat());
    let gt = bumpy_ground_truth_world();
    let opts = SurfaceDistanceOptions {
        max_pairs: 200_000,
        ..Default::default()
    };
    let raw = surface_distance(&e.raw_mesh, &gt, &opts).unwrap();
    let level_set = surface_distance(&reference, &gt, &opts).unwrap();
    // Independent value: the bumps' mean height over the torus,
    // BUMP · E|sin 3u| · E|sin 2v| = BUMP · (2/π)², in world units (× 2.5).
    let expected = 2.5 * BUMP as f64 * (2.0 / std::f64::consts::PI).powi(2);
    println!(
        "eq. 16: raw {:.5e}, level set {:.5e}, expected {expected:.5e}",
        raw.mean, level_set.mean
    );
    assert!(
        (level_set.mean - expected).abs() < 0.03 * expected,
        "level set {} vs expected {expected}",
        level_set.mean
    );
    let relative = (raw.mean - level_set.mean).abs() / level_set.mean;
    assert!(
        relative < 0.01,
        "raw {} vs level set {}: {relative}",
        raw.mean,
        level_set.mean
    );
}

/// A sphere of radius 0.6 with one constant material, exported small.
fn constant_sphere() -> (wildlight_export::Exported, wildlight_material::Material) {
    let material = wildlight_material::Material {
        base_color: [0.7, 0.45, 0.2],
        roughness: 0.55,
        clearcoat_gloss: 0.5,
        subsurface: 0.1,
        metallic: 0.15,
        dielectric: 0.5,
        clearcoat: 0.2,
    };
    let params = material.to_array::<f32>();
    let source = wildlight_export::AnalyticSource::new(|p: Vec3| p.length() - 0.6, move |_| params)
        .with_gradient(|p: Vec3| p.normalize_or_zero());
    let options = wildlight_export::ExportOptions {
        marching: MarchingOptions {
            resolution: 64,
            ..Default::default()
        },
        max_faces: 4000,
        atlas: wildlight_export::AtlasOptions {
            texture_size: 256,
            ..Default::default()
        },
        scale_mat: common::scale_mat(),
        progress: false,
        ..Default::default()
    };
    (
        wildlight_export::export_asset(&source, &options).unwrap(),
        material,
    )
}

#[test]
fn asset_view_has_the_flash_term_and_the_synthetic_environment_light() {
    let (exported, material) = constant_sphere();
    let tracer = AssetTracer::new(&exported.asset, common::scale_mat().inverse()).unwrap();
    let env = wildlight_pathtrace::EnvMap::procedural_sky();
    let lighting = LightingSettings {
        env: Some(env.clone()),
        spp: 32,
        ..Default::default()
    };
    let camera = &common::cameras()[1];
    let view = tracer.render_view(camera, camera.light_energy, 1.0, camera.index, &lighting);
    // The flash map is the flash term of render_flash; depth the ray distance.
    let flash = tracer.render_flash(camera, &lighting.flash);
    assert_eq!(view.hits(), flash.hit);
    assert!(view.hits().iter().filter(|h| **h).count() > 400);
    for (i, hit) in view.hits().iter().enumerate() {
        let want = &flash.image.data[i * 3..i * 3 + 3];
        assert_eq!(&view.flash[i][..], want);
        for c in 0..3 {
            assert!((view.rgb[i][c] - view.flash[i][c] - view.ambient[i][c]).abs() < 1e-6);
        }
        if *hit {
            // On the sphere |p| = 0.6 (normalized frame), or inside it by
            // the faceting of 4000 faces (sagitta of a face ≈ 2.5e-3).
            let ray = camera.ray((i % 64) as f64, (i / 64) as f64);
            let p = ray.at(view.depth[i] as f64);
            assert!(
                p.length() < 0.6 + 1e-4 && p.length() > 0.6 - 4e-3,
                "pixel {i}: |p| = {}",
                p.length()
            );
            let n = Vec3::from_array(view.normal[i]);
            assert!(n.angle_between(p.as_vec3().normalize()) < 0.05, "pixel {i}");
            for (k, want) in material.to_array::<f32>().iter().enumerate() {
                assert!(
                    (view.params[i][k] - want).abs() < 0.6 / 255.0 + 0.003,
                    "param {k}"
                );
            }
        } else {
            assert_eq!(view.depth[i], 0.0);
            let sky = env.radiance(ray_dir(camera, i)).as_vec3().to_array();
            assert_eq!(view.ambient[i], sky);
        }
    }
    // The environment term against the synthetic renderer's own rendering
    // of the same mesh with the same (constant) material.
    let normalized = wildlight_mesh::TriMesh::new(
        exported
            .asset
            .mesh
            .positions
            .iter()
            .map(|p| common::scale_mat().inverse().transform_point3(*p))
            .collect(),
        exported.asset.mesh.triangles.clone(),
    );
    let scene = wildlight_synth::RenderScene::new(
        &normalized,
        wildlight_synth::MaterialDefinition::Constant { material },
    );
    let settings = wildlight_synth::ShadingSettings {
        spp: 32,
        brdf: Default::default(),
        noise: 0.0,
        saturation: None,
        seed: 7,
    };
    let synth =
        wildlight_synth::render_view(&scene, &env, camera, 1, &settings, 2.5, &|| {}).unwrap();
    let (mut ours, mut theirs, mut n) = ([0.0f64; 3], [0.0f64; 3], 0);
    for (i, hit) in view.hits().iter().enumerate() {
        let (x, y) = ((i % 64) as u32, (i / 64) as u32);
        if *hit && synth.normal.get(x, y) != [0.0; 3] {
            let s = synth.ambient.get(x, y);
            for c in 0..3 {
                ours[c] += view.ambient[i][c] as f64;
                theirs[c] += s[c] as f64;
            }
            n += 1;
        }
    }
    assert!(n > 400);
    for c in 0..3 {
        assert!(
            (ours[c] - theirs[c]).abs() < 0.03 * theirs[c],
            "channel {c}: mean ambient {} vs synthetic {}",
            ours[c] / n as f64,
            theirs[c] / n as f64
        );
    }
}

fn ray_dir(camera: &wildlight_data::Camera, i: usize) -> glam::DVec3 {
    camera.ray((i % 64) as f64, (i / 64) as f64).dir.normalize()
}
