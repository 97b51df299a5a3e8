#!/usr/bin/env bash
# The main job: register the bundled Stanford bunny scans (bun000 -> bun045) with MLS-SICP from
# a start pose 10 degrees and 10 d away from the ground truth, streaming one line per iteration,
# then print the final transform and its error against the ground truth.
set -euo pipefail
cd "$(dirname "$0")/.."
MLSREG=${MLSREG:-build/mlsreg}
GT=$(awk -F, '$1 == "bun000_bun045" { print $4 }' data/bunny/pairs.csv)
exec "$MLSREG" register \
  --source data/bunny/bun000.ply --target data/bunny/bun045.ply \
  --method "${METHOD:-mls-sicp}" --init "$GT" --gt "$GT" \
  --perturb-angle 10 --perturb-translation 10 --perturb-seed 1 "$@"
