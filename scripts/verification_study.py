#!/usr/bin/env python3
"""The verdict as a detector: how often a right pose is not verified (false alarm) and a wrong
one is (false confidence), per data set, with `mlsreg verify` and `mlsreg register`.

    python3 scripts/verification_study.py --mlsreg build/mlsreg \
        --set NAME=pairs.csv[,pairs.csv...] [--set ...] [--mismatched NAME=pairs.csv,...] \
        [--jobs 2] [--out study.csv]

For every pair of a --set (manifests `id,source,target,gt`, paths relative to the manifest):
  truth      the ground-truth pose: should verify (not verified = a false alarm);
  rot5/10/15 the truth turned by 5, 10 or 15 degrees about a seeded random axis through the
             source's centroid: should not verify (verified = a false confidence);
  slide5/10/20  the truth slid by 5, 10 or 20 d along the source's dominant direction (the first
             principal axis of its points: along a road, a corridor, a wall), d the target's mean
             nearest-neighbour spacing: should not verify.
A --refined-set is a --set whose ground truth is only approximate (real scans: KITTI's SLAM poses
are good to a few cm, the Stanford .conf poses to about one spacing): its truth is first refined
by `mlsreg register --init GT` (kept when within 1 degree and 10 d of the ground truth; a pair
whose refinement strays is skipped and counted), and the wrong poses are built from that.
For every pair of a --mismatched set (two different objects or places, any gt), `mlsreg register`
with defaults runs and its result should not verify.
Every pose of a --set also gets its distance from the truth, gt_rmse_d (paper Eq. 10: the RMS
displacement of the source points, in d), and a second count judges it by the success criterion
`eval` uses (the paper's: gt_rmse_d < 5): a pose 5 degrees off can be a success (a small view
turned about its centroid moves its points by 1-3 d), and a slide of exactly 5 d is not.
By that criterion a false confidence is a verified pose at 5 d or more; a pose under 5 d that is
refused is a conservative refusal, not a false alarm (only the truth's refusals are those).
Prints one table row per set and kind; --out keeps every run, and --from CSV prints the table
of a kept run again.
"""
import argparse
import concurrent.futures
import csv
import json
import os
import subprocess
import sys
import tempfile

os.environ.setdefault("OMP_NUM_THREADS", "1")
import numpy as np  # noqa: E402

ROTATIONS = [5.0, 10.0, 15.0]
SLIDES_D = [5.0, 10.0, 20.0]
SUCCESS_D = 5.0  # the success criterion of `mlsreg eval` (paper: RMSE < 5 d)


def read_cloud(path):
    import open3d as o3d
    return np.asarray(o3d.io.read_point_cloud(path).points)


def mean_spacing(points):
    from scipy.spatial import cKDTree
    sample = points[np.random.default_rng(0).choice(len(points), min(20000, len(points)), replace=False)]
    d, _ = cKDTree(points).query(sample, k=2)
    return float(np.mean(d[:, 1]))


def rotation(axis, deg):
    axis = axis / np.linalg.norm(axis)
    a = np.radians(deg)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k


def wrong_poses(gt, source, d, seed):
    """The deliberately wrong poses of one pair: (kind, 4x4)."""
    rng = np.random.default_rng(seed)
    moved = source @ gt[:3, :3].T + gt[:3, 3]
    centre = moved.mean(axis=0)
    out = [("truth", gt)]
    for deg in ROTATIONS:
        r = np.eye(4)
        r[:3, :3] = rotation(rng.normal(size=3), deg)
        r[:3, 3] = centre - r[:3, :3] @ centre
        out.append((f"rot{deg:g}", r @ gt))
    _, _, vt = np.linalg.svd(moved - centre, full_matrices=False)
    for s in SLIDES_D:
        t = np.eye(4)
        t[:3, 3] = s * d * vt[0]
        out.append((f"slide{s:g}", t @ gt))
    return out


def ground_truth_rmse_d(source, pose, gt, d):
    """Paper Eq. 10: the RMS distance between the source under `pose` and under `gt`, in d."""
    delta = source @ (pose[:3, :3] - gt[:3, :3]).T + (pose[:3, 3] - gt[:3, 3])
    return float(np.sqrt(np.mean(np.sum(delta * delta, axis=1))) / d)


def pairs_of(manifests):
    out = []
    for manifest in manifests:
        folder = os.path.dirname(os.path.abspath(manifest))
        with open(manifest) as f:
            for row in csv.DictReader(f):
                out.append({"id": row["id"], "source": os.path.join(folder, row["source"]),
                            "target": os.path.join(folder, row["target"]),
                            "gt": np.array([float(v) for v in row["gt"].split()]).reshape(4, 4)})
    return out


def run_json(args, tmp):
    path = os.path.join(tmp, "out.json")
    p = subprocess.run(args + ["--json", path, "--threads", "1"], capture_output=True, text=True)
    if not os.path.exists(path):
        return {"error": (p.stderr or p.stdout).strip()[-200:]}
    return json.load(open(path))


def score_row(pair, kind, v, j):
    """One study row from a verification score `v` (an error, if any, from the run's JSON `j`)."""
    return {"id": pair["id"], "kind": kind, "verified": bool(v.get("verified")),
            "verdict": v.get("verdict", j.get("error", "")),
            **{k: v.get(k, "") for k in ("inlier_fraction", "worst_direction_fraction",
                                         "residual_scale", "pull_fraction", "pull_displacement",
                                         "settle_displacement", "coherent_residual",
                                         "inlier_distance", "noise", "covered",
                                         "worst_direction_samples",
                                         "worst_direction_strength", "worst_direction_error",
                                         "samples", "hidden", "seen_through")}}


def verify(exe, pair, kind, pose):
    with tempfile.TemporaryDirectory() as tmp:
        j = run_json([exe, "verify", "--source", pair["source"], "--target", pair["target"],
                      "--transform", " ".join("%.12g" % v for v in pose.ravel())], tmp)
    return score_row(pair, kind, j, j)


def register(exe, pair):
    with tempfile.TemporaryDirectory() as tmp:
        j = run_json([exe, "register", "--quiet", "--source", pair["source"], "--target",
                      pair["target"]], tmp)
    v = j.get("verification", {})
    return score_row(pair, "mismatched", v, j)


def refine(exe, pair):
    """The registration started at the approximate truth, or None when it strays from it."""
    with tempfile.TemporaryDirectory() as tmp:
        j = run_json([exe, "register", "--quiet", "--source", pair["source"], "--target",
                      pair["target"], "--init", " ".join("%.12g" % v for v in pair["gt"].ravel())],
                     tmp)
    if "transform" not in j:
        return None
    pose = np.array(j["transform"], dtype=float).reshape(4, 4)
    delta = np.linalg.inv(pair["gt"]) @ pose
    angle = np.degrees(np.arccos(np.clip((np.trace(delta[:3, :3]) - 1) / 2, -1, 1)))
    return pose, angle, np.linalg.norm(delta[:3, 3])


def failing(row):
    """Whether a pose fails the success criterion (a slide of exactly 5 d counts as failing)."""
    return row["gt_rmse_d"] >= SUCCESS_D * (1 - 1e-9)


def print_table(rows):
    """One markdown row per set and kind of pose."""
    print("| set | poses | runs | verified | false alarms | false confidences (by kind) | "
          "verified of those failing 5 d | refused under 5 d |")
    print("|---|---|---|---|---|---|---|---|")
    for name in dict.fromkeys(r["set"] for r in rows):
        for group, kinds in (("truth", ("truth",)), ("turned 5-15 deg", tuple(f"rot{d:g}" for d in ROTATIONS)),
                             ("slid 5-20 d", tuple(f"slide{s:g}" for s in SLIDES_D)),
                             ("mismatched (registered)", ("mismatched",))):
            rs = [r for r in rows if r["set"] == name and r["kind"] in kinds]
            if not rs:
                continue
            v = sum(r["verified"] for r in rs)
            right = group == "truth"
            judged = [r for r in rs if r["gt_rmse_d"] != ""]
            wrong = [r for r in judged if failing(r)]
            by_criterion = (f"{sum(r['verified'] for r in wrong)} of {len(wrong)}"
                            if judged and not right else "-")
            refused = (sum(not r["verified"] for r in judged if not failing(r))
                       if judged and not right else "-")
            print(f"| {name} | {group} | {len(rs)} | {v} | {len(rs) - v if right else '-'} | "
                  f"{'-' if right else v} | {by_criterion} | {refused} |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mlsreg")
    ap.add_argument("--from", dest="saved", metavar="CSV",
                    help="print the table of a saved run (--out) instead of running")
    ap.add_argument("--set", action="append", default=[])
    ap.add_argument("--refined-set", action="append", default=[])
    ap.add_argument("--mismatched", action="append", default=[])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--out")
    args = ap.parse_args()
    if args.saved:
        with open(args.saved) as f:
            rows = [{**r, "verified": r["verified"] == "True",
                     "gt_rmse_d": float(r["gt_rmse_d"]) if r["gt_rmse_d"] else ""}
                    for r in csv.DictReader(f)]
        print_table(rows)
        return
    if not args.mlsreg:
        ap.error("--mlsreg is required unless --from is given")
    jobs = []
    specs = [(s, False) for s in args.set] + [(s, True) for s in args.refined_set]
    for spec, refined in specs:
        name, manifests = spec.split("=", 1)
        for k, pair in enumerate(pairs_of(manifests.split(","))):
            source = read_cloud(pair["source"])
            d = mean_spacing(read_cloud(pair["target"]))
            if refined:
                r = refine(args.mlsreg, pair)
                if r is None or r[1] > 1.0 or r[2] > 10 * d:
                    print(f"{name} {pair['id']}: refinement strays from the truth ({r and r[1:]}), "
                          "skipped", file=sys.stderr)
                    continue
                print(f"{name} {pair['id']}: truth refined by {r[1]:.3f} deg, {r[2] / d:.2f} d",
                      file=sys.stderr)
                pair = {**pair, "gt": r[0]}
            for kind, pose in wrong_poses(pair["gt"], source, d, 1000 + k):
                jobs.append((name, verify, (args.mlsreg, pair, kind, pose),
                             ground_truth_rmse_d(source, pose, pair["gt"], d)))
    for spec in args.mismatched:
        name, manifests = spec.split("=", 1)
        for pair in pairs_of(manifests.split(",")):
            jobs.append((name, register, (args.mlsreg, pair), ""))
    rows = []
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        futures = [(name, pool.submit(fn, *a), e) for name, fn, a, e in jobs]
        for i, (name, f, gt_rmse_d) in enumerate(futures):
            row = {"set": name, "gt_rmse_d": gt_rmse_d, **f.result()}
            rows.append(row)
            print(f"[{i + 1}/{len(futures)}] {name} {row['id']} {row['kind']}: {row['verdict']}",
                  file=sys.stderr, flush=True)
    if args.out:
        with open(args.out, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)
    print_table(rows)


if __name__ == "__main__":
    main()
