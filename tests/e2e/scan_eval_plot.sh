#!/usr/bin/env bash
# The evaluation pipeline end to end, small: scan the Stanford bunny reconstruction with
# mlsreg-scan (12 views, 160x120, sigma 0 and 2 d), register the neighbouring views with
# `mlsreg eval`, check the ICP methods succeed on every pair and MLS-SICP recovers them to a
# fraction of d, then plot the results and check the figures and report exist.
# Usage: scan_eval_plot.sh <mlsreg-scan> <mlsreg> <source dir>
set -euo pipefail
SCAN=$1
MLSREG=$2
SRC=$3
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mesh=$SRC/../shared/data/real/stanford_bunny/reconstruction/bun_zipper.ply

"$SCAN" --mesh "bunny=$mesh" --out "$work/scans" --views 12 --noise 0,2 --width 160 --height 120 \
  > "$work/scan.log"
grep -q "^bunny: 35947 vertices, 69451 triangles; 12 views" "$work/scan.log"
test -f "$work/scans/bunny/sigma2/view_030.ply.intrinsics"

# Exit status 3 only says some run missed 5 d; the checks below judge the rows.
"$MLSREG" eval --pairs "$work/scans/bunny/sigma0/pairs.csv" --methods cp-sicp,mls-sicp,rc-bl \
  --jobs 2 --out "$work/synthetic.csv" > "$work/eval.txt" || [ $? -eq 3 ]
"$MLSREG" eval --pairs "$work/scans/bunny/sigma2/pairs.csv" --methods mls-sicp --mls-radius 8 \
  --jobs 2 --label "normal + curvature" --out "$work/ablation.csv" >> "$work/eval.txt"
cat "$work/eval.txt"
/usr/bin/python3 - "$work" <<'PY'
import csv, statistics, sys
work = sys.argv[1]
rows = list(csv.DictReader(open(f"{work}/synthetic.csv")))
assert len(rows) == 36, len(rows)
assert all(r["status"] == "ok" for r in rows), [(r["id"], r["method"], r["status"]) for r in rows]
# The ICP methods succeed on every noise-free pair. Reverse calibration is the weakest comparator
# here (about 3 in 4 successes in docs/evaluation.md; some pairs wander near 5 d), so it only has
# to succeed on most.
icp = [r for r in rows if r["method"] in ("cp-sicp", "mls-sicp")]
assert all(r["success"] == "1" for r in icp), \
    [(r["id"], r["method"], r["rmse_d"]) for r in icp if r["success"] != "1"]
rc = [r for r in rows if r["method"] == "rc-bl"]
assert sum(r["success"] == "1" for r in rc) >= 10, [(r["id"], r["rmse_d"]) for r in rc]
mls = [float(r["rmse_d"]) for r in rows if r["method"] == "mls-sicp"]
assert statistics.median(mls) < 0.3, mls  # noise-free views: well below one sampling distance
for r in rows:  # the ground-truth trace ends where the final error is
    assert abs(float(r["trace_error_d"].split()[-1]) - float(r["rmse_d"])) < 1e-3 * max(1, float(r["rmse_d"]))
ablation = list(csv.DictReader(open(f"{work}/ablation.csv")))
assert {r["label"] for r in ablation} == {"normal + curvature"}
# Every verified MLS-SICP result carries its pose covariance: 36 values, symmetric, its rotation
# sigma the square root of the rotation block's largest eigenvalue (in degrees).
import numpy as np
verified = [r for r in rows if r["method"] == "mls-sicp" and r["verified"] == "1"]
assert verified, [(r["id"], r["verdict"]) for r in rows if r["method"] == "mls-sicp"]
for r in verified:
    c = np.array(r["verify_pose_covariance"].split(), float).reshape(6, 6)
    assert np.allclose(c, c.T, rtol=1e-4, atol=1e-30), r["id"]
    sigma = np.degrees(np.sqrt(np.linalg.eigvalsh(c[:3, :3]).max()))
    assert abs(sigma - float(r["verify_pose_rotation_sigma_deg"])) <= 1e-3 * sigma, (r["id"], sigma)
    assert float(r["verify_pose_translation_sigma_d"]) > 0, r["id"]
PY

/usr/bin/python3 "$SRC/scripts/plot_evaluation.py" --results "$work" --figures "$work/figures" \
  --report "$work/evaluation.md" > /dev/null
for f in fig3_boxplots fig4_alpha_recall fig5_rmse_over_time fig7_filter_ablation; do
  test -s "$work/figures/$f.png" || { echo "missing $f.png"; exit 1; }
done
grep -q "MLS-SICP" "$work/evaluation.md"
grep -q "Table 1" "$work/evaluation.md"
echo "scan -> eval -> plot: ok"
