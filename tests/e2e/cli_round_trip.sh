#!/usr/bin/env bash
# End-to-end: the real `mlsreg serve` on 127.0.0.1, driven by the real CLI client.
# Checks: upload/get/list, a streamed remote registration whose transform equals the local one,
# bad input answered with the right status, batch with one failing job exits 1 and writes the
# rest, --resume skips done jobs, health, stats, SIGTERM drains and exits 0.
set -euo pipefail
MLSREG=$1
SRC=$2
cd "$SRC"
source scripts/lib-server.sh
work=$(mktemp -d)
trap 'kill "${MLSREG_SERVER_PID:-}" 2>/dev/null || true; rm -rf "$work"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

start_server "$work/server.log" --workers 2
A=$MLSREG_SERVER_ADDRESS
"$MLSREG" health --server "$A" | grep -qx SERVING || fail "health is not SERVING"

"$MLSREG" targets upload --server "$A" --id bun045 data/bunny/bun045.ply > "$work/upload.txt"
grep -q "^bun045 .*ready .*40097 points" "$work/upload.txt" || fail "upload: $(cat "$work/upload.txt")"
"$MLSREG" targets list --server "$A" | grep -q "^1 targets" || fail "list"
# The same id with the same content is idempotent; with other content it is refused.
"$MLSREG" targets upload --server "$A" --id bun045 data/bunny/bun045.ply > "$work/again.txt" ||
  fail "re-upload of the same content failed"
if "$MLSREG" targets upload --server "$A" --id bun045 data/bunny/bun000.ply 2> "$work/dup.txt"; then
  fail "upload of other content under a taken id succeeded"
fi
grep -q "ALREADY_EXISTS" "$work/dup.txt" || fail "duplicate: $(cat "$work/dup.txt")"
if "$MLSREG" targets get --server "$A" nope 2> "$work/nf.txt"; then fail "unknown target found"; fi
grep -q "NOT_FOUND" "$work/nf.txt" || fail "unknown target: $(cat "$work/nf.txt")"

# Remote and local registrations of the same inputs give the same transform.
GT=$(awk -F, '$1 == "bun000_bun045" { print $4 }' data/bunny/pairs.csv)
args=(--source data/bunny/bun000.ply --init "$GT" --gt "$GT" --perturb-angle 5 --perturb-translation 5
      --samples 1000 --json)
"$MLSREG" register --server "$A" --target bun045 "${args[@]}" "$work/remote.json" > "$work/remote.txt"
"$MLSREG" register --target data/bunny/bun045.ply "${args[@]}" "$work/local.json" \
  --aligned "$work/aligned.ply" --merged "$work/merged.ply" --plot "$work/plot.png" > "$work/local.txt"
# The convergence plot is a PNG (matplotlib's 880 x 715 at 110 dpi).
python3 - "$work/plot.png" <<'PY' || fail "--plot"
import struct, sys
data = open(sys.argv[1], "rb").read()
assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR", data[:16]
assert struct.unpack(">II", data[16:24]) == (880, 715), struct.unpack(">II", data[16:24])
assert len(data) > 20000, len(data)
PY
# The result clouds: the aligned source with its distance to the target's MLS surface (scalar
# field and colour ramp), and both clouds merged.
python3 - "$work/aligned.ply" "$work/merged.ply" <<'PY' || fail "--aligned / --merged clouds"
import statistics, struct, sys
def read(path):
    data = open(path, "rb").read()
    end = data.index(b"end_header\n") + 11
    header = data[:end].decode().splitlines()
    n = int(next(l for l in header if l.startswith("element vertex")).split()[2])
    props = [l.split() for l in header if l.startswith("property")]
    fmt = "<" + "".join({"double": "d", "float": "f", "uchar": "B"}[p[1]] for p in props)
    size = struct.calcsize(fmt)
    rows = [struct.unpack_from(fmt, data, end + i * size) for i in range(n)]
    assert len(data) == end + n * size, (len(data), end, n, size)
    return [p[2] for p in props], rows
names, rows = read(sys.argv[1])
assert names == ["x", "y", "z", "distance_d", "red", "green", "blue"], names
assert len(rows) == 40256, len(rows)
d = [r[3] for r in rows]
assert statistics.median(d) < 0.5 and min(d) >= 0, statistics.median(d)
near = [r for r in rows if r[3] < 0.1]
assert near and all(r[6] > 200 and r[4] == 0 for r in near), near[:3]  # blue where it fits
names, rows = read(sys.argv[2])
assert names == ["x", "y", "z", "cloud", "red", "green", "blue"], names
assert len(rows) == 40256 + 40097 and sum(r[3] for r in rows) == 40097, len(rows)
PY
if "$MLSREG" register --server "$A" --target bun045 --source data/bunny/bun000.ply \
    --aligned "$work/x.ply" 2> "$work/aligned_remote.txt"; then fail "--aligned with --server accepted"; fi
grep -q -- "--aligned and --merged need the target's cloud" "$work/aligned_remote.txt" \
  || fail "--aligned with --server: $(cat "$work/aligned_remote.txt")"
iterations=$(grep -Ec "^\[(coarse|start|finish)\] iter " "$work/remote.txt")
[ "$iterations" -ge 2 ] || fail "remote stream printed $iterations iterations"
python3 - "$work/remote.json" "$work/local.json" <<'PY' || fail "remote and local transforms differ"
import json, sys
r, l = (json.load(open(p)) for p in sys.argv[1:3])
assert r["transform"] == l["transform"], (r["transform"], l["transform"])
assert r["ground_truth"]["success"], r["ground_truth"]
# The automatic MLS radius and the noise it was chosen from cross the wire.
for k in ("mls_radius_d", "mls_radius_auto", "target_noise_sigma_d", "source_noise_sigma_d"):
    assert r[k] == l[k], (k, r[k], l[k])
assert r["mls_radius_auto"] and r["mls_radius_d"] == 5.0, r
assert 0.0 < r["target_noise_sigma_d"] < 0.5, r
# The default method is auto; near the truth the voxel clouds are aligned and verify, and (clean
# scans: a plane-to-plane finish) go straight to the finish: no refinement, no global stage.
assert r["method"] == "auto" and l["method"] == "auto", (r["method"], l["method"])
for j in (r, l):
    assert j["auto"]["verified"] and j["auto"]["early_exit"], j["auto"]
    assert len(j["auto"]["candidates"]) == 1 and j["auto"]["chosen"] == 0, j["auto"]
    assert [t["stage"] for t in j["trace"]][0] == "coarse", j["trace"][0]
    stages = [t["stage"] for t in j["trace"]]
    assert stages[-1] == "finish" and "start" not in stages and "global" not in stages, stages
    # The verified pose is polished by the finish the noise chooses, and says which and why.
    f = j["auto"]["finish"]
    assert f["kept"] and f["kind"] == ("plane-to-plane" if f["noise_d"] < f["crossover_d"] else "mls"), f
    assert j["verification"]["verified"] and j["verification"]["verdict"] == "verified", j
    # The pose covariance (row-major 6 x 6, symmetric) and its extent, in --json as on the wire.
    c = j["verification"]["pose_covariance"]
    assert len(c) == 36 and all(c[6 * a + b] == c[6 * b + a] for a in range(6) for b in range(6)), c
    assert all(c[7 * k] > 0 for k in range(6)) and j["verification"]["pose_translation_sigma"] > 0, c
assert r["verification"] == l["verification"], (r["verification"], l["verification"])
PY
grep -q "^verification: verified: " "$work/remote.txt" || fail "no verification line: $(tail -5 "$work/remote.txt")"
grep -q "^verification: verified: .*; pose uncertainty (1 sigma, least certain direction): " "$work/remote.txt" \
  || fail "no pose uncertainty in the verification line: $(grep '^verification' "$work/remote.txt")"

# Another object is not verified: exit code 4, "NOT VERIFIED", auto.verified false in --json.
python3 - "$work/sheet.xyz" <<'PY'
import math, random, sys
random.seed(3)
with open(sys.argv[1], "w") as f:
    for _ in range(20000):  # a bumpy sheet about the bunny's size, through its middle
        x, y = random.uniform(-0.05, 0.05), random.uniform(-0.05, 0.05)
        z = 0.01 * math.sin(60 * x) * math.cos(40 * y)
        f.write(f"{x - 0.02:.6f} {y + 0.1:.6f} {z:.6f}\n")
PY
status=0
"$MLSREG" register --target data/bunny/bun045.ply --source "$work/sheet.xyz" --json "$work/sheet.json" \
  > "$work/sheet.txt" 2>&1 || status=$?
[ "$status" -eq 4 ] || fail "mismatched pair: exit $status, not 4: $(tail -5 "$work/sheet.txt")"
grep -q "NOT VERIFIED" "$work/sheet.txt" || fail "mismatched pair: $(tail -5 "$work/sheet.txt")"
grep -q "^\[global\] " "$work/sheet.txt" || fail "no global stage line: $(head -20 "$work/sheet.txt")"
python3 -c "import json,sys; j=json.load(open(sys.argv[1])); assert not j['auto']['verified'] and not j['verification']['verified'], j['auto']; assert j['auto']['stage_seconds']['global'] > 0" "$work/sheet.json" \
  || fail "mismatched pair: --json says verified"
grep -q "MLS radius: 5.00 d (auto" "$work/remote.txt" || fail "no radius line: $(head -3 "$work/remote.txt")"
"$MLSREG" targets get --server "$A" bun045 | grep -q "noise 0\." || fail "targets get shows no noise"
"$MLSREG" targets get --server "$A" bun045 --json | python3 -c "import json,sys; j=json.load(sys.stdin); assert j['id'] == 'bun045' and j['points'] == 40097 and 0 < j['noise_sigma_d'] < 0.5, j" \
  || fail "targets get --json"
"$MLSREG" targets list --server "$A" --json | python3 -c "import json,sys; assert 'bun045' in [t['id'] for t in json.load(sys.stdin)]" \
  || fail "targets list --json"
"$MLSREG" health --server "$A" --json | python3 -c "import json,sys; j=json.loads(sys.stdin.readline()); assert j['serving'] and j['status'] == 'SERVING', j" \
  || fail "health --json"

# Bad input is refused with INVALID_ARGUMENT naming the field.
if "$MLSREG" register --server "$A" --target bun045 --source data/bunny/bun000.ply --mls-radius -1 \
    2> "$work/bad.txt"; then fail "negative radius accepted"; fi
grep -q -- "--mls-radius must be in" "$work/bad.txt" || fail "bad radius: $(cat "$work/bad.txt")"

# Batch: three jobs, one with a missing source; exit 1, two ok rows; --resume re-runs only that one.
cat > "$work/jobs.csv" <<CSV
id,source,target,gt
a,$SRC/data/bunny/bun000.ply,$SRC/data/bunny/bun045.ply,$GT
b,$SRC/data/bunny/missing.ply,$SRC/data/bunny/bun045.ply,$GT
c,$SRC/data/bunny/bun315.ply,$SRC/data/bunny/bun000.ply,$(awk -F, '$1 == "bun315_bun000" { print $4 }' data/bunny/pairs.csv)
CSV
set +e
"$MLSREG" batch --server "$A" --manifest "$work/jobs.csv" --results "$work/results.csv" \
  --samples 500 --concurrency 2 --report "$work/report.html" 2> "$work/batch.log"
code=$?
set -e
[ "$code" -eq 1 ] || fail "batch with a failing job exited $code: $(cat "$work/batch.log")"
[ "$(grep -c ',ok,' "$work/results.csv")" -eq 2 ] || fail "batch rows: $(cat "$work/results.csv")"
grep -q '^b,.*missing.ply' "$work/results.csv" || fail "failed job not reported"
# Every ok row carries its verdict and the pose covariance's extent, the failed one neither.
python3 - "$work/results.csv" <<'PY' || fail "batch verdict columns: $(cat "$work/results.csv")"
import csv, sys
rows = {r["id"]: r for r in csv.DictReader(open(sys.argv[1]))}
for job in "ac":
    r = rows[job]
    assert r["verified"] == "1" and r["verdict"] == "verified", r
    assert float(r["pose_rotation_sigma_deg"]) > 0 and float(r["pose_translation_sigma"]) > 0, r
assert rows["b"]["verdict"] == "" and rows["b"]["pose_translation_sigma"] == "", rows["b"]
PY
# Any method's verdict reaches the batch row, not only auto's, and agrees with the truth: G-ICP
# from the identity, 45 degrees off the truth, ends far from it (a row not verified, as its
# verdict says, and exit 4: every job ran, one result must not be trusted); from the truth it
# verifies (exit 0; JSONL: the covariance in full).
head -2 "$work/jobs.csv" > "$work/one_job.csv"
{ echo "id,source,target,gt,init"; tail -1 "$work/one_job.csv" | sed 's/^a,/near,/'; } > "$work/near_job.csv"
sed -i "2s/\$/,$GT/" "$work/near_job.csv"
for job in one_job near_job; do
  set +e
  "$MLSREG" batch --server "$A" --manifest "$work/$job.csv" --results "$work/$job.jsonl" \
    --method g-icp --samples 500 2> "$work/$job.log"
  echo $? > "$work/$job.code"
  set -e
done
[ "$(cat "$work/one_job.code")" -eq 4 ] || fail "batch with an unverified result exited $(cat "$work/one_job.code"): $(cat "$work/one_job.log")"
[ "$(cat "$work/near_job.code")" -eq 0 ] || fail "batch with every result verified exited $(cat "$work/near_job.code")"
grep -q "1 done (1 of them not verified), 0 failed" "$work/one_job.log" || fail "batch summary: $(cat "$work/one_job.log")"
python3 - "$work/one_job.jsonl" "$work/near_job.jsonl" <<'PY' || fail "g-icp batch rows: $(cat "$work"/*_job.jsonl)"
import json, sys
far, near = (json.loads(open(path).readline()) for path in sys.argv[1:])
assert far["verified"] is False and far["verdict"] not in ("", "verified") and not far["success"], far
assert near["verified"] is True and near["verdict"] == "verified" and near["success"], near
assert len(near["pose_covariance"]) == 36 and near["pose_translation_sigma"] > 0, near
PY
# The HTML report: self-contained (nothing to fetch), the failure first, every job in the table,
# the alpha-recall curve (ground truth is known) and the latency histogram.
python3 - "$work/report.html" <<'PY' || fail "--report: $(head -c 600 "$work/report.html")"
import re, sys
html = open(sys.argv[1]).read()
assert html.startswith("<!DOCTYPE html>") and html.rstrip().endswith("</html>")
assert not re.search(r"<(script|link|img|iframe)\b|url\(|@import", html), "external resource"
assert set(re.findall(r"https?://[^'\"]+", html)) <= {"http://www.w3.org/2000/svg"}
assert "3: 2 ok, 1 failed" in html and "2 of 2 jobs with ground truth" in html
rows = re.findall(r"<tr class='(failed|doubtful|ok)'><td>([abc])</td>", html)
assert [r[1] for r in rows] == ["b", "b", "a", "c"] or [r[1] for r in rows] == ["b", "b", "c", "a"], rows
assert html.count("<svg ") == 2 and "alpha-recall" in html and "latency" in html
PY
set +e
"$MLSREG" batch --server "$A" --manifest "$work/jobs.csv" --results "$work/results.csv" --resume \
  --samples 500 2> "$work/resume.log"
set -e
grep -q "1 jobs (2 already done)" "$work/resume.log" || fail "resume did not skip: $(cat "$work/resume.log")"

"$MLSREG" stats --server "$A" > "$work/stats.json"
grep -q '"rpc": "Register"' "$work/stats.json" || fail "stats: $(head -c 400 "$work/stats.json")"

stop_server || fail "server exited non-zero after SIGTERM: $(tail -5 "$work/server.log")"
echo "cli round trip: all checks passed"
