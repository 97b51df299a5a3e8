# Runs the shards of an `mlsreg eval` on a Dask cluster (`mlsreg eval --dask SCHEDULER`): one task
# per shard, each running `mlsreg eval ... --shard i/N` in a worker, whose CSV comes back to be
# merged by `mlsreg eval --merge` exactly as shards from an Indexed Job are. The workers need the
# same mlsreg binary and the manifests' files at the same paths (a shared file system or image).
#   python3 eval_dask.py INPUT.json OUT_DIR
# INPUT: {"scheduler": ADDRESS, "mlsreg": PATH, "args": [eval flags], "cwd": DIR, "shards": N}
# (N = 0: one shard per worker). Each shard runs in DIR, so relative paths mean what they meant.
# Writes OUT_DIR/shard-<i>.csv. Exit 3: no Dask (distributed) here; 1 with a last stderr line.
import json
import sys

try:
    import distributed
except ImportError as e:
    print(f"cannot import distributed ({e})", file=sys.stderr)
    sys.exit(3)


def run_shard(mlsreg, args, cwd, index, count):
    import os
    import subprocess
    import tempfile
    fd, path = tempfile.mkstemp(suffix=".csv")
    os.close(fd)
    try:
        done = subprocess.run([mlsreg, "eval", *args, "--shard", f"{index}/{count}", "--out", path],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, cwd=cwd)
        # 3: some run missed the success threshold; the rows are still the shard's result.
        if done.returncode not in (0, 3):
            lines = [line for line in done.stderr.splitlines() if line.strip()]
            raise RuntimeError(f"shard {index}/{count} exited {done.returncode}: "
                               f"{lines[-1] if lines else ''}")
        with open(path) as f:
            return f.read()
    finally:
        os.remove(path)


def main():
    with open(sys.argv[1]) as f:
        job = json.load(f)
    out_dir = sys.argv[2]
    client = distributed.Client(job["scheduler"], timeout="15s")
    try:
        count = job["shards"] or max(1, len(client.scheduler_info()["workers"]))
        futures = [client.submit(run_shard, job["mlsreg"], job["args"], job["cwd"], i, count,
                                 pure=False)  # a fresh key per call: never a cached result
                   for i in range(count)]
        for i, future in enumerate(futures):
            text = future.result()
            with open(f"{out_dir}/shard-{i}.csv", "w") as f:
                f.write(text)
            print(f"mlsreg eval: shard {i + 1}/{count} done", file=sys.stderr, flush=True)
    finally:
        client.close()


try:
    main()
except Exception as e:  # one line for the user
    print(f"{type(e).__name__}: {e}", file=sys.stderr)
    sys.exit(1)
