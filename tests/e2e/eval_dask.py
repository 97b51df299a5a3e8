"""End-to-end: `mlsreg eval --dask SCHEDULER` on a local Dask cluster of 2 worker processes
writes the CSV, summary and --json one local `mlsreg eval` writes (the timing columns aside), on
the bundled bunny pairs repeated under other ids (three shards by default: one per worker would
be two); a scheduler nobody listens on is an error naming --dask.
    eval_dask.py MLSREG SOURCE_DIR     (skips, exit 77, without python3-distributed)
"""
import csv
import json
import os
import shutil
import subprocess
import sys
import tempfile

try:
    import distributed
except ImportError:
    print("eval_dask: python3-distributed is not installed: skipped")
    sys.exit(77)

MLSREG, SOURCE = sys.argv[1], sys.argv[2]


def fail(message):
    print(f"FAIL: {message}", file=sys.stderr)
    sys.exit(1)


def without_times(path):
    rows = list(csv.reader(open(path)))
    keep = [i for i, c in enumerate(rows[0])
            if not (c.startswith("time_") or c in ("target_build_s", "trace_elapsed_s"))]
    return [[r[i] for i in keep] for r in rows]


def main():
    work = tempfile.mkdtemp()
    try:
        bunny = os.path.join(SOURCE, "data", "bunny")
        lines = open(os.path.join(bunny, "pairs.csv")).read().splitlines()
        with open(os.path.join(work, "pairs.csv"), "w") as f:
            f.write(lines[0] + "\n")
            for copy in "abc":
                for line in lines[1:]:
                    pid, rest = line.split(",", 1)
                    f.write(f"{pid}_{copy},{rest}\n")
        for name in os.listdir(bunny):
            if name.endswith(".ply"):
                shutil.copy(os.path.join(bunny, name), work)
        run = [MLSREG, "eval", "--pairs", "pairs.csv", "--methods", "cp-sicp,mls-sicp",
               "--samples", "500", "--jobs", "1", "--perturb-angle", "5",
               "--perturb-translation", "5"]
        local = subprocess.run(run + ["--out", "one.csv", "--json", "one.json"], cwd=work,
                               capture_output=True, text=True)
        if local.returncode != 0:
            fail(f"the local run exited {local.returncode}: {local.stderr[-400:]}")
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                      dashboard_address=None) as cluster:
            remote = subprocess.run(run + ["--dask", cluster.scheduler_address, "--dask-shards",
                                           "3", "--out", "dask.csv", "--json", "dask.json"],
                                    cwd=work, capture_output=True, text=True)
        if remote.returncode != 0:
            fail(f"--dask exited {remote.returncode}: {remote.stderr[-600:]}")
        if without_times(os.path.join(work, "one.csv")) != without_times(
                os.path.join(work, "dask.csv")):
            fail("the --dask CSV differs from the local run's")
        one, dask = (json.load(open(os.path.join(work, p))) for p in ("one.json", "dask.json"))
        for m in one["methods"] + dask["methods"]:
            m.pop("median_time_s")
        if one != dask:
            fail(f"the --dask summary differs: {one} vs {dask}")
        # Nobody listens there: one line naming --dask, exit 1.
        dead = subprocess.run(run + ["--dask", "tcp://127.0.0.1:9", "--out", "x.csv"], cwd=work,
                              capture_output=True, text=True)
        if dead.returncode != 1 or "--dask" not in dead.stderr:
            fail(f"an unreachable scheduler: exit {dead.returncode}: {dead.stderr[-300:]}")
        bad = subprocess.run(run + ["--dask", "tcp://127.0.0.1:9", "--shard", "0/2"], cwd=work,
                             capture_output=True, text=True)
        if bad.returncode != 2 or "--dask" not in bad.stderr:
            fail(f"--dask with --shard: exit {bad.returncode}: {bad.stderr[-300:]}")
        print("eval --dask: OK")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
