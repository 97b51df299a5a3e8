#!/usr/bin/env bash
# End-to-end: `mlsreg align` on four real Stanford bunny scans (0, 45, 90 and 315 degrees), from
# their bun.conf poses turned by a few degrees, against bun.conf as ground truth (good to about
# 0.3 degrees / 0.9 d). Checks: progress per edge, the poses within 0.5 degrees and 2 d of the
# truth, the written .conf and rows read back as the same poses, the merged cloud (as is and
# resampled onto the joint MLS surface), and bad input
# answered with exit 2 and the field named.
set -euo pipefail
MLSREG=$1
SRC=$2
B=$SRC/../shared/data/real/stanford_bunny
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
[ -f "$B/bun.conf" ] || { echo "no bunny data at $B: skipped"; exit 0; }
scans=("$B/bun000.ply" "$B/bun045.ply" "$B/bun090.ply" "$B/bun315.ply")

# bun.conf with every pose but bun000's turned by 3 degrees about y (qr kept, qj nudged).
python3 - "$B/bun.conf" > "$work/start.conf" <<'PY'
import math, sys
for line in open(sys.argv[1]):
    f = line.split()
    if f and f[0] == "bmesh" and f[1] != "bun000.ply":
        q = [float(v) for v in f[5:9]]  # qi qj qk qr
        h = math.radians(3.0) / 2  # compose with a turn about y: (0, sin h, 0, cos h) * q
        x, y, z, w = q
        s, c = math.sin(h), math.cos(h)
        q = [c * x - s * z, c * y + s * w, c * z + s * x, c * w - s * y]
        f[5:9] = ["%.9f" % v for v in q]
    print(" ".join(f))
PY
"$MLSREG" align --scans "${scans[@]}" --poses "$work/start.conf" --gt "$B/bun.conf" --pairs overlap \
  --threads 2 --out "$work/poses.conf" --json "$work/align.json" --merged "$work/merged.ply" \
  > "$work/out.txt" || fail "align: $(cat "$work/out.txt")"
[ "$(grep -c '^\[edge ' "$work/out.txt")" -ge 4 ] || fail "progress per edge: $(cat "$work/out.txt")"
python3 - "$work/align.json" "$work/poses.conf" <<'PY' || fail "poses: $(cat "$work/out.txt")"
import json, sys
j = json.load(open(sys.argv[1]))
assert len(j["scans"]) == 4 and len(j["edges"]) >= 4, j
for s in j["scans"]:
    assert s["rotation_error_deg"] < 0.5 and s["translation_error_d"] < 2.0, s
# Every edge that verified is kept; one that did not (bun090 and bun315, 135 degrees apart, share
# too little) is left out.
assert all(e["kept"] == e["trusted"] for e in j["edges"]), j["edges"]
conf = [l.split() for l in open(sys.argv[2])]
assert [c[1] for c in conf] == ["bun000.ply", "bun045.ply", "bun090.ply", "bun315.ply"], conf
PY
# The written .conf, read back as initial poses, is the result: aligning again moves nothing
# (the overlap band in metres this time: 1 cm, about 20 d on the bunny).
"$MLSREG" align --scans "${scans[@]}" --poses "$work/poses.conf" --gt "$work/poses.conf" \
  --pairs overlap --overlap-distance 1cm --out "$work/again.txt" --merged "$work/resampled.ply" --resample \
  > "$work/again.log" || fail "align again"
grep -q "^# one pose per scan" "$work/again.txt" || fail "rows file: $(cat "$work/again.txt")"
[ "$(grep -vc '^#' "$work/again.txt")" -eq 4 ] || fail "rows: $(cat "$work/again.txt")"
head -c 200 "$work/merged.ply" | grep -q "element vertex" || fail "merged cloud"
# Resampled onto the joint MLS surface: one point per voxel of d, so fewer than merged.
grep -q "resampled onto the joint MLS surface" "$work/again.log" || fail "resample: $(cat "$work/again.log")"
vertices() { head -c 400 "$1" | grep -a "element vertex" | awk '{print $3}'; }
[ "$(vertices "$work/resampled.ply")" -gt 10000 ] && \
  [ "$(vertices "$work/resampled.ply")" -lt "$(vertices "$work/merged.ply")" ] || \
  fail "resampled $(vertices "$work/resampled.ply") vs merged $(vertices "$work/merged.ply") points"

# Bad input: exit 2, the field named.
set +e
"$MLSREG" align --scans "${scans[0]}" "${scans[1]}" --poses "$B/pairs.csv" 2> "$work/bad1.txt"
code1=$?
printf '1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1\n' > "$work/one.txt"
"$MLSREG" align --scans "${scans[0]}" "${scans[1]}" --poses "$work/one.txt" 2> "$work/bad2.txt"
code2=$?
"$MLSREG" align --scans "${scans[0]}" "${scans[1]}" --pairs ring 2> "$work/bad3.txt"
code3=$?
"$MLSREG" align --scans "${scans[0]}" "${scans[1]}" --resample 2> "$work/bad4.txt"
code4=$?
"$MLSREG" align --scans "${scans[0]}" "${scans[1]}" --pairs overlap --overlap-distance 5km \
  2> "$work/bad5.txt"
code5=$?
set -e
[ "$code1" -eq 2 ] && grep -q "poses line" "$work/bad1.txt" || fail "bad poses file: $code1 $(cat "$work/bad1.txt")"
[ "$code2" -eq 2 ] && grep -q "1 poses for 2 scans" "$work/bad2.txt" || fail "pose count: $code2 $(cat "$work/bad2.txt")"
[ "$code3" -eq 2 ] && grep -q -- "--pairs" "$work/bad3.txt" || fail "bad --pairs: $code3 $(cat "$work/bad3.txt")"
[ "$code4" -eq 2 ] && grep -q -- "give --merged" "$work/bad4.txt" || fail "--resample alone: $code4 $(cat "$work/bad4.txt")"
[ "$code5" -eq 2 ] && grep -q -- "--overlap-distance: '5km' is not a length" "$work/bad5.txt" || \
  fail "bad length: $code5 $(cat "$work/bad5.txt")"

# The six bunny scans of the issue that found silent failures, default flags: edges by method
# auto put every pose within 1 degree of bun.conf. With MLS-SICP edges two poses end far off; the
# loop closure then exceeds its bound and says so, in the text and in --json.
six=("$B/bun000.ply" "$B/bun045.ply" "$B/bun090.ply" "$B/bun180.ply" "$B/bun270.ply" "$B/bun315.ply")
"$MLSREG" align --scans "${six[@]}" --gt "$B/bun.conf" --threads 2 --json "$work/six.json" \
  > "$work/six.txt" || fail "align six: exit $?: $(tail -3 "$work/six.txt")"
grep -q "edges by auto" "$work/six.txt" || fail "default edges: $(head -1 "$work/six.txt")"
python3 - "$work/six.json" <<'PY' || fail "six poses: $(cat "$work/six.txt")"
import json, sys
j = json.load(open(sys.argv[1]))
assert j["method"] == "auto", j["method"]
assert max(s["rotation_error_deg"] for s in j["scans"]) < 1.0, [s["rotation_error_deg"] for s in j["scans"]]
assert j["unverified_scans"] == [], j["unverified_scans"]
assert all(e["trusted"] == e["verification"]["verified"] for e in j["edges"]), j["edges"]
# The final solve weighs every kept edge that has a pose covariance by it (all six do here).
with_covariance = sum(e["kept"] and e["verification"]["pose_covariance"] is not None for e in j["edges"])
assert j["covariance_weighted_edges"] == with_covariance == 6, (j["covariance_weighted_edges"], with_covariance)
# And every scan but the anchor gets its pose's covariance from that solve.
assert j["scans"][0]["pose_covariance"] is None
for s in j["scans"][1:]:
    assert len(s["pose_covariance"]) == 36 and 0 < s["pose_rotation_sigma_deg"] < 1.0, s
PY
[ "$(grep -c "   graph sigma [0-9.]* deg" "$work/six.txt")" -eq 5 ] \
  || fail "pose uncertainties: $(grep -A7 '^poses' "$work/six.txt")"
grep -q "the final solve weighed 6 kept edges by their pose covariance" "$work/six.txt" \
  || fail "covariance weights: $(grep 'aligned in' "$work/six.txt")"
"$MLSREG" align --scans "${six[@]}" --gt "$B/bun.conf" --threads 2 --method mls-sicp \
  --json "$work/mls.json" > "$work/mls.txt" || true
grep -q "loop closure of the chained edges: .*WARNING: beyond 2 deg" "$work/mls.txt" \
  || fail "no loop-closure warning: $(grep 'loop closure' "$work/mls.txt")"
python3 -c "import json,sys; assert json.load(open(sys.argv[1]))['loop_closure_exceeded']" \
  "$work/mls.json" || fail "loop_closure_exceeded not in --json"
echo "cli align: all checks passed"
