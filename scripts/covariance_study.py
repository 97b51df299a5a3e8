#!/usr/bin/env python3
"""How far to trust the pose covariance every verification reports: registrations with
defaults on data with exact ground truth, and the truth's distance from each result in the
result's own covariance.

    python3 scripts/covariance_study.py --mlsreg build/mlsreg \
        --set NAME=pairs.csv[,pairs.csv...] [--set ...] [--start prior|manifest] [--out rows.csv]

Each manifest row (`id,source,target,gt[,init]`, paths relative to the manifest) is registered
once by `mlsreg register` with defaults and one thread, from an odometry prior (`prior`, the
default: the truth moved by 5 degrees and 1 m, seeded per problem as bench/lidar_peers.py does)
or from the manifest's `init` column (`manifest`: the object scans' identity starts).
For a verified result with a covariance C (verification.pose_covariance: the motion xi that takes
the result to the truth, rotation vector and translation in the target's frame), the error
xi = log(T_truth * T_result^-1) gives m2 = xi^T C^-1 xi. Were C the error's true covariance,
m2 would follow a chi-square law with 6 degrees of freedom: median 5.35, 95 % under 12.59. The
table prints per set the verified results with a covariance, the median m2, the share under
12.59, and the factor by which C's sigmas would have to grow for the median to be 5.35
(above 1: the covariance is too confident). --out keeps every run, with `shared`: the share of
the residuals' variance that neighbouring samples share (coherent_residual^2 / RMSE^2).
"""
import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "bench"))
import lidar_peers  # noqa: E402  (the prior start and the manifest reader)

CHI2_6_MEDIAN, CHI2_6_95 = 5.348, 12.592


def rotation_vector(r):
    angle = np.arccos(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0))
    if angle < 1e-12:
        return np.zeros(3)
    axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    return axis / (2.0 * np.sin(angle)) * angle


def problems(manifests):
    out = lidar_peers.problems(manifests)
    for manifest in manifests:
        with open(manifest) as f:
            inits = {row["id"]: row.get("init") for row in csv.DictReader(f)}
        for p in out:
            if p["id"] in inits and inits[p["id"]]:
                p["init"] = lidar_peers.matrix(inits[p["id"]])
    return out


def run(exe, problem, start):
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "r.json")
        subprocess.run([exe, "register", "--source", problem["source"], "--target",
                        problem["target"], "--init", " ".join("%.17g" % v for v in start.ravel()),
                        "--threads", "1", "--quiet", "--json", path], capture_output=True)
        if not os.path.exists(path):
            return None
        return json.load(open(path))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--mlsreg", required=True)
    ap.add_argument("--set", action="append", required=True, help="NAME=pairs.csv[,pairs.csv...]")
    ap.add_argument("--start", choices=["prior", "manifest"], default="prior")
    ap.add_argument("--out", help="one CSV row per registration")
    args = ap.parse_args()
    rows = []
    for spec in args.set:
        name, manifests = spec.split("=", 1)
        for p in problems(manifests.split(",")):
            start = (lidar_peers.prior_start(p["gt"], p["seed"]) if args.start == "prior"
                     else p.get("init", np.eye(4)))
            j = run(args.mlsreg, p, start)
            v = (j or {}).get("verification", {})
            row = {"set": name, "id": p["id"], "verified": bool(v.get("verified")),
                   "has_covariance": v.get("pose_covariance") is not None, "m2": float("nan")}
            if j and row["has_covariance"]:
                result = np.array(j["transform"]).reshape(4, 4)
                error = p["gt"] @ np.linalg.inv(result)
                xi = np.concatenate([rotation_vector(error[:3, :3]), error[:3, 3]])
                c = np.array(v["pose_covariance"]).reshape(6, 6)
                row["m2"] = float(xi @ np.linalg.solve(c, xi))
                row["rotation_sigma_deg"] = v["pose_rotation_sigma_deg"]
                rms = v["rmse_d"] * j["sampling_distance"]
                row["shared"] = min(1.0, (v["coherent_residual"] / rms) ** 2) if rms > 0 else 0.0
                row["rotation_error_deg"] = float(np.degrees(np.linalg.norm(xi[:3])))
            rows.append(row)
            print("[%d] %s %s verified %s m2 %.2f" % (len(rows), name, p["id"], row["verified"],
                                                       row["m2"]), flush=True)
    if args.out:
        with open(args.out, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=sorted({k for r in rows for k in r}))
            w.writeheader()
            w.writerows(rows)
    print("| set | runs | verified with a covariance | median m2 (chi2_6: 5.35) | under 12.59 "
          "(chi2_6: 95 %) | sigma factor for a calibrated median |")
    print("|---|---|---|---|---|---|")
    for name in dict.fromkeys(r["set"] for r in rows):
        mine = [r for r in rows if r["set"] == name]
        m2 = np.array([r["m2"] for r in mine if r["verified"] and r["has_covariance"]])
        if len(m2) == 0:
            print("| %s | %d | 0 | - | - | - |" % (name, len(mine)))
            continue
        median = float(np.median(m2))
        print("| %s | %d | %d | %.2f | %.0f %% | %.2f |" % (
            name, len(mine), len(m2), median, 100.0 * np.mean(m2 < CHI2_6_95),
            np.sqrt(median / CHI2_6_MEDIAN)))


if __name__ == "__main__":
    main()
