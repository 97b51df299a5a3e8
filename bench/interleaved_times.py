#!/usr/bin/env python3
"""Two mlsreg binaries timed against each other, problem by problem.

    python3 bench/interleaved_times.py --scans build/tuning/scans [--threads N] OLD NEW
    python3 bench/interleaved_times.py --pairs LIDAR_PAIRS.csv [--repeat K] [--start identity] OLD NEW

Each problem of each noise level (sigma0, sigma0.8, sigma2 of every mesh under --scans), or each
LiDAR pair of --pairs (from bench/lidar_peers.py's prior: the truth moved by 5 degrees and 1 m; or
from the identity with --start identity), is
run as a whole `mlsreg register` process with defaults and --threads (1 unless given), first with
OLD, then with NEW, so that the machine's drift hits both alike. Prints per level (or set) the
median wall time of each binary and the median of the per-problem ratios NEW / OLD.
"""
import argparse
import csv
import os
import statistics
import subprocess
import time


def timed(binary, source, target, init, threads):
    start = time.perf_counter()
    subprocess.run([binary, "register", "--source", source, "--target", target, "--init", init,
                    "--threads", str(threads), "--quiet"],
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def report(label, times, old, new):
    ratio = statistics.median(n / o for o, n in zip(times[old], times[new]))
    print(f"{label}: old {statistics.median(times[old]):.3f} s, "
          f"new {statistics.median(times[new]):.3f} s, median ratio new/old {ratio:.3f} "
          f"({len(times[old])} problems)")


def object_problems(scans, sigma):
    meshes = sorted(m for m in os.listdir(scans) if os.path.isdir(os.path.join(scans, m)))
    for mesh in meshes:
        folder = os.path.join(scans, mesh, f"sigma{sigma}")
        for row in csv.DictReader(open(os.path.join(folder, "pairs.csv"))):
            yield (os.path.join(folder, row["source"]), os.path.join(folder, row["target"]),
                   row["init"])


def lidar_problems(manifest, start_kind):
    import lidar_peers  # the same prior starts as the peer comparison
    import numpy as np
    for problem in lidar_peers.problems([manifest]):
        start = (lidar_peers.prior_start(problem["gt"], problem["seed"]) if start_kind == "prior"
                 else np.eye(4))
        yield problem["source"], problem["target"], " ".join("%.12g" % v for v in start.ravel())


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scans", default="build/tuning/scans")
    ap.add_argument("--levels", default="0,0.8,2")
    ap.add_argument("--pairs", action="append", default=[], help="LiDAR manifest (repeatable)")
    ap.add_argument("--repeat", type=int, default=1, help="runs of each problem per binary")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--start", choices=["prior", "identity"], default="prior",
                    help="LiDAR pairs: from the prior (default) or the identity")
    ap.add_argument("old")
    ap.add_argument("new")
    args = ap.parse_args()
    sets = ([(os.path.relpath(m), list(lidar_problems(m, args.start))) for m in args.pairs]
            if args.pairs else
            [(f"sigma {s} d", list(object_problems(args.scans, s))) for s in args.levels.split(",")])
    for label, problems in sets:
        times = {args.old: [], args.new: []}
        for source, target, init in problems:
            for _ in range(args.repeat):
                for binary in (args.old, args.new):
                    times[binary].append(timed(binary, source, target, init, args.threads))
        report(label, times, args.old, args.new)


if __name__ == "__main__":
    main()
