#!/usr/bin/env bash
# End-to-end: the AlignScans RPC of the real `mlsreg serve` on 127.0.0.1, driven by the real CLI
# (`mlsreg align --server`). Three real Stanford bunny scans from their bun.conf poses turned by
# 3 degrees. Checks: scans uploaded in the call and scans cached as targets give the local
# result (poses within 1e-6), per-edge progress, the poses within 0.5 degrees and 2 d of the
# truth; bad requests answered with the status and the field named; a client killed mid-job
# cancels it and the server keeps serving with nothing left in flight.
set -euo pipefail
MLSREG=$1
SRC=$2
cd "$SRC"
source scripts/lib-server.sh
B=$SRC/../shared/data/real/stanford_bunny
[ -f "$B/bun.conf" ] || { echo "no bunny data at $B: skipped"; exit 0; }
work=$(mktemp -d)
trap 'kill "${MLSREG_SERVER_PID:-}" 2>/dev/null || true; rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }
scans=("$B/bun315.ply" "$B/bun000.ply" "$B/bun045.ply")

python3 - "$B/bun.conf" > "$work/start.conf" <<'PY'
import math, sys
for line in open(sys.argv[1]):
    f = line.split()
    if f and f[0] == "bmesh" and f[1] != "bun000.ply":
        x, y, z, w = [float(v) for v in f[5:9]]
        h = math.radians(3.0) / 2
        s, c = math.sin(h), math.cos(h)
        f[5:9] = ["%.9f" % v for v in (c * x - s * z, c * y + s * w, c * z + s * x, c * w - s * y)]
    print(" ".join(f))
PY

start_server "$work/server.log" --workers 2
A=$MLSREG_SERVER_ADDRESS
common=(--poses "$work/start.conf" --pairs loop --threads 1)

"$MLSREG" align --scans "${scans[@]}" "${common[@]}" --gt "$B/bun.conf" --json "$work/local.json" \
  > "$work/local.txt" || fail "local align: $(cat "$work/local.txt")"
"$MLSREG" align --server "$A" --scans "${scans[@]}" "${common[@]}" --gt "$B/bun.conf" \
  --json "$work/uploaded.json" > "$work/uploaded.txt" || fail "uploaded: $(cat "$work/uploaded.txt")"
[ "$(grep -c '^\[edge ' "$work/uploaded.txt")" -eq 3 ] || fail "progress: $(cat "$work/uploaded.txt")"
grep -q "^request " "$work/uploaded.txt" || fail "no request id: $(cat "$work/uploaded.txt")"

for s in "${scans[@]}"; do
  id=$(basename "$s")
  "$MLSREG" targets upload --server "$A" --id "$id" "$s" > /dev/null || fail "upload $id"
done
"$MLSREG" align --server "$A" --cached --scans bun315.ply bun000.ply bun045.ply "${common[@]}" \
  --json "$work/cached.json" > "$work/cached.txt" || fail "cached: $(cat "$work/cached.txt")"

python3 - "$work/local.json" "$work/uploaded.json" "$work/cached.json" <<'PY' || fail "poses"
import json, sys
local, uploaded, cached = (json.load(open(p)) for p in sys.argv[1:])
for s in uploaded["scans"]:
    assert s["rotation_error_deg"] < 0.5 and s["translation_error_d"] < 2.0, s
for other in (uploaded, cached):
    assert len(other["scans"]) == 3 and len(other["edges"]) == 3, other
    # The graph weighed the same edges by their covariance (AlignScansResult field 13).
    assert other["covariance_weighted_edges"] == local["covariance_weighted_edges"] > 0, other
    for a, b in zip(local["scans"], other["scans"]):
        assert max(abs(x - y) for x, y in zip(a["pose"], b["pose"])) < 1e-6, (a, b)
    for a, b in zip(local["edges"], other["edges"]):
        assert (a["from"], a["to"], a["kept"], a["trusted"]) == (b["from"], b["to"], b["kept"], b["trusted"])
        assert abs(a["overlap"] - b["overlap"]) < 1e-9, (a, b)
PY

# Bad requests: the field named, exit 2 for INVALID_ARGUMENT (1 for NOT_FOUND); the server keeps
# serving.
expect() {  # expect EXIT TEXT -- command...
  local want=$1 text=$2 got=0
  shift 3
  "$@" > /dev/null 2> "$work/err.txt" || got=$?
  [ "$got" -eq "$want" ] && grep -qF -- "$text" "$work/err.txt" ||
    fail "expected exit $want '$text', got $got: $(cat "$work/err.txt")"
}
expect 1 "header.scans[1].target_id: target 'nope' not found" -- \
  "$MLSREG" align --server "$A" --cached --scans bun315.ply nope
expect 2 "is given twice" -- \
  "$MLSREG" align --server "$A" --cached --scans bun315.ply bun000.ply bun315.ply
expect 2 "header.scans[0].target_id" -- \
  "$MLSREG" align --server "$A" --cached --scans "bad/id" bun000.ply
expect 2 "anchor" -- \
  "$MLSREG" align --server "$A" --cached --scans bun315.ply bun000.ply --anchor 5
printf '0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 1 0\n' > "$work/tiny.xyz"
expect 2 "header.scans[1].cloud.point_count: a scan needs at least 10 points (got 5)" -- \
  "$MLSREG" align --server "$A" --scans "${scans[0]}" "$work/tiny.xyz"

# A client killed mid-job cancels it: the server logs the cancel and has nothing in flight.
"$MLSREG" align --server "$A" --scans "$B"/bun*.ply --pairs overlap > "$work/killed.txt" 2>&1 &
client=$!
sleep 2
kill -9 "$client" 2>/dev/null || true
wait "$client" 2>/dev/null || true
for _ in $(seq 1 100); do
  "$MLSREG" stats --server "$A" > "$work/stats.json"
  python3 -c 'import json,sys; s=json.load(open(sys.argv[1])); sys.exit(0 if s.get("activeJobs",0)==0 and int(s.get("inflightBytes",0))==0 else 1)' \
    "$work/stats.json" && break
  sleep 0.2
done
python3 -c 'import json,sys; s=json.load(open(sys.argv[1])); assert s.get("activeJobs",0)==0 and int(s.get("inflightBytes",0))==0, s' \
  "$work/stats.json" || fail "still busy after the client left: $(cat "$work/stats.json")"
"$MLSREG" health --server "$A" | grep -qx SERVING || fail "not serving after the cancel"
grep -q "AlignScans.*CANCELLED" "$work/server.log" || fail "no cancelled AlignScans in the log: $(tail -5 "$work/server.log")"
echo "align service: all checks passed"
