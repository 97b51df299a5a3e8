#!/usr/bin/env bash
# Multi-view alignment against ground truth (docs/evaluation.md, "Many scans into one frame"):
# every view of each evaluation mesh (12 virtual scans at sigma = 0, 0.8 d, 2 d) and the real
# Stanford bunny (10 scans, bun.conf) and dragon (15 scans, dragonStandRight.conf), each from its
# ground-truth poses perturbed by a seeded 10 degrees / 10 d per view. Rows: chained pairwise
# MLS-SICP, AlignScans with MLS-SICP edges, AlignScans with CP-SICP edges, Open3D 0.16's
# multiway registration with point-to-plane edges, all in one run (scripts/multiview_eval.py).
#
#   bash scripts/multiview-eval.sh
#
# Environment: BUILD_DIR (build), OUT (default $BUILD_DIR/multiview), TUNING_SCANS (the tuning
# split's scans, where Open3D's correspondence distance is tuned; scanned here when missing),
# SCANS (virtual scans of the
# evaluation meshes; default: $BUILD_DIR/evaluation/scans when scripts/evaluate.sh made them,
# else scanned here), EVAL_MESHES (default "bunny camel cow fandisk triceratops"), SHARED.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
OUT=${OUT:-$BUILD_DIR/multiview}
SHARED=${SHARED:-../shared}
EVAL_MESHES=${EVAL_MESHES:-bunny camel cow fandisk triceratops}
SCANS=${SCANS:-$BUILD_DIR/evaluation/scans}
bash scripts/install-deps.sh
bash scripts/build.sh
mkdir -p "$OUT"
source scripts/lib-meshes.sh
fetch_eval_meshes
if [ ! -d "$SCANS" ]; then
  SCANS=$OUT/scans
  [ -d "$SCANS" ] || "$BUILD_DIR/tools/scan/mlsreg-scan" "${scan_args[@]}" --out "$SCANS"
fi
# Open3D's correspondence distance is tuned on the tuning split (scripts/tuning-split.sh's scans).
TUNING_SCANS=${TUNING_SCANS:-$BUILD_DIR/tuning/scans}
if [ ! -f "$TUNING_SCANS/.done" ]; then
  bash scripts/fetch-cgal-meshes.sh "$meshes_dir" elephant armadillo dino homer
  tuning_args=()
  for m in elephant armadillo dino homer; do tuning_args+=(--mesh "$m=$meshes_dir/$m.off"); done
  rm -rf "$TUNING_SCANS"
  "$BUILD_DIR/tools/scan/mlsreg-scan" "${tuning_args[@]}" --out "$TUNING_SCANS" > /dev/null
  touch "$TUNING_SCANS/.done"
fi
/usr/bin/python3 scripts/multiview_eval.py --mlsreg "$BUILD_DIR/mlsreg" --scans "$SCANS" \
  --shared "$SHARED" --out "$OUT" --tuning-scans "$TUNING_SCANS" "${scan_args[@]}"
/usr/bin/python3 scripts/multiview_summary.py "$OUT/multiview.csv" \
  --figure docs/figures/multiview_pose_error.png > "$OUT/multiview.md"
cp "$OUT/multiview.csv" docs/figures/multiview.csv
echo "tables in $OUT/multiview.md (copy them into docs/evaluation-notes.md)"
