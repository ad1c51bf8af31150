#!/usr/bin/env bash
# The training benchmark of the default scene (issue 6): synthesize the
# built-in default capture (64 views + 8 held-out, 256×256, half with flash),
# train for a wall-clock budget, keep a snapshot of the model every few
# minutes, then score every snapshot against the ground truth: mesh distance
# (appendix eq. 16, normalized frame), base-colour PSNR after scale
# alignment, and novel-view PSNR with and without flash.
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
rm -rf "$run"
# checkpoints often enough that a snapshot is never more than ~20 s old
"$root/scripts/bench-config.sh" "$out/bench.toml" 100 1000 "$extra"
/usr/bin/time -v -o "$out/train.time" \
  "$W" train --data "$cap" --out "$run" --config "$out/bench.toml" \
  --iters 100000 --time-budget "${budget}m" --seed "${SEED:-0}" &
train_pid=$!
start=$(date +%s)
# snapshot DIR: the run's current checkpoint, its age and its last logged step
snapshot() {
  mkdir -p "$1"
  cp "$run/config.toml" "$run/run.json" "$run/checkpoint.safetensors" "$1/"
  echo "$(($(date +%s) - start))" > "$1/seconds"
  tail -n 1 "$run/metrics.jsonl" > "$1/last_metrics.json"
}
n=0
last=""
while kill -0 "$train_pid" 2>/dev/null; do
  sleep 5
  now=$(date +%s)
  if [ $((now - start)) -ge $(((n + 1) * every * 60)) ] && [ -f "$run/checkpoint.safetensors" ]; then
    n=$((n + 1))
    last="$out/snap_$(printf %03d $((n * every)))m"
    snapshot "$last"
  fi
done
wait "$train_pid"
# the final model, unless the last timed snapshot already holds it
if [ -z "$last" ] || ! cmp -s "$run/checkpoint.safetensors" "$last/checkpoint.safetensors"; then
  snapshot "$out/snap_final"
fi
: > "$out/curve.jsonl"
for snap in "$out"/snap_*; do
  WILDLIGHT="$W" "$root/scripts/score-model.sh" "$snap" "$cap"
  python3 - "$snap" <<'PY' | tee -a "$out/curve.jsonl"
import json, sys
snap = sys.argv[1]
load = lambda name: json.load(open(f"{snap}/{name}"))
mesh, mat, img = load("mesh.json"), load("materials.json"), load("images.json")
dist = mesh.get("distance", mesh)
# the last logged step before the snapshot (its checkpoint is at most
# checkpoint_every steps older)
step = json.loads(open(f"{snap}/last_metrics.json").read().strip() or "{}").get("step")
print(json.dumps({
    "snapshot": snap.rsplit("/", 1)[-1],
    "seconds": int(open(f"{snap}/seconds").read()),
    "step": step,
    "mesh_mean": dist["mean"], "mesh_median": dist["median"],
    "base_color_psnr_aligned": mat["base_color_psnr_aligned"],
    "base_color_psnr": mat["base_color_psnr"],
    "roughness_mae": mat["roughness_mae"], "metallic_mae": mat["metallic_mae"],
    "psnr_flash": img["psnr_flash"], "psnr_noflash": img["psnr_noflash"],
}))
PY
done
grep -E "Maximum resident|Elapsed" "$out/train.time"
