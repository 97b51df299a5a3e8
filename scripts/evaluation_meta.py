#!/usr/bin/python3
"""Writes meta.json for plot_evaluation.py: wall times, machine, meshes and the hand-written notes.

Usage: evaluation_meta.py --out meta.json --scan-log scan.log --wall scan=1.0 total=2.0 ...
                          --bunny-mesh PATH --meshes-dir DIR --notes docs/evaluation-notes.md
The notes file holds four sections, "## Parameters", "## Tuning split", "## Registration from
any start" (the figures of scripts/any-start.sh) and "## Many scans into one frame"
(scripts/multiview-eval.sh), copied verbatim.
"""
import argparse
import datetime
import json
import os
import re


def machine():
    model = "unknown CPU"
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    memory = ""
    try:
        with open("/proc/meminfo") as f:
            kb = int(f.readline().split()[1])
            memory = f", {kb / 2**20:.0f} GiB RAM"
    except (OSError, ValueError, IndexError):
        pass
    return f"{os.cpu_count()} cores ({model}){memory}"


def meshes(scan_log, bunny_mesh, meshes_dir):
    pattern = re.compile(r"^(\S+): (\d+) vertices, (\d+) triangles; \d+ views, ([\d.]+) points per "
                         r"view, d = ([\d.eE+-]+)")
    result = {}
    with open(scan_log) as f:
        for line in f:
            m = pattern.match(line)
            if not m:
                continue
            name = m.group(1)
            source = ("Stanford bunny reconstruction (bun_zipper.ply, ../shared/data/real)"
                      if name == "bunny" else f"CGAL example mesh data/meshes/{name}.off "
                      "(Debian libcgal-demo)")
            result[name] = {"source": source, "vertices": int(m.group(2)),
                            "triangles": int(m.group(3)), "points_per_view": float(m.group(4)),
                            "d": float(m.group(5))}
    return result


def notes(path):
    sections = {}
    current = None
    with open(path) as f:
        for line in f:
            heading = re.match(r"^## (.+?)\s*$", line)
            if heading:
                current = heading.group(1).lower()
                sections[current] = ""
            elif current:
                sections[current] += line
    return {"parameters": sections.get("parameters", "").strip(),
            "tuning": sections.get("tuning split", "").strip(),
            "any_start": sections.get("registration from any start", "").strip(),
            "multiview": sections.get("many scans into one frame", "").strip()}


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", required=True)
    parser.add_argument("--scan-log", required=True)
    parser.add_argument("--wall", nargs="*", default=[])
    parser.add_argument("--bunny-mesh", default="")
    parser.add_argument("--meshes-dir", default="")
    parser.add_argument("--notes", default="")
    args = parser.parse_args()
    meta = {
        "command": "bash scripts/evaluate.sh",
        "started": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d"),
        "wall_seconds": {k: float(v) for k, v in (w.split("=", 1) for w in args.wall)},
        "machine": machine(),
        "meshes": meshes(args.scan_log, args.bunny_mesh, args.meshes_dir),
    }
    if args.notes and os.path.exists(args.notes):
        meta.update(notes(args.notes))
    with open(args.out, "w") as f:
        json.dump(meta, f, indent=2, sort_keys=True)


if __name__ == "__main__":
    main()
