#!/usr/bin/env python3
"""Registers the same pairs in other units and far from the origin, and compares.

Every pair of a manifest (with ground truth) is written again in three other frames: the
coordinates times 1000 (metres read as millimetres), times 0.001, and shifted by (512345,
5403210, 250), where a national grid (UTM) puts a scan. The start and the truth are mapped with
them. `mlsreg register` runs in each frame with each method (defaults otherwise, one thread),
and the results are mapped back to the manifest's frame: the same data should give the same
pose and the same verdict in any frame.

Reads the scans with Open3D (`apt-get install python3-open3d`, as bench/lidar_peers.py does).

Starts: the manifest's `init` column where it has one, else the truth moved by --prior-deg
degrees and --prior-length (5 degrees and 1 m by default: bench/lidar_peers.py's odometry
prior, for LiDAR manifests without starts; give 0.005 for the bundled bunny, in metres).

  python3 scripts/frame_invariance.py --mlsreg build/mlsreg \
      --pairs ../shared/data/real/kitti00_f0000-0015/pairs.csv --count 4 \
      --methods auto,mls-sicp,g-icp --out frames.csv

Prints, per method and frame, how many results are right (within 1 degree and 5 d of the
truth, d the target's mean spacing), how many verified, and the largest distance of a pose from
the one in the manifest's own frame (rotation in degrees, translation in d).
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "bench"))
import lidar_peers  # noqa: E402  (matrix, prior_start, pose_error)

FRAMES = [
    ("unit", 1.0, np.zeros(3)),
    ("x1000", 1000.0, np.zeros(3)),
    ("x0.001", 0.001, np.zeros(3)),
    ("national-grid", 1.0, np.array([512345.0, 5403210.0, 250.0])),
]


def to_frame(t, scale, offset):
    """(R, t) acting on data mapped by p -> scale p + offset."""
    out = t.copy()
    out[:3, 3] = scale * t[:3, 3] + offset - t[:3, :3] @ offset
    return out


def from_frame(t, scale, offset):
    out = t.copy()
    out[:3, 3] = (t[:3, 3] - offset + t[:3, :3] @ offset) / scale
    return out


def read_points(path):
    import open3d as o3d  # python3-open3d
    return np.asarray(o3d.io.read_point_cloud(path).points, dtype=np.float64)


def write_ply(path, points):
    with open(path, "wb") as f:
        f.write(("ply\nformat binary_little_endian 1.0\nelement vertex %d\n"
                 "property double x\nproperty double y\nproperty double z\nend_header\n"
                 % len(points)).encode())
        f.write(np.ascontiguousarray(points, dtype="<f8").tobytes())


def rotation_deg(a, b):
    r = a[:3, :3].T @ b[:3, :3]
    return float(np.degrees(np.arccos(np.clip((np.trace(r) - 1) / 2, -1, 1))))


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mlsreg", required=True)
    ap.add_argument("--pairs", required=True, action="append")
    ap.add_argument("--count", type=int, default=4, help="pairs per manifest (first ones)")
    ap.add_argument("--methods", default="auto")
    ap.add_argument("--prior-deg", type=float, default=5.0)
    ap.add_argument("--prior-length", type=float, default=1.0)
    ap.add_argument("--out")
    args = ap.parse_args()
    methods = args.methods.split(",")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for manifest in args.pairs:
            folder = os.path.dirname(manifest)
            for k, pair in enumerate(list(csv.DictReader(open(manifest)))[:args.count]):
                gt = lidar_peers.matrix(pair["gt"])
                start = (lidar_peers.matrix(pair["init"]) if pair.get("init") else
                         lidar_peers.prior_start(gt, 1000 + k, args.prior_deg, args.prior_length))
                source = read_points(os.path.join(folder, pair["source"]))
                target = read_points(os.path.join(folder, pair["target"]))
                reference = {}
                for name, scale, offset in FRAMES:
                    s_path = os.path.join(tmp, "s.ply")
                    t_path = os.path.join(tmp, "t.ply")
                    write_ply(s_path, source * scale + offset)
                    write_ply(t_path, target * scale + offset)
                    init = to_frame(start, scale, offset)
                    for method in methods:
                        j_path = os.path.join(tmp, "r.json")
                        run = subprocess.run(
                            [args.mlsreg, "register", "--source", s_path, "--target", t_path,
                             "--init", " ".join("%.17g" % v for v in init.flatten()),
                             "--method", method, "--threads", "1", "--json", j_path, "--quiet"],
                            capture_output=True, text=True)
                        try:
                            result = json.load(open(j_path))
                            os.remove(j_path)
                        except (OSError, ValueError):
                            print("%s %s %s: exit %d %s" % (pair["id"], method, name,
                                                            run.returncode, run.stderr[-200:]))
                            continue
                        pose = from_frame(np.array(result["transform"]).reshape(4, 4), scale,
                                          offset)
                        rot, tr = lidar_peers.pose_error(pose, gt)
                        d = result["sampling_distance"] / scale
                        right = rot <= 1.0 and tr <= 5 * d
                        if name == "unit":
                            reference[method] = pose
                        ref = reference.get(method)
                        rows.append({
                            "pair": pair["id"], "method": method, "frame": name,
                            "rotation_deg": rot, "translation": tr, "right": int(right),
                            "verdict": (result.get("verification") or {}).get("verdict"),
                            "exit": run.returncode, "iterations": result["iterations"],
                            "from_unit_deg": rotation_deg(pose, ref) if ref is not None else "",
                            "from_unit": float(np.linalg.norm(pose[:3, 3] - ref[:3, 3]))
                            if ref is not None else "",
                            "d": d})
                        print("%-22s %-9s %-13s rot %.4f tr %.5f %s exit %d its %d" % (
                            pair["id"], method, name, rot, tr, rows[-1]["verdict"],
                            run.returncode, result["iterations"]), flush=True)
    if args.out and rows:
        with open(args.out, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
            w.writeheader()
            w.writerows(rows)
    print("\n| method | frame | right | verified | largest distance from the unit frame's pose |")
    print("|---|---|---|---|---|")
    for method in methods:
        for name, _, _ in FRAMES:
            sel = [r for r in rows if r["method"] == method and r["frame"] == name]
            if not sel:
                continue
            far_deg = max(float(r["from_unit_deg"] or 0) for r in sel)
            far_d = max(float(r["from_unit"] or 0) / r["d"] for r in sel)
            print("| %s | %s | %d/%d | %d/%d | %.4f deg, %.3f d |" % (
                method, name, sum(r["right"] for r in sel), len(sel),
                sum(r["verdict"] == "verified" for r in sel), len(sel), far_deg, far_d))


if __name__ == "__main__":
    main()
