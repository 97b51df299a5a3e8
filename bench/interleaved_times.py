#!/usr/bin/env python3
"""Two mlsreg binaries timed against each other on the tuning split, problem by problem.

    python3 bench/interleaved_times.py --scans build/tuning/scans [--threads N] OLD NEW

Each problem of each noise level (sigma0, sigma0.8, sigma2 of every mesh under --scans) is run as
a whole `mlsreg register` process with defaults and --threads (1 unless given), first with OLD,
then with NEW, so that the machine's drift hits both alike. Prints per level the median wall time of each
binary and the median of the per-problem ratios NEW / OLD.
"""
import argparse
import csv
import os
import statistics
import subprocess
import time


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scans", default="build/tuning/scans")
    ap.add_argument("--levels", default="0,0.8,2")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("old")
    ap.add_argument("new")
    args = ap.parse_args()
    meshes = sorted(m for m in os.listdir(args.scans) if os.path.isdir(os.path.join(args.scans, m)))
    for sigma in args.levels.split(","):
        times = {args.old: [], args.new: []}
        for mesh in meshes:
            folder = os.path.join(args.scans, mesh, f"sigma{sigma}")
            for row in csv.DictReader(open(os.path.join(folder, "pairs.csv"))):
                for binary in (args.old, args.new):
                    start = time.perf_counter()
                    subprocess.run([binary, "register", "--source", os.path.join(folder, row["source"]),
                                    "--target", os.path.join(folder, row["target"]), "--init", row["init"],
                                    "--threads", str(args.threads), "--quiet"],
                                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
                    times[binary].append(time.perf_counter() - start)
        ratio = statistics.median(n / o for o, n in zip(times[args.old], times[args.new]))
        print(f"sigma {sigma} d: old {statistics.median(times[args.old]):.3f} s, "
              f"new {statistics.median(times[args.new]):.3f} s, median ratio new/old {ratio:.3f} "
              f"({len(times[args.old])} problems)")


if __name__ == "__main__":
    main()
