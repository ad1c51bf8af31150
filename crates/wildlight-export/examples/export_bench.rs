//! Export benchmark at the defaults (512³ marching cubes, 131,072 faces,
//! 2048² textures): prints per-stage seconds, the total, and the peak RSS,
//! over several runs, with medians.
//!
//! ```text
//! RAYON_NUM_THREADS=2 cargo run --release -p wildlight-export --example export_bench -- [RUNS] [analytic|hashgrid]
//! ```
//!
//! `analytic` evaluates a bumpy-torus SDF directly; `hashgrid` adds to
//! every SDF and material evaluation the cost of a multiresolution hash
//! encoding (16 levels × 8 corners × 2 features from a 2¹⁹-entry table)
//! and a 32→64→16 MLP, like a trained fast field (the added value is
//! multiplied by zero, so the surface is the same).

use std::time::Instant;

use glam::{Vec2, Vec3};
use wildlight_export::{AnalyticSource, ExportOptions, FieldSource, export_to_dir};

fn bumpy_torus(p: Vec3) -> f32 {
    let ring = Vec2::new(p.truncate().length() - 0.5, p.z).length() - 0.22;
    ring + 0.01 * (9.0 * p.x).sin() * (9.0 * p.y).sin() * (9.0 * p.z).sin()
}

fn material(p: Vec3) -> [f32; 9] {
    let s = |x: f32| 0.5 + 0.5 * x.sin();
    [
        s(3.0 * p.x),
        s(2.0 * p.y),
        s(2.5 * p.z),
        0.5,
        0.5,
        0.1,
        0.2 * s(p.x),
        0.5,
        0.2,
    ]
}

/// A stand-in for a hash-grid field's cost.
struct HashCost {
    table: Vec<[f32; 2]>,
    weights: Vec<f32>,
}

impl HashCost {
    fn new() -> Self {
        let mut state = 0x2545F4914F6CDD1Du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32 - 0.5
        };
        HashCost {
            table: (0..1 << 19).map(|_| [next(), next()]).collect(),
            weights: (0..32 * 64 + 64 * 16).map(|_| next() * 0.1).collect(),
        }
    }

    fn eval(&self, p: Vec3) -> f32 {
        let mut features = [0.0f32; 32];
        for level in 0..16 {
            let res = 16.0 * 1.38f32.powi(level);
            let q = (p * 0.5 + 0.5) * res;
            let base = q.floor();
            let f = q - base;
            let (bx, by, bz) = (
                base.x as i64 as u64,
                base.y as i64 as u64,
                base.z as i64 as u64,
            );
            let mut acc = [0.0f32; 2];
            for c in 0..8u64 {
                let (dx, dy, dz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
                let h = ((bx + dx)
                    ^ (by + dy).wrapping_mul(2_654_435_761)
                    ^ (bz + dz).wrapping_mul(805_459_861)) as usize
                    & ((1 << 19) - 1);
                let w = (if dx == 1 { f.x } else { 1.0 - f.x })
                    * (if dy == 1 { f.y } else { 1.0 - f.y })
                    * (if dz == 1 { f.z } else { 1.0 - f.z });
                acc[0] += w * self.table[h][0];
                acc[1] += w * self.table[h][1];
            }
            features[2 * level as usize] = acc[0];
            features[2 * level as usize + 1] = acc[1];
        }
        let mut hidden = [0.0f32; 64];
        for (j, h) in hidden.iter_mut().enumerate() {
            let row = &self.weights[j * 32..j * 32 + 32];
            *h = row
                .iter()
                .zip(&features)
                .map(|(a, b)| a * b)
                .sum::<f32>()
                .max(0.0);
        }
        let out = &self.weights[32 * 64..];
        (0..16)
            .map(|k| {
                out[k * 64..k * 64 + 64]
                    .iter()
                    .zip(&hidden)
                    .map(|(a, b)| a * b)
                    .sum::<f32>()
            })
            .sum()
    }
}

fn peak_rss_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("VmHWM:")).and_then(|l| {
                l.split_whitespace()
                    .nth(1)
                    .and_then(|v| v.parse::<f64>().ok())
            })
        })
        .map(|kb| kb / 1024.0)
        .unwrap_or(f64::NAN)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn run(source: &dyn FieldSource, runs: usize) -> anyhow::Result<()> {
    let dir = tempfile::tempdir()?;
    let options = ExportOptions {
        progress: false,
        ..Default::default()
    };
    let mut totals = Vec::new();
    let mut stages: Vec<(String, Vec<f64>)> = Vec::new();
    for r in 0..runs {
        let start = Instant::now();
        let (_, report) = export_to_dir(source, &options, dir.path())?;
        let total = start.elapsed().as_secs_f64();
        println!(
            "run {r}: {total:.1} s, {} raw triangles, {} faces, texture {:?}, {} SDF evaluations, peak RSS {:.0} MiB",
            report.raw_triangles,
            report.faces,
            report.texture_size,
            report.sdf_evaluations,
            peak_rss_mib()
        );
        for (i, (name, s)) in report.seconds.iter().enumerate() {
            if stages.len() <= i {
                stages.push((name.clone(), Vec::new()));
            }
            stages[i].1.push(*s);
        }
        totals.push(total);
    }
    for (name, s) in stages {
        println!("  median {name:>20}: {:.2} s", median(s));
    }
    println!(
        "median total {:.1} s over {runs} runs ({} threads), peak RSS {:.0} MiB",
        median(totals),
        rayon::current_num_threads(),
        peak_rss_mib()
    );
    Ok(())
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let runs: usize = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(3);
    let kind = args.get(2).map(String::as_str).unwrap_or("analytic");
    match kind {
        "analytic" => run(&AnalyticSource::new(bumpy_torus, material), runs),
        "hashgrid" => {
            let cost = std::sync::Arc::new(HashCost::new());
            let (c1, c2) = (cost.clone(), cost);
            let source = AnalyticSource::new(
                move |p| bumpy_torus(p) + 0.0 * c1.eval(p),
                move |p| {
                    let mut m = material(p);
                    m[3] += 0.0 * c2.eval(p);
                    m
                },
            );
            run(&source, runs)
        }
        other => anyhow::bail!("unknown source {other:?} (analytic or hashgrid)"),
    }
}
