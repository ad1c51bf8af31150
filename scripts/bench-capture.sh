#!/usr/bin/env bash
# The training benchmark of any capture with a true mesh (issue 49): train
# CAPTURE for a wall-clock budget, keep a snapshot every few minutes, then
# score each snapshot's exported mesh (object only for a maskless run:
# export's default) against GT_MESH, a mesh in the capture's normalized
# frame, on the surface the capture's cameras see (appendix eq. 16,
# normalized by scale_mat); and, when the capture has held-out views
# (val/), their PSNR over the masks (the object; the whole image without
# masks) and over the whole image (`_whole`).
#
#   [SEED=S] [MASKS=use|ignore] scripts/bench-capture.sh CAPTURE GT_MESH OUT [BUDGET_MINUTES] [SNAPSHOT_MINUTES] [EXTRA.toml]
#
# MASKS (default: the capture's own: masks when it has them) is passed to
# train --masks. Prints one JSON line per snapshot, also in OUT/curve.jsonl.
set -euo pipefail
cap=$1
gt=$2
out=$3
budget=${4:-30}
every=${5:-5}
extra=${6:-}
root=$(cd "$(dirname "$0")/.." && pwd)
cargo build --release --quiet --manifest-path "$root/Cargo.toml" -p wildlight
W="$root/target/release/wildlight"
mkdir -p "$out"
run="$out/run"
rm -rf "$run" "$out/final"
"$root/scripts/bench-config.sh" "$out/bench.toml" 1000000 1000 "$extra"
masks=()
[ -n "${MASKS:-}" ] && masks=(--masks "$MASKS")
/usr/bin/time -v -o "$out/train.time" \
  "$W" train --data "$cap" --out "$run" --config "$out/bench.toml" "${masks[@]}" \
  --iters 100000 --time-budget "${budget}m" --snapshot-every "${every}m" \
  --seed "${SEED:-0}" 2> "$out/train.log"
tail -n 1 "$out/train.log"
# Score every snapshot, then the final model when no snapshot holds it.
mapfile -t snaps < <("$root/scripts/bench-snapshots.sh" "$out" "$run")
: > "$out/curve.jsonl"
for snap in "${snaps[@]}"; do
  "$W" export --run "$snap" --out "$snap/asset" --normalized --resolution 256 --faces 65536 \
    --texture 512 --quiet > "$snap/export.log" 2>&1
  "$W" eval mesh --pred "$snap/asset/mesh_raw.ply" --gt "$gt" \
    --cameras "$cap" --frame normalized --json > "$snap/mesh.json"
  if [ -d "$cap/val" ]; then
    "$W" render --run "$snap" --data "$cap" --split val --out "$snap/render-val" --quiet \
      > "$snap/render.log" 2>&1
    "$W" eval images --pred "$snap/render-val" --gt "$cap" --json > "$snap/images.json" \
      2> "$snap/images.log" || echo '{}' > "$snap/images.json"
    "$W" eval images --pred "$snap/render-val" --gt "$cap" --whole-image --json \
      > "$snap/images_whole.json" 2>> "$snap/images.log" || echo '{}' > "$snap/images_whole.json"
  else
    echo '{}' > "$snap/images.json"
    echo '{}' > "$snap/images_whole.json"
  fi
  python3 - "$snap" <<'PY' | tee -a "$out/curve.jsonl"
import json, sys
snap = sys.argv[1]
load = lambda name: json.load(open(f"{snap}/{name}"))
mesh, img, info = load("mesh.json"), load("images.json"), load("snapshot.json")
whole = load("images_whole.json")
dist = mesh.get("distance", mesh)
row = {"snapshot": snap.rsplit("/", 1)[-1], "seconds": round(info["seconds"]),
       "step": info["step"], "mesh_mean": dist["mean"], "mesh_median": dist["median"]}
for k, v in img.items():
    if k.startswith("psnr"):
        row[k] = v
for k, v in whole.items():
    if k.startswith("psnr"):
        row[k + "_whole"] = v
print(json.dumps(row))
PY
done
grep -E "Maximum resident|Elapsed" "$out/train.time"
