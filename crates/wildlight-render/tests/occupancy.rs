//! The occupancy grid never marks a cell that contains surface as skippable.
#![allow(clippy::needless_range_loop)] // index-heavy test arithmetic over parallel arrays

mod common;

use common::Torus;
use wildlight_render::occupancy::{CellState, OccupancyGrid, OccupancySettings, RefreshMode};
use wildlight_render::sampler::{CoarseSamples, RaySamples, Rays, Sampler, SamplerSettings};

fn sphere_sdf(radius: f32) -> impl FnMut(&[[f32; 3]], &mut [f32]) {
    move |p: &[[f32; 3]], out: &mut [f32]| {
        for (o, x) in out.iter_mut().zip(p) {
            *o = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt() - radius;
        }
    }
}

/// Every cell whose box meets the sphere |x| = radius (exact box test) is a surface cell.
fn assert_sphere_covered(grid: &OccupancyGrid, radius: f64) -> usize {
    let r = grid.resolution();
    let h = 2.0 / r as f64;
    let mut crossing = 0;
    for z in 0..r {
        for y in 0..r {
            for x in 0..r {
                let (mut near2, mut far2) = (0.0f64, 0.0f64);
                for c in [x, y, z] {
                    let lo = -1.0 + c as f64 * h;
                    let hi = lo + h;
                    let n = 0.0f64.clamp(lo, hi);
                    near2 += n * n;
                    far2 += lo.abs().max(hi.abs()).powi(2);
                }
                if near2.sqrt() <= radius && radius <= far2.sqrt() {
                    crossing += 1;
                    let i = grid.cell_index(x, y, z);
                    assert_eq!(
                        grid.state(i),
                        CellState::Surface,
                        "cell ({x},{y},{z}) contains surface"
                    );
                }
            }
        }
    }
    crossing
}

#[test]
fn sphere_surface_cells_are_never_skipped_even_with_the_tightest_band() {
    // Lipschitz 1, no margin, huge s: band = the cell half-diagonal, the
    // smallest band that is still correct for an exact SDF.
    let settings = OccupancySettings {
        resolution: 48,
        lipschitz: 1.0,
        tail: 1e-6,
        margin: 1e-6,
    };
    let mut grid = OccupancyGrid::new(settings).unwrap();
    let measured = grid.refresh(sphere_sdf(0.55), 1e6, RefreshMode::Full);
    assert!(measured < 48 * 48 * 48 && measured > 48 * 48 * 48 / 2);
    let crossing = assert_sphere_covered(&grid, 0.55);
    let (surface, inside, empty) = grid.counts();
    assert!(crossing > 1000);
    // The grid does skip: most cells are empty or inside, and the surface
    // shell is at most a few cells thick.
    assert!(
        surface < 3 * crossing,
        "surface {surface} vs crossing {crossing}"
    );
    assert!(inside > 0 && empty > surface);
}

#[test]
fn torus_surface_points_lie_in_surface_cells() {
    let torus = Torus::standard();
    let mut grid = common::occupancy_grid(64);
    grid.refresh(torus.batch_sdf(), 1500.0, RefreshMode::Full);
    let (nu, nw) = (1200, 500);
    for i in 0..nu {
        for j in 0..nw {
            let u = i as f64 / nu as f64 * std::f64::consts::TAU;
            let w = j as f64 / nw as f64 * std::f64::consts::TAU;
            let p = torus.surface_point(u, w).map(|x| x as f32);
            assert_eq!(grid.state_at(p), CellState::Surface, "surface point {p:?}");
        }
    }
    assert!(
        grid.occupied_fraction() < 0.35,
        "fraction {}",
        grid.occupied_fraction()
    );
}

/// With the tightest band (no margin, no NeuS tail), a partial refresh
/// still follows a surface that moves by half a cell per refresh, outwards
/// and back: the re-measured neighbours of the surface cells catch it.
#[test]
fn partial_refresh_follows_a_surface_that_moves_half_a_cell_per_refresh() {
    let settings = OccupancySettings {
        resolution: 40,
        lipschitz: 1.0,
        tail: 1e-6,
        margin: 1e-6,
    };
    let mut grid = OccupancyGrid::new(settings).unwrap();
    grid.refresh(sphere_sdf(0.6), 1e6, RefreshMode::Full);
    assert_sphere_covered(&grid, 0.6);
    let cells_in_sphere = {
        let (s, i, e) = grid.counts();
        s + i + e
    };
    let step = 0.5 * grid.cell_size();
    let radii: Vec<f32> = (1..=6)
        .chain((0..6).rev())
        .map(|k| 0.6 + step * k as f32)
        .collect();
    for r in radii {
        let measured = grid.refresh(sphere_sdf(r), 1e6, RefreshMode::Partial { stride: 16 });
        assert_sphere_covered(&grid, r as f64);
        // A partial refresh measures far fewer cells than the whole sphere.
        assert!(
            measured < cells_in_sphere / 2,
            "measured {measured} of {cells_in_sphere}"
        );
    }
}

#[test]
fn reclassify_widens_the_band_for_small_sharpness() {
    let mut grid = common::occupancy_grid(32);
    grid.refresh(sphere_sdf(0.5), 2000.0, RefreshMode::Full);
    let sharp = grid.occupied_fraction();
    grid.reclassify(20.0);
    // band = 0.5 + … > 0.5: every cell near the sphere, and all inside, is sampled.
    assert!(grid.current_band() > 0.5);
    assert!(grid.occupied_fraction() > sharp);
    assert_eq!(grid.state_at([0.0, 0.0, 0.0]), CellState::Surface);
}

#[test]
fn invalid_settings_are_rejected() {
    assert!(
        OccupancyGrid::new(OccupancySettings {
            resolution: 1,
            ..Default::default()
        })
        .is_err()
    );
    assert!(
        OccupancyGrid::new(OccupancySettings {
            lipschitz: 0.5,
            ..Default::default()
        })
        .is_err()
    );
    assert!(
        OccupancyGrid::new(OccupancySettings {
            margin: f32::NAN,
            ..Default::default()
        })
        .is_err()
    );
}

/// The sampled intervals of the block-skipping march agree with a
/// brute-force walk that looks up the cell of closely spaced points.
#[test]
fn sampled_intervals_agree_with_point_lookups() {
    let torus = Torus::standard();
    let mut grid = common::occupancy_grid(64);
    grid.refresh(torus.batch_sdf(), 600.0, RefreshMode::Full);
    let mut rng = common::TestRng(77);
    let mut checked = 0usize;
    let mut intervals = Vec::new();
    for _ in 0..400 {
        let o = [
            rng.uniform(-2.0, 2.0),
            rng.uniform(-2.0, 2.0),
            rng.uniform(-2.0, 2.0),
        ]
        .map(|x| x as f32);
        let aim = [
            rng.uniform(-0.5, 0.5),
            rng.uniform(-0.3, 0.3),
            rng.uniform(-0.5, 0.5),
        ]
        .map(|x| x as f32);
        let d = [aim[0] - o[0], aim[1] - o[1], aim[2] - o[2]];
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let d = d.map(|x| x / l);
        let Some([near, far]) = wildlight_render::sphere_chord(o, d, 1.0) else {
            continue;
        };
        intervals.clear();
        grid.sampled_intervals(o, d, near, far, &mut intervals);
        let inside = |t: f32| intervals.iter().any(|iv| t >= iv[0] && t <= iv[1]);
        // Where the march stopped: the end of the first inside cell it met
        // (possibly a corner cut too thin for the point walk to see).
        let mut t_stop = far;
        grid.march(o, d, near, far, |_, t1, st| {
            if st == CellState::Inside {
                t_stop = t1;
            }
            st != CellState::Inside
        });
        let step = grid.cell_size() / 40.0;
        let mut t = near + 0.5 * step;
        while t < t_stop {
            let at = |t: f32| grid.state_at([o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]]);
            let state = at(t);
            // Skip points within a hair of a cell boundary.
            if at(t - 1e-4) == state && at(t + 1e-4) == state {
                assert_eq!(
                    state != CellState::Empty,
                    inside(t),
                    "t = {t}, state {state:?}"
                );
                checked += 1;
            }
            t += step;
        }
    }
    assert!(checked > 100_000, "checked {checked}");
}

/// A torus SDF (f32 batch closure) with its centre shifted along x.
fn torus_sdf(torus: Torus, shift: f64) -> impl Fn(&[[f32; 3]], &mut [f32]) {
    move |p: &[[f32; 3]], out: &mut [f32]| {
        for (o, x) in out.iter_mut().zip(p) {
            let q = [x[0] as f64 - shift, x[1] as f64, x[2] as f64];
            *o = torus.eval(q).0 as f32;
        }
    }
}

/// Every cell state, the march visits and the sampler's output of `a` and
/// `b` are bit-identical.
fn assert_grids_identical(
    a: &OccupancyGrid,
    b: &OccupancyGrid,
    sdf: impl Fn(&[[f32; 3]], &mut [f32]),
    s: f32,
) {
    let n = a.resolution().pow(3);
    assert_eq!(a.current_band().to_bits(), b.current_band().to_bits());
    assert_eq!(a.refresh_round(), b.refresh_round());
    assert_eq!(a.counts(), b.counts());
    for i in 0..n {
        assert_eq!(a.state(i), b.state(i), "cell {i}");
    }
    let mut rng = common::TestRng(5);
    let mut origins = Vec::new();
    let mut dirs = Vec::new();
    for _ in 0..300 {
        let o = [0; 3].map(|_| rng.uniform(-2.0, 2.0) as f32);
        let aim = [0; 3].map(|_| rng.uniform(-0.5, 0.5) as f32);
        let d = [aim[0] - o[0], aim[1] - o[1], aim[2] - o[2]];
        let l = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let d = d.map(|x| x / l);
        let Some([near, far]) = wildlight_render::sphere_chord(o, d, 1.0) else {
            continue;
        };
        let walk = |g: &OccupancyGrid| {
            let mut v = Vec::new();
            g.march(o, d, near, far, |t0, t1, st| {
                v.push((t0.to_bits(), t1.to_bits(), st));
                true
            });
            v
        };
        let visits = walk(a);
        assert!(!visits.is_empty());
        assert_eq!(visits, walk(b));
        origins.push(o);
        dirs.push(d);
    }
    let rays = Rays {
        origins: &origins,
        dirs: &dirs,
    };
    let run = |g: &OccupancyGrid| {
        let mut sampler = Sampler::new(SamplerSettings::default()).unwrap();
        let (mut coarse, mut out) = (CoarseSamples::default(), RaySamples::default());
        sampler.sample(g, &rays, &sdf, s, Some(3), &mut coarse, &mut out);
        out
    };
    let (sa, sb) = (run(a), run(b));
    assert!(sa.len() > 1000, "{} samples", sa.len());
    assert_eq!(sa.offsets, sb.offsets);
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&sa.t), bits(&sb.t));
    assert_eq!(bits(&sa.delta), bits(&sb.delta));
}

#[test]
fn a_restored_grid_classifies_marches_samples_and_refreshes_like_the_original() {
    let torus = Torus::standard();
    let settings = OccupancySettings {
        resolution: 48,
        ..Default::default()
    };
    let mut grid = OccupancyGrid::new(settings).unwrap();
    // A history of refreshes: full, then partial ones of a moving surface
    // with a changing sharpness (the rotation phase depends on the count).
    grid.refresh(torus_sdf(torus, 0.0), 200.0, RefreshMode::Full);
    for k in 1..=3 {
        grid.refresh(
            torus_sdf(torus, 0.004 * k as f64),
            200.0 + 100.0 * k as f32,
            RefreshMode::Partial { stride: 8 },
        );
    }
    grid.reclassify(650.0);
    let snapshot = grid.snapshot();
    assert_eq!(snapshot.round, 4);
    assert_eq!(snapshot.sdf.as_slice(), grid.sdf_values());

    let mut restored = OccupancyGrid::new(settings).unwrap();
    restored.restore(&snapshot).unwrap();
    assert_eq!(restored.snapshot(), snapshot);
    assert_grids_identical(&grid, &restored, torus_sdf(torus, 0.012), 650.0);

    // The next partial refreshes (same rotation phase) agree as well.
    for k in 4..=5 {
        let f = torus_sdf(torus, 0.004 * k as f64);
        let na = grid.refresh(&f, 700.0, RefreshMode::Partial { stride: 8 });
        let nb = restored.refresh(&f, 700.0, RefreshMode::Partial { stride: 8 });
        assert_eq!(na, nb);
    }
    assert_grids_identical(&grid, &restored, torus_sdf(torus, 0.02), 700.0);

    // set_sdf_values with the band of the current sharpness is the same as
    // restoring and reclassifying.
    let mut other = OccupancyGrid::new(settings).unwrap();
    other
        .set_sdf_values(grid.sdf_values(), grid.band(700.0), grid.refresh_round())
        .unwrap();
    assert_grids_identical(&grid, &other, torus_sdf(torus, 0.02), 700.0);
}

#[test]
fn restoring_a_bad_snapshot_is_an_error_and_changes_nothing() {
    let settings = OccupancySettings {
        resolution: 16,
        ..Default::default()
    };
    let mut grid = OccupancyGrid::new(settings).unwrap();
    grid.refresh(sphere_sdf(0.5), 300.0, RefreshMode::Full);
    let good = grid.snapshot();

    let mut short = good.clone();
    short.sdf.pop();
    let mut nan_inside = good.clone();
    let centre = grid.cell_index(8, 8, 8);
    nan_inside.sdf[centre] = f32::NAN;
    let mut nan_band = good.clone();
    nan_band.band = f32::NAN;
    let mut negative_band = good.clone();
    negative_band.band = -0.1;
    let mut other_resolution = OccupancyGrid::new(OccupancySettings {
        resolution: 20,
        ..settings
    })
    .unwrap()
    .snapshot();
    other_resolution.band = 0.1;
    for bad in [short, nan_inside, nan_band, negative_band, other_resolution] {
        let err = grid.restore(&bad).unwrap_err();
        assert!(err.to_string().contains("occupancy"), "{err}");
        assert_eq!(grid.snapshot(), good);
    }
    // Values outside the sphere are ignored (stored as +∞).
    let mut corner = good.clone();
    corner.sdf[grid.cell_index(0, 0, 0)] = f32::NAN;
    grid.restore(&corner).unwrap();
    assert_eq!(grid.snapshot(), good);
}
