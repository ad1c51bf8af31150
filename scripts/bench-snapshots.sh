#!/usr/bin/env bash
# Lists the models a budgeted benchmark run scores, one folder per line:
# every snapshot of RUN (train --snapshot-every), then the final model as
# OUT/final unless the last snapshot was taken after the last step (the
# snapshots are named by their step; the step count and the seconds come
# from the trainer's closing line in OUT/train.log).
#
#   scripts/bench-snapshots.sh OUT RUN
set -euo pipefail
out=$1
run=$2
snaps=("$run"/snapshots/step_*)
[ -e "${snaps[0]}" ] || snaps=()
steps=$(sed -n 's/^trained \([0-9]*\) steps in .*/\1/p' "$out/train.log")
if [ ${#snaps[@]} -eq 0 ] || [ "${snaps[-1]##*/}" != "$(printf 'step_%06d' "$steps")" ]; then
  final="$out/final"
  mkdir -p "$final"
  cp "$run/config.toml" "$run/run.json" "$run/checkpoint.safetensors" "$final/"
  sed -n 's/^trained \([0-9]*\) steps in \([0-9.]*\) s.*/{"step": \1, "seconds": \2}/p' \
    "$out/train.log" > "$final/snapshot.json"
  snaps+=("$final")
fi
printf '%s\n' "${snaps[@]}"
