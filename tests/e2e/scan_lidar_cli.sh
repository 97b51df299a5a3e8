#!/usr/bin/env bash
# mlsreg-scan --lidar: a short drive down a street writes scans, poses and both manifests (their
# parsing by ReadManifest is in tests/scan/lidar_protocol_test.cc); bad values exit 2 naming the
# flag; the pinhole mode's flags are refused.
#   scan_lidar_cli.sh MLSREG_SCAN
set -euo pipefail
SCAN=$1
fail() { echo "FAIL: $*" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

"$SCAN" --lidar --scene street --scene-seed 4 --frames 30 --pairs 2 --pair-gaps 4,8 \
  --noise-m 0.02 --movers 5 --out "$work/lidar" > "$work/out.txt"
grep -q "^street_s4: .* 2 pairs" "$work/out.txt" || fail "summary: $(cat "$work/out.txt")"
dir=$work/lidar/street_s4
[ -f "$dir/poses.csv" ] || fail "no poses.csv"
head -1 "$dir/noise0.02/pairs.csv" | grep -q "^id,source,target,gt,distance_m," || fail "pairs.csv header"
head -1 "$dir/noise0.02/pairs_identity.csv" | grep -q "^id,source,target,gt,init," || fail "pairs_identity.csv header"
[ "$(ls "$dir"/noise0.02/scan_*.ply | wc -l)" -eq 4 ] || fail "expected 4 scans"
head -c 200 "$(ls "$dir"/noise0.02/scan_*.ply | head -1)" | grep -aq "format binary_little_endian" || fail "not binary PLY"

expect_bad() {  # flag-in-message, args...
  local flag=$1; shift
  set +e
  "$SCAN" "$@" --out "$work/bad" > /dev/null 2> "$work/err.txt"
  local code=$?
  set -e
  [ $code -eq 2 ] || fail "$* exited $code, not 2"
  grep -q -- "$flag" "$work/err.txt" || fail "$*: message does not name $flag: $(cat "$work/err.txt")"
}
expect_bad --azimuth-step --lidar --azimuth-step 0.5
expect_bad --beams --lidar --beams 0
expect_bad --scene --lidar --scene highway
expect_bad --noise-m --lidar --noise-m -0.1
expect_bad --pair-gaps --lidar --pair-gaps 0,4
expect_bad --movers --lidar --movers -1
expect_bad --frames --lidar --frames 1
expect_bad --max-range --lidar --max-range 1
expect_bad --beams --lidar --beams abc
expect_bad --views --lidar --views 3
expect_bad --beams --mesh whatever.off --beams 32
[ ! -e "$work/bad" ] || fail "a refused run wrote $work/bad"
echo "scan_lidar_cli: ok"
