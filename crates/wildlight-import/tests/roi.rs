//! The region of interest on synthetic cameras and points: an object on a
//! table, far background and stray points; centre and radius recovered,
//! the object inside, every camera well outside.

use glam::DVec3;
use wildlight_import::roi::{
    MAX_RADIUS_OF_NEAREST, Roi, RoiCamera, cameras_inside, estimate_roi, nearest_point_to_axes,
};

const CENTER: DVec3 = DVec3::new(0.3, -0.2, 1.0);
const OBJECT_RADIUS: f64 = 0.5;

/// A deterministic sequence in [0, 1).
struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// 30 cameras on a spiral 2.5 away, aiming at the centre within ±2°.
fn cameras(rng: &mut Lcg) -> Vec<RoiCamera> {
    (0..30)
        .map(|k| {
            let az = k as f64 * 0.7;
            let el = (15.0 + k as f64 * 1.2f64).to_radians();
            let eye = CENTER + 2.5 * DVec3::new(el.cos() * az.cos(), el.sin(), el.cos() * az.sin());
            let jitter = DVec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5) * 0.07;
            RoiCamera {
                center: eye,
                axis: ((CENTER - eye).normalize() + jitter).normalize(),
                half_fov: (300.0f64 / 800.0).atan(),
            }
        })
        .collect()
}

/// The object (the part of a sphere above the table), the table (a disc
/// of radius 3 at the object's bottom), far background and strays.
fn points(rng: &mut Lcg, table: bool) -> Vec<DVec3> {
    let mut pts = Vec::new();
    while pts.len() < 300 {
        let d = DVec3::new(rng.next() - 0.5, rng.next() - 0.5, rng.next() - 0.5);
        if let Some(d) = d.try_normalize() {
            let p = CENTER + OBJECT_RADIUS * d;
            if p.y > CENTER.y - 0.8 * OBJECT_RADIUS {
                pts.push(p);
            }
        }
    }
    if table {
        for _ in 0..900 {
            let (r, a) = (3.0 * rng.next().sqrt(), rng.next() * std::f64::consts::TAU);
            let p = CENTER + DVec3::new(r * a.cos(), -OBJECT_RADIUS * 0.8, r * a.sin());
            if (p - CENTER).length() > OBJECT_RADIUS {
                pts.push(p);
            }
        }
    }
    for _ in 0..60 {
        let d = DVec3::new(rng.next() - 0.5, rng.next() * 0.5, rng.next() - 0.5).normalize();
        pts.push(CENTER + (20.0 + 30.0 * rng.next()) * d);
    }
    for _ in 0..10 {
        pts.push(CENTER + DVec3::new(rng.next(), rng.next(), rng.next()) * 4.0 - 2.0);
    }
    pts
}

fn check(cams: &[RoiCamera], pts: &[DVec3]) -> Roi {
    let est = estimate_roi(cams, pts).expect("an estimate");
    let roi = est.roi;
    let off = (roi.center - CENTER).length();
    assert!(
        off < 0.1,
        "centre {} is {off} from the object's",
        roi.center
    );
    assert!(
        roi.radius >= off + OBJECT_RADIUS,
        "radius {} does not cover the object ({off} off)",
        roi.radius
    );
    assert!(
        roi.radius < 2.0 * OBJECT_RADIUS,
        "radius {} too large",
        roi.radius
    );
    let centers: Vec<DVec3> = cams.iter().map(|c| c.center).collect();
    assert!(cameras_inside(&roi, &centers).is_empty());
    assert!(est.nearest_camera >= 1.0 / MAX_RADIUS_OF_NEAREST - 1e-9);
    roi
}

#[test]
fn object_on_a_table_with_outliers() {
    let mut rng = Lcg(7);
    let cams = cameras(&mut rng);
    let pts = points(&mut rng, true);
    check(&cams, &pts);
}

#[test]
fn object_without_a_table() {
    let mut rng = Lcg(11);
    let cams = cameras(&mut rng);
    let pts = points(&mut rng, false);
    check(&cams, &pts);
}

#[test]
fn without_points_the_framing_decides() {
    let mut rng = Lcg(3);
    let cams = cameras(&mut rng);
    let est = estimate_roi(&cams, &[]).unwrap();
    // 2.5 · sin(atan(300/800)) = 0.8779
    assert!((est.roi.radius - 0.8779).abs() < 0.03, "{}", est.roi.radius);
    assert!((est.roi.center - CENTER).length() < 0.1);
}

#[test]
fn the_radius_stays_inside_the_nearest_camera() {
    let mut rng = Lcg(5);
    let mut cams = cameras(&mut rng);
    // one camera very close to the object
    let eye = CENTER + DVec3::new(0.0, 0.3, 0.6);
    cams.push(RoiCamera {
        center: eye,
        axis: (CENTER - eye).normalize(),
        half_fov: 0.6,
    });
    let est = estimate_roi(&cams, &points(&mut rng, true)).unwrap();
    let nearest = (eye - est.roi.center).length();
    assert!(est.roi.radius <= MAX_RADIUS_OF_NEAREST * nearest + 1e-12);
    assert!(cameras_inside(&est.roi, &[eye]).is_empty());
}

#[test]
fn axes_meeting_in_a_point_and_parallel_axes() {
    let p = DVec3::new(1.0, 2.0, 3.0);
    let cams: Vec<RoiCamera> = [DVec3::X, DVec3::Y, DVec3::new(1.0, 1.0, 1.0)]
        .iter()
        .map(|d| RoiCamera {
            center: p - 4.0 * *d,
            axis: d.normalize(),
            half_fov: 0.5,
        })
        .collect();
    assert!((nearest_point_to_axes(&cams).unwrap() - p).length() < 1e-9);
    let parallel: Vec<RoiCamera> = (0..3)
        .map(|k| RoiCamera {
            center: DVec3::new(k as f64, 0.0, 0.0),
            axis: DVec3::Z,
            half_fov: 0.5,
        })
        .collect();
    assert!(nearest_point_to_axes(&parallel).is_none());
    assert!(estimate_roi(&parallel, &[]).is_none());
}

#[test]
fn cameras_inside_are_listed_with_their_distance() {
    let roi = Roi {
        center: DVec3::ZERO,
        radius: 2.0,
    };
    let inside = cameras_inside(
        &roi,
        &[DVec3::new(3.0, 0.0, 0.0), DVec3::new(0.0, 1.0, 0.0)],
    );
    assert_eq!(inside, [(1, 0.5)]);
}
