#!/usr/bin/env bash
# A fixed-step experiment on the default scene (issue 6): train a given
# number of steps (the learning-rate schedule spans exactly them, unlike a
# time budget), then score the model against the ground truth as
# bench-train.sh scores its snapshots. Training is deterministic for a seed
# and a thread count, so two settings compare without run-to-run noise.
#
#   [SEED=S] scripts/bench-steps.sh OUT_DIR CAPTURE_DIR ITERS [EXTRA.toml]
#
# CAPTURE_DIR is synthesized there (`synth --scene kettle`) if it holds no
# capture yet. EXTRA.toml is prepended to the run's configuration (its
# top-level keys stay top-level). Prints one JSON line of metrics.
set -euo pipefail
out=$1
cap=$2
iters=$3
extra=${4:-}
root=$(cd "$(dirname "$0")/.." && pwd)
cargo build --release --quiet --manifest-path "$root/Cargo.toml" -p wildlight
W="$root/target/release/wildlight"
if [ ! -f "$cap/cameras_sphere.npz" ]; then
  "$W" synth --scene kettle --out "$cap" --quiet
fi
rm -rf "$out"
mkdir -p "$out"
"$root/scripts/bench-config.sh" "$out/bench.toml" 1000 100000 "$extra"
/usr/bin/time -v -o "$out/train.time" \
  "$W" train --data "$cap" --out "$out/run" --config "$out/bench.toml" \
  --iters "$iters" --seed "${SEED:-0}" --quiet > "$out/train.log" 2>&1
WILDLIGHT="$W" "$root/scripts/score-model.sh" "$out/run" "$cap"
python3 - "$out" <<'PY' | tee "$out/result.json"
import json, sys
out = sys.argv[1]
load = lambda name: json.load(open(f"{out}/run/{name}"))
mesh, mat, img = load("mesh.json"), load("materials.json"), load("images.json")
dist = mesh.get("distance", mesh)
print(json.dumps({
    "out": out,
    "mesh_mean": dist["mean"], "mesh_median": dist["median"],
    "base_color_psnr_aligned": mat["base_color_psnr_aligned"],
    "roughness_mae": mat["roughness_mae"], "metallic_mae": mat["metallic_mae"],
    "normal_error_median_deg": mat["normal_error_median_deg"],
    "psnr_flash": img["psnr_flash"], "psnr_noflash": img["psnr_noflash"],
}))
PY
grep -E "Maximum resident|Elapsed" "$out/train.time"
