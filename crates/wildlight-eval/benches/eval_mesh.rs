//! Benchmark of `wildlight eval mesh` (issue 4 target: two 100 000-triangle
//! meshes with visibility from 64 cameras in under 30 s on 2 cores).
//!
//! Run with `cargo bench -p wildlight-eval --bench eval_mesh [-- REPEATS [BUMP]]`;
//! BUMP (default 0.01) is the amplitude of the prediction's bumps: 0.01
//! lets the σ rule stop early, 0.1 forces the full million pairs (the
//! slowest case).
//! set RAYON_NUM_THREADS=1 or 2 to compare thread counts. Prints every run
//! and the median, split into visibility and eq. 16.

use glam::Vec3;
use std::time::Instant;
use wildlight_eval::shapes::{fibonacci_sphere, torus};
use wildlight_eval::{SurfaceDistanceOptions, Viewpoint, surface_distance, visible_triangles};

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let repeats: usize = args.first().and_then(|a| a.parse().ok()).unwrap_or(5);
    let bump: f32 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(0.01);
    // Ground truth: a torus (it hides part of its inner ring from most
    // cameras). Prediction: a differently tessellated bumpy torus.
    let gt = torus(1.0, 0.35, 500, 100, |_, _| 0.0);
    let pred = torus(1.0, 0.35, 400, 125, |u, v| {
        bump * (7.0 * u).sin() * (5.0 * v).cos()
    });
    assert_eq!(gt.triangles.len(), 100_000);
    assert_eq!(pred.triangles.len(), 100_000);
    // 64 cameras on the upper hemisphere (an object standing on a table):
    // the underside is hidden, which is the expensive case (every camera and
    // test point is tried before a triangle is declared invisible).
    let cameras: Vec<Viewpoint> = fibonacci_sphere(128, 3.0, Vec3::ZERO)
        .into_iter()
        .filter(|c| c.z > 0.0)
        .map(|c| Viewpoint::omnidirectional(c.as_dvec3()))
        .collect();
    assert_eq!(cameras.len(), 64);
    println!(
        "eval mesh: 2 × 100000 triangles, 64 cameras, bump {bump}, {} thread(s), {repeats} runs",
        rayon::current_num_threads()
    );
    let mut totals = Vec::new();
    for run in 0..repeats {
        let start = Instant::now();
        let (vis_pred, vis_gt) = rayon::join(
            || visible_triangles(&pred, &cameras).unwrap(),
            || visible_triangles(&gt, &cameras).unwrap(),
        );
        let pred_used = pred.select_triangles(&vis_pred);
        let gt_used = gt.select_triangles(&vis_gt);
        let visibility = start.elapsed().as_secs_f64();
        let result =
            surface_distance(&pred_used, &gt_used, &SurfaceDistanceOptions::default()).unwrap();
        let total = start.elapsed().as_secs_f64();
        println!(
            "run {run}: total {total:.2} s (visibility {visibility:.2} s, eq. 16 {:.2} s); \
             visible {}/{} pred, {}/{} gt; mean {:.6} median {:.6} pairs {} σ {:.2e}",
            total - visibility,
            pred_used.triangles.len(),
            pred.triangles.len(),
            gt_used.triangles.len(),
            gt.triangles.len(),
            result.mean,
            result.median,
            result.pairs,
            result.std_of_mean
        );
        totals.push(total);
    }
    totals.sort_by(f64::total_cmp);
    println!("median total: {:.2} s", totals[totals.len() / 2]);
}
