//! Profiling helper: encodes ray samples repeatedly, level-major over the batch (`ENC_REPS`, `BENCH_LOG2T`;
//! `SORT=1` sorts the points in Morton order first).

use wildlight_fields::{HashGrid, HashGridConfig};

fn main() {
    let env = |k: &str, d: usize| {
        std::env::var(k)
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(d)
    };
    let cfg = HashGridConfig {
        log2_table_size: env("BENCH_LOG2T", 19) as u32,
        ..HashGridConfig::default()
    };
    let grid = HashGrid::<f32>::new(&cfg, 1).expect("grid");
    let n = 1 << 18;
    let x: Vec<[f32; 3]> = wildlight_fields::bench::ray_samples(n, 1)
        .into_iter()
        .map(|p| p.map(|v| (v + 1.0) * 0.5))
        .collect();
    let mut x = x;
    if env("SORT", 0) == 1 {
        let key = |p: &[f32; 3]| {
            let mut k = 0u64;
            let q = p.map(|v| (v.clamp(0.0, 1.0) * 1023.0) as u64);
            for b in 0..10 {
                for (d, qd) in q.iter().enumerate() {
                    k |= ((qd >> b) & 1) << (3 * b + d);
                }
            }
            k
        };
        x.sort_by_key(key);
    }
    let no = grid.n_outputs();
    let rows = wildlight_fields::CHUNK_ROWS;
    let layout = wildlight_fields::hash_grid::BlockLayout::column_major(rows);
    let mut blocks: Vec<Vec<f32>> = (0..n.div_ceil(rows))
        .map(|_| vec![0.0; rows * no])
        .collect();
    let t = std::time::Instant::now();
    for _ in 0..env("ENC_REPS", 5) {
        let mut outs: Vec<&mut [f32]> = blocks.iter_mut().map(|b| b.as_mut_slice()).collect();
        grid.encode_blocks(&x, &mut outs, layout, 0, 16);
    }
    let sum: f32 = blocks.iter().flatten().sum();
    println!("{:?} checksum {}", t.elapsed(), sum);
}
