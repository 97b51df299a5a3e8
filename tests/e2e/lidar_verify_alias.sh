#!/usr/bin/env bash
# `mlsreg verify` of a pose far along a corridor from the truth: a dense tripod scanner's corridor
# (the `tls` sensor of lidar_prior.sh, corridor seed 901 at 5 mm), pair 161 -> 149, at the pose the
# global stage of `auto` once returned verified from the identity: 6.5 m along the corridor and
# 1.4 degrees off, 92 % of its overlap within the band. The rival search of `verify` reaches as
# far as that of a global stage's result (a pose given by the caller may come from anywhere):
# the probe 4 capture ranges away explains as large a share, so the verdict is `ambiguous`,
# exit 4, with the rival in the JSON. The truth itself verifies (exit 0).
#   lidar_verify_alias.sh MLSREG_SCAN MLSREG PYTHON
set -euo pipefail
SCAN=$1
MLSREG=$2
PYTHON=$3
fail() { echo "FAIL: $*" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

"$SCAN" --lidar --scene corridor --scene-seed 901 --movers 4 --beams 150 --top-elevation 45 \
  --bottom-elevation -45 --azimuth-step 0.4 --sensor-height 1.5 --no-ego-body --noise-m 0.005 \
  --pair-gaps 4,8,12 --pairs 16 --out "$work" > /dev/null
dir=$work/corridor_s901/noise0.005
truth=$(grep "^corridor_s901_noise0.005_000161_000149," "$dir/pairs.csv" | cut -d, -f4)
[ -n "$truth" ] || fail "pair 161 -> 149 not in the manifest"
alias="0.999543551 -0.016242317 0.025473048 5.173530843 0.016245423 0.999868031 0.000085015
       0.038803601 -0.025471067 0.000328844 0.999675506 -0.090167525 0 0 0 1"

verify() {  # transform, json -> exit code
  set +e
  "$MLSREG" verify --source "$dir/scan_000161.ply" --target "$dir/scan_000149.ply" \
    --transform "$1" --threads 2 --json "$2" > "$work/out.txt" 2>&1
  local code=$?
  set -e
  echo $code
}
code=$(verify "$alias" "$work/alias.json")
[ "$code" -eq 4 ] || fail "the alias: exit $code, not 4: $(tail -3 "$work/out.txt")"
"$PYTHON" - "$work/alias.json" <<'PY'
import json, sys
score = json.load(open(sys.argv[1]))
assert score["verdict"] == "ambiguous", score["verdict"]
PY
grep -q "^rival: a pose" "$work/out.txt" || fail "no rival named: $(cat "$work/out.txt")"
code=$(verify "$truth" "$work/truth.json")
[ "$code" -eq 0 ] || fail "the truth: exit $code, not 0: $(tail -3 "$work/out.txt")"
echo "alias ambiguous, truth verified"
