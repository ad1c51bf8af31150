//! Runs the fields benchmark without the CLI:
//! `cargo run --release -p wildlight-fields --example bench_fields`
//! (environment overrides: `BENCH_LOG2T`, `BENCH_BATCH`, `BENCH_REPS`).

fn main() {
    let mut cfg = wildlight_fields::bench::BenchConfig::default();
    let env = |k: &str| std::env::var(k).ok().and_then(|v| v.parse::<usize>().ok());
    if let Some(t) = env("BENCH_LOG2T") {
        cfg.field.grid.log2_table_size = t as u32;
    }
    if let Some(b) = env("BENCH_BATCH") {
        cfg.batch = b;
    }
    if let Some(r) = env("BENCH_REPS") {
        cfg.reps = r;
    }
    let report = wildlight_fields::bench::run(&cfg).expect("benchmark");
    println!("{}", serde_json::to_string_pretty(&report).expect("json"));
}
