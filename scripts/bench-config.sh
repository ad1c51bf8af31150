#!/usr/bin/env bash
# Writes the training configuration of a benchmark run: EXTRA.toml first,
# so that its top-level keys stay top-level, then an [output] table with
# the given checkpoint and preview intervals.
#
#   scripts/bench-config.sh OUT.toml CHECKPOINT_EVERY PREVIEW_EVERY [EXTRA.toml]
set -euo pipefail
out=$1
: > "$out"
if [ -n "${4:-}" ]; then
  cat "$4" >> "$out"
fi
printf '\n[output]\ncheckpoint_every = %s\npreview_every = %s\n' "$2" "$3" >> "$out"
