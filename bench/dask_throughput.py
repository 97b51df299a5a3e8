#!/usr/bin/env python3
"""Pairs per second: mlsreg.dask.register_many on a local Dask cluster against `mlsreg eval`.

usage: PYTHONPATH=build/python python3 bench/dask_throughput.py [--build build] [--tasks 24]
                                                                 [--workers 2]

The bundled bunny pairs (data/bunny/pairs.csv) are repeated to --tasks registrations (method
auto, from the identity: a manifest with an init column, so that `mlsreg eval` starts where
register_many does, not at the ground truth) and run
  - on a LocalCluster of --workers processes with one thread each (cluster start-up not
    counted; cold target caches, so each worker builds the targets it is sent), and
  - by `<build>/mlsreg eval --pairs MANIFEST --methods auto --jobs WORKERS` (the process's whole
    wall time: start, reading the clouds, building each target once, registering).
Prints pairs/second for both and their ratio (Dask over eval), and checks that the two agree on
every transform's success against the ground truth.
"""

import argparse
import csv
import os
import pathlib
import subprocess
import sys
import tempfile
import time

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--build", default=str(ROOT / "build"))
    parser.add_argument("--tasks", type=int, default=24)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()

    import distributed
    import mlsreg.dask as md

    base = md.read_manifest(ROOT / "data" / "bunny" / "pairs.csv")
    rows = [dict(base[i % len(base)], id=f"{base[i % len(base)]['id']}_{i}")
            for i in range(args.tasks)]
    identity = " ".join(f"{v:g}" for v in np.eye(4).ravel())

    with tempfile.TemporaryDirectory() as tmp:
        manifest = pathlib.Path(tmp) / "pairs.csv"
        with open(manifest, "w", newline="") as f:
            out = csv.writer(f)
            out.writerow(["id", "source", "target", "gt", "init"])
            for row in rows:
                out.writerow([row["id"], row["source"], row["target"],
                              " ".join(repr(float(v)) for v in row["gt"].ravel()), identity])

        cluster = distributed.LocalCluster(n_workers=args.workers, threads_per_worker=1,
                                           processes=True, dashboard_address=":0",
                                           host="127.0.0.1")
        client = distributed.Client(cluster)
        try:
            start = time.perf_counter()
            results = md.register_many(manifest, client=client, method="auto")
            dask_seconds = time.perf_counter() - start
            stats = client.run(md.worker_stats)
        finally:
            client.close()
            cluster.close()
        errors = [r.error for r in results if r.error]
        if errors:
            print("register_many errors:", errors, file=sys.stderr)
            return 1

        cli = pathlib.Path(args.build) / "mlsreg"
        eval_csv = pathlib.Path(tmp) / "eval.csv"
        start = time.perf_counter()
        subprocess.run([str(cli), "eval", "--pairs", str(manifest), "--methods", "auto",
                        "--jobs", str(args.workers), "--out", str(eval_csv)], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        eval_seconds = time.perf_counter() - start
        with open(eval_csv) as f:
            eval_rows = {r["id"]: r for r in csv.DictReader(f)}

    dask_success = sum(bool(r.success) for r in results)
    eval_success = sum(r.get("success") == "1" for r in eval_rows.values())
    builds = sum(s["builds"] for s in stats.values())
    print(f"pairs: {args.tasks} (bunny x{args.tasks / len(base):g}), method auto, "
          f"{args.workers} workers x 1 thread, {os.cpu_count()} cores")
    print(f"dask register_many: {dask_seconds:7.2f} s  {args.tasks / dask_seconds:6.2f} pairs/s "
          f"({builds} target builds over {len(stats)} workers; {dask_success} successes)")
    print(f"mlsreg eval --jobs {args.workers}: {eval_seconds:7.2f} s  "
          f"{args.tasks / eval_seconds:6.2f} pairs/s ({eval_success} successes)")
    print(f"ratio (dask / eval): {eval_seconds / dask_seconds:.2f}")
    return 0 if dask_success == eval_success == args.tasks else 1


if __name__ == "__main__":
    sys.exit(main())
