#!/usr/bin/env bash
# Scores a trained model against the ground truth of a synthetic capture,
# as the benchmarks of issue 6 do: renders the held-out views into
# MODEL/render-val, exports the mesh (256³, normalized frame) into
# MODEL/asset, and writes MODEL/mesh.json (appendix eq. 16 on the visible
# surface), MODEL/materials.json and MODEL/images.json.
#
#   scripts/score-model.sh MODEL_DIR CAPTURE_DIR
#
# MODEL_DIR is a run folder or a snapshot of one (config.toml, run.json,
# checkpoint.safetensors). WILDLIGHT names the binary (default: the
# workspace's release build).
set -euo pipefail
model=$1
cap=$2
root=$(cd "$(dirname "$0")/.." && pwd)
W=${WILDLIGHT:-"$root/target/release/wildlight"}
"$W" render --run "$model" --data "$cap" --split val --out "$model/render-val" --quiet \
  > "$model/render.log" 2>&1
"$W" export --run "$model" --out "$model/asset" --normalized --resolution 256 --faces 65536 \
  --texture 1024 --quiet > "$model/export.log" 2>&1
"$W" eval mesh --pred "$model/asset/mesh_raw.ply" --gt "$cap/gt/mesh_normalized.ply" \
  --cameras "$cap" --frame normalized --json > "$model/mesh.json"
"$W" eval materials --pred "$model/render-val" --gt "$cap" --split val --json \
  > "$model/materials.json"
"$W" eval images --pred "$model/render-val" --gt "$cap" --json > "$model/images.json"
