#!/usr/bin/env python3
"""What starting an mlsreg process costs before any work: programs timed against each other.

    python3 bench/process_start.py [--runs N] PROGRAM... 

Runs `PROGRAM --version` N times (default 200), the programs interleaved run by run so that the
machine's drift hits all alike, and prints each one's median and 10th-90th percentile wall time
and how many shared libraries it maps (ldd). `/bin/true` is timed too, as the floor.
Example: the tool with its transport module loaded on demand against a build linking gRPC:
    python3 bench/process_start.py build/mlsreg /tmp/mlsreg-linked
"""
import argparse
import statistics
import subprocess
import time


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=200)
    parser.add_argument("programs", nargs="+")
    args = parser.parse_args()
    commands = [["/bin/true"]] + [[p, "--version"] for p in args.programs]
    times = [[] for _ in commands]
    for _ in range(args.runs):
        for k, command in enumerate(commands):
            start = time.perf_counter()
            subprocess.run(command, stdout=subprocess.DEVNULL, check=True)
            times[k].append(time.perf_counter() - start)
    for command, t in zip(commands, times):
        libraries = subprocess.run(["ldd", command[0]], capture_output=True, text=True).stdout
        count = sum(1 for line in libraries.splitlines() if "=>" in line or "ld-linux" in line)
        q = statistics.quantiles(t, n=10)
        print(f"{command[0]:40s} {1e3 * statistics.median(t):6.2f} ms "
              f"(10-90 %: {1e3 * q[0]:.2f}-{1e3 * q[-1]:.2f})  {count} shared libraries")


if __name__ == "__main__":
    main()
