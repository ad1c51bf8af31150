//! Times the default benchmark capture (built-in default scene, 64 views +
//! 8 val views, 256×256, 64 ambient samples per pixel) and prints the wall
//! time of each run and the median:
//! `RAYON_NUM_THREADS=2 cargo run --release -p wildlight-synth --example capture_timing -- [runs] [scene]`.

use std::time::Instant;

use wildlight_synth::{BuiltinScene, SceneSource, SynthOptions, synthesize};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let runs: usize = args.get(1).map(|r| r.parse()).transpose()?.unwrap_or(3);
    let scene = match args.get(2) {
        Some(name) => {
            BuiltinScene::from_name(name).ok_or_else(|| anyhow::anyhow!("unknown scene {name}"))?
        }
        None => BuiltinScene::ALL[0],
    };
    let dir = tempfile::tempdir()?;
    let mut times = Vec::new();
    for run in 0..runs {
        let opts = SynthOptions {
            source: SceneSource::Builtin(scene),
            out: dir.path().join(format!("run{run}")),
            progress: false,
            ..SynthOptions::default()
        };
        let start = Instant::now();
        let summary = synthesize(&opts)?;
        let secs = start.elapsed().as_secs_f64();
        println!(
            "run {run}: {secs:.2} s ({} + {} views, {} triangles, {} threads)",
            summary.train_views,
            summary.val_views,
            summary.triangles,
            rayon::current_num_threads()
        );
        times.push(secs);
    }
    times.sort_by(f64::total_cmp);
    println!("median {:.2} s over {runs} runs", times[times.len() / 2]);
    Ok(())
}
