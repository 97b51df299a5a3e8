#!/usr/bin/env python3
"""mlsreg against Open3D 0.16 on LiDAR pairs with ground truth, in one run, one thread.

    python3 bench/lidar_peers.py --mlsreg build/mlsreg --pairs PAIRS.csv [--pairs ...] \
        [--start prior|identity|both] [--out rows.csv] [--limit N]

Problems: every row of the manifests (`id,source,target,gt`, paths relative to the manifest; the
KITTI set in ../shared/data/real/kitti00_f0000-0015 and the synthetic streets of
scripts/lidar-scenes.sh). Two starts:
  prior     the ground truth moved by 5 degrees about a random axis and 1 m in a random direction
            (an odometry prior), seeded per problem, the same for every method;
  identity  no prior.
Methods, each problem one process (mlsreg) or one call (Open3D), one thread:
  mlsreg        `mlsreg register --threads 1` with default parameters (method auto); the whole
                process is timed (reading both files included);
  o3d-icp       Open3D point-to-plane ICP, both clouds on a 0.3 m voxel grid, normals from 30
                neighbours within 1 m, max correspondence distance 1 m, 100 iterations
                (the everyday LiDAR setting; the prior start only: ICP needs a prior);
  o3d-ransac    Open3D FPFH (0.5 m voxels, 2.5 m radius) + RANSAC (100k trials, 0.999) + the
                ICP above (the identity start).
Open3D's time is its preparation (voxel grid, normals, features) and registration; reading is
not counted. A result within 0.3 m and 1 degree of the ground truth is a success. For mlsreg the
verdict is read from its JSON (`verification.verified`); a verified result outside the tolerance
is a false confidence, a success not verified a false alarm.
"""
import argparse
import csv
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
import numpy as np  # noqa: E402

SUCCESS_M, SUCCESS_DEG = 0.3, 1.0
PRIOR_DEG, PRIOR_M = 5.0, 1.0
ICP_VOXEL, ICP_NORMAL_RADIUS, ICP_MAX_DISTANCE = 0.3, 1.0, 1.0
FPFH_VOXEL = 0.5


def matrix(text):
    return np.array([float(v) for v in text.split()]).reshape(4, 4)


def rotation(axis, deg):
    axis = axis / np.linalg.norm(axis)
    a = np.radians(deg)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(a) * k + (1 - np.cos(a)) * k @ k


def prior_start(gt, seed, degrees=PRIOR_DEG, length=PRIOR_M):
    """The truth moved by `degrees` about a random axis and `length` along a random direction."""
    rng = np.random.default_rng(seed)
    p = np.eye(4)
    p[:3, :3] = rotation(rng.normal(size=3), degrees)
    t = rng.normal(size=3)
    p[:3, 3] = t / np.linalg.norm(t) * length
    return p @ gt


def pose_error(estimate, gt):
    e = np.linalg.inv(gt) @ estimate
    rot = float(np.degrees(np.arccos(np.clip((np.trace(e[:3, :3]) - 1) / 2, -1, 1))))
    return rot, float(np.linalg.norm(estimate[:3, 3] - gt[:3, 3]))


def problems(manifests):
    out = []
    for manifest in manifests:
        folder = os.path.dirname(os.path.abspath(manifest))
        with open(manifest) as f:
            for k, row in enumerate(csv.DictReader(f)):
                out.append({"set": os.path.relpath(folder), "id": row["id"],
                            "source": os.path.join(folder, row["source"]),
                            "target": os.path.join(folder, row["target"]),
                            "gt": matrix(row["gt"]), "seed": 1000 + len(out)})
    return out


def run_mlsreg(exe, problem, start):
    with tempfile.TemporaryDirectory() as tmp:
        result = os.path.join(tmp, "r.json")
        t0 = time.perf_counter()
        p = subprocess.run([exe, "register", "--source", problem["source"], "--target",
                            problem["target"], "--init", " ".join("%.12g" % v for v in start.ravel()),
                            "--threads", "1", "--quiet", "--json", result],
                           capture_output=True, text=True)
        seconds = time.perf_counter() - t0
        if not os.path.exists(result):
            return {"error": p.stderr.strip()[-200:], "seconds": seconds}
        j = json.load(open(result))
    v = j.get("verification", {})
    return {"transform": np.array(j["transform"]).reshape(4, 4), "seconds": seconds,
            "verified": bool(v.get("verified")), "verdict": v.get("verdict", "")}


class Open3D:
    def __init__(self):
        import open3d as o3d
        self.o3d = o3d
        self.cache = {}

    def cloud(self, path):
        if path not in self.cache:
            if len(self.cache) > 8:
                self.cache.clear()
            self.cache[path] = self.o3d.io.read_point_cloud(path)
        return self.cache[path]

    def icp(self, source, target, start):
        o3d = self.o3d
        reg = o3d.pipelines.registration
        s = source.voxel_down_sample(ICP_VOXEL)
        t = target.voxel_down_sample(ICP_VOXEL)
        for c in (s, t):
            c.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=ICP_NORMAL_RADIUS, max_nn=30))
        return reg.registration_icp(s, t, ICP_MAX_DISTANCE, start,
                                    reg.TransformationEstimationPointToPlane(),
                                    reg.ICPConvergenceCriteria(max_iteration=100)).transformation

    def run(self, method, problem, start):
        o3d = self.o3d
        reg = o3d.pipelines.registration
        source, target = self.cloud(problem["source"]), self.cloud(problem["target"])
        t0 = time.perf_counter()
        if method == "o3d-ransac":
            v = FPFH_VOXEL
            s, t = source.voxel_down_sample(v), target.voxel_down_sample(v)
            for c in (s, t):
                c.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2 * v, max_nn=30))
            fs, ft = (reg.compute_fpfh_feature(c, o3d.geometry.KDTreeSearchParamHybrid(radius=5 * v, max_nn=100))
                      for c in (s, t))
            found = reg.registration_ransac_based_on_feature_matching(
                s, t, fs, ft, True, 1.5 * v, reg.TransformationEstimationPointToPoint(False), 3,
                [reg.CorrespondenceCheckerBasedOnEdgeLength(0.9),
                 reg.CorrespondenceCheckerBasedOnDistance(1.5 * v)],
                reg.RANSACConvergenceCriteria(100000, 0.999))
            start = found.transformation
        transform = self.icp(source, target, start)
        return {"transform": np.asarray(transform), "seconds": time.perf_counter() - t0}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mlsreg", required=True)
    ap.add_argument("--pairs", action="append", required=True)
    ap.add_argument("--start", choices=["prior", "identity", "both"], default="both")
    ap.add_argument("--methods", default="mlsreg,o3d-icp,o3d-ransac")
    ap.add_argument("--out", help="one CSV row per run")
    ap.add_argument("--limit", type=int, default=0, help="at most this many problems per manifest")
    args = ap.parse_args()
    manifests = args.pairs
    todo = problems(manifests)
    if args.limit:
        by_set = {}
        for p in todo:
            by_set.setdefault(p["set"], []).append(p)
        todo = [p for ps in by_set.values() for p in ps[:args.limit]]
    starts = ["prior", "identity"] if args.start == "both" else [args.start]
    methods = args.methods.split(",")
    o3d = Open3D() if any(m.startswith("o3d") for m in methods) else None
    rows = []
    for start_kind in starts:
        for problem in todo:
            gt = problem["gt"]
            start = prior_start(gt, problem["seed"]) if start_kind == "prior" else np.eye(4)
            for method in methods:
                if method == "o3d-icp" and start_kind == "identity":
                    continue
                if method == "o3d-ransac" and start_kind == "prior":
                    continue
                r = run_mlsreg(args.mlsreg, problem, start) if method == "mlsreg" else o3d.run(method, problem, start)
                row = {"set": problem["set"], "id": problem["id"], "start": start_kind,
                       "method": method, "seconds": r["seconds"]}
                if "transform" in r:
                    row["rotation_deg"], row["translation_m"] = pose_error(r["transform"], gt)
                    row["success"] = row["rotation_deg"] < SUCCESS_DEG and row["translation_m"] < SUCCESS_M
                else:
                    row.update(rotation_deg=float("nan"), translation_m=float("nan"), success=False)
                row["verified"] = r.get("verified", "")
                row["verdict"] = r.get("verdict", r.get("error", ""))
                rows.append(row)
                print("%-10s %-8s %-28s %-10s rot %7.3f deg  tr %7.3f m  %6.2f s %s %s" % (
                    start_kind, method, problem["id"][:28], problem["set"][-10:], row["rotation_deg"],
                    row["translation_m"], row["seconds"], "ok " if row["success"] else "MISS",
                    row["verdict"]), file=sys.stderr, flush=True)
    if args.out:
        with open(args.out, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)
    summarise(rows)


def summarise(rows):
    print("| set | start | method | successes (0.3 m / 1 deg) | median rotation (deg) | median translation (m) | median time (s) | verified | false confidences | false alarms |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    keys = []
    for r in rows:
        k = (r["set"], r["start"], r["method"])
        if k not in keys:
            keys.append(k)
    for k in keys:
        rs = [r for r in rows if (r["set"], r["start"], r["method"]) == k]
        ok = sum(r["success"] for r in rs)
        med = lambda f: statistics.median(r[f] for r in rs)
        if rs[0]["method"] == "mlsreg":
            ver = sum(r["verified"] is True for r in rs)
            fc = sum(r["verified"] is True and not r["success"] for r in rs)
            fa = sum(r["verified"] is not True and r["success"] for r in rs)
            extra = "%d | %d | %d" % (ver, fc, fa)
        else:
            extra = "- | - | -"
        print("| %s | %s | %s | %d/%d | %.3f | %.3f | %.2f | %s |" % (
            k[0], k[1], k[2], ok, len(rs), med("rotation_deg"), med("translation_m"), med("seconds"), extra))


if __name__ == "__main__":
    main()
