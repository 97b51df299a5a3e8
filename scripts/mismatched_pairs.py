#!/usr/bin/env python3
"""Mismatched pairs for scripts/any-start.sh: view k of one mesh as the source, view k of the next
mesh as the target, the source scaled about its centroid so that its sampling distance d equals
the target's and moved onto the target's centroid, so that the two shapes are the same size in
the same place and only their form differs. Writes the scaled sources and a manifest
(id,source,target,gt with identity gt) to OUT.

    python3 scripts/mismatched_pairs.py SCANS OUT [SIGMA]

SIGMA names the noise level of the scans used (default 0.8: sigma0.8/view_*.ply).
"""
import os
import sys

import numpy as np
import open3d as o3d

MESHES = ["elephant", "armadillo", "dino", "homer"]
VIEWS = ["000", "060", "120", "180", "240"]
SIGMA = "0.8"


def main():
    scans, out = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    sigma = sys.argv[3] if len(sys.argv) > 3 else SIGMA
    os.makedirs(out, exist_ok=True)
    rows = ["id,source,target,gt"]
    for k in VIEWS:
        for i, a in enumerate(MESHES):
            b = MESHES[(i + 1) % len(MESHES)]
            source = o3d.io.read_point_cloud(os.path.join(scans, a, f"sigma{sigma}", f"view_{k}.ply"))
            target_path = os.path.join(scans, b, f"sigma{sigma}", f"view_{k}.ply")
            target = o3d.io.read_point_cloud(target_path)
            ds = float(np.mean(source.compute_nearest_neighbor_distance()))
            dt = float(np.mean(target.compute_nearest_neighbor_distance()))
            p = np.asarray(source.points)
            c = p.mean(axis=0)
            scaled = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(
                (p - c) * (dt / ds) + np.asarray(target.points).mean(axis=0)))
            name = f"{a}_as_{b}_{k}.ply"
            o3d.io.write_point_cloud(os.path.join(out, name), scaled)
            rows.append(f"{a}_{b}_{k},{name},{target_path},1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1")
    with open(os.path.join(out, "pairs.csv"), "w") as f:
        f.write("\n".join(rows) + "\n")


if __name__ == "__main__":
    main()
