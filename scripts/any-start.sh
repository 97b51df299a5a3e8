#!/usr/bin/env bash
# Registration from any start (docs/evaluation.md, "Registration from any start"): method auto
# against mls-sicp, fgr and g-icp, with default parameters, on the same problems from the same
# seeded starts:
#
#   synthetic  the tuning split's virtual scans (scripts/tuning-split.sh: 4 CGAL meshes x 12
#              views x sigma = 0, 0.8 d, 2 d), each view to its neighbour
#   real       the Stanford bunny (14 pairs) and dragon turntable (20 pairs) in ../shared/data/real
#   mismatched 20 pairs of views of two different meshes (sigma = 0.8 d), the source scaled to
#              the target's sampling distance and placed on it: none may verify
#
# Starts: "scanner" (the virtual scanner's 30-degree neighbour, synthetic only), "near" (10
# degrees, 10 d from the truth), "rot90" (90 degrees about a random axis) and "any" (uniform on
# SO(3)), both with translations of 10-50 d, seed 1.
#
#   bash scripts/any-start.sh        (after scripts/build.sh and scripts/tuning-split.sh)
#
# Needs python3-open3d (the mismatched sources) and python3-matplotlib (the figure). With
# $OUT/peers_global.csv from `bench/peer_comparison.py --global`, the summary adds Open3D's global
# peers on the same problems. Writes per-run CSVs and summary.md (success per set, start and method; alpha-recall per
# start-angle band; verification of the mismatched pairs) to $OUT (default
# $BUILD_DIR/any-start). Environment: BUILD_DIR, OUT, TUNING (the tuning split's output, default
# $BUILD_DIR/tuning), JOBS, SHARED (default ../shared), METHODS.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_DIR=${BUILD_DIR:-build}
OUT=${OUT:-$BUILD_DIR/any-start}
TUNING=${TUNING:-$BUILD_DIR/tuning}
JOBS=${JOBS:-$(nproc)}
SHARED=${SHARED:-../shared}
METHODS=${METHODS:-auto,mls-sicp,fgr,g-icp}
MLSREG=$BUILD_DIR/mlsreg
MESHES="elephant armadillo dino homer"
mkdir -p "$OUT"
if [ ! -f "$TUNING/scans/.done" ]; then
  echo "no tuning-split scans in $TUNING/scans: run scripts/tuning-split.sh first" >&2
  exit 1
fi

declare -A START_FLAGS=(
  [scanner]=""
  [near]="--perturb-angle 10 --perturb-translation 10"
  [rot90]="--perturb-angle 90 --perturb-translation 10 --perturb-translation-max 50"
  [any]="--perturb-uniform-rotation --perturb-translation 10 --perturb-translation-max 50"
)

run_eval() {  # label, output, then eval flags
  local label=$1 out=$2
  shift 2
  if [ -f "$out" ]; then return; fi
  # Exit status 3 only says some run missed 5 d.
  "$MLSREG" eval --jobs "$JOBS" --label "$label" --perturb-seed 1 "$@" --out "$out.tmp" \
    > "$out.log" 2>&1 || [ $? -eq 3 ]
  mv "$out.tmp" "$out"
}

for start in scanner near rot90 any; do
  for sigma in 0 0.8 2; do
    manifests=()
    for m in $MESHES; do manifests+=(--pairs "$TUNING/scans/$m/sigma$sigma/pairs.csv"); done
    if [ $sigma = 2 ]; then fgr=(--fgr-radius 15); else fgr=(--fgr-radius 10); fi
    echo "== synthetic sigma $sigma, start $start"
    # shellcheck disable=SC2086
    run_eval "synthetic,$sigma,$start" "$OUT/synthetic_sigma${sigma}_$start.csv" \
      "${manifests[@]}" --methods "$METHODS" "${fgr[@]}" ${START_FLAGS[$start]}
  done
done

for start in near rot90 any; do
  echo "== real, start $start"
  # shellcheck disable=SC2086
  run_eval "real,,$start" "$OUT/real_$start.csv" \
    --pairs "$SHARED/data/real/stanford_bunny/pairs.csv" \
    --pairs "$SHARED/data/real/stanford_dragon_stand/pairs.csv" \
    --methods "$METHODS" ${START_FLAGS[$start]}
done

# Mismatched: view k of one mesh against view k of the next, 5 views x 4 meshes, the source
# scaled to the target's sampling distance and moved onto it (scripts/mismatched_pairs.py).
mismatched=$OUT/mismatched/pairs.csv
[ -f "$mismatched" ] || /usr/bin/python3 scripts/mismatched_pairs.py "$TUNING/scans" "$OUT/mismatched"
echo "== mismatched pairs"
run_eval "mismatched,0.8,scanner" "$OUT/mismatched.csv" --pairs "$mismatched" --methods auto

peers=()
[ -f "$OUT/peers_global.csv" ] && peers=(--peers "$OUT/peers_global.csv")
/usr/bin/python3 scripts/any_start_summary.py "$OUT" "${peers[@]}" --figure "$OUT/any_start_recall.png" \
  > "$OUT/summary.md"
cat "$OUT/summary.md"
