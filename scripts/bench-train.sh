#!/usr/bin/env bash
# The training benchmark of the default scene (issue 6): synthesize the
# built-in default capture (64 views + 8 held-out, 256×256, half with flash),
# train for a wall-clock budget, keep a snapshot of the model every few
# minutes (train --snapshot-every), then score every snapshot against the
# ground truth: mesh distance (appendix eq. 16, normalized frame),
# base-colour PSNR after scale alignment, and novel-view PSNR with and
# without flash.
#
#   [SEED=S] scripts/bench-train.sh [OUT_DIR] [BUDGET_MINUTES] [SNAPSHOT_MINUTES] [EXTRA.toml]
#
# EXTRA.toml (optional) is prepended to the run's configuration, to benchmark
# a setting against the defaults. SEED (default 0) is the training seed, for
# repeated runs whose median is the benchmark's result.
#
# Prints one JSON line per snapshot and writes them to OUT_DIR/curve.jsonl;
# peak memory of the training process is in OUT_DIR/train.time.
set -euo pipefail
out=${1:-bench-train}
budget=${2:-30}
every=${3:-5}
extra=${4:-}
root=$(cd "$(dirname "$0")/.." && pwd)
cargo build --release --quiet --manifest-path "$root/Cargo.toml" -p wildlight
W="$root/target/release/wildlight"
mkdir -p "$out"
cap="$out/capture"
if [ ! -f "$cap/cameras_sphere.npz" ]; then
  "$W" synth --scene kettle --out "$cap" --quiet
fi
run="$out/run"
rm -rf "$run" "$out"/snap_* "$out/final"
# The run keeps its own snapshots at each mark of wall time (train
# --snapshot-every), so no frequent checkpoints (about 0.8 s each) are
# needed: the run's checkpoint is written at the end only.
"$root/scripts/bench-config.sh" "$out/bench.toml" 1000000 1000 "$extra"
/usr/bin/time -v -o "$out/train.time" \
  "$W" train --data "$cap" --out "$run" --config "$out/bench.toml" \
  --iters 100000 --time-budget "${budget}m" --snapshot-every "${every}m" \
  --seed "${SEED:-0}" 2> "$out/train.log"
tail -n 1 "$out/train.log"
# Score every snapshot, then the final model when no snapshot holds it.
mapfile -t snaps < <("$root/scripts/bench-snapshots.sh" "$out" "$run")
: > "$out/curve.jsonl"
for snap in "${snaps[@]}"; do
  WILDLIGHT="$W" "$root/scripts/score-model.sh" "$snap" "$cap"
  python3 - "$snap" <<'PY' | tee -a "$out/curve.jsonl"
import json, sys
snap = sys.argv[1]
load = lambda name: json.load(open(f"{snap}/{name}"))
mesh, mat, img, info = load("mesh.json"), load("materials.json"), load("images.json"), load("snapshot.json")
dist = mesh.get("distance", mesh)
print(json.dumps({
    "snapshot": snap.rsplit("/", 1)[-1],
    "seconds": round(info["seconds"]),
    "step": info["step"],
    "mesh_mean": dist["mean"], "mesh_median": dist["median"],
    "base_color_psnr_aligned": mat["base_color_psnr_aligned"],
    "base_color_psnr": mat["base_color_psnr"],
    "roughness_mae": mat["roughness_mae"], "metallic_mae": mat["metallic_mae"],
    "psnr_flash": img["psnr_flash"], "psnr_noflash": img["psnr_noflash"],
}))
PY
done
grep -E "Maximum resident|Elapsed" "$out/train.time"
