//! The background behind the object (`--background room|table|none`):
//! what the photos show where their rays miss the object, that masks and
//! ground truth stay the object's, the table's texture, flash and record,
//! and that no camera looks from below the table.

use std::path::Path;

use glam::DVec3;
use wildlight_data::exr_io::read_exr_rgb;
use wildlight_data::{Dataset, LoadOptions, View};
use wildlight_mesh::TriMesh;
use wildlight_pathtrace::EnvMap;
use wildlight_synth::{
    BackgroundInfo, BackgroundKind, BuiltinScene, MaterialDefinition, RenderScene, RigOptions,
    SceneSource, SynthOptions, synthesize,
};

/// A small capture; elevations ≥ 5° so that the table does not change the
/// rig, and the three backgrounds share their cameras.
fn options(out: &Path, background: BackgroundKind) -> SynthOptions {
    SynthOptions {
        source: SceneSource::Builtin(BuiltinScene::Kettle),
        rig: RigOptions {
            views: 4,
            val_views: 1,
            width: 64,
            height: 56,
            elevation_min_deg: 5.0,
            flash_fraction: 0.5,
            seed: 5,
            ..RigOptions::default()
        },
        // enough samples that no pixel of the table's shadows is black by
        // chance (every sample of a pixel's light blocked)
        spp: 64,
        val_spp: 64,
        mesh_resolution: 64,
        saturation: None,
        background,
        out: out.to_path_buf(),
        progress: false,
        ..SynthOptions::default()
    }
}

fn load(dir: &Path) -> Dataset {
    Dataset::load(dir, &LoadOptions::default()).expect("the capture loads")
}

/// Training and held-out views of a capture, with the folder of their
/// ground-truth maps.
fn all_views(dir: &Path) -> Vec<(View, std::path::PathBuf)> {
    let data = load(dir);
    let mut views: Vec<_> = data
        .views
        .iter()
        .map(|v| (v.clone(), dir.join("gt")))
        .collect();
    let val = data.val.as_ref().expect("val split");
    views.extend(val.views.iter().map(|v| (v.clone(), dir.join("val/gt"))));
    views
}

fn object(dir: &Path) -> RenderScene {
    let mesh = TriMesh::read(dir.join("gt/mesh_normalized.ply")).unwrap();
    RenderScene::new(
        &mesh,
        MaterialDefinition::Procedural {
            name: "kettle".into(),
        },
    )
}

/// The three backgrounds of one rig: the object's pixels are the same with
/// the room and with none, and no brighter with the table, which hides the
/// lower environment from the object (the same samples, some of them now
/// blocked: the lower parts darken); the masks are bit-identical; where the
/// pixel's centre ray misses the object the room shows the environment
/// radiance in its direction, none shows exactly 0, and the table shows
/// neither black nor the room.
#[test]
fn backgrounds_differ_only_where_rays_miss_the_object() {
    let dir = tempfile::tempdir().unwrap();
    let render = |kind: BackgroundKind| {
        let out = dir.path().join(kind.name());
        synthesize(&options(&out, kind)).unwrap();
        out
    };
    let (room, table, none) = (
        render(BackgroundKind::Room),
        render(BackgroundKind::Table),
        render(BackgroundKind::None),
    );
    assert!(!room.join("gt/background.json").exists());
    assert_eq!(
        BackgroundInfo::load(&room).unwrap().kind,
        BackgroundKind::Room
    );
    assert_eq!(
        BackgroundInfo::load(&none).unwrap().kind,
        BackgroundKind::None
    );
    let env = EnvMap::procedural_sky();
    let obj = object(&room);
    let (views_r, views_t, views_n) = (all_views(&room), all_views(&table), all_views(&none));
    let (mut misses, mut table_not_black, mut table_not_room) = (0usize, 0usize, 0usize);
    let (mut object_px, mut darker) = (0usize, 0usize);
    for ((vr, gr), ((vt, _), (vn, gn))) in views_r.iter().zip(views_t.iter().zip(&views_n)) {
        let cam = &vr.camera;
        assert_eq!(cam, &vt.camera, "the table changed the rig");
        assert_eq!(vr.mask, vt.mask, "view {}: table mask", cam.index);
        assert_eq!(vr.mask, vn.mask, "view {}: none mask", cam.index);
        let name = format!("{:03}.exr", cam.index);
        for kind in ["base_color", "normal", "depth", "params"] {
            let a = std::fs::read(gr.join(kind).join(&name)).unwrap();
            let b = std::fs::read(gn.join(kind).join(&name)).unwrap();
            assert!(a == b, "view {}: {kind} differs for none", cam.index);
        }
        let amb_n = read_exr_rgb(&gn.join("ambient").join(&name)).unwrap();
        for y in 0..cam.height {
            for x in 0..cam.width {
                let ray = cam.ray(x as f64, y as f64);
                let (r, t, n) = (vr.image.get(x, y), vt.image.get(x, y), vn.image.get(x, y));
                if obj.trace(ray.origin, ray.dir).is_some() {
                    // the object: none is the room's exactly
                    assert_eq!(r, n, "view {} ({x},{y})", cam.index);
                    object_px += 1;
                    assert!((0..3).all(|c| t[c] <= r[c]), "({x},{y}): {t:?} > {r:?}");
                    darker += (0..3).any(|c| t[c] < 0.99 * r[c]) as usize;
                    continue;
                }
                misses += 1;
                let e = env.radiance(ray.dir);
                for c in 0..3 {
                    assert_eq!(r[c], e[c] as f32, "room at ({x},{y}) is the environment");
                    assert_eq!(n[c], 0.0, "none at ({x},{y}) is black");
                    assert_eq!(amb_n.get(x, y)[c], 0.0);
                }
                table_not_black += (t.iter().sum::<f32>() > 0.0) as usize;
                table_not_room += (0..3).any(|c| (t[c] - r[c]).abs() > 1e-3 * r[c]) as usize;
            }
        }
    }
    assert!(misses > 5000, "{misses} background pixels");
    assert_eq!(
        table_not_black, misses,
        "black background pixels with a table"
    );
    // rays below the horizon see the table (the elevations ≥ 5° put most
    // of every image's background on it)
    let frac = table_not_room as f64 / misses as f64;
    assert!(frac > 0.5, "only {frac} of the background shows the table");
    let frac = darker as f64 / object_px as f64;
    eprintln!("{frac} of {object_px} object pixels darker on the table");
    assert!(
        frac > 0.05,
        "only {frac} of object pixels darker on the table"
    );
}

/// With a table: masks are "the first surface along the ray is the object"
/// (the centre ray cast at the object alone agrees away from the edges),
/// no mask-0 pixel is black, the table near the object's foot shows both
/// squares of its checker, the flash lights it by the inverse-square law
/// with its albedo, gt/background.json records the plane in both frames,
/// every camera lies above it, and the capture is deterministic.
#[test]
fn table_capture() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("table");
    let mut opts = options(&out, BackgroundKind::Table);
    opts.rig.elevation_min_deg = -10.0; // raised to 5° by the table
    opts.rig.flash_fraction = 1.0;
    synthesize(&opts).unwrap();

    let info = BackgroundInfo::load(&out).unwrap();
    assert_eq!(info.kind, BackgroundKind::Table);
    let t = info.table.clone().expect("table record");
    let mesh = TriMesh::read(out.join("gt/mesh_normalized.ply")).unwrap();
    let world = TriMesh::read(out.join("gt/mesh_world.ply")).unwrap();
    let low = mesh
        .positions
        .iter()
        .map(|p| p.y as f64)
        .fold(f64::MAX, f64::min);
    let low_world = world
        .positions
        .iter()
        .map(|p| p.y as f64)
        .fold(f64::MAX, f64::min);
    assert_eq!(t.normal, [0.0, 1.0, 0.0]);
    assert!((t.offset_normalized - low).abs() < 1e-6, "{t:?} vs {low}");
    assert!(
        (t.offset_world - low_world).abs() < 1e-5,
        "{t:?} vs {low_world}"
    );
    assert!((t.radius_world - t.radius_normalized * opts.rig.world_scale).abs() < 1e-9);
    assert!(t.radius_normalized > 20.0);
    let table = t.table;

    let obj = object(&out);
    let (mut edge_disagree, mut disagree, mut pixels) = (0usize, 0usize, 0usize);
    let (mut bg, mut black) = (0usize, 0usize);
    let mut squares = [(0.0f64, 0usize); 2];
    let (mut flash_px, mut albedo_hits) = (0usize, [0usize; 2]);
    for (view, gt) in all_views(&out) {
        let cam = &view.camera;
        assert!(cam.center.y > table.height + 0.05, "camera below the table");
        assert!(cam.flash());
        let mask = view.mask.as_ref().unwrap();
        let name = format!("{:03}.exr", cam.index);
        let ambient = read_exr_rgb(&gt.join("ambient").join(&name)).unwrap();
        let flash = read_exr_rgb(&gt.join("flash").join(&name)).unwrap();
        let (w, h) = (cam.width, cam.height);
        let hit = |x: u32, y: u32| {
            let ray = cam.ray(x as f64, y as f64);
            obj.trace(ray.origin, ray.dir).is_some()
        };
        for y in 0..h {
            for x in 0..w {
                pixels += 1;
                let centre = hit(x, y);
                if centre != mask.get(x, y) {
                    disagree += 1;
                    // only where the object's outline crosses the pixel
                    let edge = [(-1i64, 0i64), (1, 0), (0, -1), (0, 1)]
                        .iter()
                        .any(|(dx, dy)| {
                            let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                            nx >= 0
                                && ny >= 0
                                && nx < w as i64
                                && ny < h as i64
                                && hit(nx as u32, ny as u32) != centre
                        });
                    edge_disagree += edge as usize;
                }
                if mask.get(x, y) {
                    continue;
                }
                bg += 1;
                black += (view.image.get(x, y) == [0.0; 3]) as usize;
                if centre {
                    continue;
                }
                let ray = cam.ray(x as f64, y as f64);
                let Some(tt) = table.intersect(ray.origin, ray.dir, f64::INFINITY) else {
                    continue;
                };
                let p = ray.at(tt);
                // the flash: E ⊙ albedo/π · cos / t², albedo between the two
                let c = -ray.dir.y;
                let f = flash.get(x, y);
                let rho: Vec<f64> = (0..3)
                    .map(|ch| f[ch] as f64 * tt * tt / (cam.light_energy[ch] * c))
                    .collect();
                for (ch, r) in rho.iter().enumerate() {
                    let (a, b) = (table.albedos[0][ch], table.albedos[1][ch]);
                    let albedo = r * std::f64::consts::PI;
                    assert!(
                        albedo >= a.min(b) - 1e-4 && albedo <= a.max(b) + 1e-4,
                        "flash albedo {albedo} at {p}"
                    );
                }
                flash_px += 1;
                for (k, alb) in table.albedos.iter().enumerate() {
                    let albedo = rho[0] * std::f64::consts::PI;
                    albedo_hits[k] += ((albedo - alb[0]).abs() < 1e-3) as usize;
                }
                // near the object's foot, away from the squares' edges
                let (u, v) = (p.x / table.cell, p.z / table.cell);
                let margin = 0.2;
                if DVec3::new(p.x, 0.0, p.z).length() < 1.5
                    && (u - u.round()).abs() > margin
                    && (v - v.round()).abs() > margin
                {
                    let k = ((u.floor() + v.floor()) as i64).rem_euclid(2) as usize;
                    squares[k].0 += ambient.get(x, y)[0] as f64;
                    squares[k].1 += 1;
                }
            }
        }
    }
    assert!(
        bg > 5000 && black == 0,
        "{black} of {bg} background pixels black"
    );
    let frac = disagree as f64 / pixels as f64;
    assert!(
        frac < 0.02,
        "mask and ray cast disagree on {frac} of pixels"
    );
    assert_eq!(
        edge_disagree, disagree,
        "disagreements away from the outline"
    );
    // both albedos appear, exactly, under the flash
    assert!(flash_px > 3000, "{flash_px} table pixels");
    assert!(
        albedo_hits[0] > 300 && albedo_hits[1] > 300,
        "{albedo_hits:?}"
    );
    // the two kinds of squares near the foot differ like their albedos
    let mean = |(s, n): (f64, usize)| {
        assert!(n > 30, "{n} pixels");
        s / n as f64
    };
    let (m0, m1) = (mean(squares[0]), mean(squares[1]));
    let (a0, a1) = (table.albedos[0][0], table.albedos[1][0]);
    let (bright, dark) = if a0 > a1 { (m0, m1) } else { (m1, m0) };
    assert!(
        bright > 1.5 * dark,
        "the checker near the foot: {m0} vs {m1} (albedos {a0}, {a1})"
    );

    // deterministic for a seed
    let again = dir.path().join("again");
    opts.out = again.clone();
    synthesize(&opts).unwrap();
    for (a, b) in all_views(&out).iter().zip(all_views(&again).iter()) {
        assert_eq!(a.0.image, b.0.image);
    }
}

/// A camera below the table is impossible: with a table the lowest
/// elevation is raised to 5°, and a rig entirely below it is refused
/// before anything is written.
#[test]
fn cameras_below_the_table_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("below");
    let mut opts = options(&out, BackgroundKind::Table);
    opts.rig.elevation_min_deg = -60.0;
    opts.rig.elevation_max_deg = -20.0;
    let e = synthesize(&opts).unwrap_err().to_string();
    assert!(e.contains("--elevation-max") && e.contains("table"), "{e}");
    assert!(!out.exists(), "a refused capture wrote files");
    // the same rig without a table is fine
    opts.background = BackgroundKind::Room;
    synthesize(&opts).unwrap();
}
