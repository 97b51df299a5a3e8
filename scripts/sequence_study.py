#!/usr/bin/env python3
"""`mlsreg align` over the synthetic LiDAR sequences, against their exact ground truth.

    python3 scripts/sequence_study.py --mlsreg build/mlsreg [--mlsreg other/mlsreg ...] \
        build/lidar/tuning/street_s1/noise0.03 build/lidar/tuning/street_s2/noise0.01 ...

Each argument is one scene's scans at one noise level (scripts/lidar-scenes.sh: scan_FFFFFF.ply
beside ../poses.csv, the sensor's pose per frame). Every scan of the sequence is aligned with
`--pairs overlap`, method `auto` (the defaults), from an odometry-like start: the true relative
poses chained with an error of about 0.5 degrees and 0.2 m per step (seeded by the scene's
name, the same for every binary). Per binary and sequence it prints the edges (registered,
trusted, kept) and the scans' pose errors in the first scan's frame (translation median, mean
and max in metres; rotation median and max in degrees), and how well each scan's pose covariance
(`pose_covariance` in align's --json) describes its error: m2 = xi^T C^-1 xi with xi the
rotation vector and translation of the origin that take the pose to the truth, which a calibrated
covariance makes chi-square with 6 degrees of freedom (median 5.35, 95 % under 12.59). Each
run's --json is kept in --out.
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import zlib

import numpy as np
from scipy.spatial.transform import Rotation

STEP_ROTATION_DEG = 0.5
STEP_TRANSLATION = 0.2


def true_poses(scans_dir):
    """(scan paths, poses into the first scan's frame) from the scene's poses.csv."""
    with open(os.path.join(scans_dir, "..", "poses.csv")) as f:
        rows = list(csv.DictReader(f))
    world = [np.array(r["sensor_to_world"].split(), float).reshape(4, 4) for r in rows]
    to_first = np.linalg.inv(world[0])
    paths = [os.path.join(scans_dir, "scan_%06d.ply" % int(r["frame"])) for r in rows]
    return paths, [to_first @ w for w in world]


def odometry(truth, seed):
    """The true steps chained, each off by a random turn and shift."""
    rng = np.random.default_rng(seed)
    poses = [truth[0]]
    for previous, current in zip(truth, truth[1:]):
        error = np.eye(4)
        error[:3, :3] = Rotation.from_rotvec(
            np.radians(STEP_ROTATION_DEG) * rng.standard_normal(3) / np.sqrt(3)).as_matrix()
        error[:3, 3] = STEP_TRANSLATION * rng.standard_normal(3) / np.sqrt(3)
        poses.append(poses[-1] @ np.linalg.inv(previous) @ current @ error)
    return poses


def m2_of(scan, truth):
    """xi^T C^-1 xi for one scan of align's --json against its true pose, or None."""
    if scan.get("pose_covariance") is None:
        return None
    pose = np.array(scan["pose"], float).reshape(4, 4)
    w = Rotation.from_matrix(truth[:3, :3] @ pose[:3, :3].T).as_rotvec()
    xi = np.concatenate([w, truth[:3, 3] - pose[:3, 3]])
    c = np.array(scan["pose_covariance"], float).reshape(6, 6)
    return float(xi @ np.linalg.solve(c, xi))


def write_rows(path, poses):
    with open(path, "w") as f:
        for p in poses:
            f.write(" ".join("%.12g" % v for v in p.ravel()) + "\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--mlsreg", action="append", required=True, help="binary (repeatable)")
    parser.add_argument("--out", default="build/sequence-study")
    parser.add_argument("scans", nargs="+", help="a scene's scans at one noise level")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    print("| sequence | binary | scans | edges | trusted | kept | translation median / mean / max (m) "
          "| rotation median / max (deg) | pose sigma median (m) | m2 median / under 12.59 "
          "| time (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for scans_dir in args.scans:
        scene = os.path.basename(os.path.dirname(os.path.abspath(scans_dir)))
        name = f"{scene}_{os.path.basename(os.path.abspath(scans_dir))}"
        paths, truth = true_poses(scans_dir)
        gt_path = os.path.join(args.out, f"{name}_gt.txt")
        start_path = os.path.join(args.out, f"{name}_odometry.txt")
        write_rows(gt_path, truth)
        write_rows(start_path, odometry(truth, zlib.crc32(scene.encode())))
        for k, binary in enumerate(args.mlsreg):
            out = os.path.join(args.out, f"{name}_{k}.json")
            subprocess.run([binary, "align", "--scans", *paths, "--pairs", "overlap", "--poses",
                            start_path, "--gt", gt_path, "--json", out],
                           check=True, stdout=subprocess.DEVNULL)
            j = json.load(open(out))
            d = j["sampling_distance"]
            t = np.array([s["translation_error_d"] for s in j["scans"]]) * d
            r = np.array([s["rotation_error_deg"] for s in j["scans"]])
            edges = j["edges"]
            m2 = [m for m in (m2_of(s, p) for s, p in zip(j["scans"], truth)) if m is not None]
            sigma = [s["pose_translation_sigma"] for s in j["scans"] if s.get("pose_covariance")]
            calibration = (f"{np.median(sigma):.4f} | {np.median(m2):.1f} / "
                           f"{np.mean(np.array(m2) < 12.59):.0%}" if m2 else "- | -")
            print(f"| {name} | {binary} | {len(paths)} | {len(edges)} | "
                  f"{sum(e['trusted'] for e in edges)} | {sum(e['kept'] for e in edges)} | "
                  f"{np.median(t):.4f} / {t.mean():.4f} / {t.max():.4f} | "
                  f"{np.median(r):.4f} / {r.max():.4f} | {calibration} | {j['seconds']:.1f} |",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
