#!/usr/bin/env python3
"""The numbers and claims of the documentation that a run produces agree with that run.

usage: docs_numbers_test.py SOURCE_DIR MLSREG_BINARY
  - the README gives one evaluation time, the one docs/evaluation.md's last run measured;
  - reflection is never listed as served on port 50051 without saying it is off by default (the
    server's default, checked by ServerLifecycleTest.ReflectionIsOffByDefault);
  - `mlsreg serve --help` says so too, and `mlsreg register --help` names every cloud format
    the readers take.
The bytes a cached target holds per point (docs/operations.md) are measured by
tests/unit/target_test.cc, which needs the library.
"""
import os
import re
import subprocess
import sys

src, binary = sys.argv[1], sys.argv[2]
failures = []


def check(condition, what):
    if not condition:
        failures.append(what)


def read(path):
    with open(os.path.join(src, path)) as f:
        return f.read()


readme, evaluation = read("README.md"), read("docs/evaluation.md")

# One evaluation time in the README, equal to the measured total of docs/evaluation.md.
total = re.search(r"^\| total \| ([0-9.]+) \|$", evaluation, re.M)
check(total, "docs/evaluation.md has no measured total (Runtime table)")
times = re.findall(r"scripts/evaluate\.sh` in ([0-9.]+) s", readme)
check(len(times) == 1, f"the README gives {len(times)} times for scripts/evaluate.sh, not one")
check(not re.search(r"about \d+ minutes", readme),
      "the README gives an evaluation time in minutes beside the measured one")
if total and times:
    check(round(float(times[0])) == round(float(total.group(1))),
          f"the README says scripts/evaluate.sh takes {times[0]} s, docs/evaluation.md measured "
          f"{total.group(1)} s: copy the measured total into the README")

# Reflection: opt-in wherever the ports are described.
for path in ["Dockerfile", "docs/operations.md", "README.md", "docs/service.md"]:
    text = read(path)
    for match in re.finditer(r"[^\n]*50051[^\n]*\n[^\n]*", text):
        if "reflection" in match.group(0).lower():
            check(re.search(r"off by default|only with", match.group(0)),
                  f"{path} lists reflection on port 50051 without saying it is off by default: "
                  f"{match.group(0)!r}")

serve_help = subprocess.run([binary, "serve", "--help"], capture_output=True, text=True).stdout
check(re.search(r"--reflection BOOLEAN=(0|false)\b", serve_help),
      "mlsreg serve --help does not show reflection off by default")
register_help = subprocess.run([binary, "register", "--help"], capture_output=True,
                               text=True).stdout
for fmt in ["PLY", "PCD", "XYZ/CSV", "NPY"]:
    check(re.search(r"--source[^\n]*" + re.escape(fmt), register_help),
          f"mlsreg register --help does not name {fmt} for --source")

if failures:
    print("FAIL:\n  " + "\n  ".join(failures), file=sys.stderr)
    sys.exit(1)
print("PASS")
