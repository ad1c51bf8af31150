//! Helpers shared by the CLI integration tests (`tests/cli_*.rs`): running
//! the `wildlight` binary of this build and writing a tiny synthetic capture.

// Every test binary compiles this module but uses only some of its helpers.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// The `wildlight` binary of this build, ready for arguments.
pub fn wildlight() -> Command {
    Command::new(env!("CARGO_BIN_EXE_wildlight"))
}

/// Runs `wildlight` with `args` and returns what it printed and its status.
pub fn run(args: &[&str]) -> Output {
    wildlight()
        .args(args)
        .output()
        .expect("the wildlight binary runs")
}

/// Runs `wildlight` with `args`, which must succeed (a failure shows the
/// command and its stderr); returns its stdout.
pub fn run_ok(args: &[&str]) -> String {
    let out = run(args);
    assert!(
        out.status.success(),
        "{args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("stdout is UTF-8")
}

/// [`run_ok`], its stdout read as one JSON object.
pub fn run_json(args: &[&str]) -> serde_json::Value {
    serde_json::from_str(&run_ok(args)).expect("stdout is one JSON object")
}

/// The Mitsuba 3 torus capture (`crates/wildlight-data/tests/fixtures`, its
/// README): a capture that wildlight did not write.
pub fn mitsuba_torus() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("crates/wildlight-data/tests/fixtures/mitsuba-torus")
}

/// `p` as a command-line argument (temporary and fixture paths are UTF-8).
pub fn path_arg(p: &Path) -> &str {
    p.to_str().expect("test paths are UTF-8")
}

/// The size of the tiny synthetic capture the CLI tests use: 4 training
/// views and 1 validation view of 32×32 pixels at 4 samples per pixel, and
/// a ground-truth mesh extracted at resolution 48.
pub const TINY_CAPTURE_ARGS: [&str; 14] = [
    "--views",
    "4",
    "--val-views",
    "1",
    "--width",
    "32",
    "--height",
    "32",
    "--spp",
    "4",
    "--val-spp",
    "4",
    "--mesh-resolution",
    "48",
];

/// `wildlight synth --scene <scene> --out <out>` writing a tiny capture
/// ([`TINY_CAPTURE_ARGS`]) quietly; callers may add arguments before running it.
pub fn tiny_synth(scene: &str, out: &Path) -> Command {
    let mut command = wildlight();
    command
        .args(["synth", "--scene", scene, "--out"])
        .arg(out)
        .args(TINY_CAPTURE_ARGS)
        .arg("--quiet");
    command
}

/// A training configuration of a small model, so that a test trains in
/// seconds.
pub const TINY_MODEL_CONFIG: &str = "\
batch_rays = 256
eikonal_points = 64
[model.sdf]
levels = 8
log2_table_size = 15
base_resolution = 8
finest_resolution = 128
hidden = [32]
[model.material]
levels = 6
log2_table_size = 14
base_resolution = 8
finest_resolution = 64
hidden = [32]
[model.ambient]
levels = 4
log2_table_size = 12
base_resolution = 8
finest_resolution = 32
hidden = [32]
[model.ambient_room]
levels = 3
log2_table_size = 12
base_resolution = 8
finest_resolution = 32
hidden = []
[sampling]
grid_resolution = 32
[output]
preview_every = 0
checkpoint_every = 20
";
